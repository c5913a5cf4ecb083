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
# (The release wheel, as users get it. Built in the test profile, to reuse what `cargo
# test` built, maturin made a test harness, not a loadable module.)
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps "$root/python"

# The CLI as `cargo test` builds it (test profile, the tests' features): a no-op after the
# README's test command has run `cargo test`; a plain `cargo build` would compile every
# dependency again with other features.
(cd "$root" && cargo test --workspace --no-run --quiet)
# From python/tests (not the repository root) so `import tdpcr` is the installed package.
cd "$root/python/tests"
TDPCR_BIN="$target/debug/tdpcr" "$py" -m pytest -q .
