#!/usr/bin/env bash
# Every test of the project, from a fresh clone: the Rust crate's (unit, integration, doc), then
# the Python package's (ruff, mypy, stubtest, pytest; the report page in headless Chromium),
# built with maturin and installed into a virtual environment under target/ (created on first
# use; packages from PyPI only).
set -euo pipefail
cd "$(dirname "$0")/.."

# The report page's browser test (python/tests/test_report_page.py) renders reports/index.html in
# headless Chromium: Debian's package, installed here when missing (as root; DIFFSOFT_CHROMIUM
# names another binary). Without it that test fails, it never skips.
if [ -z "${DIFFSOFT_CHROMIUM:-}" ] && [ ! -x /usr/bin/chromium ]; then
    if [ "$(id -u)" -eq 0 ]; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
    else
        echo "tests/run.sh: /usr/bin/chromium is missing: install Debian's chromium package (apt-get install chromium) or set DIFFSOFT_CHROMIUM" >&2
        exit 1
    fi
fi

cargo test --release --workspace

venv="${DIFFSOFT_VENV:-target/venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
py="$venv/bin/python"
"$py" -m pip install --quiet --disable-pip-version-check -r python/requirements-test.txt
# Lint and formatting of the Python code (settings in python/pyproject.toml; --config so that
# they apply to examples/python/ too).
export RUFF_CACHE_DIR="${RUFF_CACHE_DIR:-target/ruff_cache}" MYPY_CACHE_DIR="${MYPY_CACHE_DIR:-target/mypy_cache}"
"$venv/bin/ruff" check --config python/pyproject.toml python examples/python benches
"$venv/bin/ruff" format --check --config python/pyproject.toml python examples/python benches
# Builds the extension (release) in an isolated environment with maturin from PyPI.
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps ./python
# Types of the package's modules, and the stubs of the native module against the installed one.
"$py" -m mypy --config-file python/pyproject.toml python/diffsoft
"$py" -m mypy.stubtest diffsoft._diffsoft
"$py" -m pytest -q python/tests
