#!/usr/bin/env python3
"""A reproducible adversarial probe of diffsoft (issue 33's "probe of your own").

It writes a few hundred hostile inputs into a scratch directory, runs each through the
command-line tool (or, for the Python class, through ``diffsoft.Scene`` in a fresh interpreter),
and classifies what happened. Inputs come from a fixed seed, so two runs give the same inputs.

Classes (``--class`` selects some; default all):

1. ``numeric``   values that pass type checks but sit at the edge of double precision: tiny,
                 huge and denormal moduli, densities, time steps, tolerances, caps, Anderson
                 memories, mesh scales, vectors (gravity, joint axes, normals, directions).
2. ``files``     malformed scene and mesh files: truncated or mistyped JSON, unknown and
                 duplicate keys, duplicate tets, vertices, names and actuator tets, degenerate
                 and inverted tets, indices out of range, NaN/inf coordinates, empty meshes, odd
                 extensions, non-UTF-8 bytes.
3. ``outputs``   where reports go: symbolic links, character devices, FIFOs, directories,
                 unwritable places, paths equal to an input (the scene, its mesh, a .node/.ele
                 pair) or to another output.
4. ``initial``   initial states: bodies inside the ground, a mesh obstacle or each other.
5. ``gradients`` small seeded scenes (free bodies, ground contact with friction, a box or ball
                 dropped on a fixed box, a ball pushed into a pinned ball, cloth, contact
                 kinks) where ``grad`` in both modes is compared with central differences of
                 the forward loss at p +- h (``Scene.simulate`` when its loss at p matches
                 the CLI's, else ``grad --set P=p+-h --allow-unconverged``).
6. ``python``    the same kinds of hostile input through the Python API, each case in its own
                 interpreter (a dead interpreter is seen as such), and Ctrl-C in long calls.

Outcomes: ``ok-result``, ``clear-error``, ``warning``; for gradients ``agree``, ``refused``,
``warned``. Failures: ``CRASH`` (exit 101/134/137/139, a signal, ``panicked`` in stderr,
``PanicException``, a dead interpreter), ``SILENT-NAN`` (exit 0 / a return with a non-finite
number and no warning about it), ``DISAGREE-SILENT`` (exit 0, more than 10% off central
differences, no warning), ``HANG`` (past the time limit), ``FILE-DAMAGE`` (an input, device,
FIFO or link replaced or changed, or exit 0 with the report lost), ``LATE-INTERRUPT``
(``KeyboardInterrupt`` more than a second after SIGINT). Soft findings (reported, not
failures): ``KINK-SILENT`` (one-sided differences disagree, the gradient agrees with the central
one and says nothing), ``UNREPORTED-OVERLAP`` (an initial interpenetration run with exit 0 and
no word about it), ``ACCEPTED-SILENT`` (input issue 33 wants refused, e.g. duplicates, run with
exit 0), and on error messages ``multi-line``, ``unnamed`` (names none of the inputs the case
expects), ``repeated`` (a phrase twice) and ``misleading`` ("must be non-zero" for a non-zero
vector, ``extension '.'``).

Usage (from the repository root, after ``cargo build --release -p diffsoft-cli`` and installing
the Python package into the interpreter that runs this script)::

    python3 tests/probe/hostile.py --bin target/release/diffsoft --out probe.json --markdown probe.md

Only the standard library, numpy and diffsoft are used. Exit status: 0 when no case fails, 1
otherwise.
"""

from __future__ import annotations

import argparse
import base64
import concurrent.futures
import hashlib
import itertools
import json
import math
import os
import random
import re
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

SEED = 20240633
TIMEOUT = 60.0
FAILURES = {"CRASH", "SILENT-NAN", "DISAGREE-SILENT", "HANG", "FILE-DAMAGE", "LATE-INTERRUPT"}
CLASSES = ["numeric", "files", "outputs", "initial", "gradients", "python"]
CRASH_CODES = {101, 134, 137, 139}

# --------------------------------------------------------------------------------------------
# Meshes and scenes
# --------------------------------------------------------------------------------------------

CUBE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 2 3 4\n"
TET_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n"


def grid_box(cells: int, size: float) -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int, int]]]:
    """A cube of side ``size`` cut into ``cells**3`` cells, each split into six positively
    oriented tets (Kuhn)."""
    n = cells + 1
    h = size / cells
    verts = [(i * h, j * h, k * h) for k in range(n) for j in range(n) for i in range(n)]

    def vid(i: int, j: int, k: int) -> int:
        return i + n * (j + n * k)

    tets = []
    for i, j, k in itertools.product(range(cells), repeat=3):
        for perm in itertools.permutations(range(3)):
            c = [0, 0, 0]
            path = [vid(i, j, k)]
            for ax in perm:
                c[ax] += 1
                path.append(vid(i + c[0], j + c[1], k + c[2]))
            a, b, cc, d = (verts[p] for p in path)
            m = [[b[r] - a[r] for r in range(3)], [cc[r] - a[r] for r in range(3)], [d[r] - a[r] for r in range(3)]]
            det = (
                m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
            )
            if det < 0:
                path[1], path[2] = path[2], path[1]
            tets.append(tuple(path))
    return verts, tets


def obj_text(verts, tets, header: str = "") -> str:
    lines = [header] if header else []
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in verts]
    lines += ["t " + " ".join(str(i) for i in t) for t in tets]
    return "\n".join(lines) + "\n"


def cloth_grid(cells: int, size: float, y: float) -> str:
    n = cells + 1
    lines = [
        f"v {i * size / cells - size / 2!r} {y!r} {j * size / cells - size / 2!r}" for j in range(n) for i in range(n)
    ]
    for i, j in itertools.product(range(cells), repeat=2):
        a = 1 + i + n * j
        b, c, d = a + 1, a + n, a + n + 1
        lines.append(f"f {a} {c} {b}")
        lines.append(f"f {b} {c} {d}")
    return "\n".join(lines) + "\n"


BOX_SURFACE = """v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 4 8 7
f 4 7 3
f 1 5 8
f 1 8 4
f 2 3 7
f 2 7 6
"""

