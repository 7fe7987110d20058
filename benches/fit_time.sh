#!/usr/bin/env bash
# Whole-process wall time and peak memory of `npf fit` over a folder of
# tables, several option sets side by side: per table, the sets run in
# turn (A B A B ...) RUNS times, so drift of a shared machine falls on all
# of them alike; each set's per-table median is reported, then the median
# and maximum of those over the tables and the largest peak.
#
#   benches/fit_time.sh DATA_DIR RUNS [LABEL=OPTIONS ...]
#   benches/fit_time.sh /tmp/merl 3 default= auto="--model auto"
#
# OPTIONS starting with @PATH run the npf binary at PATH instead of
# target/release/npf (a build from before a change, for example:
# before="@/tmp/old/npf --model auto"). Needs GNU time. Fits go to a
# temporary folder, removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:?usage: benches/fit_time.sh DATA_DIR RUNS [LABEL=OPTIONS ...]}
runs=${2:?usage: benches/fit_time.sh DATA_DIR RUNS [LABEL=OPTIONS ...]}
shift 2
[ $# -gt 0 ] || set -- "default="
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for ref in "$data"/*.binary; do
    name=$(basename "$ref" .binary)
    for ((r = 0; r < runs; r++)); do
        for set in "$@"; do
            label=${set%%=*}
            read -r -a opts <<<"${set#*=}"
            npf=$PWD/target/release/npf
            if [ ${#opts[@]} -gt 0 ] && [[ ${opts[0]} == @* ]]; then
                npf=${opts[0]#@}
                opts=("${opts[@]:1}")
            fi
            rm -f "$work/fit.json"
            /usr/bin/time -f "%e %M" -o "$work/time" "$npf" fit "$ref" -o "$work/fit.json" --quiet "${opts[@]}"
            read -r wall kb <"$work/time"
            echo "$name $label $wall $kb" >>"$work/all"
        done
    done
done
python3 - "$work/all" "$@" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
labels = [s.split('=', 1)[0] for s in sys.argv[2:]]
tables = sorted({r[0] for r in rows})
med = {(t, l): statistics.median(float(r[2]) for r in rows if r[0] == t and r[1] == l) for t in tables for l in labels}
peak = {(t, l): max(int(r[3]) for r in rows if r[0] == t and r[1] == l) / 1024 for t in tables for l in labels}
print('%-24s' % 'table' + ''.join('%20s' % (l + ' s / MB') for l in labels))
for t in tables:
    print('%-24s' % t + ''.join('%20s' % ('%.2f / %.0f' % (med[t, l], peak[t, l])) for l in labels))
for l in labels:
    m = [med[t, l] for t in tables]
    print('%s: median %.2f s, max %.2f s (per-table medians of %d runs), peak %.0f MB'
          % (l, statistics.median(m), max(m), len(rows) // len(tables) // len(labels), max(peak[t, l] for t in tables)))
PY
