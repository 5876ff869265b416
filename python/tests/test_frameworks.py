"""PyTorch and JAX: gradients of losses written in the framework, through the simulation."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import central

torch = pytest.importorskip("torch")
jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402

import diffsoft  # noqa: E402


def loss_np(q: np.ndarray) -> float:
    # Mean squared distance of the final state from a target, plus a mean over time.
    return float(((q[-1] - 0.05) ** 2).mean() + q[:, :, 1].mean())


def fd_youngs(scene, steps, e, h):
    def f(x):
        s = scene.copy()
        s.set("youngs_modulus", x)
        return loss_np(s.simulate(steps).positions)

    return central(f, e, h)


def test_torch_gradients(beam):
    steps = 6
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    v0 = torch.tensor(beam.get("initial_velocities"), requires_grad=True)
    q = diffsoft.torch.simulate(beam, steps, {"youngs_modulus": e, "initial_velocities": v0})
    assert q.shape == (steps + 1, beam.n_vertices, 3) and q.dtype == torch.float64
    loss = ((q[-1] - 0.05) ** 2).mean() + q[:, :, 1].mean()
    loss.backward()
    assert e.grad.shape == () and v0.grad.shape == (beam.n_vertices, 3)
    assert float(e.grad) == pytest.approx(fd_youngs(beam, steps, 2e4, 20.0), rel=1e-5)
    # The scene itself is not modified by the call.
    assert beam.get("youngs_modulus") == 2e4


def test_torch_autograd_gradcheck(beam):
    steps = 4
    v0 = torch.tensor(beam.get("initial_velocities"), requires_grad=True)

    def f(v):
        return diffsoft.torch.simulate(beam, steps, {"initial_velocities": v})[-1, :3]

    assert torch.autograd.gradcheck(f, (v0,), eps=1e-6, atol=1e-7, rtol=1e-5)


def test_torch_velocities_output(beam):
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    q, v = diffsoft.torch.simulate(beam, 4, {"youngs_modulus": e}, with_velocities=True)
    (v[-1, :, 1].sum() + 0 * q.sum()).backward()

    def f(x):
        s = beam.copy()
        s.set("youngs_modulus", x)
        return float(s.simulate(4).velocities[-1, :, 1].sum())

    assert float(e.grad) == pytest.approx(central(f, 2e4, 20.0), rel=1e-5)


def test_wrappers_refuse_bools_complex_numbers_and_a_bad_mode_before_running(beam):
    """`True` or a complex tensor is not a modulus (torch and JAX converted them to 1 and the
    real part); torch checks the mode before the forward, as JAX does."""
    for value in (True, torch.tensor(True), torch.tensor(2e4 + 1j)):
        with pytest.raises(diffsoft.InputError, match="youngs_modulus: got"):
            diffsoft.torch.simulate(beam, 2, {"youngs_modulus": value})
    for value in (True, jax.numpy.asarray(True), np.complex128(2e4)):
        with pytest.raises(diffsoft.InputError, match="youngs_modulus: got"):
            diffsoft.jax.simulate(beam, 2, {"youngs_modulus": value})
    with pytest.raises(diffsoft.InputError, match="mode 'bogus'"):
        diffsoft.torch.simulate(beam, 2, {"youngs_modulus": torch.tensor(2e4)}, mode="bogus")


def test_wrappers_name_the_parameter_of_none_text_and_a_bare_name(beam):
    """Text was read as a number by JAX ("300" as 300), and None, text or a bare name as
    `params` gave messages naming nothing."""
    for simulate in (diffsoft.torch.simulate, diffsoft.jax.simulate):
        for value, shown in ((None, "NoneType None"), ("300", "str '300'"), (np.array(["300"]), "text")):
            with pytest.raises(diffsoft.InputError, match=f"density: got {shown}"):
                simulate(beam, 2, {"density": value})
        with pytest.raises(TypeError, match="params must be a dict of parameter names to values, got str 'density'"):
            simulate(beam, 2, "density")


def test_jax_reads_steps_as_the_native_calls_do(beam):
    """JAX compared `steps < 1` (a str or None raised Python's own TypeError, 2.0 a shape
    error) and allocated the trajectory before any check (JAX's RESOURCE_EXHAUSTED)."""
    for steps, cls, message in (
        ("2", TypeError, "steps must be an int, got str '2'"),
        (None, TypeError, "steps must be an int, got NoneType None"),
        (2.0, TypeError, "steps must be an int, got float 2.0"),
        (0, diffsoft.InputError, "steps must be at least 1, got 0"),
        (10**15, diffsoft.OutOfMemoryError, "memory"),
    ):
        for simulate in (diffsoft.torch.simulate, diffsoft.jax.simulate):
            with pytest.raises(cls, match=message):
                simulate(beam, steps)


def test_jax_gradients_and_jit(beam):
    steps = 6

    def loss(params):
        q = diffsoft.jax.simulate(beam, steps, params)
        return ((q[-1] - 0.05) ** 2).mean() + q[:, :, 1].mean()

    params = {"youngs_modulus": jnp.asarray(2e4), "initial_velocities": jnp.asarray(beam.get("initial_velocities"))}
    value, grads = jax.value_and_grad(loss)(params)
    assert float(value) == pytest.approx(loss_np(beam.simulate(steps).positions), rel=1e-12)
    assert float(grads["youngs_modulus"]) == pytest.approx(fd_youngs(beam, steps, 2e4, 20.0), rel=1e-5)
    g_jit = jax.jit(jax.grad(loss))(params)
    np.testing.assert_allclose(g_jit["initial_velocities"], grads["initial_velocities"], rtol=1e-12)


def test_torch_and_jax_agree(beam):
    steps = 5
    e = torch.tensor(3e4, dtype=torch.float64, requires_grad=True)
    diffsoft.torch.simulate(beam, steps, {"youngs_modulus": e})[-1].sum().backward()
    gj = jax.grad(lambda x: diffsoft.jax.simulate(beam, steps, {"youngs_modulus": x})[-1].sum())(jnp.asarray(3e4))
    assert float(e.grad) == pytest.approx(float(gj), rel=1e-12)


@pytest.fixture
def neo(tmp_path):
    """The beam in the stable neo-Hookean model (Newton's method, implicit gradients)."""
    import json

    from conftest import DATA

    scene = json.loads((DATA / "beam.json").read_text())
    scene["bodies"][0]["material"]["model"] = "neo_hookean"
    scene["bodies"][0]["mesh"] = str(DATA / "beam.obj")
    scene["solver"]["solver"] = "auto"
    path = tmp_path / "neo.json"
    path.write_text(json.dumps(scene))
    return diffsoft.Scene.load(path)


def test_hyperelastic_gradients_in_torch_and_jax(neo):
    steps = 4
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    q = diffsoft.torch.simulate(neo, steps, {"youngs_modulus": e}, mode="implicit")
    loss = ((q[-1] - 0.05) ** 2).mean() + q[:, :, 1].mean()
    loss.backward()
    fd = fd_youngs(neo, steps, 2e4, 20.0)
    assert float(e.grad) == pytest.approx(fd, rel=1e-5)

    def f(x):
        qj = diffsoft.jax.simulate(neo, steps, {"youngs_modulus": x}, mode="implicit")
        return ((qj[-1] - 0.05) ** 2).mean() + qj[:, :, 1].mean()

    g = jax.grad(f)(jnp.asarray(2e4))
    assert float(g) == pytest.approx(fd, rel=1e-5)


def test_the_forward_does_not_depend_on_the_order_of_the_dict(beam):
    # A per-tet modulus overrides the scalar in the same dict, whichever comes first; the
    # Poisson ratio keeps per-tet moduli. Both wrappers and grad_batch give one forward.
    steps = 4
    e_t = np.linspace(1e4, 4e4, beam.n_tets)
    items = [("youngs_modulus", 2e4), ("youngs_modulus_per_tet", e_t), ("poisson_ratio", 0.25)]
    runs = []
    for order in (items, items[::-1], [items[1], items[0], items[2]]):
        params = {k: torch.as_tensor(v, dtype=torch.float64) for k, v in order}
        runs.append(diffsoft.torch.simulate(beam, steps, params).detach().numpy())
        runs.append(np.asarray(diffsoft.jax.simulate(beam, steps, {k: jnp.asarray(v) for k, v in order})))
    for r in runs[1:]:
        np.testing.assert_array_equal(r, runs[0])
    # And it is the forward of the per-tet moduli with the new Poisson ratio.
    ref = beam.copy()
    ref.set("poisson_ratio", 0.25)
    ref.set("youngs_modulus_per_tet", e_t)
    np.testing.assert_array_equal(ref.simulate(steps).positions, runs[0])
