#!/usr/bin/env bash
# Issue 45's round trip, scored by the independent scorer
# (../shared/tools/score.py): fit each MERL table of a folder, export the
# fit as an RGL .bsdf, fit that file with each option set, and score every
# fit against the table. One line per table and option set: the render
# PSNR of the table's fit and of the .bsdf's, their difference, the
# .bsdf's size, and the whole-process wall time and peak memory of the
# .bsdf fit.
#
#   benches/rgl_roundtrip.sh DATA_DIR [LABEL=FIT_OPTIONS ...]
#   NPF_EXPORT_OPTS="--samples 96" benches/rgl_roundtrip.sh /tmp/merl default=
#
# NPF_EXPORT_OPTS are passed to `npf export`. Needs target/release/npf
# (cargo build --release), GNU time, bc, and a Python with numpy for the
# scorer (PYTHON, default python3). Files go to a temporary folder,
# removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:?usage: benches/rgl_roundtrip.sh DATA_DIR [LABEL=FIT_OPTIONS ...]}
shift
[ $# -gt 0 ] || set -- "default="
. benches/common/scorer.sh
read -r -a export_opts <<<"${NPF_EXPORT_OPTS:-}"
psnr() { "$python" "$score" "$1" "$2" | "$python" -c 'import json,sys; print("%.3f" % json.load(sys.stdin)["render_psnr"])'; }
printf '%-24s %-10s %9s %9s %7s %8s %7s %7s\n' table options table_db bsdf_db diff_db bsdf_mb wall_s peak_mb
for ref in "$data"/*.binary; do
    name=$(basename "$ref" .binary)
    w=$work/$name
    "$npf" fit "$ref" -o "$w.json" --quiet
    "$npf" reconstruct "$w.json" -o "$w.binary" >/dev/null
    a=$(psnr "$ref" "$w.binary")
    "$npf" export "$w.json" -o "$w.bsdf" --quiet "${export_opts[@]}"
    mb=$(echo "$(stat -c %s "$w.bsdf") / 1048576" | bc -l)
    for set in "$@"; do
        label=${set%%=*}
        read -r -a opts <<<"${set#*=}"
        /usr/bin/time -f "%e %M" -o "$w.time" "$npf" fit "$w.bsdf" -o "$w.rgl.json" --quiet "${opts[@]}"
        "$npf" reconstruct "$w.rgl.json" -o "$w.rgl.binary" >/dev/null
        b=$(psnr "$ref" "$w.rgl.binary")
        read -r wall kb <"$w.time"
        printf '%-24s %-10s %9s %9s %7.2f %8.1f %7.2f %7.0f\n' "$name" "$label" "$a" "$b" \
            "$(echo "$b - $a" | bc -l)" "$mb" "$wall" "$((kb / 1024))"
        rm -f "$w".rgl.*
    done
    rm -f "$w".*
done
