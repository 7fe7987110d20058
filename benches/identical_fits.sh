#!/usr/bin/env bash
# Fits before and after a change, compared bit for bit: the npf of git
# revision REV and the npf of the working tree fit the demo table and every
# measured table of DATA_DIR (optional), each to .npfb (the model's every
# number, nothing else) and to .json; the .npfb files must be identical, and
# the .json files identical but for the fit record's timings.
#
#   benches/identical_fits.sh REV [DATA_DIR] [-- FIT_FLAGS...]
#   benches/identical_fits.sh HEAD~1 /tmp/merl
#   benches/identical_fits.sh main /tmp/merl -- --model auto
#
# REV is built in a temporary git worktree sharing target/ (only npf's own
# crates rebuild). Exits non-zero on the first table whose fits differ.
set -euo pipefail
cd "$(dirname "$0")/.."
rev=${1:?usage: benches/identical_fits.sh REV [DATA_DIR] [-- FIT_FLAGS...]}
shift
data=
if [ $# -gt 0 ] && [ "$1" != "--" ]; then data=$1; shift; fi
[ "${1:-}" = "--" ] && shift
flags=("$@")

work=$(mktemp -d)
cleanup() {
    git worktree remove --force "$work/before-src" >/dev/null 2>&1 || true
    rm -rf "$work"
}
trap cleanup EXIT
target=$(cd "${CARGO_TARGET_DIR:-target}" 2>/dev/null && pwd || echo "$PWD/target")

cargo build --release -q --bin npf
cp "$target/release/npf" "$work/npf-after"
git worktree add -q --detach "$work/before-src" "$rev"
(cd "$work/before-src" && CARGO_TARGET_DIR="$target" cargo build --release -q --bin npf)
cp "$target/release/npf" "$work/npf-before"
# Leave target/release/npf as the working tree's.
cargo build --release -q --bin npf

"$work/npf-after" demo -o "$work/demo" --quiet
tables=("$work/demo/ggx-lambert.binary")
if [ -n "$data" ]; then
    for t in "$data"/*.binary "$data"/*.bin; do [ -e "$t" ] && tables+=("$t"); done
fi

# The JSON files without the fit record's wall times.
strip_times() {
    python3 - "$1" <<'EOF'
import json, sys
def drop(v):
    if isinstance(v, dict):
        return {k: drop(x) for k, x in v.items() if not (k == "seconds" or k.endswith("_seconds") or k.endswith("_ms"))}
    if isinstance(v, list):
        return [drop(x) for x in v]
    return v
print(json.dumps(drop(json.load(open(sys.argv[1]))), sort_keys=True))
EOF
}

printf '%-28s %8s %8s  %s\n' table before_s after_s result
status=0
for t in "${tables[@]}"; do
    name=$(basename "${t%.*}")
    line=()
    for side in before after; do
        s=$(date +%s.%N)
        "$work/npf-$side" fit "$t" -o "$work/$name.$side.npfb" --quiet "${flags[@]}"
        "$work/npf-$side" fit "$t" -o "$work/$name.$side.json" --quiet "${flags[@]}"
        line+=("$(awk -v a="$s" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')")
    done
    if ! cmp -s "$work/$name.before.npfb" "$work/$name.after.npfb"; then
        result="DIFFERENT (.npfb)"
    elif [ "$(strip_times "$work/$name.before.json")" != "$(strip_times "$work/$name.after.json")" ]; then
        result="DIFFERENT (.json)"
    else
        result="identical ($(stat -c %s "$work/$name.after.npfb") bytes)"
    fi
    printf '%-28s %8.2f %8.2f  %s\n' "$name" "${line[0]}" "${line[1]}" "$result"
    case $result in identical*) ;; *) status=1 ;; esac
done
exit $status
