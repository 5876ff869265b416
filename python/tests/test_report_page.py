"""The report page (reports/index.html, written by the main job and `diffsoft report-page`) in a
real browser: headless Chromium (Debian's `chromium`; tests/run.sh installs it when missing)
loads it without errors, every plot decodes, nothing comes from the network, and every verdict
of reports/*.json is on it, failing ones first.

Chromium is driven over the DevTools protocol on a pipe (`--remote-debugging-pipe`: commands on
its fd 3, replies on its fd 4, NUL-terminated JSON), so no package beyond the standard library
is needed. The verdicts the page must show are read here from the JSON files on their own (any
object with `claim` and `holds`), not by the page's generator.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
REPORTS = REPO / "reports"
PAGE = REPORTS / "index.html"
CHROMIUM = os.environ.get("DIFFSOFT_CHROMIUM", "/usr/bin/chromium")
# Without the background-networking flags Chromium dials out, and a closed network refuses it.
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--hide-scrollbars",
    "--disable-dev-shm-usage",
    "--remote-debugging-pipe",
]
TIMEOUT_S = 60.0


class Browser:
    """Headless Chromium and one page of it, over the DevTools protocol on a pipe."""

    def __init__(self, profile: Path, log: Path) -> None:
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()

        def descriptors() -> None:
            # The protocol's fixed descriptors in the child: it reads fd 3 and writes fd 4.
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        with open(log, "wb") as err:
            self.proc = subprocess.Popen(
                [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                stdin=subprocess.DEVNULL,
                stdout=err,
                stderr=err,
                preexec_fn=descriptors,
                close_fds=False,
            )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buffer = b""
        self._next_id = 0
        self.events: list[dict[str, Any]] = []
        self.session: str | None = None
        self.deadline = time.monotonic() + TIMEOUT_S

    def _receive(self) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            left = self.deadline - time.monotonic()
            ready, _, _ = select.select([self._from_chrome], [], [], max(left, 0.0))
            if not ready:
                raise TimeoutError(f"Chromium did not answer within {TIMEOUT_S} s")
            chunk = os.read(self._from_chrome, 1 << 20)
            if not chunk:
                raise ConnectionError(f"Chromium closed the pipe (exit status {self.proc.poll()})")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        parsed: dict[str, Any] = json.loads(message)
        return parsed

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send a command (to the attached page once there is one) and return its result."""
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params}
        if self.session is not None:
            message["sessionId"] = self.session
        os.write(self._to_chrome, json.dumps(message).encode() + b"\0")
        while True:
            reply = self._receive()
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                result: dict[str, Any] = reply.get("result", {})
                return result
            self.events.append(reply)

    def wait_for(self, event: str) -> None:
        """Read messages until `event` arrives (keeping every event seen)."""
        while not any(e.get("method") == event for e in self.events):
            self.events.append(self._receive())

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page."""
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def close(self) -> None:
        try:
            self.session = None
            self.call("Browser.close")
        except (OSError, RuntimeError, TimeoutError, ConnectionError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._to_chrome)
        os.close(self._from_chrome)


def expected_verdicts() -> list[tuple[str, str, bool, float | None, float | None]]:
    """(report, claim, holds, measured, threshold) of every verdict of every report."""
    found: list[tuple[str, str, bool, float | None, float | None]] = []

    def walk(node: Any, file: str) -> None:
        if isinstance(node, dict):
            if "claim" in node and "holds" in node:
                claim = " ".join(str(node["claim"]).split())
                found.append((file, claim, node["holds"], node.get("measured"), node.get("threshold")))
                return
            for v in node.values():
                walk(v, file)
        elif isinstance(node, list):
            for v in node:
                walk(v, file)

    for path in sorted(REPORTS.rglob("*.json")):
        walk(json.loads(path.read_text()), path.relative_to(REPORTS).as_posix())
    return found


# The rendered table, as the browser has it.
ROWS_JS = """Array.from(document.querySelectorAll('tr.verdict')).map(tr => {
  const cell = c => tr.querySelector('td.' + c);
  const value = c => cell(c).dataset.value === undefined ? null : Number(cell(c).dataset.value);
  return {report: tr.dataset.report, status: cell('status').innerText.trim(),
          claim: tr.querySelector('.claim-text').innerText,
          measured: value('measured'), measured_text: cell('measured').innerText.trim(),
          threshold: value('threshold'), threshold_text: cell('threshold').innerText.trim(),
          link: tr.querySelector('td.report a').getAttribute('href')};
})"""
PAGE_JS = """({
  summary: document.getElementById('summary').innerText,
  images: Array.from(document.images).map(i => ({alt: i.alt, complete: i.complete, width: i.naturalWidth})),
  links: Array.from(document.querySelectorAll('a[href]')).map(a => a.getAttribute('href')),
  scripts: document.scripts.length,
  external: Array.from(document.querySelectorAll('[src], link[href]'))
    .map(e => e.getAttribute('src') || e.getAttribute('href')).filter(u => !u.startsWith('data:')),
  resources: performance.getEntriesByType('resource').map(r => r.name),
})"""


def errors_in(events: list[dict[str, Any]]) -> list[str]:
    """Exceptions, console errors, error log entries and failed loads among the events."""
    found = []
    for e in events:
        method, p = e.get("method"), e.get("params", {})
        if method == "Runtime.exceptionThrown":
            found.append(f"exception: {p['exceptionDetails']}")
        elif method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            found.append(f"console.{p['type']}: {p.get('args')}")
        elif method == "Log.entryAdded" and p["entry"].get("level") == "error":
            found.append(f"log: {p['entry'].get('text')} ({p['entry'].get('url')})")
        elif method == "Network.loadingFailed":
            found.append(f"failed load: {p.get('errorText')}")
    return found


def shown_number(text: str, value: float | None) -> bool:
    """The cell's text is the value to four significant digits (or a dash for none)."""
    if value is None:
        return text == "\u2014"
    shown = float(text)
    return shown == value or abs(shown - value) <= 5e-4 * abs(value)


