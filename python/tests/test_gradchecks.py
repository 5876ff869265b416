"""`torch.autograd.gradcheck` and `jax.test_util.check_grads` (float64, reverse mode) through
`diffsoft.torch.simulate` / `diffsoft.jax.simulate` on a free body, a body in frictional ground
contact, Baymax with its skeleton and torques, and the actuated octopus.

Each scene runs a fixed number of local-global iterations (tolerance 0), so the trajectory is a
smooth function of its inputs and central differences converge to the reverse-mode gradient.
Array parameters are checked along one random direction: ``x(alpha) = x0 + alpha * u``.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import DATA, REPO

torch = pytest.importorskip("torch")
jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
from jax.test_util import check_grads  # noqa: E402

import diffsoft  # noqa: E402


def scene_free():
    return diffsoft.Scene.load(DATA / "free.json"), "initial_velocities", 1e-2, 4


def scene_ground():
    return diffsoft.Scene.load(DATA / "ground.json"), "initial_velocities", 1e-2, 6


def scene_baymax_torques():
    return diffsoft.Scene.load(REPO / "verification/scenes/baymax_skeleton.json"), "initial_velocities", 1e-2, 3


def scene_octopus():
    s = diffsoft.Scene.load(REPO / "verification/paper/octopus/octopus.json")
    steps = 3
    s.set("activations", np.full((steps, len(s.actuator_groups)), 0.3))
    return s, "activations", 0.1, steps


CASES = {
    "free_body": scene_free,
    "ground_contact": scene_ground,
    "baymax_torques": scene_baymax_torques,
    "octopus_actuated": scene_octopus,
}


def setup(name):
    scene, param, scale, steps = CASES[name]()
    scene.configure(tolerance=0.0, max_iterations=8, anderson=0, solver="direct")
    x0 = np.asarray(scene.get(param), dtype=np.float64)
    u = np.random.default_rng(7).normal(size=x0.shape) * scale
    # A few output coordinates keep gradcheck's numerical Jacobian small.
    rows = np.linspace(0, scene.n_vertices - 1, 4).astype(int)
    return scene, param, steps, x0, u, rows


@pytest.mark.parametrize("name", list(CASES))
def test_torch_gradcheck(name):
    scene, param, steps, x0, u, rows = setup(name)
    x0t, ut = torch.from_numpy(x0), torch.from_numpy(u)

    def f(alpha):
        q = diffsoft.torch.simulate(scene, steps, {param: x0t + alpha * ut})
        return q[-1, rows]

    alpha = torch.zeros(1, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(f, (alpha,), eps=1e-6, atol=1e-8, rtol=1e-5)


@pytest.mark.parametrize("name", list(CASES))
def test_jax_check_grads(name):
    scene, param, steps, x0, u, rows = setup(name)

    def f(alpha):
        q = diffsoft.jax.simulate(scene, steps, {param: jnp.asarray(x0) + alpha * jnp.asarray(u)})
        return q[-1, rows]

    check_grads(f, (jnp.asarray(0.0),), order=1, modes=["rev"], eps=1e-6, atol=1e-8, rtol=1e-5)


def test_negative_steps_raise(beam):
    with pytest.raises(diffsoft.InputError, match="steps must be at least 1, got -1"):
        beam.simulate(-1)
    with pytest.raises(diffsoft.InputError, match="steps must be at least 1, got -5"):
        beam.grad(-5)