MSH22 = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
$EndNodes
$Elements
1
1 4 2 0 1 1 2 3 4
$EndElements
"""

# The paper's ball (43 vertices, 80 tets, radius 0.3 about (0, 0.998, 0)), if the repository has it.
_BALL = Path(__file__).resolve().parents[2] / "verification/paper/droneman/ball_tet.obj"
BALL_OBJ = _BALL.read_text() if _BALL.is_file() else None

NODE = "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n"
ELE = "2 4 0\n0 0 1 2 3\n1 1 2 3 4\n"


def body(name="c", mesh="cube.obj", E=1e5, nu=0.3, density=1000.0, **extra) -> dict:
    b = {"name": name, "mesh": mesh, "material": {"youngs_modulus": E, "poisson_ratio": nu}}
    if density is not None:
        b["density"] = density
    b.update(extra)
    return b


def scene(bodies=None, dt=0.01, gravity=(0, -9.81, 0), **top) -> dict:
    s: dict[str, Any] = {"schema": "diffsoft.scene/1", "time_step": dt, "gravity": list(gravity)}
    s["bodies"] = [body()] if bodies is None else bodies
    s.update(top)
    return s


def ground(y=0.0, friction=0.3, name="ground", normal=(0, 1, 0), thickness=None) -> dict:
    o = {"name": name, "plane": {"point": [0, y, 0], "normal": list(normal)}, "friction": friction}
    if thickness is not None:
        o["thickness"] = thickness
    return o


# --------------------------------------------------------------------------------------------
# Cases and results
# --------------------------------------------------------------------------------------------


@dataclass
class Case:
    cls: str
    desc: str
    argv: list[str] | None = None  # CLI arguments after the binary
    py: str | None = None  # Python snippet: defines case() returning a value
    cwd: Path | None = None
    names: list[str] = field(default_factory=list)  # what an error message should name (any of)
    timeout: float = TIMEOUT
    stdin_null: bool = True
    before: Callable[[Case], Any] | None = None  # set-up right before the run
    after: Callable[[Case, dict], tuple[str, str] | None] | None = None  # post-check
    special: Callable[[Case], dict] | None = None  # runs itself (gradients, races)
    nan_check: Callable[[Case, dict], str | None] | None = None
    overlap: bool = False  # an initial interpenetration the run should report
    expect_error: bool = False  # issue 33 asks for an error (duplicates): exit 0 is a soft finding
    expect_warning: bool = False  # exit 0 must come with a warning (steps that stop unconverged)
    nonzero: bool = False  # the case's vector is non-zero: "must be non-zero" would mislead
    stdout_to: str | None = None  # path of a file/device for stdout
    env: dict | None = None
    state: dict = field(default_factory=dict)


def first_line(text: str) -> str:
    for line in text.splitlines():
        if line.strip():
            return line.strip()[:300]
    return ""


def error_lines(stderr: str) -> list[str]:
    """The lines of an error message (warnings, notes, clap's usage hints left out)."""
    out = []
    for line in stderr.splitlines():
        s = line.strip()
        if not s or s.startswith(("warning", "note", "Usage:", "For more information", "tip:")):
            continue
        out.append(s)
    return out


def repeated(msg: str) -> bool:
    """A phrase of six or more words, or a ': '-separated part of 15+ characters, twice."""
    parts = [p.strip() for p in re.split(r": ", msg) if len(p.strip()) >= 15]
    if len(parts) != len(set(parts)):
        return True
    words = re.findall(r"\S+", msg)
    seen = set()
    for i in range(len(words) - 5):
        g = tuple(words[i : i + 6])
        if g in seen:
            return True
        seen.add(g)
    return False


def message_findings(case: Case, msg_lines: list[str]) -> list[str]:
    found = []
    if len(msg_lines) > 1:
        found.append("multi-line")
    msg = " ".join(msg_lines)
    norm = lambda t: re.sub(r"[\s'_`-]", "", t.lower())  # noqa: E731 (Young's modulus = youngs_modulus)
    if case.names and not any(norm(n) in norm(msg) for n in case.names):
        found.append("unnamed")
    if msg and repeated(msg):
        found.append("repeated")
    if "extension '.'" in msg:
        found.append("misleading (extension '.')")
    if case.nonzero and "non-zero" in msg:
        found.append("misleading ('non-zero' for a non-zero vector)")
    return found


# A value printed as NaN or infinite ("= NaN", "= inf"; not prose such as "as h -> inf").
NONFINITE = re.compile(r"=\s*[-+]?(nan|NaN|inf|Infinity)(?![A-Za-z])")


def walk_nonfinite(v: Any) -> bool:
    if isinstance(v, float):
        return not math.isfinite(v)
    if v is None:
        return False
    if isinstance(v, dict):
        return any(walk_nonfinite(x) for x in v.values())
    if isinstance(v, list):
        return any(walk_nonfinite(x) for x in v)
    return False


def json_nulls(v: Any, path: str = "") -> list[str]:
    """Paths of numbers serialised as null (serde writes NaN and infinity as null)."""
    out: list[str] = []
    if v is None:
        out.append(path)
    elif isinstance(v, dict):
        for k, x in v.items():
            out += json_nulls(x, f"{path}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v):
            out += json_nulls(x, f"{path}[{i}]")
    return out


def vtu_arrays(path: Path) -> dict[str, list[float]]:
    """The Float64 arrays of a binary VTU frame (Points and point data), decoded."""
    import struct

    text = path.read_text()
    out = {}
    for m in re.finditer(r'<DataArray([^>]*)format="binary"[^>]*>\s*([A-Za-z0-9+/=]+)\s*</DataArray>', text):
        attrs = m.group(1)
        if 'type="Float64"' not in attrs:
            continue
        name = re.search(r'Name="([^"]*)"', attrs)
        raw = base64.b64decode(m.group(2))
        (nbytes,) = struct.unpack("<Q", raw[:8])
        vals = struct.unpack(f"<{nbytes // 8}d", raw[8 : 8 + nbytes])
        out[name.group(1) if name else "Points"] = list(vals)
    return out


def run_log_check(run_dir: Path) -> str | None:
    """Non-finite numbers in a run's log or last frame (None: all finite)."""
    log = run_dir / "run.json"
    if not log.exists():
        return None
    try:
        v = json.loads(log.read_text())
    except Exception:
        return None
    bad = [p for p in json_nulls(v.get("summary", {}), "summary") if not p.endswith("error")]
    for i, s in enumerate(v.get("steps", [])):
        for p in json_nulls(s, f"steps[{i}]"):
            if any(k in p for k in ("energy", "residual", "penetration", "change")):
                bad.append(p)
    frames = sorted(run_dir.glob("frame_*.vtu"))
    if frames:
        try:
            arrays = vtu_arrays(frames[-1])
            for name, vals in arrays.items():
                if any(not math.isfinite(x) for x in vals):
                    bad.append(f"{frames[-1].name}:{name}")
        except Exception as e:  # a frame we cannot read is reported, not fatal
            bad.append(f"{frames[-1].name}: unreadable ({e})")
    return ", ".join(bad[:5]) if bad else None


def frame_extremes(run_dir: Path) -> tuple[float, float]:
    frames = sorted(run_dir.glob("frame_*.vtu"))
    if not frames:
        return (float("nan"), float("nan"))
    a = vtu_arrays(frames[-1])
    q = max((abs(x) for x in a.get("Points", [0.0])), default=0.0)
    v = max((abs(x) for x in a.get("velocity", [0.0])), default=0.0)
    return q, v


def classify_cli(case: Case, proc: subprocess.CompletedProcess | None, timed_out: bool, elapsed: float) -> dict:
    r: dict[str, Any] = {"class": case.cls, "desc": case.desc, "seconds": round(elapsed, 3)}
    r["command"] = "diffsoft " + " ".join(shell_quote(a) for a in case.argv or [])
    r["cwd"] = str(case.cwd)
    if timed_out:
        r.update(outcome="HANG", exit=None, stderr_first=f"(killed after {case.timeout:g}s)", findings=[])
        return r
    assert proc is not None
    out, err = proc.stdout, proc.stderr
    r["exit"] = proc.returncode
    r["stderr_first"] = first_line(err)
    r["stdout_tail"] = out[-400:]
    findings: list[str] = []
    if proc.returncode < 0 or proc.returncode in CRASH_CODES or "panicked" in err or "RUST_BACKTRACE" in err:
        outcome = "CRASH"
        if proc.returncode < 0:
            r["signal"] = signal.Signals(-proc.returncode).name
    elif proc.returncode == 0:
        warned = "warning" in out.lower() or "warning" in err.lower()
        outcome = "warning" if warned else "ok-result"
        nan = None
        if case.nan_check:
            nan = case.nan_check(case, r)
        if nan is None and NONFINITE.search(out):
            nan = "non-finite number printed: " + NONFINITE.search(out).group(0)
        # A NaN is "warned" only by a warning about it (not, say, the unrolled mode's note).
        nan_warned = bool(
            re.search(
                r"warning[^\n]*(nan|non-finite|not finite|infinit|overflow|underflow|diverg)", (out + err).lower()
            )
        )
        if nan and not nan_warned:
            outcome = "SILENT-NAN"
            r["nan"] = nan
        if case.overlap and not re.search(
            r"inside|overlap|interpenetrat|penetrates|starts? ", (out + err).replace("max penetration", "")
        ):
            outcome = "UNREPORTED-OVERLAP"
        if case.expect_error and outcome in ("ok-result", "warning"):
            outcome = "ACCEPTED-SILENT"
        if case.expect_warning and outcome == "ok-result":
            outcome = "ACCEPTED-SILENT"
    else:
        outcome = "clear-error"
        findings = message_findings(case, error_lines(err))
        if not err.strip():
            findings.append("empty-message")
    r["outcome"] = outcome
    r["findings"] = findings
    return r


def shell_quote(a: str) -> str:
    return a if re.fullmatch(r"[A-Za-z0-9_./=:,+@%-]+", a) else "'" + a.replace("'", "'\\''") + "'"


class Runner:
    def __init__(self, binary: Path, python: str, root: Path):
        self.bin = binary
        self.python = python
        self.root = root

    def cli(self, case: Case) -> dict:
        if case.before:
            case.before(case)
        t0 = time.monotonic()
        stdout = subprocess.PIPE
        fh = None
        if case.stdout_to:
            fh = open(case.stdout_to, "wb")  # noqa: SIM115
            stdout = fh
        try:
            p = subprocess.Popen(
                [str(self.bin), *case.argv],
                cwd=case.cwd,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=subprocess.PIPE,
                env={**os.environ, **(case.env or {}), "RUST_BACKTRACE": "0"},
                start_new_session=True,
            )
            try:
                o, e = p.communicate(timeout=case.timeout)
                proc = subprocess.CompletedProcess(
                    p.args, p.returncode, (o or b"").decode("utf-8", "replace"), e.decode("utf-8", "replace")
                )
                timed_out = False
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.communicate()
                proc, timed_out = None, True
        finally:
            if fh:
                fh.close()
        r = classify_cli(case, proc, timed_out, time.monotonic() - t0)
        if case.after:
            verdict = case.after(case, r)
            if verdict:
                r["outcome"], r["note"] = verdict
        return r

    def pyrun(self, case: Case) -> dict:
        if case.before:
            case.before(case)
        script = PY_PRELUDE + "\n" + case.py + "\n" + PY_EPILOGUE
        t0 = time.monotonic()
        r: dict[str, Any] = {"class": case.cls, "desc": case.desc, "command": case.py.strip(), "findings": []}
        try:
            p = subprocess.run(
                [self.python, "-c", script],
                cwd=case.cwd,
                capture_output=True,
                text=True,
                timeout=case.timeout,
                env={**os.environ, "PROBE_DIR": str(self.root), "RUST_BACKTRACE": "0"},
            )
        except subprocess.TimeoutExpired:
            r.update(outcome="HANG", exit=None, stderr_first=f"(killed after {case.timeout:g}s)")
            return r
        r["seconds"] = round(time.monotonic() - t0, 3)
        r["exit"] = p.returncode
        res = None
        for line in p.stdout.splitlines():
            if line.startswith("@@RESULT@@"):
                res = json.loads(line[len("@@RESULT@@") :])
        r["stderr_first"] = first_line(p.stderr)
        if res is None:
            r["outcome"] = "CRASH"
            r["note"] = "dead interpreter" + (f" ({signal.Signals(-p.returncode).name})" if p.returncode < 0 else "")
            r["stderr_tail"] = p.stderr[-600:]
            return r
        r["result"] = res
        if res["status"] == "exception":
            r["stderr_first"] = f"{res['type']}: {first_line(res['msg'])}"
            if "PanicException" in res["mro"] or "panicked" in res["msg"]:
                r["outcome"] = "CRASH"
            elif res.get("expected_interrupt"):
                r["outcome"] = "clear-error"
            else:
                r["outcome"] = "clear-error"
                lines = [x for x in res["msg"].splitlines() if x.strip()]
                r["findings"] = message_findings(case, lines)
        else:
            warned = bool(res.get("warnings")) or bool(res.get("warned"))
            if res.get("compare") is not None:
                r["outcome"] = res["compare"]
            elif res.get("nan") and not warned:
                r["outcome"] = "SILENT-NAN"
            else:
                r["outcome"] = "warning" if warned else "ok-result"
            if case.expect_error and r["outcome"] in ("ok-result", "warning"):
                r["outcome"] = "ACCEPTED-SILENT"
        if case.after:
            verdict = case.after(case, r)
            if verdict:
                r["outcome"], r["note"] = verdict
        return r

    def run(self, case: Case) -> dict:
        try:
            if case.special:
                r = case.special(case)
            elif case.py is not None:
                r = self.pyrun(case)
            else:
                r = self.cli(case)
        except Exception as e:  # a bug of the probe, not of diffsoft: recorded as such
            r = {
                "class": case.cls,
                "desc": case.desc,
                "outcome": "probe-error",
                "stderr_first": repr(e),
                "findings": [],
            }
        r.setdefault("class", case.cls)
        r.setdefault("desc", case.desc)
        r.setdefault("findings", [])
        return r


PY_PRELUDE = r"""
import json, math, os, sys, warnings
import numpy as np
D = os.environ["PROBE_DIR"]
def _nonfinite(v, depth=0):
    if depth > 6: return False
    if isinstance(v, float): return not math.isfinite(v)
    if isinstance(v, np.ndarray):
        return v.dtype.kind in "fc" and not np.all(np.isfinite(v))
    if isinstance(v, (list, tuple)): return any(_nonfinite(x, depth + 1) for x in v)
    if isinstance(v, dict): return any(_nonfinite(x, depth + 1) for x in v.values())
    for a in ("positions", "velocities"):
        if hasattr(v, a): return _nonfinite(getattr(v, a), depth + 1)
    return False
def _short(v):
    s = repr(v)
    return s[:300]
def rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)
"""

PY_EPILOGUE = r"""
_out = {}
with warnings.catch_warnings(record=True) as _w:
    warnings.simplefilter("always")
    try:
        import diffsoft
        _r = case()
        _out = {"status": "ok", "nan": _nonfinite(_r), "value": _short(_r)}
        if isinstance(_r, dict) and "compare" in _r:
            _out["compare"] = _r["compare"]
            _out["detail"] = _short(_r)
        if isinstance(_r, dict) and _r.get("warned"):
            _out["warned"] = True
    except BaseException as _e:
        _out = {"status": "exception", "type": type(_e).__name__,
                "mro": [c.__name__ for c in type(_e).__mro__], "msg": str(_e)}
        if isinstance(_e, KeyboardInterrupt):
            _out["expected_interrupt"] = True
    _out["warnings"] = [str(x.message)[:300] for x in _w]
print("@@RESULT@@" + json.dumps(_out), flush=True)
"""


# --------------------------------------------------------------------------------------------
# The generators of each class
# --------------------------------------------------------------------------------------------


class Probe:
    def __init__(self, root: Path, rng: random.Random):
        self.root = root
        self.rng = rng
        self.cases: list[Case] = []
        self.n = 0
        self.is_root = os.geteuid() == 0
        (root / "shared").mkdir(parents=True, exist_ok=True)

    def dir(self, tag: str) -> Path:
        self.n += 1
        d = self.root / f"{self.n:04d}-{tag}"
        d.mkdir(parents=True)
        return d

    @staticmethod
    def write(d: Path, name: str, content: Any) -> Path:
        p = d / name
        if isinstance(content, bytes):
            p.write_bytes(content)
        elif isinstance(content, (dict, list)):
            p.write_text(json.dumps(content, indent=1))
        else:
            p.write_text(content)
        return p

    def scene_dir(self, tag: str, sc: Any, meshes: dict | None = None, scene_name: str = "scene.json"):
        d = self.dir(tag)
        for name, text in (meshes or {"cube.obj": CUBE_OBJ}).items():
            self.write(d, name, text)
        self.write(d, scene_name, sc)
        return d, d / scene_name

    def add(self, case: Case):
        self.cases.append(case)

    # -- simulate / grad helpers --

    def sim_case(
        self,
        cls,
        desc,
        sc,
        names=(),
        steps=3,
        meshes=None,
        flags=(),
        overlap=False,
        raw=None,
        scene_name="scene.json",
        timeout=TIMEOUT,
        expect_error=False,
        nonzero=False,
    ):
        d, path = self.scene_dir(cls, raw if raw is not None else sc, meshes, scene_name)
        out = d / "run"
        argv = ["simulate", scene_name, "--steps", str(steps), "--out", "run", "--every", str(max(steps, 1)), *flags]
        self.add(
            Case(
                cls,
                desc,
                argv=argv,
                cwd=d,
                names=list(names),
                nan_check=lambda c, r, out=out: run_log_check(out),
                overlap=overlap,
                expect_error=expect_error,
                nonzero=nonzero,
                after=self._overlap_after if overlap else None,
                timeout=timeout,
            )
        )

    def equiv_case(self, cls, desc, hostile, reference, names=(), steps=3):
        """``hostile`` must run as ``reference`` does (same final frame), or be refused."""
        d = self.dir(cls)
        self.write(d, "cube.obj", CUBE_OBJ)
        self.write(d, "scene.json", hostile)
        self.write(d, "reference.json", reference)
        argv = ["simulate", "scene.json", "--steps", str(steps), "--out", "run", "--every", str(steps)]

        def after(c: Case, r: dict):
            if r["outcome"] not in ("ok-result", "warning"):
                return None
            ref = subprocess.run(
                [
                    str(RUNNER.bin),
                    "simulate",
                    "reference.json",
                    "--steps",
                    str(steps),
                    "--out",
                    "ref",
                    "--every",
                    str(steps),
                ],
                cwd=c.cwd,
                capture_output=True,
                text=True,
            )
            if ref.returncode != 0:
                return ("probe-error", "reference run failed: " + first_line(ref.stderr))
            a = vtu_arrays(sorted((c.cwd / "run").glob("frame_*.vtu"))[-1])["Points"]
            b = vtu_arrays(sorted((c.cwd / "ref").glob("frame_*.vtu"))[-1])["Points"]
            diff = max(abs(x - y) for x, y in zip(a, b, strict=False))
            r["max_position_difference"] = diff
            if diff > 1e-9 * max(1.0, max(abs(y) for y in b)):
                return ("DISAGREE-SILENT", f"final positions differ from the unit vector's run by {diff:.3g} m")
            return None

        self.add(Case(cls, desc, argv=argv, cwd=d, names=list(names), after=after, nonzero=True))

    def grad_case(
        self, cls, desc, sc, names=(), steps=3, param="density", meshes=None, flags=(), raw=None, mode="unrolled"
    ):
        d, path = self.scene_dir(cls, raw if raw is not None else sc, meshes)
        argv = [
            "grad",
            "scene.json",
            "--steps",
            str(steps),
            "--param",
            param,
            "--mode",
            mode,
            "--json",
            "g.json",
            *flags,
        ]

        def nan_check(c, r, d=d):
            p = d / "g.json"
            if p.exists():
                v = json.loads(p.read_text())
                bad = json_nulls({"loss": v.get("loss"), "gradient": v.get("gradient")})
                return ", ".join(bad) if bad else None
            return None

        self.add(Case(cls, desc, argv=argv, cwd=d, names=list(names), nan_check=nan_check))

    @staticmethod
    def _overlap_after(case: Case, r: dict):
        # Record how fast the bodies left the overlap: a launch is the symptom of issue 33.
        try:
            q, v = frame_extremes(case.cwd / "run")
            r["max_speed"] = v
            if r["outcome"] in ("ok-result", "UNREPORTED-OVERLAP", "warning"):
                r["note"] = f"max |v| in the last frame {v:.3g} m/s"
        except Exception:
            pass
        return None

    # ---------------------------------------------------------------- class 1: numeric extremes
    def numeric(self):
        C = "numeric"
        box = obj_text(*grid_box(1, 0.1))
        for E in [
            "5e-324",
            "1e-320",
            "2.2250738585072014e-308",
            "1e-300",
            "1e-200",
            "1e-30",
            "1e30",
            "1e200",
            "1e300",
            "1.7976931348623157e308",
        ]:
            sc = scene([body(E=float(E))])
            self.sim_case(C, f"youngs_modulus {E} (simulate)", sc, names=["youngs", "modulus", E, "tet"])
        for E in ["4e-324", "1e-310", "1e305"]:
            self.grad_case(
                C,
                f"youngs_modulus {E} (grad density)",
                scene([body(E=float(E))]),
                names=["youngs", "modulus", "tet", E],
            )
        for nu in [
            0.5,
            0.4999999,
            0.49999999999999,
            0.4999999999999999,
            -0.9999999999,
            -0.99,
            -1.0,
            -1e-300,
            5e-324,
            1e-300,
        ]:
            sc = scene([body(nu=nu)])
            self.sim_case(C, f"poisson_ratio {nu!r}", sc, names=["poisson", repr(nu)])
        for nu in [0.49999999999, -0.999999999]:
            self.grad_case(
                C,
                f"poisson_ratio {nu!r} (grad poisson_ratio)",
                scene([body(nu=nu)]),
                names=["poisson"],
                param="poisson_ratio",
            )
        for rho in [5e-324, 1e-310, 1e-300, 1e-100, 1e100, 1e300, 1.7976931348623157e308]:
            self.sim_case(C, f"density {rho!r}", scene([body(density=rho)]), names=["density", "mass", repr(rho)])
        for m in [5e-324, 1e-300, 1e300]:
            self.sim_case(
                C, f"total_mass {m!r}", scene([body(density=None, total_mass=m)]), names=["total_mass", "mass"]
            )
        for dt in [5e-324, 1e-300, 1e-200, 1e-15, 1e3, 1e100, 1e300]:
            self.sim_case(
                C, f"time_step {dt!r}", scene([body()], dt=dt), names=["time step", "dt", "time_step", repr(dt)]
            )
        for flag, vals in {
            "--tolerance": ["5e-324", "1e-300", "1e300", "1.7976931348623157e308"],
            "--max-iterations": ["0", "1", "18446744073709551615"],
            "--anderson": ["64", "65", "1000000", "18446744073709551615"],
            "--dt": ["5e-324", "1e300"],
        }.items():
            for v in vals:
                self.sim_case(
                    C,
                    f"simulate {flag} {v}",
                    scene([body()]),
                    names=[flag, flag.strip("-").replace("-", "_"), v],
                    flags=(flag, v),
                )
        for v in ["1000000", "4294967296"]:
            self.grad_case(C, f"grad --anderson {v}", scene([body()]), names=["anderson"], flags=("--anderson", v))
        for v in ["1e300", "5e-324"]:
            self.grad_case(
                C,
                f"grad --implicit-tolerance {v} (implicit mode)",
                scene([body()]),
                names=["implicit"],
                flags=("--implicit-tolerance", v),
                mode="implicit",
            )
        for v in ["1e-300", "1e300", "nan"]:
            self.grad_case(C, f"grad --store-mb {v}", scene([body()]), names=["store"], flags=("--store-mb", v))
        for steps in ["18446744073709551615", "1000000000000", "0"]:
            self.sim_case(C, f"simulate --steps {steps}", scene([body()]), names=["--steps", steps], steps=int(steps))
        self.grad_case(C, "grad --steps 2^61", scene([body()]), names=["steps"], steps=2**61)
        for s in [1e-150, 1e-100, 1e-50, 1e50, 1e100, 1e150]:
            self.sim_case(C, f"body scale {s!r}", scene([body(scale=s)]), names=["scale", "body 'c'", "'c'"])
        self.sim_case(
            C,
            "mesh coordinates 1e-50 with E 1e-250",
            scene([body(E=1e-250)]),
            names=["youngs", "tet"],
            meshes={
                "cube.obj": obj_text(
                    [(x * 1e-50, y * 1e-50, z * 1e-50) for x, y, z in grid_box(1, 1.0)[0]], grid_box(1, 1.0)[1]
                )
            },
        )
        self.sim_case(
            C,
            "mesh coordinates 1e150 (volumes overflow)",
            scene([body()]),
            names=["cube.obj", "volume", "overflow"],
            meshes={
                "cube.obj": obj_text(
                    [(x * 1e150, y * 1e150, z * 1e150) for x, y, z in grid_box(1, 1.0)[0]], grid_box(1, 1.0)[1]
                )
            },
        )
        for t in [[1e300, 0, 0], [1e308, 1e308, 0], [-1e308, 0, 0]]:
            self.sim_case(C, f"translate {t}", scene([body(translate=t)]), names=["translate", "body 'c'", "'c'"])
        for r in [[1e300, 0, 0], [1e-320, 0, 0], [1e308, 1e308, 1e308]]:
            self.sim_case(C, f"rotate {r}", scene([body(rotate=r)]), names=["rotate", "'c'"])
        for g in [
            [0, 0, 0],
            [5e-324, 0, 0],
            [1e-310, -1e-310, 0],
            [1e308, 1e308, 0],
            [0, -1e300, 0],
            [0, -1.7976931348623157e308, 0],
        ]:
            self.sim_case(C, f"gravity {g}", scene([body()], gravity=g), names=["gravity"])
        for v in [[1e300, 0, 0], [1e308, 1e308, 1e308], [5e-324, 0, 0]]:
            self.sim_case(
                C,
                f"initial_velocity {v}",
                scene([body(initial_velocity=v)]),
                names=["initial_velocity", "velocity", "'c'"],
            )
        for n in [[0, 0, 0], [1e-300, 0, 0], [5e-324, 5e-324, 5e-324], [1e308, 1e308, 0], [0, 1e-200, 0]]:
            sc = scene([body(translate=[0, 0.5, 0])], obstacles=[ground(y=0.0, normal=n)])
            self.sim_case(C, f"plane normal {n}", sc, names=["normal", "ground", "obstacle"], nonzero=any(n))
        for mu in [1e300, 5e-324, 1.7976931348623157e308]:
            sc = scene([body(translate=[0, 0.01, 0], initial_velocity=[1, -1, 0])], obstacles=[ground(friction=mu)])
            self.sim_case(C, f"ground friction {mu!r}", sc, names=["friction", "ground"], steps=5)
        for th in [1e-300, 1e300, 5e-324]:
            sc = scene([body(translate=[0, 0.5, 0])], obstacles=[ground(thickness=th)])
            # A thickness as large as the bodies is refused up front, naming it.
            self.sim_case(C, f"ground thickness {th!r}", sc, names=["thickness", "ground"], expect_error=th > 1)
        for th in [1e-300, 1e300]:
            sc = scene(
                [body(name="a"), body(name="b", translate=[0, 2, 0])], collisions={"thickness": th, "friction": 0.3}
            )
            self.sim_case(C, f"collision thickness {th!r}", sc, names=["thickness", "collision"], expect_error=th > 1)
        for k in [1e300, 5e-324, 1.7976931348623157e308]:
            sc = scene([body(attachments=[{"vertices": {"indices": [0]}, "stiffness": k}])])
            self.sim_case(C, f"attachment stiffness {k!r}", sc, names=["stiffness", "attachment"])
        for setting, v in [
            ("damping", 5e-324),
            ("damping", 1e-300),
            ("contact_margin", 1e300),
            ("contact_margin", 5e-324),
            ("inner_max_iterations", 0),
            ("inner_tolerance", 1e300),
            ("contact_rounds", 0),
            ("contact_rounds", 10**19),
            ("crossing_rounds", 0),
            ("crossing_rounds", 10**19),
        ]:
            sc = scene([body(translate=[0, 0.01, 0])], obstacles=[ground()], solver={setting: v})
            self.sim_case(C, f"solver.{setting} {v!r}", sc, names=[setting])
        # Joint axes and muscle directions: zero, denormal, overflowing norm.
        cube_bone = lambda axis: body(  # noqa: E731
            skeleton={
                "bones": [
                    {"name": "root", "joint": {"fixed": {}}, "vertices": {"indices": [0, 1]}},
                    {
                        "name": "arm",
                        "parent": "root",
                        "joint": {"rotational": {"position": [0.5, 0.5, 0.5], "axis": axis}},
                        "vertices": {"indices": [4]},
                        "torque": {"times": [0, 1], "values": [1, 1]},
                    },
                ]
            }
        )
        for axis in [[0, 0, 0], [5e-324, 0, 0], [1e-300, 1e-300, 0], [1e308, 1e308, 0], [1.7976931348623157e308, 0, 0]]:
            self.sim_case(
                C,
                f"rotational joint axis {axis}",
                scene([cube_bone(axis)], gravity=[0, 0, 0]),
                names=["axis", "arm"],
                steps=3,
                nonzero=any(axis),
            )
        for axis in [[0, 0, 0], [1e308, 0, 1e308]]:
            b = body(
                skeleton={
                    "bones": [
                        {"name": "root", "joint": {"fixed": {}}, "vertices": {"indices": [0, 1]}},
                        {
                            "name": "slide",
                            "parent": "root",
                            "joint": {"prismatic": {"axis": axis}},
                            "vertices": {"indices": [4]},
                        },
                    ]
                }
            )
            self.sim_case(
                C,
                f"prismatic joint axis {axis}",
                scene([b], gravity=[0, 0, 0]),
                names=["axis", "slide"],
                nonzero=any(axis),
            )
        for dvec in [[0, 0, 0], [1e-310, 0, 0], [1e308, 1e308, 1e308]]:
            b = body(
                actuators=[
                    {
                        "name": "m",
                        "muscle": {"tets": {"all": {}}, "direction": dvec},
                        "stiffness": 1e5,
                        "activation": 0.3,
                    }
                ]
            )
            self.sim_case(
                C, f"muscle direction {dvec}", scene([b]), names=["direction", "muscle", "'m'"], nonzero=any(dvec)
            )
        for a in [1e-300, 1e300, 5e-324]:
            b = body(actuators=[{"name": "p", "pneumatic": {"tets": {"all": {}}}, "stiffness": 1e5, "activation": a}])
            self.sim_case(C, f"pneumatic activation {a!r}", scene([b]), names=["activation", "'p'", "pneumatic"])
        for k in [1e300, 5e-324]:
            b = body(actuators=[{"name": "p", "pneumatic": {"tets": {"all": {}}}, "stiffness": k, "activation": 1.2}])
            self.sim_case(C, f"actuator stiffness {k!r}", scene([b]), names=["stiffness", "'p'"])
        # Vectors the reader normalises: a scaled copy must give the run of the unit vector
        # (issue 33: an axis whose norm overflows became a zero axis). Compared frame by frame.
        arm = lambda axis: scene([cube_bone(axis)], gravity=[0, 0, 0])  # noqa: E731
        for k in [1e300, 1e-300, 5e-324, 1.7976931348623157e308]:
            self.equiv_case(
                C,
                f"rotational joint axis [0, 0, {k!r}] equals [0, 0, 1]",
                arm([0, 0, k]),
                arm([0, 0, 1]),
                names=["axis", "arm"],
            )
        slide = lambda axis: scene(
            [
                body(
                    skeleton={
                        "bones": [
                            {"name": "root", "joint": {"fixed": {}}, "vertices": {"indices": [0, 1]}},
                            {
                                "name": "slide",
                                "parent": "root",
                                "joint": {"prismatic": {"axis": axis}},
                                "vertices": {"indices": [4]},
                                "torque": {"times": [0, 1], "values": [5, 5]},
                            },
                        ]
                    }
                )
            ],
            gravity=[0, 0, 0],
        )  # noqa: E731
        for k in [1e308, 1e-300]:
            self.equiv_case(
                C,
                f"prismatic joint axis [{k!r}, 0, {k!r}] equals [1, 0, 1]",
                slide([k, 0, k]),
                slide([1, 0, 1]),
                names=["axis", "slide"],
            )
        fall = lambda n: scene(
            [body(translate=[0, 0.01, 0], initial_velocity=[0.5, -1, 0])], obstacles=[ground(normal=n)]
        )  # noqa: E731
        for n in [[0, 1e300, 0], [0, 1.7976931348623157e308, 0], [0, 1e-200, 0], [0, 5e-324, 0]]:
            self.equiv_case(
                C, f"plane normal {n} equals [0, 1, 0]", fall(n), fall([0, 1, 0]), names=["normal", "ground"], steps=5
            )
        pull = lambda dvec: scene(
            [
                body(
                    actuators=[
                        {
                            "name": "m",
                            "muscle": {"tets": {"all": {}}, "direction": dvec},
                            "stiffness": 1e5,
                            "activation": 0.3,
                        }
                    ]
                )
            ],
            gravity=[0, 0, 0],
        )  # noqa: E731
        for k in [1e300, 1e-300]:
            self.equiv_case(
                C,
                f"muscle direction [{k!r}, 0, 0] equals [1, 0, 0]",
                pull([k, 0, 0]),
                pull([1, 0, 0]),
                names=["direction", "'m'"],
            )
        # bounds / sweep / generate at the edge of double precision
        d = self.dir("numeric-mesh")
        self.write(d, "box.obj", box)
        for rho, mu, dt in [
            ("5e-324", "1e5", "0.01"),
            ("1000", "5e-324", "0.01"),
            ("1000", "1e308", "0.01"),
            ("1e308", "1e5", "1e-300"),
            ("1000", "1e5", "1e300"),
            ("1000", "1e5", "5e-324"),
        ]:
            self.add(
                Case(
                    C,
                    f"bounds --rho {rho} --mu {mu} --dt {dt}",
                    argv=[
                        "bounds",
                        "--mesh",
                        "box.obj",
                        "--rho",
                        rho,
                        "--mu",
                        mu,
                        "--dt",
                        dt,
                        "--json",
                        f"b-{rho}-{mu}-{dt}.json",
                    ],
                    cwd=d,
                    names=["--rho", "--mu", "--dt", "rho", "mu", "dt"],
                )
            )
        for lo, hi in [("5e-324", "1e308"), ("1e-300", "1e-299"), ("1", "1.0000000000000002")]:
            self.add(
                Case(
                    C,
                    f"sweep --dt-min {lo} --dt-max {hi}",
                    argv=[
                        "sweep",
                        "--mesh",
                        "box.obj",
                        "--rho",
                        "1000",
                        "--mu",
                        "1e5",
                        "--dt-min",
                        lo,
                        "--dt-max",
                        hi,
                        "--points",
                        "3",
                    ],
                    cwd=d,
                    names=["--dt-min", "--dt-max", "dt"],
                )
            )
        for size, jitter in [
            ("1e-200,1e-200,1e-200", "0"),
            ("1e-100,1,1", "0"),
            ("1,1,1", "0.4999999999"),
            ("1e200,1e200,1e-200", "0"),
        ]:
            self.add(
                Case(
                    C,
                    f"generate --size {size} --jitter {jitter}",
                    argv=[
                        "generate",
                        "--cells",
                        "2,2,2",
                        "--size",
                        size,
                        "--jitter",
                        jitter,
                        "--out",
                        f"gen{self.rng.randrange(10**6)}.obj",
                    ],
                    cwd=d,
                    names=["--size", "--jitter", "size"],
                )
            )
        # Flag values nothing can mean, and selections that select nothing: errors naming them.
        for argv, names in [
            (["sweep", "--mesh", "box.obj", "--rho", "1000", "--mu", "1e5", "--mark-dt", "nan"], ["--mark-dt"]),
            (["sweep", "--mesh", "box.obj", "--rho", "1000", "--mu", "1e5", "--mark-dt", "-5"], ["--mark-dt"]),
            (
                ["bounds", "--mesh", "box.obj", "--rho", "1000", "--mu", "1e5", "--dt", "0.01", "--min-tet-quality", "nan"],
                ["--min-tet-quality"],
            ),
            (["gradcheck", "--steps", "0", "--json", "gc.json"], ["--steps"]),
            (["validate", "--study", "hertz", "--subset", "fast", "--json", "v.json"], ["hertz", "--subset"]),
        ]:
            self.add(Case(C, " ".join(argv[:1] + argv[-4:]), argv=argv, cwd=d, names=names, expect_error=True))
        # A run whose steps stop at the iteration cap says so (a stiff box gains energy that way).
        d, _ = self.scene_dir("numeric", scene([body(E=1e17)]))
        self.add(
            Case(
                C,
                "simulate a stiff box whose steps stop at the iteration cap (max_iterations 1)",
                argv=["simulate", "scene.json", "--steps", "5", "--max-iterations", "1"],
                cwd=d,
                expect_warning=True,
            )
        )
        # A joint that starts outside its limits, or at an angle no double can hold to 1e-10.
        for angle, limits in [(2.0, [-1, 1]), (1e300, None), (-0.5, [0, 0])]:
            joint = {"position": [0, 0, 0], "axis": [0, 0, 1], "angle": angle}
            if limits is not None:
                joint["limits"] = limits
            bone = {"name": "arm", "joint": {"rotational": joint}, "vertices": {"indices": [0]}}
            self.sim_case(
                C,
                f"bone initial angle {angle} with limits {limits}",
                scene([body(skeleton={"bones": [bone]})]),
                names=["arm", "angle"],
                expect_error=True,
            )

    # ---------------------------------------------------------------- class 2: malformed files
    def files(self):
        C = "files"
        good = json.dumps(scene([body()]), indent=1)
        # Truncated JSON at seeded cut points.
        for cut in sorted(self.rng.sample(range(1, len(good) - 1), 6)):
            self.sim_case(C, f"scene truncated at byte {cut}", None, raw=good[:cut], names=["scene.json"])
        for text, what in [
            ("", "empty scene file"),
            ("null", "scene 'null'"),
            ("[]", "scene '[]'"),
            ("{}", "scene '{}'"),
            ("\ufeff" + good, "scene with a UTF-8 BOM"),
            (good.replace("diffsoft.scene/1", "diffsoft.scene/2"), "schema diffsoft.scene/2"),
        ]:
            self.sim_case(C, what, None, raw=text, names=["scene.json"])
        self.sim_case(
            C,
            "scene with non-UTF-8 bytes in a string",
            None,
            raw=good.encode().replace(b'"c"', b'"\xff\xfe"'),
            names=["scene.json", "UTF-8", "utf"],
        )
        self.sim_case(
            C, "scene with a NUL byte", None, raw=good.encode().replace(b'"c"', b'"c\x00"'), names=["scene.json"]
        )
        self.sim_case(
            C, "scene number 1e999", None, raw=good.replace("100000.0", "1e999"), names=["scene.json", "1e999"]
        )
        self.sim_case(C, "scene number NaN literal", None, raw=good.replace("100000.0", "NaN"), names=["scene.json"])
        wrong_types = [
            ("youngs_modulus as a string", lambda s: s["bodies"][0]["material"].__setitem__("youngs_modulus", "1e5")),
            ("gravity with two components", lambda s: s.__setitem__("gravity", [0, -9.81])),
            ("gravity as a string", lambda s: s.__setitem__("gravity", "down")),
            ("bodies as an object", lambda s: s.__setitem__("bodies", {"c": s["bodies"][0]})),
            ("mesh as a number", lambda s: s["bodies"][0].__setitem__("mesh", 42)),
            ("body name null", lambda s: s["bodies"][0].__setitem__("name", None)),
            ("density true", lambda s: s["bodies"][0].__setitem__("density", True)),
            ("fixed indices negative", lambda s: s["bodies"][0].__setitem__("fixed", {"indices": [-1]})),
            ("fixed indices out of range", lambda s: s["bodies"][0].__setitem__("fixed", {"indices": [99]})),
            ("fixed index 2^64", lambda s: s["bodies"][0].__setitem__("fixed", {"indices": [18446744073709551616]})),
            (
                "fixed box min > max",
                lambda s: s["bodies"][0].__setitem__("fixed", {"box": {"min": [1, 1, 1], "max": [-1, -1, -1]}}),
            ),
            (
                "fixed selects every vertex",
                lambda s: s["bodies"][0].__setitem__("fixed", {"box": {"min": [-9, -9, -9], "max": [9, 9, 9]}}),
            ),
            (
                "attachment indices out of range",
                lambda s: s["bodies"][0].__setitem__("attachments", [{"vertices": {"indices": [7]}, "stiffness": 1e3}]),
            ),
            ("unknown top-level key", lambda s: s.__setitem__("gravityy", [0, -9.81, 0])),
            ("unknown body key", lambda s: s["bodies"][0].__setitem__("colour", "red")),
            ("unknown material key", lambda s: s["bodies"][0]["material"].__setitem__("shear_modulus", 1e5)),
            ("unknown solver key (typo)", lambda s: s.__setitem__("solver", {"tolerence": 1e-6})),
            ("solver name unknown", lambda s: s.__setitem__("solver", {"solver": "magic"})),
            ("material model unknown", lambda s: s["bodies"][0]["material"].__setitem__("model", "rubber")),
            ("time step twice", lambda s: s.__setitem__("solver", {"dt": 0.01})),
            ("no time step", lambda s: s.pop("time_step")),
            ("density and total_mass", lambda s: s["bodies"][0].__setitem__("total_mass", 1.0)),
            ("neither density nor total_mass", lambda s: s["bodies"][0].pop("density")),
            ("no bodies", lambda s: s.__setitem__("bodies", [])),
            ("duplicate body names", lambda s: s["bodies"].append(body(translate=[0, 3, 0]))),
            ("mesh missing", lambda s: s["bodies"][0].__setitem__("mesh", "missing.obj")),
            ("mesh is a directory", lambda s: s["bodies"][0].__setitem__("mesh", ".")),
            ("mesh is the scene itself", lambda s: s["bodies"][0].__setitem__("mesh", "scene.json")),
            ("mesh path empty", lambda s: s["bodies"][0].__setitem__("mesh", "")),
            ("mesh extension 'x.'", lambda s: s["bodies"][0].__setitem__("mesh", "cube.")),
            ("mesh without extension", lambda s: s["bodies"][0].__setitem__("mesh", "cube")),
            ("mesh extension .face", lambda s: s["bodies"][0].__setitem__("mesh", "cube.face")),
            ("mesh extension .OBJ (upper case)", lambda s: s["bodies"][0].__setitem__("mesh", "CUBE.OBJ")),
            (
                "torque times decreasing",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "r", "joint": {"fixed": {}}, "vertices": {"indices": [0]}},
                            {
                                "name": "a",
                                "parent": "r",
                                "joint": {"rotational": {"position": [0, 0, 0], "axis": [0, 0, 1]}},
                                "vertices": {"indices": [4]},
                                "torque": {"times": [1, 0], "values": [0, 1]},
                            },
                        ]
                    },
                ),
            ),
            (
                "torque times and values of different lengths",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "r", "joint": {"fixed": {}}, "vertices": {"indices": [0]}},
                            {
                                "name": "a",
                                "parent": "r",
                                "joint": {"rotational": {"position": [0, 0, 0], "axis": [0, 0, 1]}},
                                "vertices": {"indices": [4]},
                                "torque": {"times": [0, 1, 2], "values": [0, 1]},
                            },
                        ]
                    },
                ),
            ),
            (
                "bone parent cycle",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "a", "parent": "b", "joint": {"fixed": {}}, "vertices": {"indices": [0]}},
                            {"name": "b", "parent": "a", "joint": {"fixed": {}}, "vertices": {"indices": [4]}},
                        ]
                    },
                ),
            ),
            (
                "duplicate bone names",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "a", "joint": {"fixed": {}}, "vertices": {"indices": [0]}},
                            {"name": "a", "joint": {"fixed": {}}, "vertices": {"indices": [4]}},
                        ]
                    },
                ),
            ),
            (
                "two bones share a vertex",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "a", "joint": {"fixed": {}}, "vertices": {"indices": [0, 1]}},
                            {
                                "name": "b",
                                "parent": "a",
                                "joint": {"rotational": {"position": [0, 0, 0], "axis": [0, 0, 1]}},
                                "vertices": {"indices": [1, 4]},
                            },
                        ]
                    },
                ),
            ),
            (
                "joint limits reversed",
                lambda s: s["bodies"][0].__setitem__(
                    "skeleton",
                    {
                        "bones": [
                            {"name": "r", "joint": {"fixed": {}}, "vertices": {"indices": [0]}},
                            {
                                "name": "a",
                                "parent": "r",
                                "joint": {"rotational": {"position": [0, 0, 0], "axis": [0, 0, 1], "limits": [1, -1]}},
                                "vertices": {"indices": [4]},
                            },
                        ]
                    },
                ),
            ),
            (
                "duplicate actuator tets",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [{"name": "p", "pneumatic": {"tets": {"indices": [0, 0]}}, "stiffness": 1e5, "activation": 1.1}],
                ),
            ),
            (
                "duplicate actuator names",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {"name": "p", "pneumatic": {"tets": {"indices": [0]}}, "stiffness": 1e5, "activation": 1.1},
                        {"name": "p", "pneumatic": {"tets": {"indices": [1]}}, "stiffness": 1e5, "activation": 1.1},
                    ],
                ),
            ),
            (
                "one tet in two actuator groups",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {"name": "p", "pneumatic": {"tets": {"indices": [0]}}, "stiffness": 1e5, "activation": 1.1},
                        {"name": "q", "pneumatic": {"tets": {"indices": [0]}}, "stiffness": 1e5, "activation": 0.9},
                    ],
                ),
            ),
            (
                "actuator tets out of range",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [{"name": "p", "pneumatic": {"tets": {"indices": [5]}}, "stiffness": 1e5, "activation": 1.1}],
                ),
            ),
            (
                "actuator both pneumatic and muscle",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "p",
                            "pneumatic": {"tets": {"all": {}}},
                            "muscle": {"tets": {"all": {}}, "direction": [1, 0, 0]},
                            "stiffness": 1e5,
                            "activation": 0.5,
                        }
                    ],
                ),
            ),
            (
                "muscle polyline of one point",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "m",
                            "muscle": {"polyline": [[0, 0, 0]], "radius": 1},
                            "stiffness": 1e5,
                            "activation": 0.5,
                        }
                    ],
                ),
            ),
            (
                "muscle radius negative",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "m",
                            "muscle": {"polyline": [[0, 0, 0], [1, 1, 1]], "radius": -1},
                            "stiffness": 1e5,
                            "activation": 0.5,
                        }
                    ],
                ),
            ),
            (
                "activation series unsorted",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "p",
                            "pneumatic": {"tets": {"all": {}}},
                            "stiffness": 1e5,
                            "activation": {"times": [1, 0.5, 0], "values": [1, 1, 1]},
                        }
                    ],
                ),
            ),
            (
                "actuator selects no tet",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "p",
                            "pneumatic": {"tets": {"box": {"min": [5, 5, 5], "max": [6, 6, 6]}}},
                            "stiffness": 1e5,
                            "activation": 1.1,
                        }
                    ],
                ),
            ),
            (
                "tet selector min_shared 0",
                lambda s: s["bodies"][0].__setitem__(
                    "actuators",
                    [
                        {
                            "name": "p",
                            "pneumatic": {"tets": {"vertices": {"indices": [0], "min_shared": 0}}},
                            "stiffness": 1e5,
                            "activation": 1.1,
                        }
                    ],
                ),
            ),
            ("duplicate obstacle names", lambda s: s.__setitem__("obstacles", [ground(y=-1), ground(y=-2)])),
            (
                "obstacle with plane and mesh",
                lambda s: s.__setitem__(
                    "obstacles",
                    [
                        {
                            "plane": {"point": [0, -1, 0], "normal": [0, 1, 0]},
                            "mesh": {"file": "cube.obj"},
                            "friction": 0.3,
                        }
                    ],
                ),
            ),
            (
                "obstacle mesh without faces",
                lambda s: s.__setitem__("obstacles", [{"name": "m", "mesh": {"file": "cube.obj"}, "friction": 0.3}]),
            ),
            (
                "cloth mesh of tets only",
                lambda s: s.__setitem__(
                    "cloths", [{"name": "f", "mesh": "cube.obj", "stretching": 100, "area_density": 0.3}]
                ),
            ),
            (
                "cloth named like the body",
                lambda s: s.__setitem__(
                    "cloths",
                    [
                        {
                            "name": "c",
                            "mesh": "sheet.obj",
                            "stretching": 100,
                            "area_density": 0.3,
                            "translate": [0, 5, 0],
                        }
                    ],
                ),
            ),
        ]
        sheet = cloth_grid(2, 1.0, 0.0)
        dup = {
            "duplicate body names",
            "duplicate actuator tets",
            "duplicate obstacle names",
            "cloth named like the body",
        }
        for what, edit in wrong_types:
            s = scene([body()])
            edit(s)
            self.sim_case(
                C,
                what,
                None,
                raw=s,
                names=["scene.json", "cube", "sheet.obj", "missing.obj", ".:"],
                expect_error=what in dup,
                meshes={
                    "cube.obj": CUBE_OBJ,
                    "CUBE.OBJ": CUBE_OBJ,
                    "cube": CUBE_OBJ,
                    "cube.": CUBE_OBJ,
                    "cube.face": CUBE_OBJ,
                    "sheet.obj": sheet,
                },
            )
        s = scene([body()])
        raw = json.dumps(s).replace('"density": 1000.0', '"density": 1000.0, "density": 2000.0')
        self.sim_case(C, "duplicate JSON key density", None, raw=raw, names=["scene.json", "density"])
        # Hostile meshes (through simulate, with the scene naming them).
        meshes = {
            "empty mesh file": "",
            "vertices only": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n",
            "tets only": "t 0 1 2 3\n",
            "tet index out of range": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 4\n",
            "negative tet index": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt -1 1 2 3\n",
            "1-based tet indices": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 1 2 3 4\n",
            "duplicate tet": CUBE_OBJ + "t 0 1 2 3\n",
            "duplicate tet, permuted": CUBE_OBJ + "t 1 0 3 2\n",
            "tet repeating a vertex": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 2\n",
            "duplicate vertices (two coincident, both used)": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 0 0\nt 0 1 2 3\nt 4 2 1 3\n",
            "degenerate (coplanar) tet": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nt 0 1 2 3\n",
            "inverted tet": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 2 1 3\n",
            "one inverted tet of two": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nt 0 1 2 3\nt 1 3 2 4\n",
            "NaN coordinate": "v nan 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n",
            "inf coordinate": "v 0 0 0\nv inf 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n",
            "coordinate 1e999": "v 0 0 0\nv 1e999 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n",
            "NaN in an unused vertex": TET_OBJ + "v nan nan nan\n",
            "coordinates 1e300": "v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nv 0 0 1e300\nt 0 1 2 3\n",
            "coordinates 1e-300": "v 0 0 0\nv 1e-300 0 0\nv 0 1e-300 0\nv 0 0 1e-300\nt 0 1 2 3\n",
            "sliver of quality 1e-12": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.3 0.3 1e-12\nt 0 1 2 3\n",
            "tet line with three indices": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2\n",
            "tet line with five indices": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3 3\n",
            "fractional tet index": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3.5\n",
            "tet index 2^64": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 18446744073709551616\n",
            "vertex with two coordinates": "v 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nt 0 1 2 3\n",
            "vertex weight 0 (v x y z 0)": "v 0 0 0 0\nv 1 0 0 0\nv 0 1 0 0\nv 0 0 1 0\nt 0 1 2 3\n",
            "CRLF line endings": TET_OBJ.replace("\n", "\r\n"),
            "unknown statement": TET_OBJ + "zz 1 2 3\n",
            "isolated unused vertex far away": TET_OBJ + "v 1e6 1e6 1e6\n",
        }
        for what, text in meshes.items():
            self.sim_case(
                C,
                f"mesh: {what}",
                scene([body(mesh="m.obj")]),
                names=["m.obj"],
                meshes={"m.obj": text},
                expect_error=what.startswith("duplicate"),
            )
        self.sim_case(
            C,
            "mesh: non-UTF-8 bytes in a comment",
            scene([body(mesh="m.obj")]),
            names=["m.obj"],
            meshes={"m.obj": b"# \xff\xfe caf\xe9\n" + TET_OBJ.encode()},
        )
        self.sim_case(
            C,
            "mesh: non-UTF-8 byte in a coordinate",
            scene([body(mesh="m.obj")]),
            names=["m.obj"],
            meshes={"m.obj": TET_OBJ.replace("v 1 0 0", "v 1\xff 0 0").encode("latin-1")},
        )
        self.sim_case(
            C,
            "mesh: 200k-character line",
            scene([body(mesh="m.obj")]),
            names=["m.obj"],
            meshes={"m.obj": "# " + "x" * 200000 + "\n" + TET_OBJ},
        )
        # TetGen pairs
        tetgen = {
            "node count larger than the lines": ("9 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n", "1 4 0\n0 0 1 2 3\n"),
            "node count 10^15": ("1000000000000000 3 0 0\n0 0 0 0\n", "1 4 0\n0 0 1 2 3\n"),
            "ele count 10^15": (NODE, "1000000000000000 4 0\n0 0 1 2 3\n"),
            "dimension 2": ("4 2 0 0\n0 0 0\n1 1 0\n2 0 1\n3 1 1\n", ELE),
            "node ids not consecutive": ("4 3 0 0\n0 0 0 0\n1 1 0 0\n5 0 1 0\n3 0 0 1\n", "1 4 0\n0 0 1 2 3\n"),
            "ele refers to a missing node": (NODE, "1 4 0\n0 0 1 2 9\n"),
            "ele with 3 nodes per tet": (NODE, "1 3 0\n0 0 1 2\n"),
            "1-based ids": ("4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", "1 4 0\n1 1 2 3 4\n"),
            "negative node count": ("-4 3 0 0\n", ELE),
            "nan node": ("4 3 0 0\n0 nan 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n", "1 4 0\n0 0 1 2 3\n"),
            "empty .ele": (NODE, ""),
        }
        for what, (node, ele) in tetgen.items():
            self.sim_case(
                C,
                f"tetgen: {what}",
                scene([body(mesh="t.node")]),
                names=["t.node", "t.ele"],
                meshes={"t.node": node, "t.ele": ele},
            )
        self.sim_case(C, "tetgen: .ele missing", scene([body(mesh="t.node")]), names=["t.ele"], meshes={"t.node": NODE})
        gmsh = {
            "valid 2.2 one tet": MSH22,
            "truncated after $Nodes": MSH22.split("$Elements")[0],
            "node count 10^15": MSH22.replace("$Nodes\n4\n", "$Nodes\n1000000000000000\n"),
            "version 1.0": MSH22.replace("2.2 0 8", "1.0 0 8"),
            "element refers to node 9": MSH22.replace("1 4 2 0 1 1 2 3 4", "1 4 2 0 1 1 2 3 9"),
            "no tets (a triangle)": MSH22.replace("1 4 2 0 1 1 2 3 4", "1 2 2 0 1 1 2 3"),
        }
        for what, text in gmsh.items():
            self.sim_case(C, f"gmsh: {what}", scene([body(mesh="m.msh")]), names=["m.msh"], meshes={"m.msh": text})
        # Straight to the mesh tools.
        d = self.dir("files-quality")
        for name, text in [
            ("q.obj", "v 0 0 0\nt 0 0 0 0\n"),
            ("x.", TET_OBJ),
            ("noext", TET_OBJ),
            ("bin.obj", bytes(range(256)) * 4),
            ("dir.obj", None),
        ]:
            if text is None:
                (d / name).mkdir()
            else:
                self.write(d, name, text)
            self.add(Case(C, f"quality --mesh {name}", argv=["quality", "--mesh", name], cwd=d, names=[name]))
        self.add(
            Case(C, "quality --mesh (file missing)", argv=["quality", "--mesh", "nope.obj"], cwd=d, names=["nope.obj"])
        )
        self.add(
            Case(
                C,
                "merge of two unrelated JSON files",
                argv=["merge", "a.json", "b.json", "--json", "m.json"],
                cwd=d,
                names=["a.json", "b.json"],
                before=lambda c: (self.write(c.cwd, "a.json", {"schema": "x"}), self.write(c.cwd, "b.json", [1, 2])),
            )
        )
        self.add(
            Case(
                C,
                "scene file is a directory",
                argv=["simulate", ".", "--steps", "1"],
                cwd=d,
                names=["'.'", " . ", ".:", "directory"],
            )
        )
        self.add(
            Case(
                C,
                "scene file missing",
                argv=["grad", "nope.json", "--param", "density", "--steps", "1"],
                cwd=d,
                names=["nope.json"],
            )
        )

    # ---------------------------------------------------------------- class 3: outputs
    def outputs(self):
        C = "outputs"

        def fs_setup(tag):
            d = self.dir(tag)
            self.write(d, "cube.obj", CUBE_OBJ)
            self.write(d, "scene.json", scene([body()]))
            self.write(d, "t.node", NODE)
            self.write(d, "t.ele", ELE)
            return d

        def digest(p: Path) -> str:
            return (
                hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else f"<{stat.filemode(p.lstat().st_mode)}>"
            )

        def guard(files):
            """before: hash the inputs; after: any change is FILE-DAMAGE."""

            def before(c: Case):
                c.state["hashes"] = {f: digest(c.cwd / f) for f in files}

            def after(c: Case, r: dict):
                for f, h in c.state["hashes"].items():
                    p = c.cwd / f
                    if not p.exists() and not p.is_symlink():
                        return ("FILE-DAMAGE", f"{f} was removed")
                    if digest(p) != h:
                        return ("FILE-DAMAGE", f"{f} changed")
                return None

            return before, after

        grad_args = ["grad", "scene.json", "--steps", "2", "--param", "density"]
        bounds_args = ["bounds", "--mesh", "t.node", "--rho", "1000", "--mu", "1e5", "--dt", "0.01"]
        quality_obj = ["quality", "--mesh", "cube.obj"]
        # Outputs equal to an input, spelled in several ways.
        for argv, out, what in [
            (grad_args, "scene.json", "grad --json = the scene"),
            (grad_args, "./sub/../scene.json", "grad --json = the scene via sub/.."),
            (grad_args, "cube.obj", "grad --json = the scene's mesh"),
            (grad_args, "link-to-cube.obj", "grad --json = a symlink to the scene's mesh"),
            (bounds_args, "t.ele", "bounds --mesh t.node --json t.ele"),
            (bounds_args, "t.node", "bounds --mesh t.node --json t.node"),
            (
                ["bounds", "--mesh", "t.ele", "--rho", "1000", "--mu", "1e5", "--dt", "0.01"],
                "t.node",
                "bounds --mesh t.ele --json t.node",
            ),
            (["quality", "--mesh", "t.ele"], "t.node", "quality --mesh t.ele --json t.node"),
            (
                ["quality", "--mesh", "t.node"],
                "t.face",
                "quality --mesh t.node --json t.face (a sibling that does not exist yet)",
            ),
            (quality_obj, "cube.obj", "quality --json = its mesh"),
            (quality_obj, "hard-link-to-cube.obj", "quality --json = a hard link to its mesh"),
        ]:
            d = fs_setup("outputs")
            (d / "sub").mkdir()
            os.symlink("cube.obj", d / "link-to-cube.obj")
            os.link(d / "cube.obj", d / "hard-link-to-cube.obj")
            b, a = guard(["scene.json", "cube.obj", "t.node", "t.ele"])
            self.add(
                Case(
                    C, what, argv=[*argv, "--json", out], cwd=d, names=[out, Path(out).name, "input"], before=b, after=a
                )
            )
        # A scene with a non-.json name (or upper-case) whose mesh is the output.
        for sname in ["scene.txt", "scene.JSON", "scene"]:
            d = fs_setup("outputs")
            shutil.copy(d / "scene.json", d / sname)
            b, a = guard(["cube.obj", sname])
            self.add(
                Case(
                    C,
                    f"grad {sname} --json cube.obj (scene not named .json)",
                    argv=["grad", sname, "--steps", "2", "--param", "density", "--json", "cube.obj"],
                    cwd=d,
                    names=["cube.obj", sname],
                    before=b,
                    after=a,
                )
            )
        # An upper-case TetGen pair.
        d = fs_setup("outputs")
        self.write(d, "T.NODE", NODE)
        self.write(d, "T.ele", ELE)
        b, a = guard(["T.NODE", "T.ele"])
        self.add(
            Case(
                C,
                "bounds --mesh T.NODE --json T.ele (upper-case extension)",
                argv=["bounds", "--mesh", "T.NODE", "--rho", "1000", "--mu", "1e5", "--dt", "0.01", "--json", "T.ele"],
                cwd=d,
                names=["T.ele", "T.NODE"],
                before=b,
                after=a,
            )
        )
        # A scene whose mesh sits in a sub-directory named with '..', and an obstacle mesh.
        d = fs_setup("outputs")
        (d / "m").mkdir()
        self.write(d / "m", "ob.obj", BOX_SURFACE)
        self.write(
            d,
            "scene.json",
            scene(
                [body(mesh="m/../cube.obj", translate=[0, 3, 0])],
                obstacles=[{"name": "box", "mesh": {"file": "m/ob.obj"}, "friction": 0.3}],
            ),
        )
        b, a = guard(["cube.obj", "m/ob.obj"])
        self.add(
            Case(
                C,
                "grad --json = the obstacle mesh",
                argv=[*grad_args, "--json", "m/ob.obj"],
                cwd=d,
                names=["ob.obj"],
                before=b,
                after=a,
            )
        )
        d2 = fs_setup("outputs")
        self.write(d2, "scene.json", scene([body(mesh="m/../cube.obj", translate=[0, 3, 0])]))
        (d2 / "m").mkdir()
        b, a = guard(["cube.obj"])
        self.add(
            Case(
                C,
                "grad --json = the mesh named m/../cube.obj",
                argv=[*grad_args, "--json", "cube.obj"],
                cwd=d2,
                names=["cube.obj"],
                before=b,
                after=a,
            )
        )
        # Two outputs with one path.
        for j, s in [
            ("same.out", "same.out"),
            ("d/../same.out", "same.out"),
            ("./same.out", "same.out"),
            ("same.out", "link.svg"),
        ]:
            d = fs_setup("outputs")
            (d / "d").mkdir()
            os.symlink("same.out", d / "link.svg")
            self.add(
                Case(
                    C,
                    f"sweep --json {j} --svg {s}",
                    argv=[
                        "sweep",
                        "--mesh",
                        "t.node",
                        "--rho",
                        "1000",
                        "--mu",
                        "1e5",
                        "--points",
                        "3",
                        "--json",
                        j,
                        "--svg",
                        s,
                    ],
                    cwd=d,
                    names=["--json", "--svg", "same"],
                    after=self._same_output_after,
                )
            )
        # Symbolic links, devices, FIFOs, directories, unwritable places.
        d = fs_setup("outputs")
        os.symlink("real.json", d / "link.json")

        def link_after(c, r):
            p = c.cwd / "link.json"
            if not p.is_symlink():
                return ("FILE-DAMAGE", "the symlink was replaced by a file")
            if r["exit"] == 0 and not (c.cwd / "real.json").is_file():
                return ("FILE-DAMAGE", "exit 0 but the link's target was not written")
            return None

        self.add(
            Case(
                C,
                "grad --json to a symlink (dangling, target in the same dir)",
                argv=[*grad_args, "--json", "link.json"],
                cwd=d,
                after=link_after,
            )
        )
        d = fs_setup("outputs")
        (d / "elsewhere").mkdir()
        os.symlink("elsewhere/real.json", d / "link.json")

        def link_after2(c, r):
            p = c.cwd / "link.json"
            if not p.is_symlink():
                return ("FILE-DAMAGE", "the symlink was replaced by a file")
            if r["exit"] == 0 and not (c.cwd / "elsewhere/real.json").is_file():
                return ("FILE-DAMAGE", "exit 0 but the link's target was not written")
            return None

        self.add(
            Case(
                C,
                "grad --json to a symlink into another directory",
                argv=[*grad_args, "--json", "link.json"],
                cwd=d,
                after=link_after2,
            )
        )
        d = fs_setup("outputs")
        os.symlink("loop2.json", d / "loop1.json")
        os.symlink("loop1.json", d / "loop2.json")
        self.add(
            Case(
                C,
                "grad --json to a symlink loop",
                argv=[*grad_args, "--json", "loop1.json"],
                cwd=d,
                names=["loop1.json"],
            )
        )
        d = fs_setup("outputs")
        os.symlink("scene.json", d / "link-to-scene.json")
        b, a = guard(["scene.json"])
        self.add(
            Case(
                C,
                "grad --json to a symlink to the scene",
                argv=[*grad_args, "--json", "link-to-scene.json"],
                cwd=d,
                names=["link-to-scene.json", "scene.json"],
                before=b,
                after=a,
            )
        )
        # Character devices: a private copy of /dev/null and /dev/full when root (never the
        # machine's own), else the real ones (which a non-root rename cannot replace).
        for dev, (major, minor), expect in [("null", (1, 3), 0), ("full", (1, 7), 1)]:
            d = fs_setup("outputs")
            path = self._chardev(d, dev, major, minor)
            if path is None:
                continue

            def dev_after(c, r, path=path, expect=expect):
                if not stat.S_ISCHR(os.lstat(path).st_mode):
                    return ("FILE-DAMAGE", f"{path} is no longer a character device")
                if expect == 1 and r["exit"] == 0:
                    return ("FILE-DAMAGE", "exit 0 although the device is full (report lost silently)")
                return None

            for argv in [grad_args, [*bounds_args]]:
                self.add(
                    Case(
                        C,
                        f"{argv[0]} --json to a character device ({dev})",
                        argv=[*argv, "--json", str(path)],
                        cwd=d,
                        names=[str(path), dev],
                        after=dev_after,
                    )
                )
        d = fs_setup("outputs")
        full = self._chardev(d, "full-stdout", 1, 7)
        if full:
            self.add(
                Case(
                    C,
                    "simulate with stdout on a full device",
                    argv=["simulate", "scene.json", "--steps", "3", "--out", "run"],
                    cwd=d,
                    stdout_to=str(full),
                    after=lambda c, r: None if (c.cwd / "run/run.json").exists() else ("FILE-DAMAGE", "no run log"),
                )
            )
        for argv in [grad_args, bounds_args]:
            d = fs_setup("outputs")
            self.add(
                self._fifo_case(
                    C, f"{argv[0]} --json to a FIFO (with a reader)", [*argv, "--json", "fifo.json"], d, d / "fifo.json"
                )
            )
        # simulate --out a FIFO / a file / unwritable / the scene's directory
        d = fs_setup("outputs")
        os.mkfifo(d / "fifo")
        self.add(
            Case(
                C,
                "simulate --out a FIFO",
                argv=["simulate", "scene.json", "--steps", "2", "--out", "fifo"],
                cwd=d,
                names=["fifo"],
                timeout=20,
            )
        )
        # Links and special files inside --out under the names a run writes: never written
        # through (the scene would be replaced by the run log), never opened (a FIFO blocks).
        for name, make, overwrite in [
            ("run.json", "link-scene", False),
            ("run.json", "link-scene", True),
            ("frames.pvd", "link-mesh", True),
            ("frame_00001.vtu", "fifo", True),
            ("frame_00000.vtu", "dir", True),
        ]:
            d = fs_setup("outputs")
            (d / "run").mkdir()
            if make == "link-scene":
                os.symlink("../scene.json", d / "run" / name)
            elif make == "link-mesh":
                os.symlink("../cube.obj", d / "run" / name)
            elif make == "fifo":
                os.mkfifo(d / "run" / name)
            else:
                (d / "run" / name).mkdir()
            b, a = guard(["scene.json", "cube.obj"])
            argv = ["simulate", "scene.json", "--steps", "2", "--out", "run", *(["--overwrite"] if overwrite else [])]
            self.add(
                Case(
                    C,
                    f"simulate --out run{' --overwrite' if overwrite else ''} where run/{name} is a {make}",
                    argv=argv,
                    cwd=d,
                    names=[name],
                    before=b,
                    after=a,
                    timeout=20,
                    expect_error=True,
                )
            )
        d = fs_setup("outputs")
        b, a = guard(["scene.json", "cube.obj"])
        self.add(
            Case(
                C,
                "simulate --out an existing file (the mesh)",
                argv=["simulate", "scene.json", "--steps", "2", "--out", "cube.obj"],
                cwd=d,
                names=["cube.obj"],
                before=b,
                after=a,
            )
        )
        d = fs_setup("outputs")
        b, a = guard(["scene.json", "cube.obj"])
        self.add(
            Case(
                C,
                "simulate --out . (the scene's own directory)",
                argv=["simulate", "scene.json", "--steps", "2", "--out", "."],
                cwd=d,
                before=b,
                after=a,
            )
        )
        d = fs_setup("outputs")
        self.write(d, "run.json", scene([body()]))
        b, a = guard(["run.json", "cube.obj"])
        self.add(
            Case(
                C,
                "simulate run.json --out . (scene named like the run log)",
                argv=["simulate", "run.json", "--steps", "2", "--out", ".", "--overwrite"],
                cwd=d,
                names=["run.json"],
                before=b,
                after=a,
            )
        )
        d = fs_setup("outputs")
        self.write(d, "frames.pvd", scene([body()]))
        b, a = guard(["frames.pvd", "cube.obj"])
        self.add(
            Case(
                C,
                "simulate frames.pvd --out . --overwrite (scene named like an output)",
                argv=["simulate", "frames.pvd", "--steps", "2", "--out", ".", "--overwrite"],
                cwd=d,
                names=["frames.pvd"],
                before=b,
                after=a,
            )
        )
        for tmpname in ["run.json.tmp.4242", "frames.pvd.tmp.77", "frame_00001.vtu.tmp.9"]:
            d = fs_setup("outputs")
            self.write(d, tmpname, scene([body()]))
            b, a = guard([tmpname, "cube.obj"])
            self.add(
                Case(
                    C,
                    f"simulate {tmpname} --out . --overwrite (the scene is named like a temporary output)",
                    argv=["simulate", tmpname, "--steps", "2", "--out", ".", "--overwrite"],
                    cwd=d,
                    names=[tmpname],
                    before=b,
                    after=a,
                )
            )
        for target, what in [
            ("/proc/diffsoft-probe.json", "under /proc"),
            ("/sys/diffsoft-probe.json", "under /sys"),
            ("cube.obj/x.json", "under a regular file"),
            ("missing-dir/sub/x.json", "in a missing directory"),
            (".", "a directory"),
            ("", "an empty path"),
        ]:
            d = fs_setup("outputs")
            b, a = guard(["cube.obj", "scene.json"])
            self.add(
                Case(
                    C,
                    f"grad --json {what}",
                    argv=[*grad_args, "--json", target],
                    cwd=d,
                    names=[target or "json", "--json"],
                    before=b,
                    after=a,
                )
            )
        if not self.is_root:
            d = fs_setup("outputs")
            (d / "ro").mkdir()
            os.chmod(d / "ro", 0o500)
            self.add(
                Case(
                    C,
                    "grad --json in a read-only directory",
                    argv=[*grad_args, "--json", "ro/x.json"],
                    cwd=d,
                    names=["ro/x.json"],
                )
            )
        d = fs_setup("outputs")
        self.add(
            Case(
                C,
                "merge --json = one of its inputs via ./",
                argv=["merge", "p.json", "--json", "./p.json"],
                cwd=d,
                names=["p.json"],
                before=lambda c: self.write(c.cwd, "p.json", {}),
                after=lambda c, r: (
                    None if (c.cwd / "p.json").read_text() == "{}" else ("FILE-DAMAGE", "p.json changed")
                ),
            )
        )
        d = fs_setup("outputs")
        self.add(
            Case(
                C,
                "generate --out = .node beside an existing .ele input name",
                argv=["generate", "--cells", "1,1,1", "--out", "t.node"],
                cwd=d,
            )
        )
        # stdout closed by the reader (grad), and a second run into a locked directory.
        d = fs_setup("outputs")
        self.add(
            Case(C, "grad with stdout closed at once", argv=grad_args, cwd=d, special=lambda c: self._closed_stdout(c))
        )
        d = fs_setup("outputs")
        self.write(d, "scene.json", scene([body(translate=[0, 0.01, 0])], obstacles=[ground()]))
        self.add(
            Case(
                C,
                "second simulate --overwrite into a directory a live run holds",
                argv=["simulate", "scene.json", "--steps", "100000000", "--every", "1000", "--out", "run"],
                cwd=d,
                special=lambda c: self._lock_race(c),
            )
        )

    def _chardev(self, d: Path, name: str, major: int, minor: int) -> Path | None:
        p = d / name
        if self.is_root:
            try:
                os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(major, minor))
                return p
            except OSError:
                return None
        real = Path(f"/dev/{name.split('-')[0]}")
        return real if real.exists() else None

    @staticmethod
    def _same_output_after(c: Case, r: dict):
        if r["exit"] == 0:
            j = c.argv[c.argv.index("--json") + 1]
            try:
                json.loads((c.cwd / j).read_text())
            except Exception:
                return ("FILE-DAMAGE", "exit 0 but the JSON report was overwritten by the SVG")
        return None

    def _fifo_case(self, C, desc, argv, d, fifo):
        os.mkfifo(fifo)
        got: dict[str, Any] = {"data": b"", "stop": False}

        def reader():
            while not got["stop"]:
                try:
                    with open(fifo, "rb") as f:
                        got["data"] += f.read()
                except OSError:
                    return

        def before(c):
            t = threading.Thread(target=reader, daemon=True)
            t.start()
            c.state["t"] = t

        def after(c, r):
            got["stop"] = True
            try:  # release the reader if it waits on open
                fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
                os.close(fd)
            except OSError:
                pass
            c.state["t"].join(timeout=5)
            if not stat.S_ISFIFO(os.lstat(fifo).st_mode):
                return ("FILE-DAMAGE", "the FIFO was replaced")
            if r["exit"] == 0 and b'"schema"' not in got["data"]:
                return ("FILE-DAMAGE", "exit 0 but the reader got no report")
            r["note"] = f"reader got {len(got['data'])} bytes"
            return None

        return Case(C, desc, argv=argv, cwd=d, names=["fifo.json"], before=before, after=after, timeout=30)

    def _closed_stdout(self, c: Case) -> dict:
        t0 = time.monotonic()
        p = subprocess.Popen([str(RUNNER.bin), *c.argv], cwd=c.cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        p.stdout.close()
        try:
            _, err = p.communicate(timeout=c.timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            return {
                "outcome": "HANG",
                "exit": None,
                "command": "diffsoft " + " ".join(c.argv) + " | (closed)",
                "stderr_first": "",
            }
        proc = subprocess.CompletedProcess(p.args, p.returncode, "", err.decode("utf-8", "replace"))
        r = classify_cli(c, proc, False, time.monotonic() - t0)
        r["command"] += "   # stdout a pipe whose reader has gone"
        if r["outcome"] == "CRASH" and p.returncode == -signal.SIGPIPE:
            r["outcome"], r["note"] = "clear-error", "SIGPIPE (the conventional quiet exit)"
        return r

    def _lock_race(self, c: Case) -> dict:
        t0 = time.monotonic()
        a = subprocess.Popen([str(RUNNER.bin), *c.argv], cwd=c.cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        log = c.cwd / "run" / "run.json"
        while time.monotonic() - t0 < 30:
            try:
                if json.loads(log.read_text()).get("status") == "running":
                    break
            except Exception:
                pass
            time.sleep(0.05)
        argv2 = ["simulate", "scene.json", "--steps", "3", "--out", "run", "--overwrite"]
        b = subprocess.run([str(RUNNER.bin), *argv2], cwd=c.cwd, capture_output=True, text=True, timeout=60)
        a.send_signal(signal.SIGINT)
        try:
            _, aerr = a.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            a.kill()
            return {"outcome": "HANG", "exit": None, "command": "first run ignored SIGINT", "stderr_first": ""}
        case2 = Case(c.cls, c.desc, argv=argv2, cwd=c.cwd, names=["run", "lock", "another run"])
        r = classify_cli(case2, b, False, time.monotonic() - t0)
        r["command"] = "diffsoft " + " ".join(c.argv) + " &  then  diffsoft " + " ".join(argv2)
        status = None
        try:
            status = json.loads(log.read_text()).get("status")
        except Exception:
            pass
        r["note"] = f"first run exit {a.returncode}, its log '{status}'"
        if b.returncode == 0:
            r["outcome"], r["note"] = (
                "FILE-DAMAGE",
                "the second run was let into a directory the first holds; " + r["note"],
            )
        elif a.returncode != 130 or status != "interrupted":
            r["outcome"] = "FILE-DAMAGE"
            r["note"] = "first run not finalised as interrupted/130; " + r["note"]
        return r

    # ---------------------------------------------------------------- class 4: initial states
    def initial(self):
        C = "initial"
        box = obj_text(*grid_box(2, 0.1))
        m = {"box.obj": box, "ob.obj": BOX_SURFACE, "cube.obj": CUBE_OBJ}
        for depth in [0.05, 0.01, 1e-4, 1e-7, 0.0, -1e-4]:
            sc = scene([body(mesh="box.obj", translate=[0, -depth, 0])], obstacles=[ground(friction=0.3)])
            self.sim_case(
                C,
                f"box {depth} m into the ground",
                sc,
                names=["inside", "ground", "'c'"],
                meshes=m,
                overlap=depth > 1e-6,
            )
        sc = scene(
            [body(mesh="box.obj", translate=[-0.05, -0.05, -0.05])],
            obstacles=[
                {"name": "block", "mesh": {"file": "ob.obj", "scale": 0.2}, "friction": 0.3, "thickness": 0.001}
            ],
        )
        # A mesh obstacle is two-sided: a body wholly within its closed surface touches nothing.
        self.sim_case(
            C,
            "box wholly within a closed mesh obstacle (two-sided: not an overlap)",
            sc,
            names=["inside", "block"],
            meshes=m,
        )
        sc = scene(
            [body(mesh="box.obj", translate=[-0.05, 0.15, -0.05])],
            obstacles=[
                {"name": "block", "mesh": {"file": "ob.obj", "scale": 0.2}, "friction": 0.3, "thickness": 0.001}
            ],
        )
        self.sim_case(C, "box half inside a mesh obstacle", sc, names=["inside", "block"], meshes=m, overlap=True)
        sc = scene([body(mesh="box.obj", translate=[0, -0.05, 0])], obstacles=[ground(thickness=0.1)])
        self.sim_case(
            C,
            "box within the ground's thickness (above the plane's inside)",
            sc,
            names=["inside", "ground", "thickness"],
            meshes=m,
            overlap=True,
        )
        sc = scene(
            [body(mesh="box.obj", translate=[-0.1, 0.0, 0])], obstacles=[ground(name="tilted", normal=[1, 1, 0])]
        )
        self.sim_case(C, "box cut by a tilted plane", sc, names=["inside", "tilted"], meshes=m, overlap=True)
        coll = {"thickness": 0.001, "friction": 0.3}
        for off, what in [
            ([0, 0, 0], "two identical boxes at one place"),
            ([0.05, 0.05, 0.05], "two boxes overlapping by half"),
            ([0.0, 0.099, 0.0], "two boxes overlapping by 1 mm"),
            ([0.0, 0.1005, 0.0], "two boxes 0.5 mm apart (inside the thickness, not an overlap)"),
            ([0.01, 0.01, 0.01], "a box mostly inside another"),
            ([0.03, 0.0, 0.0], "a box overlapping another by 7 cm, sideways"),
        ]:
            sc = scene(
                [body(name="a", mesh="box.obj"), body(name="b", mesh="box.obj", translate=off)],
                gravity=[0, 0, 0],
                collisions=coll,
            )
            self.sim_case(
                C,
                what + " (collisions on)",
                sc,
                names=["'a'", "'b'", "overlap", "inside"],
                meshes=m,
                overlap="not an overlap" not in what,
            )
        sc = scene(
            [body(name="a", mesh="box.obj"), body(name="b", mesh="box.obj", translate=[0.05, 0.05, 0.05])],
            obstacles=[ground(y=-0.5)],
            collisions=coll,
        )
        self.sim_case(
            C,
            "two overlapping boxes falling on the ground, 20 steps",
            sc,
            names=["'a'", "'b'"],
            meshes=m,
            overlap=True,
            steps=20,
        )
        sc = scene(
            [body(name="a", mesh="box.obj"), body(name="b", mesh="box.obj", translate=[0.05, 0.05, 0.05])],
            gravity=[0, 0, 0],
        )
        self.sim_case(C, "two boxes overlapping by half (collisions off)", sc, meshes=m)
        cloth = cloth_grid(4, 0.4, 0.05)
        sc = scene(
            [body(mesh="box.obj")],
            cloths=[{"name": "sheet", "mesh": "sheet.obj", "stretching": 200, "area_density": 0.3}],
            collisions=coll,
            gravity=[0, 0, 0],
        )
        self.sim_case(
            C,
            "cloth cutting through a box (collisions on)",
            sc,
            names=["sheet", "'c'", "inside"],
            meshes={**m, "sheet.obj": cloth},
            overlap=True,
        )
        for steps in [3]:
            sc = scene(
                [body(name="a", mesh="box.obj"), body(name="b", mesh="box.obj", translate=[0.05, 0.05, 0.05])],
                gravity=[0, 0, 0],
                collisions=coll,
            )
            self.grad_case(
                C,
                "grad through two overlapping boxes (collisions on)",
                sc,
                names=["'a'", "'b'", "overlap", "inside"],
                meshes=m,
                steps=steps,
            )
            sc = scene([body(mesh="box.obj", translate=[0, -0.02, 0])], obstacles=[ground()])
            self.grad_case(
                C, "grad of a box starting 2 cm into the ground", sc, names=["inside", "ground"], meshes=m, steps=steps
            )

    # ---------------------------------------------------------------- class 5: gradients
    def gradients(self):
        C = "gradients"
        rng = self.rng
        box1 = obj_text(*grid_box(1, 0.1))
        box2 = obj_text(*grid_box(2, 0.1))
        meshes = {"box1.obj": box1, "box2.obj": box2}
        solver = {"solver": "direct", "tolerance": 1e-10, "max_iterations": 200}
        specs = []
        # Free bodies (no contact): the easy baseline.
        for _ in range(3):
            sc = scene(
                [
                    body(
                        mesh="box1.obj",
                        E=10 ** rng.uniform(3, 5),
                        nu=rng.uniform(0.1, 0.45),
                        density=rng.uniform(300, 2000),
                        initial_velocity=[rng.uniform(-1, 1), rng.uniform(0, 1), 0],
                        attachments=[{"vertices": {"indices": [0]}, "stiffness": 50.0}],
                    )
                ],
                solver=solver,
            )
            specs.append(
                (
                    "free body with an attachment",
                    sc,
                    rng.choice(["youngs_modulus", "poisson_ratio", "density"]),
                    rng.choice(["final_com.x", "final_com.y", "mean_com.y"]),
                    rng.randint(10, 20),
                    False,
                )
            )
        # Ground contact with friction.
        for i in range(12):
            mu = rng.choice([0.0, 0.2, 0.5, 1.0])
            sc = scene(
                [
                    body(
                        mesh="box1.obj",
                        E=10 ** rng.uniform(3, 5),
                        nu=rng.uniform(0.1, 0.45),
                        density=rng.uniform(300, 2000),
                        translate=[0, rng.uniform(0.002, 0.03), 0],
                        initial_velocity=[rng.uniform(-1, 1), -rng.uniform(0.5, 2), rng.uniform(-0.5, 0.5)],
                    )
                ],
                obstacles=[ground(friction=mu)],
                solver=solver if i % 3 else {},
            )
            specs.append(
                (
                    f"box hitting the ground (friction {mu}{', default solver settings' if i % 3 == 0 else ''})",
                    sc,
                    rng.choice(
                        [
                            "youngs_modulus",
                            "poisson_ratio",
                            "density",
                            "initial_velocity.x",
                            "initial_velocity.y",
                            "gravity.y",
                        ]
                    ),
                    rng.choice(["final_com.x", "final_com.y", "mean_com.y"]),
                    rng.randint(8, 20),
                    False,
                )
            )
        # Collisions between bodies. (a) The issue's example and variants: a box or a ball
        # dropped on a fixed box (the contact solve often stalls: such gradients must be refused,
        # or warned with --allow-unconverged). (b) A ball pushed into a partly pinned ball, no
        # gravity, fixed iteration counts (tolerance 0): a smooth forward that must agree.
        ball = BALL_OBJ or box2
        for i in range(8):
            gap = rng.uniform(0.003, 0.02)
            speed = rng.uniform(0.5, 2.0)
            fric = rng.choice([0.0, 0.3])
            E, nu = 10 ** rng.uniform(3.5, 5), rng.uniform(0.2, 0.45)
            lower = body(
                name="lower",
                mesh="box2.obj",
                E=E,
                nu=nu,
                density=1000.0,
                fixed={"box": {"min": [-1, -1, -1], "max": [2, 0.001, 2]}},
            )
            if i % 2 == 0:
                upper = body(
                    name="upper",
                    mesh="box2.obj",
                    E=E,
                    nu=nu,
                    translate=[rng.uniform(-0.03, 0.03), 0.1 + gap, rng.uniform(-0.03, 0.03)],
                    initial_velocity=[0, -speed, 0],
                )
                what = "box"
            else:
                upper = body(
                    name="upper",
                    mesh="ball.obj",
                    E=E,
                    nu=nu,
                    scale=0.1,
                    translate=[0.05, 0.1 + gap - 0.0698087, 0.05],
                    initial_velocity=[0, -speed, 0],
                )
                what = "ball"
            sol = rng.choice(
                [
                    {"solver": "direct"},
                    {"solver": "direct", "tolerance": 1e-8, "max_iterations": 300},
                    {"solver": "direct", "tolerance": 0, "max_iterations": 40},
                ]
            )
            sc = scene(
                [lower, upper],
                dt=rng.choice([0.01, 0.02]),
                collisions={"thickness": 0.001, "friction": fric},
                solver=sol,
            )
            specs.append(
                (
                    f"{what} dropped at {speed:.2f} m/s on a fixed box (collisions, friction {fric}, solver {sol})",
                    sc,
                    rng.choice(["density", "poisson_ratio", "youngs_modulus", "initial_velocity.y", "gravity.y"]),
                    rng.choice(["final_com.y", "mean_com.y"]),
                    rng.randint(8, 12),
                    what == "ball",
                )
            )
        for _ in range(8):
            speed = rng.uniform(0.3, 0.9)
            fric = rng.choice([0.0, 0.3])
            E, nu = 10 ** rng.uniform(3.8, 4.8), rng.uniform(0.2, 0.45)
            a = body(name="a", mesh="ball.obj", E=E, nu=nu, scale=0.1, initial_velocity=[speed, 0, 0])
            b = body(
                name="b",
                mesh="ball.obj",
                E=E,
                nu=nu,
                scale=0.1,
                translate=[0.065, rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01)],
                fixed={"box": {"min": [0.08, -1, -1], "max": [1, 1, 1]}},
            )
            sol = {"solver": "direct", "tolerance": 0, "max_iterations": rng.choice([40, 60])}
            sc = scene([a, b], gravity=[0, 0, 0], collisions={"thickness": 0.001, "friction": fric}, solver=sol)
            specs.append(
                (
                    f"ball pushed at {speed:.2f} m/s into a pinned ball (collisions, friction {fric}, {sol['max_iterations']} fixed iterations)",
                    sc,
                    rng.choice(["initial_velocity.x", "youngs_modulus", "poisson_ratio", "density"]),
                    rng.choice(["final_com.x", "mean_com.x"]),
                    rng.randint(10, 15),
                    False,
                )
            )
        # Cloth (gravity must reach it): fixed iteration counts, as a hanging cloth converges slowly.
        cloth = cloth_grid(3, 0.4, 0.0)
        fixed_it = {"solver": "direct", "tolerance": 0, "max_iterations": 60}
        sc = scene(
            [body(name="ball", mesh="box1.obj", translate=[-0.05, 0.02, -0.05], initial_velocity=[0, -0.5, 0])],
            cloths=[
                {
                    "name": "sheet",
                    "mesh": "sheet.obj",
                    "stretching": 500,
                    "area_density": 0.3,
                    "fixed": {"indices": [0, 3, 12, 15]},
                }
            ],
            collisions={"thickness": 0.002, "friction": 0.2},
            solver=fixed_it,
        )
        specs.append(("box falling on a pinned cloth (60 fixed iterations)", sc, "gravity.y", "final_com.y", 12, True))
        sc = scene(
            [],
            cloths=[
                {
                    "name": "sheet",
                    "mesh": "sheet.obj",
                    "stretching": 500,
                    "area_density": 0.3,
                    "fixed": {"indices": [0, 3]},
                }
            ],
            solver=fixed_it,
        )
        specs.append(
            ("cloth alone hanging from two corners (60 fixed iterations)", sc, "gravity.y", "final_com.y", 10, False)
        )
        sc = scene(
            [],
            cloths=[
                {
                    "name": "sheet",
                    "mesh": "sheet.obj",
                    "stretching": 500,
                    "area_density": 0.3,
                    "fixed": {"indices": [0, 3]},
                }
            ],
            solver=fixed_it,
        )
        specs.append(
            ("cloth alone hanging from two corners (60 fixed iterations)", sc, "gravity.x", "final_com.x", 10, False)
        )
        # Kinks: contact at zero gap, friction at the stick/slip threshold.
        for mu in [0.3, 0.6]:
            sc = scene(
                [body(mesh="box1.obj", E=1e4, nu=0.3)],
                gravity=[mu * 9.81, -9.81, 0],
                obstacles=[ground(friction=mu)],
                solver=solver,
            )
            specs.append(
                (
                    f"box resting on the ground, tangential gravity at the friction threshold (mu {mu})",
                    sc,
                    "gravity.x",
                    "final_com.x",
                    10,
                    False,
                )
            )
        sc = scene(
            [body(mesh="box1.obj", E=1e4, nu=0.3)], gravity=[0, 0, 0], obstacles=[ground(friction=0.3)], solver=solver
        )
        specs.append(
            (
                "box resting on the ground without gravity, initial_velocity.y = 0 (contact at zero gap and speed)",
                sc,
                "initial_velocity.y",
                "final_com.y",
                10,
                False,
            )
        )
        sc = scene(
            [body(mesh="box1.obj", E=1e4, nu=0.3)], gravity=[0, 0, 0], obstacles=[ground(friction=0.3)], solver=solver
        )
        specs.append(
            ("box resting on the ground, gravity.y = 0 (pressed or lifted)", sc, "gravity.y", "final_com.y", 10, False)
        )
        sc = scene([body(mesh="box1.obj", E=1e4, nu=0.3)], obstacles=[ground(friction=0.3)], solver=solver)
        specs.append(
            (
                "box resting on the ground under gravity, initial_velocity.y = 0",
                sc,
                "initial_velocity.y",
                "mean_com.y",
                10,
                False,
            )
        )
        for desc, sc, param, loss, steps, allow_too in specs:
            d = self.dir("gradients")
            for n, t in meshes.items():
                self.write(d, n, t)
            self.write(d, "ball.obj", ball)
            self.write(d, "sheet.obj", cloth)
            self.write(d, "scene.json", sc)
            p0 = self._param_value(sc, param)
            shared: dict[str, Any] = {}
            lock = threading.Lock()
            variants = [("unrolled", False), ("implicit", False)] + (
                [("unrolled", True), ("implicit", True)] if allow_too else []
            )
            for mode, allow in variants:
                c = Case(
                    C,
                    f"{desc}: d {loss} / d {param}, {steps} steps, {mode}{' --allow-unconverged' if allow else ''}",
                    cwd=d,
                    names=[param, "converge", "--allow-unconverged"],
                    timeout=150,
                )
                c.state.update(
                    param=param, p0=p0, loss=loss, steps=steps, mode=mode, allow=allow, shared=shared, lock=lock
                )
                c.special = self._grad_compare
                self.add(c)

    @staticmethod
    def _param_value(sc: dict, param: str) -> float:
        b = sc["bodies"][0] if sc["bodies"] else None
        if param == "youngs_modulus":
            return b["material"]["youngs_modulus"]
        if param == "poisson_ratio":
            return b["material"]["poisson_ratio"]
        if param == "density":
            return b["density"]
        if param.startswith("initial_velocity."):
            return b.get("initial_velocity", [0, 0, 0])["xyz".index(param[-1])]
        if param.startswith("gravity."):
            return sc["gravity"]["xyz".index(param[-1])]
        raise ValueError(param)

    def _grad_run(
        self, c: Case, value: float, mode: str, allow: bool, tag: str
    ) -> tuple[dict | None, subprocess.CompletedProcess | None, bool, list[str]]:
        st = c.state
        out = c.cwd / f"g-{tag}.json"
        argv = [
            "grad",
            "scene.json",
            "--steps",
            str(st["steps"]),
            "--loss",
            st["loss"],
            "--param",
            st["param"],
            "--set",
            f"{st['param']}={value!r}",
            "--mode",
            mode,
            "--json",
            out.name,
        ]
        if allow:
            argv.append("--allow-unconverged")
        try:
            p = subprocess.run([str(RUNNER.bin), *argv], cwd=c.cwd, capture_output=True, text=True, timeout=c.timeout)
        except subprocess.TimeoutExpired:
            return None, None, True, argv
        rep = json.loads(out.read_text()) if p.returncode == 0 and out.exists() else None
        return rep, p, False, argv

    def _py_losses(self, c: Case, values: list[float]) -> list[float] | None:
        """The forward losses at ``values`` from ``Scene.simulate`` (no backward pass: cheap where
        the unrolled backward through stalled contact solves takes minutes); None if unavailable."""
        st = c.state
        axis = "xyz".index(st["loss"][-1])
        mean = st["loss"].startswith("mean_")
        src = (
            "import json, sys, numpy as np, diffsoft\n"
            f"out = []\nfor v in {values!r}:\n"
            "    S = diffsoft.Scene.load('scene.json')\n"
            f"    S.set({st['param']!r}, v)\n"
            f"    q = S.simulate({st['steps']}).positions\n"
            "    m = S.masses\n"
            f"    com = (q[1:] * m[None, :, None]).sum(1)[:, {axis}] / m.sum()\n"
            f"    out.append(float(com.mean() if {mean} else com[-1]))\n"
            "print(json.dumps(out))\n"
        )
        try:
            p = subprocess.run([RUNNER.python, "-c", src], cwd=c.cwd, capture_output=True, text=True, timeout=c.timeout)
            return json.loads(p.stdout.strip().splitlines()[-1]) if p.returncode == 0 else None
        except Exception:
            return None

    def _fd(self, c: Case, loss_cli: float) -> dict:
        """Losses at p0 and p0 +- h (computed once per scene, shared by both modes): from the
        Python API's forward when its loss at p0 matches the CLI's to 1e-9, else from the CLI
        (grad --allow-unconverged at p0 +- h, taking its loss)."""
        st = c.state
        with st["lock"]:
            if "fd" in st["shared"]:
                return st["shared"]["fd"]
            p0 = st["p0"]
            h = 1e-4 * abs(p0) if p0 != 0 else 1e-4
            if st["param"] == "poisson_ratio":
                h = 1e-5
            losses = {}
            how = None
            py = self._py_losses(c, [p0 - h, p0, p0 + h])
            if py is not None and abs(py[1] - loss_cli) <= 1e-9 * abs(loss_cli) + 1e-15:
                losses, how = {"m": py[0], "0": py[1], "p": py[2]}, "python Scene.simulate"
            for k, v in [("m", p0 - h), ("0", p0), ("p", p0 + h)] if how is None else []:
                rep = None
                for mode in ["implicit", "unrolled"]:
                    rep, p, to, _ = self._grad_run(c, v, mode, True, f"fd{k}-{mode}")
                    if rep is not None:
                        how = mode
                        break
                losses[k] = rep["loss"] if rep else None
            fd: dict[str, Any] = {"h": h, "losses": losses, "via": how}
            if all(isinstance(losses[k], float) for k in "m0p"):
                lm, l0, lp = losses["m"], losses["0"], losses["p"]
                fd["central"] = (lp - lm) / (2 * h)
                fd["forward"] = (lp - l0) / h
                fd["backward"] = (l0 - lm) / h
                fd["noise"] = 1e-9 * max(abs(l0), 1e-2) / h
            st["shared"]["fd"] = fd
            return fd

    def _grad_compare(self, c: Case) -> dict:
        st = c.state
        t0 = time.monotonic()
        rep, p, to, argv = self._grad_run(
            c, st["p0"], st["mode"], st.get("allow", False), st["mode"] + ("-allow" if st.get("allow") else "")
        )
        r: dict[str, Any] = {
            "class": c.cls,
            "desc": c.desc,
            "command": f"(cd {c.cwd} && diffsoft " + " ".join(shell_quote(a) for a in argv) + ")",
        }
        if to:
            r.update(outcome="HANG", exit=None, stderr_first="")
            return r
        cp = classify_cli(Case(c.cls, c.desc, argv=argv, cwd=c.cwd, names=c.names), p, False, 0)
        r.update(exit=p.returncode, stderr_first=cp["stderr_first"], findings=cp["findings"])
        if cp["outcome"] == "CRASH":
            r["outcome"] = "CRASH"
            return r
        if p.returncode != 0:
            r["outcome"] = "refused"
            return r
        g = rep["gradient"].get(st["param"]) if rep else None
        stats = rep.get("stats", {}) if rep else {}
        warned = "warning" in p.stdout.lower() or "warning" in p.stderr.lower() or stats.get("unconverged_steps", 0) > 0
        fd = self._fd(c, rep["loss"])
        r["warnings"] = [ln.strip()[:200] for ln in (p.stdout + p.stderr).splitlines() if "warning" in ln.lower()]
        r.update(
            gradient=g,
            fd=fd,
            stats={
                k: stats.get(k)
                for k in (
                    "unconverged_steps",
                    "one_iteration_steps",
                    "replay_deviation",
                    "implicit_residual",
                    "contact_residual",
                    "forward_ms",
                    "backward_ms",
                )
            },
        )
        if g is None or not math.isfinite(g):
            r["outcome"] = "warned" if warned else "SILENT-NAN"
            return r
        if "central" not in fd:
            r["outcome"] = "warned" if warned else "fd-unavailable"
            return r
        cen = fd["central"]
        err = abs(g - cen)
        r["rel_error"] = err / max(abs(cen), 1e-300)
        agree = err <= 0.1 * abs(cen) + fd["noise"]
        kink = abs(fd["forward"] - fd["backward"]) > 0.1 * max(abs(fd["forward"]), abs(fd["backward"])) + fd["noise"]
        if agree and not kink:
            r["outcome"] = "agree"
        elif warned:
            r["outcome"] = "warned"
        elif not agree:
            r["outcome"] = "DISAGREE-SILENT"
            if kink:
                r["note"] = (
                    f"at a kink: one-sided differences {fd['forward']:.4g} / {fd['backward']:.4g}, central {cen:.4g}, gradient {g:.4g}"
                )
        else:
            r["outcome"] = "KINK-SILENT"
            r["note"] = f"one-sided differences {fd['forward']:.4g} / {fd['backward']:.4g}, gradient {g:.4g}"
        r["seconds"] = round(time.monotonic() - t0, 3)
        return r

    # ---------------------------------------------------------------- class 6: Python API
    def python(self):
        C = "python"
        d = self.dir("python")
        self.write(d, "cube.obj", CUBE_OBJ)
        self.write(d, "box1.obj", obj_text(*grid_box(1, 0.1)))
        self.write(
            d,
            "scene.json",
            scene(
                [body(mesh="box1.obj", attachments=[{"vertices": {"indices": [0]}, "stiffness": 100.0}])],
                solver={"solver": "direct", "tolerance": 1e-10, "max_iterations": 200},
            ),
        )
        self.write(
            d,
            "two.json",
            scene(
                [body(name="a", mesh="box1.obj", E=2e4), body(name="b", mesh="box1.obj", E=5e4, translate=[0.5, 0, 0])],
                solver={"solver": "direct", "tolerance": 1e-10, "max_iterations": 200},
            ),
        )
        self.write(d, "sheet.obj", cloth_grid(3, 0.4, 0.0))
        self.write(
            d,
            "cloth.json",
            scene(
                [],
                cloths=[
                    {
                        "name": "sheet",
                        "mesh": "sheet.obj",
                        "stretching": 500,
                        "area_density": 0.3,
                        "fixed": {"indices": [0, 3]},
                    }
                ],
                solver={"solver": "direct", "tolerance": 1e-10, "max_iterations": 200},
            ),
        )
        self.write(
            d,
            "act.json",
            scene(
                [
                    body(
                        mesh="box1.obj",
                        actuators=[
                            {"name": "p", "pneumatic": {"tets": {"all": {}}}, "stiffness": 1e4, "activation": 1.1}
                        ],
                    )
                ]
            ),
        )
        self.write(d, "bad.json", b'{"schema": "diffsoft.scene/1", \xff\xfe')
        self.write(d, "trunc.json", json.dumps(scene([body()]))[:40])
        load = 'S = diffsoft.Scene.load(os.path.join(D, "{d}", "{f}"))\n'
        rel = d.name

        def py(desc, body_src, f="scene.json", names=(), timeout=TIMEOUT, expect_error=False):
            src = load.format(d=rel, f=f) if f else ""
            src = "def case():\n    import diffsoft\n" + "".join(
                "    " + line + "\n" for line in (src + body_src).splitlines()
            )
            self.add(Case(C, desc, py=src, cwd=d, names=list(names), timeout=timeout, expect_error=expect_error))

        bad_scalars = [
            "float('nan')",
            "float('inf')",
            "-1.0",
            "0.0",
            "5e-324",
            "1e308",
            "'abc'",
            "None",
            "[1.0, 2.0]",
            "True",
            "complex(1, 1)",
            "np.float32(1e5)",
            "np.array([1e5])",
            "10**400",
        ]
        for v in bad_scalars:
            py(
                f"set('youngs_modulus', {v}) then simulate(2)",
                f"S.set('youngs_modulus', {v})\nreturn S.simulate(2)",
                names=["youngs_modulus"],
                expect_error=v == "True",
            )
        for v in ["0.5", "-1.0", "0.49999999999999", "float('nan')", "-0.9999999999"]:
            py(
                f"set('poisson_ratio', {v}) then simulate(2)",
                f"S.set('poisson_ratio', {v})\nreturn S.simulate(2)",
                names=["poisson_ratio"],
            )
        for v in ["0.0", "-1.0", "5e-324", "1e308"]:
            py(
                f"set('density', {v}) then simulate(2)",
                f"S.set('density', {v})\nreturn S.simulate(2)",
                names=["density"],
            )
        for v in ["1e308", "float('nan')", "-1.7976931348623157e308"]:
            py(
                f"set('gravity.y', {v}) then simulate(2)",
                f"S.set('gravity.y', {v})\nreturn S.simulate(2)",
                names=["gravity"],
            )
        py("set('gravity', [0, -9.81, 0]) (no such name)", "S.set('gravity', [0, -9.81, 0])", names=["gravity"])
        py("get('nonexistent')", "return S.get('nonexistent')", names=["nonexistent"])
        n_t = 6
        for v, what in [
            (f"np.ones({n_t + 1}) * 1e4", "one value too many"),
            (f"np.ones(({n_t}, 1)) * 1e4", "shape (tets, 1)"),
            (f"np.full({n_t}, np.nan)", "NaN entries"),
            (f"-np.ones({n_t})", "negative"),
            (f"np.zeros({n_t})", "zeros"),
            ("np.array([])", "empty"),
            ("1e4", "a scalar"),
            (f"['a'] * {n_t}", "strings"),
            (f"np.full({n_t}, 5e-324)", "denormal entries"),
            (f"np.full({n_t}, 1e4, dtype=np.float32)", "float32"),
            (f"np.full({n_t}, 1e4).astype(object)", "object dtype"),
        ]:
            py(
                f"set('youngs_modulus_per_tet', {what}) then simulate(2)",
                f"S.set('youngs_modulus_per_tet', {v})\nreturn S.simulate(2)",
                names=["youngs_modulus_per_tet"],
            )
        for v, what in [
            ("S.get('initial_positions')[:, :2]", "shape (n, 2)"),
            ("S.get('initial_positions') * np.nan", "NaN"),
            ("S.get('initial_positions') * 1e300", "scaled by 1e300"),
            ("np.zeros_like(S.get('initial_positions'))", "all at one point"),
            ("S.get('initial_positions')[None]", "shape (1, n, 3)"),
            ("np.asfortranarray(S.get('initial_positions'))", "Fortran order (valid)"),
            ("S.get('initial_positions')[::-1]", "reversed (inverted tets)"),
        ]:
            py(
                f"set('initial_positions', {what}) then simulate(2)",
                f"S.set('initial_positions', {v})\nreturn S.simulate(2)",
                names=["initial_positions"],
            )
        for v, what in [
            ("np.full_like(S.get('initial_positions'), np.inf)", "inf"),
            ("np.ones((3, 3))", "wrong vertex count"),
        ]:
            py(
                f"set('initial_velocities', {what})",
                f"S.set('initial_velocities', {v})\nreturn S.simulate(2)",
                names=["initial_velocities"],
            )
        for v, what in [
            ("np.zeros((2, 3))", "two targets for one attachment"),
            ("np.full((1, 3), np.nan)", "NaN target"),
        ]:
            py(
                f"set('attachment_targets', {what})",
                f"S.set('attachment_targets', {v})\nreturn S.simulate(2)",
                names=["attachment_targets"],
            )
        py(
            "set('activations', ...) on a scene without actuators",
            "S.set('activations', np.ones((2, 1)))\nreturn S.simulate(2)",
            names=["activations", "actuator"],
        )
        py(
            "set('activations') with NaN",
            "S.set('activations', np.full((2, 1), np.nan))\nreturn S.simulate(2)",
            f="act.json",
            names=["activations"],
        )
        py(
            "set('activations') of 2 steps, simulate(5)",
            "S.set('activations', np.ones((2, 1)))\nreturn S.simulate(5)",
            f="act.json",
            names=["activations", "steps"],
        )
        py(
            "set('torques') without a skeleton",
            "S.set('torques', np.ones((2, 1)))\nreturn S.simulate(2)",
            names=["torques", "skeleton", "joint"],
        )
        for kw, what in [
            ("anderson=10**9", ""),
            ("anderson=2**64", ""),
            ("anderson=-1", ""),
            ("dt=float('nan')", ""),
            ("dt=0.0", ""),
            ("dt=5e-324", " then simulate(1)"),
            ("tolerance=-1.0", ""),
            ("max_iterations=0", " then simulate(1)"),
            ("max_iterations=2**64", ""),
            ("solver='nope'", ""),
            ("unknown_setting=1", ""),
            ("tolerance='1e-6'", ""),
            ("damping=float('inf')", ""),
            ("inner_max_iterations=10**12", " then simulate(1)"),
        ]:
            then = "\nreturn S.simulate(1)" if what else "\nreturn S.settings"
            py(f"configure({kw}){what}", f"S.configure({kw}){then}", names=[kw.split("=")[0]])
        py(
            "configure(anderson=10**6) then grad",
            "S.configure(anderson=10**6)\nreturn S.grad(2, params=['density'])",
            names=["anderson"],
        )
        for arg in ["-1", "0", "2**64", "10**12", "1.5", "'3'", "None"]:
            py(f"simulate({arg})", f"return S.simulate({arg})", names=["steps"])
        for kw, what in [
            ("steps=-1", ""),
            ("steps=2, loss='bogus'", ""),
            ("steps=2, params=['nope']", ""),
            ("steps=2, mode='weird'", ""),
            ("steps=2, params=[]", ""),
            ("steps=2, params=['youngs_modulus_per_tet']", " (an array parameter)"),
            ("steps=2, loss='joint_angle.x'", " (no skeleton)"),
            ("steps=2, params='density'", " (a string, not a list)"),
            ("steps=10**12, params=['density']", ""),
            ("steps=2, params=['density', 'density']", " (twice)"),
            ("steps=2, params=['initial_joint_state']", " (no skeleton)"),
        ]:
            py(
                f"grad({kw}){what}",
                f"return S.grad({kw})",
                names=[
                    "steps",
                    "loss",
                    "nope",
                    "mode",
                    "param",
                    "joint",
                    "bogus",
                    "weird",
                    "density",
                    "initial_joint_state",
                    "youngs_modulus_per_tet",
                ],
            )
        for cot, what in [
            ("np.zeros((4, 8, 3))", "of 3 steps for 2"),
            ("np.full((3, 8, 3), np.nan)", "NaN cotangent"),
            ("np.zeros((0,))", "empty"),
            ("np.zeros((3, 8))", "2-D"),
            ("'abc'", "a string"),
        ]:
            py(
                f"vjp(2, ['density'], cotangent {what})",
                f"return S.vjp(2, ['density'], {cot})",
                names=["cotangent", "shape"],
            )
        py(
            "vjp with velocity_cotangent of the wrong shape",
            "return S.vjp(2, ['density'], np.zeros((3, 8, 3)), velocity_cotangent=np.zeros((2, 8, 3)))",
            names=["velocity_cotangent", "cotangent"],
        )
        for vals, what in [
            ("[{'youngs_modulus': float('nan')}]", "NaN value"),
            ("[{'youngs_modulus': -1.0}, {'youngs_modulus': 1e4}]", "one bad value of two"),
            ("[]", "no values"),
            ("[{'nope': 1.0}]", "unknown name"),
            ("[{1: 1.0}]", "a non-string key"),
            ("[None]", "None in the list"),
        ]:
            py(
                f"simulate_batch {what}",
                f"return diffsoft.simulate_batch(S, 2, {vals})",
                names=["youngs_modulus", "nope", "values", "parameter"],
            )
            py(
                f"grad_batch {what}",
                f"return diffsoft.grad_batch(S, 2, 'final_com.y', ['density'], {vals})",
                names=["youngs_modulus", "nope", "values", "parameter"],
            )
        for args, what in [
            ("os.path.join(D, 'nope.obj'), 1000, 1e5, 0.01", "missing mesh"),
            ("MESH, float('nan'), 1e5, 0.01", "rho NaN"),
            ("MESH, 1000, 1e5, 0.0", "dt 0"),
            ("MESH, 1000, 1e5, 0.01, scale=1e300", "scale 1e300"),
            ("MESH, 1000, 1e5, 0.01, method='bogus'", "method bogus"),
            ("MESH, 5e-324, 1e308, 0.01", "rho denormal, mu 1e308"),
        ]:
            py(
                f"bounds({what})",
                f"MESH = os.path.join(D, '{rel}', 'cube.obj')\nreturn diffsoft.bounds({args})",
                f=None,
                names=["mesh", "nope.obj", "rho", "dt", "scale", "method", "bogus", "mu"],
            )
        for kw in ["steps=0", "steps=2, iterations=0", "steps=2, params=['nope']", "steps=2, loss='bogus'"]:
            py(
                f"gradcheck({kw})",
                f"return diffsoft.gradcheck(S, {kw})",
                names=["steps", "iterations", "nope", "bogus"],
            )
        for f, what in [
            ("bad.json", "non-UTF-8 scene"),
            ("trunc.json", "truncated scene"),
            ("nope.json", "missing scene"),
            (".", "a directory as the scene"),
        ]:
            py(f"Scene.load({what})", f"return diffsoft.Scene.load(os.path.join(D, '{rel}', '{f}'))", f=None, names=[f])
        py(
            "Scene.load(b'bytes path')",
            f"return diffsoft.Scene.load(os.path.join(D, '{rel}', 'scene.json').encode())",
            f=None,
            names=["path"],
        )
        py(
            "Scene.load with a NUL in the path",
            f"return diffsoft.Scene.load(os.path.join(D, '{rel}', 'scene\\x00.json'))",
            f=None,
            names=["path", "nul"],
        )
        py(
            "set E that underflows the weight (5e-324) then grad",
            "S.set('youngs_modulus', 5e-324)\nreturn S.grad(2, params=['density'])",
            names=["youngs", "tet"],
        )
        # Parameter state: per-tet and scalar values, order of sets (issue 33 item 2).
        py(
            "per-tet E then set('poisson_ratio', same value): get() must keep the per-tet values",
            "E = np.linspace(1e4, 5e4, S.n_tets)\nS.set('youngs_modulus_per_tet', E)\nS.set('poisson_ratio', S.get('poisson_ratio'))\n"
            "kept = np.allclose(S.get('youngs_modulus_per_tet'), E)\nreturn {'compare': 'agree' if kept else 'DISAGREE-SILENT', 'kept': bool(kept)}",
        )
        py(
            "per-tet E: d final_com.y / d poisson_ratio vs central differences",
            "S.set('gravity.y', -9.81)\nE = np.linspace(5e3, 5e4, S.n_tets)\nS.set('youngs_modulus_per_tet', E)\n"
            "nu = 0.3\nS.set('poisson_ratio', nu)\nS.set('youngs_modulus_per_tet', E)\n"
            "L, g = S.grad(15, params=['poisson_ratio'], mode='implicit')\nh = 1e-5\nls = []\n"
            "for v in (nu - h, nu + h):\n    T = S.copy()\n    T.set('poisson_ratio', v)\n    T.set('youngs_modulus_per_tet', E)\n    ls.append(T.grad(15, params=['density'], allow_unconverged=True)[0])\n"
            "fd = (ls[1] - ls[0]) / (2 * h)\nok = abs(g['poisson_ratio'] - fd) <= 0.1 * abs(fd) + 1e-9\n"
            "return {'compare': 'agree' if ok else 'DISAGREE-SILENT', 'grad': g['poisson_ratio'], 'fd': fd}",
            names=["poisson_ratio"],
        )
        py(
            "cloth only: d final_com.y / d gravity.y vs central differences",
            "S.configure(tolerance=0.0, max_iterations=60)\nL, g = S.grad(10, params=['gravity.y'], mode='implicit')\nh = 1e-4\nls = []\n"
            "for v in (-9.81 - h, -9.81 + h):\n    T = S.copy()\n    T.set('gravity.y', v)\n    ls.append(T.grad(10, params=['gravity.y'], mode='implicit', allow_unconverged=True)[0])\n"
            "fd = (ls[1] - ls[0]) / (2 * h)\nok = abs(g['gravity.y'] - fd) <= 0.1 * abs(fd) + 1e-9\n"
            "return {'compare': 'agree' if ok else 'DISAGREE-SILENT', 'grad': g['gravity.y'], 'fd': fd}",
            f="cloth.json",
        )
        py(
            "two bodies of different E: set('youngs_modulus_per_tet') then get('youngs_modulus')",
            "E = S.get('youngs_modulus_per_tet')\nreturn S.get('youngs_modulus')",
            f="two.json",
            names=["youngs_modulus", "differs"],
        )
        py(
            "two bodies of different E: grad wrt youngs_modulus",
            "return S.grad(3, params=['youngs_modulus'])",
            f="two.json",
            names=["youngs_modulus", "differs"],
        )
        py(
            "set('gravity.x') on a cloth-only scene applies?",
            "S.set('gravity.x', 1.0)\nreturn S.get('gravity.x')",
            f="cloth.json",
            names=["gravity"],
        )
        py(
            "set('density') on a cloth-only scene (applies to nothing)",
            "S.set('density', 1000.0)\nreturn S.get('density')",
            f="cloth.json",
            names=["density", "nothing"],
        )
        py(
            "set('youngs_modulus') on a cloth-only scene (applies to nothing)",
            "S.set('youngs_modulus', 1e4)\nreturn S.get('youngs_modulus')",
            f="cloth.json",
            names=["youngs_modulus", "nothing"],
            expect_error=True,
        )
        py(
            "set('poisson_ratio') on a cloth-only scene (applies to nothing)",
            "S.set('poisson_ratio', 0.3)\nreturn S.get('poisson_ratio')",
            f="cloth.json",
            names=["poisson_ratio", "nothing"],
            expect_error=True,
        )
        py(
            "set('initial_velocity.x') on a cloth-only scene (applies to the cloth)",
            "S.set('initial_velocity.x', 0.1)\nreturn S.simulate(2)",
            f="cloth.json",
            names=["initial_velocity"],
        )
        # Ctrl-C in a long call: KeyboardInterrupt (not a panic), and the scene stays usable.
        for call, what, warm in [
            ("S.simulate(40000)", "first simulate of the process", ""),
            ("S.simulate(40000)", "a simulate after an earlier one", "S.simulate(1)\n"),
            ("S.grad(20000, params=['density'])", "grad", "S.simulate(1)\n"),
            ("diffsoft.simulate_batch(S, 30000, [{}, {}])", "simulate_batch", "S.simulate(1)\n"),
        ]:
            src = (
                warm + "import signal, threading\nS.configure(tolerance=0.0, max_iterations=50)\n"
                "threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()\nimport time\nt0 = time.time()\n"
                f"try:\n    {call}\n    return {{'compare': 'ok-result', 'note': 'finished before the signal: inconclusive'}}\n"
                "except KeyboardInterrupt:\n    dt = time.time() - t0\n    S.simulate(1)\n"
                "    return {'compare': 'clear-error' if dt < 2.0 else 'LATE-INTERRUPT', 'seconds_to_interrupt': dt}"
            )
            py(f"Ctrl-C during {what}", src, timeout=90)

    def build(self, classes):
        for c in classes:
            getattr(self, c)()


# --------------------------------------------------------------------------------------------


RUNNER: Runner


def markdown(report: dict, cols: list[str], failures: list[dict]) -> str:
    """The run's summary as Markdown: outcomes per class, soft findings, failing cases."""
    table = report["table"]
    lines = [
        f"Run at commit `{report['commit'] or 'unknown'}`, seed {report['seed']}, {report['cases']} cases, "
        f"{report['seconds']:.0f} s.",
        "",
        "| class | cases | " + " | ".join(cols) + " |",
        "|---|---:|" + "---:|" * len(cols),
    ]
    for c in CLASSES:
        if c in table:
            t = table[c]
            lines.append(f"| {c} | {sum(t.values())} | " + " | ".join(str(t.get(o, 0)) for o in cols) + " |")
    tot = {o: sum(t.get(o, 0) for t in table.values()) for o in cols}
    lines.append(f"| **total** | **{report['cases']}** | " + " | ".join(f"**{tot[o]}**" for o in cols) + " |")
    lines += [
        "",
        "Soft findings on error messages: "
        + (", ".join(f"{k} {v}" for k, v in sorted(report["soft_findings"].items())) or "none")
        + ".",
    ]
    lines += ["", f"Failing cases ({len(failures)}):", ""]
    for r in failures:
        cmd = r.get("command", "")
        if cmd.startswith("def case():"):
            cmd = "python: " + "; ".join(ln.strip() for ln in cmd.splitlines()[2:] if ln.strip())
        note = r.get("note") or r.get("stderr_first", "")
        lines.append(
            f"- **{r['outcome']}** ({r['class']}) {r['desc']}: `{cmd[:300]}`" + (f" — {note[:200]}" if note else "")
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    global RUNNER
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default="target/release/diffsoft", help="the diffsoft binary (default: %(default)s)")
    ap.add_argument("--out", default="probe-results.json", help="JSON results file (default: %(default)s)")
    ap.add_argument(
        "--python", default=sys.executable, help="interpreter with diffsoft installed, for the Python class"
    )
    ap.add_argument(
        "--class", dest="classes", action="append", choices=CLASSES, help="run only these classes (repeatable)"
    )
    ap.add_argument("--jobs", type=int, default=max(1, min(4, os.cpu_count() or 1)), help="cases run at once")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory (its path is printed)")
    ap.add_argument("--workdir", help="scratch directory (default: a new temporary one)")
    ap.add_argument("--markdown", help="also write the summary as Markdown tables here (for docs/reliability.md)")
    args = ap.parse_args()
    binary = Path(args.bin).resolve()
    if not binary.is_file():
        print(
            f"error: no diffsoft binary at {binary} (build it: cargo build --release -p diffsoft-cli)", file=sys.stderr
        )
        return 2
    classes = args.classes or CLASSES
    root = Path(args.workdir).resolve() if args.workdir else Path(tempfile.mkdtemp(prefix="diffsoft-probe-"))
    if args.workdir:
        shutil.rmtree(root, ignore_errors=True)
        root.mkdir(parents=True)
    RUNNER = Runner(binary, args.python, root)
    probe = Probe(root, random.Random(args.seed))
    probe.build(classes)
    cases = probe.cases
    print(f"{len(cases)} cases in {root} ({args.jobs} at a time)", flush=True)
    t0 = time.monotonic()
    results: list[dict | None] = [None] * len(cases)
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        futs = {pool.submit(RUNNER.run, c): i for i, c in enumerate(cases)}
        done = 0
        for f in concurrent.futures.as_completed(futs):
            i = futs[f]
            results[i] = f.result()
            results[i]["id"] = i
            done += 1
            if done % 25 == 0:
                print(f"  {done}/{len(cases)} ({time.monotonic() - t0:.0f} s)", flush=True)
    elapsed = time.monotonic() - t0
    res = [r for r in results if r is not None]
    # Summary
    order = [
        "ok-result",
        "clear-error",
        "warning",
        "agree",
        "refused",
        "warned",
        "fd-unavailable",
        "KINK-SILENT",
        "UNREPORTED-OVERLAP",
        "ACCEPTED-SILENT",
        "LATE-INTERRUPT",
        "probe-error",
        *sorted(FAILURES),
    ]
    table: dict[str, dict[str, int]] = {}
    for r in res:
        table.setdefault(r["class"], {}).setdefault(r["outcome"], 0)
        table[r["class"]][r["outcome"]] += 1
    cols = [o for o in dict.fromkeys(order) if any(o in t for t in table.values())]
    w = max(len(c) for c in CLASSES) + 2
    print()
    print("class".ljust(w) + "cases".rjust(7) + "".join(c.rjust(max(len(c), 5) + 2) for c in cols))
    for c in CLASSES:
        if c not in table:
            continue
        t = table[c]
        print(
            c.ljust(w)
            + str(sum(t.values())).rjust(7)
            + "".join(str(t.get(o, 0)).rjust(max(len(o), 5) + 2) for o in cols)
        )
    tot = {o: sum(t.get(o, 0) for t in table.values()) for o in cols}
    print("total".ljust(w) + str(len(res)).rjust(7) + "".join(str(tot[o]).rjust(max(len(o), 5) + 2) for o in cols))
    soft: dict[str, int] = {}
    for r in res:
        for f in r.get("findings", []):
            soft[f] = soft.get(f, 0) + 1
    print("\nsoft findings on error messages: " + (", ".join(f"{k} {v}" for k, v in sorted(soft.items())) or "none"))
    failures = [r for r in res if r["outcome"] in FAILURES or r["outcome"] == "probe-error"]
    if failures:
        print(f"\n{len(failures)} failing case(s):")
        for r in failures:
            print(f"  [{r['outcome']}] {r['class']}: {r['desc']}")
            cmd = r.get("command", "")
            if cmd.startswith("def case():"):  # a Python snippet: its statements on one line
                cmd = "python: " + "; ".join(ln.strip() for ln in cmd.splitlines()[2:] if ln.strip())
            print(f"      {cmd[:400]}")
            print(
                f"      exit {r.get('exit')}: {r.get('stderr_first', '')}"
                + (f"  ({r['note']})" if r.get("note") else "")
            )
    else:
        print("\nno failing case")
    commit = ""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=Path(__file__).parent
        ).stdout.strip()
    except OSError:
        pass
    report = {
        "probe": "tests/probe/hostile.py",
        "seed": args.seed,
        "commit": commit,
        "binary": str(binary),
        "seconds": round(elapsed, 1),
        "cases": len(res),
        "table": table,
        "soft_findings": soft,
        "results": res,
    }
    Path(args.out).write_text(json.dumps(report, indent=1, default=str))
    if args.markdown:
        Path(args.markdown).write_text(markdown(report, cols, failures))
    print(f"\nwrote {args.out} ({elapsed:.0f} s)")
    if not args.keep and not args.workdir:
        shutil.rmtree(root, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
