#!/usr/bin/env bash
# The project's one test command (README; .ci/run calls exactly this).
#  1. Rust: unit, integration and doc tests of every crate in the workspace,
#     then clippy (warnings are errors).
#  2. Python and renderer tests (python/tests), in a local venv this script
#     makes itself (numpy, pytest, Mitsuba 3 from PyPI; the npf package when
#     there is a pyproject.toml), plus the Debian tools they need.
set -euo pipefail
cd "$(dirname "$0")/.."

# A Debian package, installed when its command is missing (CI and fresh
# machines run as root; elsewhere say what is missing and fail).
need_deb() {
    local cmd=$1 pkg=$2
    command -v "$cmd" >/dev/null 2>&1 && return 0
    if [ "$(id -u)" = 0 ]; then
        apt-get update -qq >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$pkg" >/dev/null
    else
        echo "run-all: $cmd missing: install the Debian package $pkg" >&2
        return 1
    fi
}

# Tools some Rust tests call (shader compilers): with NPF_REQUIRE_TOOLS set
# those tests fail when a tool is missing instead of skipping.
while read -r cmd pkg; do
    case "$cmd" in "" | "#"*) continue ;; esac
    need_deb "$cmd" "$pkg"
done < python/deb-packages.txt
export NPF_REQUIRE_TOOLS=1

cargo test --workspace --release

# Lints: the workspace stays clippy-clean (warnings are errors).
cargo clippy --workspace --all-targets -q -- -D warnings

if [ -d python/tests ]; then
    venv="${NPF_TEST_VENV:-target/test-venv}"
    [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check -r python/requirements-test.txt
    if [ -f pyproject.toml ]; then
        "$venv/bin/python" -m pip install -q --disable-pip-version-check .
    fi
    # The npf program cargo just built (CARGO_TARGET_DIR, if set, moves it).
    NPF_BIN="$(cd "${CARGO_TARGET_DIR:-target}" && pwd)/release/npf" "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
fi
