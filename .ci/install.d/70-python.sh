#!/usr/bin/env bash
# The Python bindings (crates/nsrm-py, python/nsrm; docs/guide/11-python.md): a virtual
# environment at target/python-venv with maturin, numpy, pytest, colour-science (the reference
# the tests judge nsrm against) and tifffile, and the `nsrm` wheel built from this checkout
# (`maturin build --release`, an abi3 wheel) installed into it: a real wheel install, as a user
# gets it. tests/all/python.rs runs the pytest suite python/tests with that interpreter.
#
# Only what is missing or stale is redone: the venv when its packages are missing, the wheel when
# the sources it is built from changed since (a hash of them is kept in the venv).
# python/tests/test_readme.py runs the README's Python block against what this installs.
# `--check`: change nothing, exit 0 when the venv holds a wheel of the current sources, 1 if not.
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=target/python-venv
py="$venv/bin/python"
stamp="$venv/nsrm-wheel.sha256"

# The sources the wheel is built from: the library, the binding crate, the output session it
# writes exports with, the Python package.
sources_hash() {
    find src shaders assets crates/nsrm-py crates/nsrm-io crates/nsrm-chart crates/nsrm-export crates/nsrm-output python/nsrm Cargo.toml Cargo.lock pyproject.toml \
        -type f ! -name '*.pyc' -print0 | LC_ALL=C sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1
}

if [ "${1:-}" = "--check" ]; then
    [ -x "$py" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$(sources_hash)" ]
    exit
fi

if [ ! -x "$py" ]; then
    if ! python3 -m venv "$venv"; then
        # Debian's python3 has venv and ensurepip in a package of their own.
        rm -rf "$venv"
        apt-get update -qq
        apt-get install -y -qq python3-venv
        python3 -m venv "$venv"
    fi
fi
if ! "$py" -c 'import maturin, numpy, pytest, colour, tifffile' >/dev/null 2>&1; then
    "$py" -m pip install -q --disable-pip-version-check maturin numpy pytest colour-science tifffile
fi
want="$(sources_hash)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && "$py" -c 'import nsrm' >/dev/null 2>&1; then
    exit 0
fi
# As the README says: `pip install .` at the top of the checkout (pip runs maturin's build
# backend, which builds the abi3 wheel in the release profile under target/, then installs it).
"$py" -m pip install -q --disable-pip-version-check --force-reinstall --no-deps .
"$py" -c 'import nsrm; print("ci: nsrm", nsrm.__version__, "installed in target/python-venv")'
echo "$want" > "$stamp"
