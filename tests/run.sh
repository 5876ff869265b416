#!/usr/bin/env bash
# Every test of the project, from a fresh clone: the Rust crate's (unit, integration, doc), then
# the Python package's, built with maturin and installed into a virtual environment under
# target/ (created on first use; packages from PyPI only).
set -euo pipefail
cd "$(dirname "$0")/.."

cargo test --release --workspace

venv="${DIFFSOFT_VENV:-target/venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
py="$venv/bin/python"
"$py" -m pip install --quiet --disable-pip-version-check -r python/requirements-test.txt
# Builds the extension (release) in an isolated environment with maturin from PyPI.
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps ./python
"$py" -m pytest -q python/tests
