#!/usr/bin/env bash
# `npf view` on every measured table of a folder: fit it (npf's default),
# write its page with the table as reference, and open the page in
# headless Chromium. Per table: npf view's wall time, the page's size, the
# time from navigation start until the page is set up (its own
# performance.now() at the end of its script, `data-ready-ms`) and until
# the sphere's first picture is on the canvas (`data-first-frame-ms`:
# the lights and the first environment passes, GPU work finished), the
# whole Chromium run, and the time its sphere takes to render in full
# (`#nt=12&sync`: 291 passes at 256 px, all run before the load ends).
#
#   benches/view_pages.sh DATA_DIR
#   benches/view_pages.sh /tmp/merl
#
# Needs target/release/npf (cargo build --release) and chromium (Debian).
# Fits and pages go to a temporary folder, removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:?usage: benches/view_pages.sh DATA_DIR}
npf=$PWD/target/release/npf
chromium=${NPF_CHROMIUM:-chromium}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
flags=(--headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader --use-angle=swiftshader
    --disable-quic --no-first-run --disable-background-networking --disable-component-update
    --disable-sync --hide-scrollbars --force-device-scale-factor=1)
now() { date +%s.%N; }
printf '%-24s %7s %8s %8s %8s %9s %9s %7s\n' table view_s page_kb ready_ms first_ms chrome_s render_s status
for ref in "$data"/*.binary "$data"/*.bin; do
    [ -e "$ref" ] || continue
    name=$(basename "${ref%.*}")
    "$npf" fit "$ref" -o "$work/$name.json" --quiet
    t0=$(now)
    "$npf" view "$work/$name.json" --reference "$ref" -o "$work/$name.html" --quiet
    t1=$(now)
    # a few seconds of (virtual) time: the first animation frame runs
    dom=$("$chromium" "${flags[@]}" --user-data-dir="$work/profile-$name" --virtual-time-budget=3000 \
        --dump-dom "file://$work/$name.html" 2>/dev/null)
    t2=$(now)
    ready=$(grep -o 'data-ready-ms="[0-9]*"' <<<"$dom" | grep -o '[0-9]*' || echo -)
    first=$(grep -o 'data-first-frame-ms="[0-9]*"' <<<"$dom" | grep -o '[0-9]*' || echo -)
    status=$(grep -o 'data-status="[a-z]*"' <<<"$dom" | cut -d'"' -f2 || echo -)
    sync=$("$chromium" "${flags[@]}" --user-data-dir="$work/profile-$name" --dump-dom "file://$work/$name.html#nt=12&sync" 2>/dev/null)
    full=$(grep -o 'data-ready-ms="[0-9]*"' <<<"$sync" | grep -o '[0-9]*' || echo 0)
    kb=$(($(stat -c %s "$work/$name.html") / 1024))
    printf '%-24s %7.2f %8d %8s %8s %9.2f %9.2f %7s\n' "$name" "$(echo "$t1 - $t0" | bc)" "$kb" "$ready" "$first" \
        "$(echo "$t2 - $t1" | bc)" "$(echo "$full / 1000" | bc -l)" "$status"
done
