"""System identification with PyTorch: recover the Young's modulus of the paper's bridgesus.

A reference trajectory is simulated at the scene's own Young's modulus; the optimiser starts
10x too stiff and fits log(E) by matching the whole trajectory (mean squared vertex distance),
differentiating through the simulation with diffsoft's reverse mode (``diffsoft.torch``).

Run from anywhere:  python examples/python/sysid_bridgesus.py
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import torch

import diffsoft

REPO = Path(__file__).resolve().parents[2]
STEPS = 40
ITERATIONS = 60
ITERATIONS_PER_STEP = 10


def main() -> None:
    t0 = time.perf_counter()
    scene = diffsoft.Scene.load(REPO / "verification/paper/bridgesus/bridgesus.json")
    # A fixed number of local-global iterations per step (tolerance 0) with the direct solver,
    # for the target and the fit alike: the simulation is then one smooth function of E, whose
    # exact derivative the unrolled backward returns. At the scene's own tolerance the
    # iterations stop before their derivative converges, and every gradient would warn that it
    # is off by up to 10% (`unrolled_leftover`, docs/gradients.md).
    scene.configure(solver="direct", tolerance=0, max_iterations=ITERATIONS_PER_STEP)
    true_e = scene.get("youngs_modulus")
    target = torch.from_numpy(scene.simulate(STEPS).positions)
    # The loss is relative to the target's own mean squared displacement, so it is of order 1.
    scale = float(((target - target[0]) ** 2).sum(-1).mean())
    print(f"bridgesus: {scene.n_vertices} vertices, {scene.n_tets} tets, {STEPS} steps of {scene.dt} s")
    print(f"true Young's modulus {true_e:.6g} Pa; start at 10x: {10 * true_e:.6g} Pa")

    log_e = torch.tensor(math.log(10 * true_e), dtype=torch.float64, requires_grad=True)
    evaluations = 0

    def closure() -> torch.Tensor:
        nonlocal evaluations
        evaluations += 1
        opt.zero_grad()
        q = diffsoft.torch.simulate(scene, STEPS, {"youngs_modulus": log_e.exp()})
        loss = ((q - target) ** 2).sum(-1).mean() / scale
        loss.backward()
        return loss

    # Far from the answer the loss is flat in log(E): Adam's normalised steps cross it; near the
    # answer L-BFGS (quasi-Newton, strong Wolfe line search) converges in a few iterations.
    opt = torch.optim.Adam([log_e], lr=0.2)
    print(f"{'iter':>4} {'optimiser':>9} {'E (Pa)':>12} {'rel. error':>11} {'rel. loss':>12}")
    rel = math.inf
    for it in range(1, ITERATIONS + 1):
        if rel < 0.1 and isinstance(opt, torch.optim.Adam):
            opt = torch.optim.LBFGS(
                [log_e], max_iter=5, line_search_fn="strong_wolfe", tolerance_grad=1e-12, tolerance_change=1e-15
            )
        loss = opt.step(closure)
        e = log_e.detach().exp().item()
        rel = abs(e - true_e) / true_e
        print(f"{it:4d} {type(opt).__name__:>9} {e:12.6g} {rel:11.3e} {loss.item():12.4e}")
        if rel < 1e-5:
            break
    print(f"recovered E = {log_e.detach().exp().item():.8g} Pa (true {true_e:.8g}), relative error {rel:.2e}")
    print(f"{evaluations} simulations with gradients, {time.perf_counter() - t0:.1f} s")
    if rel > 1e-3:
        raise SystemExit("system identification did not converge")


if __name__ == "__main__":
    main()
