"""What the docs quote about the Python package, checked against reality (as the harness's
``doc_numbers`` test checks the reports): the README's Python quick start runs verbatim from the
repository root and prints what the README says, and ``docs/python.md`` quotes the number of
tests pytest collects."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from conftest import REPO

pytest.importorskip("torch")
pytest.importorskip("jax")


def _block(text: str, after: str, lang: str) -> str:
    """The first fenced block of ``lang`` after the text ``after``."""
    start = text.index(after)
    m = re.compile(rf"^```{lang}\n(.*?)^```$", re.S | re.M).search(text, start)
    assert m, f"no ```{lang} block after {after!r}"
    return m.group(1)


def test_the_readme_python_quick_start_runs_verbatim_and_prints_its_numbers():
    readme = (REPO / "README.md").read_text()
    install = _block(readme, "### Python quick start", "sh")
    # A virtual environment first (system Pythons refuse pip installs), then the package.
    venv, pip = install.splitlines()[:2]
    assert venv.startswith("python3 -m venv .venv && . .venv/bin/activate"), install
    assert pip.startswith('pip install "./python[torch]"'), install
    code = _block(readme, "### Python quick start", "python")
    printed = _block(readme, "It prints", "text")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout == printed
    # Not a warning either.
    assert done.stderr == ""


def test_docs_quote_the_number_of_python_tests():
    quoted = re.findall(r"`python/tests` \((\d+) tests", (REPO / "docs/python.md").read_text())
    assert len(quoted) == 1, "docs/python.md quotes the number of tests once, as '`python/tests` (N tests'"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", "python/tests"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    m = re.search(r"^(\d+) tests? collected", done.stdout, re.M)
    assert m, done.stdout[-2000:] + done.stderr[-2000:]
    assert int(quoted[0]) == int(m.group(1)), f"docs/python.md says {quoted[0]} tests, pytest collects {m.group(1)}"
