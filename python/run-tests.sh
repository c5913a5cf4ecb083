#!/usr/bin/env bash
# The Python package's tests from a fresh clone: a virtual environment in target/py-venv
# (or $TDPCR_PY_VENV; target/ is $CARGO_TARGET_DIR if set), maturin/numpy/pytest from
# PyPI, the package built and installed by `pip install ./python`, the CLI built for the
# agreement tests, then pytest.
# Exits non-zero when anything fails. $PYTHON picks the interpreter (default python3).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
target="${CARGO_TARGET_DIR:-$root/target}"
venv="${TDPCR_PY_VENV:-$target/py-venv}"

if [ ! -x "$venv/bin/python" ]; then
    "${PYTHON:-python3}" -m venv "$venv"
fi
py="$venv/bin/python"
"$py" -m pip install --quiet --disable-pip-version-check maturin numpy pytest distributed
# --force-reinstall: the version does not change between commits, the code does.
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$root/python"

(cd "$root" && cargo build --quiet --bin tdpcr)
# From python/tests (not the repository root) so `import tdpcr` is the installed package.
cd "$root/python/tests"
TDPCR_BIN="$target/debug/tdpcr" "$py" -m pytest -q .
