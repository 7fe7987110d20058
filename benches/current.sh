#!/usr/bin/env bash
# Re-measures the figures BENCHMARKS.md gives as current, one benchmark
# after the other (never two at once: the machine has 2 cores), each into
# its own log in OUT_DIR. BENCHMARKS.md names the step behind every table.
#
#   benches/current.sh MERL_DIR RGL_DIR OUT_DIR [STEP ...]
#
# Steps (all by default, in this order):
#   forms      benches/score_forms.sh on MERL_DIR and RGL_DIR: every form, scored
#   time       benches/fit_time.sh: whole-process wall time and peak memory
#              of the default fit and of --model auto on every MERL_DIR and
#              RGL_DIR table, 3 runs each, in turn
#   fit        examples/fit_bench on MERL_DIR: sweeps, objective, errors, memory
#   folder     one `npf fit FOLDER -o DIR` of 100 tables (the MERL_DIR and
#              RGL_DIR tables, hard-linked over and over into one folder)
#   aniso      examples/aniso_bench on the synthetic anisotropic catalogue
#   bsdf       criterion eval/sample/pdf throughput on the synthetic model and two fits
#   sampling   examples/sampling_bench on four fits (variance against cosine
#              sampling under an environment, throughput)
#   selection  examples/selection_bench on MERL_DIR (psnr=35, psnr=45)
#   stability  examples/stability_report (351 fits of the hard cases)
#   shader     examples/shader_export_bench
#   export     npf export sizes and times (.bsdf RGB, spectral, .binary)
#   knobs      benches/score_forms.sh with each tuning knob of `npf fit --help`
#              ("Advanced") set away from its default, and the Oren-Nayar and
#              energy-coupled diffuse forms, on four tables: MERL
#              teflon and chrome, RGL chm_mint_rgb and acrylic_felt_white_rgb
#              (docs/fitting.md's table of measured effects)
#   python     examples/python_bench.py (needs the package installed in
#              target/test-venv, as tests/run-all.sh leaves it)
#
# Needs GNU time and a Python with numpy for the scorer (PYTHON).
# Make the tables with ../shared/tools/nbrdf2merl.py (README of ../shared).
set -euo pipefail
cd "$(dirname "$0")/.."
merl=${1:?usage: benches/current.sh MERL_DIR RGL_DIR OUT_DIR [STEP ...]}
rgl=${2:?usage: benches/current.sh MERL_DIR RGL_DIR OUT_DIR [STEP ...]}
out=${3:?usage: benches/current.sh MERL_DIR RGL_DIR OUT_DIR [STEP ...]}
shift 3
[ $# -gt 0 ] || set -- forms time fit folder aniso bsdf sampling selection stability shader export python knobs
mkdir -p "$out"
cargo build --release -q --examples --bin npf
npf=$PWD/target/release/npf
forms=(default= auto="--model auto" independent-g="--model independent-g"
       separable="--diffuse separable" cosine-l2="--weighting cosine-l2")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

step() { # NAME: run the rest, log to OUT/NAME.txt with its wall time
    local name=$1
    shift
    echo "== $name: $* ($(date -u +%H:%M:%S) UTC, load $(cut -d' ' -f1-3 /proc/loadavg))" >&2
    local t0=$SECONDS
    "$@" >"$out/$name.txt" 2>"$out/$name.err"
    echo "   $((SECONDS - t0)) s" >&2
}

for s in "$@"; do
    case $s in
    forms)
        step forms-merl benches/score_forms.sh "$merl" "${forms[@]}"
        step forms-rgl benches/score_forms.sh "$rgl" "${forms[@]}" ;;
    time)
        mkdir -p "$work/all"
        ln -sf "$(realpath "$merl")"/*.binary "$(realpath "$rgl")"/*.binary "$work/all/"
        step time benches/fit_time.sh "$work/all" 3 default= auto="--model auto" ;;
    fit) step fit target/release/examples/fit_bench "$merl" ;;
    folder)
        mkdir -p "$work/f100"
        tables=("$merl"/*.binary "$rgl"/*.binary)
        for i in $(seq 0 99); do
            t=${tables[i % ${#tables[@]}]}
            ln "$t" "$work/f100/$(printf %03d "$i")-$(basename "$t")" 2>/dev/null ||
                ln -s "$(realpath "$t")" "$work/f100/$(printf %03d "$i")-$(basename "$t")"
        done
        step folder /usr/bin/time -f "wall %e s, user %U s, sys %S s, peak %M KiB" "$npf" fit "$work/f100" -o "$work/folder" --form npfb --quiet ;;
    aniso) step aniso target/release/examples/aniso_bench --threads 2 ;;
    bsdf)
        "$npf" fit "$merl/chrome.binary" -o "$work/chrome.npfb" --quiet
        "$npf" fit "$merl/white-fabric.binary" -o "$work/white-fabric.npfb" --quiet
        step bsdf-synthetic cargo bench -q --bench bsdf -- --measurement-time 2 --warm-up-time 1 --output-format bencher
        NPF_BENCH_MODEL=$work/chrome.npfb step bsdf-chrome cargo bench -q --bench bsdf -- --measurement-time 2 --warm-up-time 1 --output-format bencher _batch
        NPF_BENCH_MODEL=$work/white-fabric.npfb step bsdf-white-fabric cargo bench -q --bench bsdf -- --measurement-time 2 --warm-up-time 1 --output-format bencher _batch ;;
    sampling)
        mkdir -p "$work/fits"
        for m in chrome black-obsidian specular-blue-phenolic gold-metallic-paint; do
            "$npf" fit "$merl/$m.binary" -o "$work/fits/$m.json" --quiet
        done
        step sampling target/release/examples/sampling_bench "$work/fits" "$out/sampling.md" "$out/sampling.svg" ;;
    selection) step selection target/release/examples/selection_bench "$merl" psnr=35 psnr=45 ;;
    stability) step stability target/release/examples/stability_report --thin 4 --sweeps 50 ;;
    shader) step shader target/release/examples/shader_export_bench ;;
    export)
        "$npf" fit "$merl/gold-metallic-paint.binary" -o "$work/gold.json" --quiet
        step export sh -c "
            for o in 'm.bsdf' 'm.bsdf --spectral' 'm.bsdf --theta-i 16 --samples 32 --vndf 32 --ndf 64' 'm.binary'; do
                set -- \$o; f=$work/\$1; shift
                /usr/bin/time -f \"\$o: %e s, peak %M KiB\" $npf export $work/gold.json -o \$f --force \"\$@\" >/dev/null
                echo \"\$o: \$(stat -c %s \$f) bytes\"; rm -f \$f
            done" ;;
    knobs)
        mkdir -p "$work/knobs"
        for t in "$merl/teflon.binary" "$merl/chrome.binary" "$rgl/chm_mint_rgb.binary" "$rgl/acrylic_felt_white_rgb.binary"; do
            ln -s "$(realpath "$t")" "$work/knobs/"
        done
        step knobs benches/score_forms.sh "$work/knobs" default= \
            eps-1e-2="--epsilon 1e-2" eps-med-0.3="--epsilon-median 0.3" eps-med-untr-0="--epsilon-median-untrusted 0" \
            trust-0="--grazing-trust 0" pool-0="--pool-scale-below 0" pool-untr-0="--pool-scale-below-untrusted 0" \
            max-theta-80="--max-theta 80" taper-80="--taper-from 80" theta-h-85="--max-theta-h 85" \
            sweeps-10="--max-sweeps 10" tol-1e-2="--tol 1e-2" g-golden="--g-method golden" g-fixed="--g-method fixed" \
            smooth-g-1="--smooth-g 1" mono-75="--d-monotone-from 75" free-tail="--free-d-tail" no-accel="--no-accelerate" \
            coarse-1="--coarse 1" coarse-tol-1e-3="--coarse-tol 1e-3" coarse-300="--coarse-max-sweeps 300" \
            keep-g-off="--keep-coarse-g off" kept-tol-3e-3="--kept-g-tol 3e-3" energy-on="--energy-scale on" \
            energy-off="--energy-scale off" gn-on="--gauss-newton on" coarse-gn-on="--coarse-gauss-newton on" \
            masking-hc="--masking height-correlated" compensate="--compensate" \
            oren-nayar="--diffuse oren-nayar" energy-coupled="--diffuse energy-coupled" ;;
    python) step python target/test-venv/bin/python examples/python_bench.py --n 2000000 --repeats 5 --npf "$npf" ;;
    *) echo "unknown step: $s" >&2; exit 2 ;;
    esac
done
