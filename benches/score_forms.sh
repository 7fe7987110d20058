#!/usr/bin/env bash
# Fit every MERL table of a folder with several `npf fit` option sets and
# score each fit with the independent scorer (../shared/tools/score.py):
# render PSNR, log RMSE, and the fit's whole-process wall time and peak
# memory, and for `--model auto` the form it chose. One line per table and
# option set; the option sets of one table run one after the other, so
# their times are comparable.
#
#   benches/score_forms.sh DATA_DIR [LABEL=OPTIONS ...]
#   benches/score_forms.sh /tmp/merl default= separable="--diffuse separable"
#
# Needs target/release/npf (cargo build --release), GNU time, and a Python
# with numpy for the scorer (PYTHON, default python3). Fits and tables go
# to a temporary folder, removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:?usage: benches/score_forms.sh DATA_DIR [LABEL=OPTIONS ...]}
shift
[ $# -gt 0 ] || set -- "default="
. benches/common/scorer.sh
printf '%-24s %-12s %8s %9s %7s %7s  %s\n' table options psnr_db log_rmse wall_s peak_mb chosen
for ref in "$data"/*.binary; do
    name=$(basename "$ref" .binary)
    for set in "$@"; do
        label=${set%%=*}
        read -r -a opts <<<"${set#*=}"
        fit=$work/$name.$label
        /usr/bin/time -f "%e %M" -o "$fit.time" "$npf" fit "$ref" -o "$fit.json" --quiet "${opts[@]}"
        "$npf" reconstruct "$fit.json" -o "$fit.binary" >/dev/null
        read -r wall kb <"$fit.time"
        "$python" "$score" "$ref" "$fit.binary" | "$python" -c "
import json, sys
d = json.load(sys.stdin)
auto = json.load(open('$fit.json'))['fit'].get('selection', {}).get('auto', {})
print('%-24s %-12s %8.3f %9.5f %7.2f %7.0f  %s' % ('$name', '$label', d['render_psnr'], d['log_rmse'], $wall, $kb / 1024, auto.get('chosen', '-')))"
        rm -f "$fit.binary"
    done
done
