"""Batched rollouts: 8 Baymax gradients (and simulations) run in parallel against a loop.

Each parameter set is the paper's Baymax on the ground with another Young's modulus. The loop
calls ``Scene.grad`` eight times; ``diffsoft.grad_batch`` runs the same eight on all cores
(rayon, GIL released). The results are identical; the script prints both times and the ratio.
Every step runs a fixed 10 local-global iterations (tolerance 0): at the scene's own tolerance
many steps stop after their first iteration, which the unrolled gradient would differentiate as
that one iteration (docs/python.md, "Warnings and unconverged runs").

Run from anywhere:  python examples/python/batch_speedup.py
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

import diffsoft

REPO = Path(__file__).resolve().parents[2]
STEPS = 50
REPEATS = 3


def best(f) -> float:
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    scene = diffsoft.Scene.load(REPO / "verification/scenes/baymax_ground.json")
    # What gradients with contact need, at a fixed iteration count.
    scene.configure(solver="direct", anderson=0, tolerance=0, max_iterations=10)
    values = [{"youngs_modulus": e} for e in np.geomspace(400.0, 3200.0, 8)]
    params = ["youngs_modulus", "initial_velocities"]
    print(
        f"Baymax on the ground: {scene.n_vertices} vertices, {scene.n_tets} tets, {STEPS} steps, "
        f"8 parameter sets, {os.cpu_count()} cores; best of {REPEATS}"
    )

    def loop_grad():
        out = []
        for v in values:
            s = scene.copy()
            s.set("youngs_modulus", v["youngs_modulus"])
            out.append(s.grad(STEPS, "final_com.y", params))
        return out

    batch = diffsoft.grad_batch(scene, STEPS, "final_com.y", params, values)
    for (l1, g1), (l2, g2) in zip(loop_grad(), batch):
        assert l1 == l2 and g1["youngs_modulus"] == g2["youngs_modulus"]
    t_loop = best(loop_grad)
    t_batch = best(lambda: diffsoft.grad_batch(scene, STEPS, "final_com.y", params, values))
    print(f"gradients:   loop {t_loop:.3f} s, grad_batch {t_batch:.3f} s, speed-up {t_loop / t_batch:.2f}x")

    def loop_sim():
        out = []
        for v in values:
            s = scene.copy()
            s.set("youngs_modulus", v["youngs_modulus"])
            out.append(s.simulate(STEPS))
        return out

    t_loop = best(loop_sim)
    t_batch = best(lambda: diffsoft.simulate_batch(scene, STEPS, values))
    print(f"simulations: loop {t_loop:.3f} s, simulate_batch {t_batch:.3f} s, speed-up {t_loop / t_batch:.2f}x")


if __name__ == "__main__":
    main()
