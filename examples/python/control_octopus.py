"""Open-loop control with PyTorch: the octopus's muscle activations steer a tentacle tip.

The paper's octopus (muscle fibres in its tentacles, no gravity) starts at rest. The controls
are every muscle group's activation at every step, parametrised as ``a = 0.5 * sigmoid(theta)``
so they stay in the admissible range [0, 1]. The loss is the squared distance of the paper's
end-effector vertex from a target at the final step; the target is where a fixed, made-up
activation pattern puts it, so it is reachable. Gradient descent with a backtracking line search
(a step is kept only if it lowers the loss), so the loss falls monotonically.

Run from anywhere:  python examples/python/control_octopus.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

import diffsoft

REPO = Path(__file__).resolve().parents[2]
STEPS = 30
ITERATIONS_PER_STEP = 10
TIP = 330  # the paper's "End Effector Index" of the octopus


def main() -> None:
    t0 = time.perf_counter()
    scene = diffsoft.Scene.load(REPO / "verification/paper/octopus/octopus.json")
    # A fixed number of local-global iterations per step (tolerance 0) with the direct solver:
    # the simulation is then one smooth function of the activations, whose exact derivative the
    # unrolled backward returns. At the scene's own tolerance a tentacle at rest meets it in one
    # iteration, and the gradients would warn that most of their derivative was left out
    # (`unrolled_leftover` up to 0.8, docs/gradients.md).
    scene.configure(solver="direct", tolerance=0, max_iterations=ITERATIONS_PER_STEP)
    groups = len(scene.actuator_groups)
    print(f"octopus: {scene.n_vertices} vertices, {scene.n_tets} tets, {groups} muscle groups, {STEPS} steps")

    # The target: where a smooth made-up activation pattern takes the tip.
    t = np.linspace(0.0, 1.0, STEPS)[:, None]
    phase = np.linspace(0.0, np.pi, groups)[None, :]
    reference = 0.25 + 0.2 * np.sin(2 * np.pi * t + phase)
    ref_scene = scene.copy()
    ref_scene.set("activations", reference)
    target = torch.from_numpy(ref_scene.simulate(STEPS).positions[-1, TIP])

    def loss_of(theta: torch.Tensor) -> torch.Tensor:
        q = diffsoft.torch.simulate(scene, STEPS, {"activations": 0.5 * torch.sigmoid(theta)})
        return ((q[-1, TIP] - target) ** 2).sum()

    theta = torch.zeros(STEPS, groups, dtype=torch.float64, requires_grad=True)
    step = 50.0
    history = []
    print(f"{'iter':>4} {'loss (m^2)':>12} {'tip distance (m)':>17} {'step':>8}")
    for it in range(15):
        loss = loss_of(theta)
        (grad,) = torch.autograd.grad(loss, theta)
        value = loss.item()
        history.append(value)
        print(f"{it:4d} {value:12.5e} {value**0.5:17.5f} {step:8.3g}")
        with torch.no_grad():
            while True:
                trial = theta - step * grad
                if loss_of(trial).item() < value:
                    theta.copy_(trial)
                    step *= 1.5
                    break
                step *= 0.5
                if step < 1e-8:
                    break
    with torch.no_grad():
        final = loss_of(theta).item()
    history.append(final)
    print(f"final loss {final:.5e} m^2 ({history[0] / final:.1f}x lower), {time.perf_counter() - t0:.1f} s")
    if any(b >= a for a, b in zip(history, history[1:])):
        raise SystemExit("the loss did not fall monotonically")


if __name__ == "__main__":
    main()
