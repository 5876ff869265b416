"""How a batch of gradients scales with cores: one machine, four ways to run N gradients.

Each item is a gradient of the paper's bridge (``verification/paper/bridge/bridge.json``, STEPS
steps, loss ``mean_com.y`` with respect to ``youngs_modulus``) at its own Young's modulus. The
script times, best of REPEATS each:

* ``loop, 1 thread``: ``Scene.grad`` N times in a child process with ``RAYON_NUM_THREADS=1``;
* ``loop, all threads``: the same loop with every core available to each call;
* ``grad_batch``: ``diffsoft.grad_batch`` of the N items (one item per core, single-threaded);
* ``N processes``: N child processes started together, each computing one item on one thread
  (the throughput of independent jobs; includes each process's start and scene load).

The speed-ups are against the single-threaded loop. Used for the many-core measurements of
docs/performance.md (``python benches/many_cores.py --items 16``); it needs only the package.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "verification/paper/bridge/bridge.json"
STEPS = 60
REPEATS = 2


def moduli(n: int) -> list[float]:
    """N Young's moduli spread over a factor of two around the scene's own."""
    import diffsoft

    e0 = float(diffsoft.Scene.load(SCENE).get("youngs_modulus"))
    return [e0 * (0.7 + 0.7 * i / max(n - 1, 1)) for i in range(n)]


def loop(values: list[float]) -> float:
    """Seconds for ``Scene.grad`` over ``values``, one after another, in this process."""
    import diffsoft

    scene = diffsoft.Scene.load(SCENE)
    t0 = time.perf_counter()
    for e in values:
        s = scene.copy()
        s.set("youngs_modulus", e)
        s.grad(STEPS, "mean_com.y", ["youngs_modulus"])
    return time.perf_counter() - t0


def batch(values: list[float]) -> float:
    """Seconds for one ``grad_batch`` of ``values``."""
    import diffsoft

    scene = diffsoft.Scene.load(SCENE)
    t0 = time.perf_counter()
    diffsoft.grad_batch(scene, STEPS, "mean_com.y", ["youngs_modulus"], [{"youngs_modulus": e} for e in values])
    return time.perf_counter() - t0


def child(mode: str, values: list[float], threads: int | None) -> subprocess.Popen:
    env = dict(os.environ)
    if threads is not None:
        env["RAYON_NUM_THREADS"] = str(threads)
    args = [sys.executable, __file__, "--child", mode, "--values", ",".join(repr(e) for e in values)]
    return subprocess.Popen(args, env=env, stdout=subprocess.PIPE, text=True)


def seconds(p: subprocess.Popen) -> float:
    out, _ = p.communicate()
    if p.returncode != 0:
        raise SystemExit(f"child failed with exit status {p.returncode}")
    return float(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--items", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--child", choices=["loop", "batch"])
    ap.add_argument("--values")
    a = ap.parse_args()
    if a.child:
        values = [float(v) for v in a.values.split(",")]
        print(loop(values) if a.child == "loop" else batch(values))
        return
    values = moduli(a.items)
    print(f"paper bridge, {STEPS} steps, {a.items} gradients, {os.cpu_count()} cores; best of {REPEATS}")
    t_single = min(seconds(child("loop", values, 1)) for _ in range(REPEATS))
    t_all = min(seconds(child("loop", values, None)) for _ in range(REPEATS))
    t_batch = min(seconds(child("batch", values, None)) for _ in range(REPEATS))
    walls = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        procs = [child("loop", [e], 1) for e in values]
        for p in procs:
            seconds(p)
        walls.append(time.perf_counter() - t0)
    t_procs = min(walls)
    for name, t in [
        ("loop, 1 thread", t_single),
        ("loop, all threads", t_all),
        ("grad_batch", t_batch),
        (f"{a.items} processes", t_procs),
    ]:
        print(f"{name:>20}: {t:8.3f} s   speed-up {t_single / t:5.2f}x")


if __name__ == "__main__":
    main()
