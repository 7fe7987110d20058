# Shared set-up of the benchmarks that score fits with the independent
# scorer (sourced from the repository root): the npf binary, the scorer
# and its Python, and a temporary folder removed on exit.
npf=$PWD/target/release/npf
score=${SCORE:-$PWD/../shared/tools/score.py}
python=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