@pytest.fixture(scope="module")
def page() -> Any:
    if not Path(CHROMIUM).is_file():
        pytest.fail(
            f"{CHROMIUM} is missing: install Debian's chromium (apt-get install chromium; tests/run.sh "
            "does it when run as root) or set DIFFSOFT_CHROMIUM to a Chromium binary"
        )
    assert PAGE.is_file(), f"{PAGE} is missing: `cargo run --release -- report-page` writes it"
    with tempfile.TemporaryDirectory(prefix="diffsoft-chromium-") as tmp:
        browser = Browser(Path(tmp) / "profile", Path(tmp) / "chromium.log")
        try:
            target = browser.call("Target.createTarget", url="about:blank")["targetId"]
            browser.session = browser.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
            for domain in ("Page", "Runtime", "Log", "Network"):
                browser.call(f"{domain}.enable")
            nav = browser.call("Page.navigate", url=PAGE.as_uri())
            assert "errorText" not in nav, nav
            browser.wait_for("Page.loadEventFired")
            yield {
                "rows": browser.evaluate(ROWS_JS),
                "page": browser.evaluate(PAGE_JS),
                "errors": errors_in(browser.events),
            }
        except Exception:
            log = (Path(tmp) / "chromium.log").read_text(errors="replace")
            print(f"Chromium's output:\n{log[-4000:]}")
            raise
        finally:
            browser.close()


def test_the_page_loads_without_errors(page: dict[str, Any]) -> None:
    assert page["errors"] == []
    p = page["page"]
    # Self-contained: no script, nothing but data URLs as sources, nothing fetched.
    assert p["scripts"] == 0 and p["external"] == [] and p["resources"] == []
    svgs = sorted(path.relative_to(REPORTS).as_posix() for path in REPORTS.rglob("*.svg"))
    assert sorted(i["alt"] for i in p["images"]) == svgs
    broken = [i["alt"] for i in p["images"] if not (i["complete"] and i["width"] > 0)]
    assert broken == [], f"plots that did not decode: {broken}"


def test_every_verdict_is_on_the_page_failing_first(page: dict[str, Any]) -> None:
    want = expected_verdicts()
    assert len(want) > 0
    rows = page["rows"]
    got = [
        (r["report"], " ".join(r["claim"].split()), r["status"] == "holds", r["measured"], r["threshold"]) for r in rows
    ]
    assert Counter(got) == Counter(want)
    for r in rows:
        holds = r["status"] == "holds"
        assert holds or r["status"].startswith("FAILS"), r
        assert shown_number(r["measured_text"], r["measured"]), r
        assert shown_number(r["threshold_text"], r["threshold"]), r
        assert (REPORTS / r["link"]).is_file() and r["link"] == r["report"], r
    holding = [r["status"] == "holds" for r in rows]
    assert holding == sorted(holding), "a failing verdict comes after one that holds"
    failing = sum(1 for w in want if not w[2])
    assert f"{len(want)} verdicts" in page["page"]["summary"]
    assert f"{failing} fail" in page["page"]["summary"]


def test_every_report_is_linked(page: dict[str, Any]) -> None:
    reports = {p.relative_to(REPORTS).as_posix() for p in REPORTS.rglob("*.json")}
    links = set(page["page"]["links"])
    assert reports <= links, f"not linked: {sorted(reports - links)}"
