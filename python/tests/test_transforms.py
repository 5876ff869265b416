"""Function transforms through the wrappers: ``torch.func.vmap``/``jacrev``/``grad``,
``jax.vmap``/``jacrev``, ``vjp_batch``, ``with_velocities``; each against loops of single
calls. Second derivatives raise a clear ``NotImplementedError``."""

from __future__ import annotations

import numpy as np
import pytest

import diffsoft

torch = pytest.importorskip("torch")
jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402

STEPS = 4
MODULI = [1.5e4, 2e4, 3.5e4]


def _single(scene, e):
    s = scene.copy()
    s.set("youngs_modulus", e)
    return s.simulate(STEPS)


def test_vjp_batch_equals_a_loop_of_vjps(beam):
    rng = np.random.default_rng(7)
    shape = (STEPS + 1, beam.n_vertices, 3)
    cots = [rng.standard_normal(shape) for _ in MODULI]
    vcots = [rng.standard_normal(shape), None, rng.standard_normal(shape)]
    params = ["youngs_modulus", "initial_velocities"]
    values = [{"youngs_modulus": e} for e in MODULI]
    batch = diffsoft.vjp_batch(beam, STEPS, params, values, cots, vcots, mode="implicit")
    for e, c, vc, got in zip(MODULI, cots, vcots, batch):
        s = beam.copy()
        s.set("youngs_modulus", e)
        ref = s.vjp(STEPS, params, c, vc, mode="implicit")
        assert got["youngs_modulus"] == ref["youngs_modulus"]
        np.testing.assert_array_equal(got["initial_velocities"], ref["initial_velocities"])
    # The batch's own input errors name the item.
    with pytest.raises(diffsoft.InputError, match=r"cotangents\[1\]: cotangent: shape"):
        diffsoft.vjp_batch(beam, STEPS, params, values, [cots[0], cots[1][:-1], cots[2]])
    with pytest.raises(diffsoft.InputError, match="2 arrays for 3 parameter sets"):
        diffsoft.vjp_batch(beam, STEPS, params, values, cots[:2])


# --- PyTorch -------------------------------------------------------------------------------


def _torch_sim(scene, **kw):
    def f(e):
        return diffsoft.torch.simulate(scene, STEPS, {"youngs_modulus": e}, **kw)

    return f


def test_torch_vmap_equals_a_loop(beam):
    es = torch.tensor(MODULI, dtype=torch.float64)
    q = torch.func.vmap(_torch_sim(beam))(es)
    assert q.shape == (len(MODULI), STEPS + 1, beam.n_vertices, 3)
    for k, e in enumerate(MODULI):
        np.testing.assert_array_equal(q[k].numpy(), _single(beam, e).positions)
    # Positions and velocities; a batched array beside an unbatched scalar; nested vmaps.
    qv = torch.func.vmap(_torch_sim(beam, with_velocities=True))(es)
    for k, e in enumerate(MODULI):
        np.testing.assert_array_equal(qv[1][k].numpy(), _single(beam, e).velocities)
    v0 = torch.tensor(beam.get("initial_velocities"))
    v0s = torch.stack([v0, 2 * v0])

    def g(v, e):
        return diffsoft.torch.simulate(beam, STEPS, {"initial_velocities": v, "youngs_modulus": e})

    out = torch.func.vmap(g, in_dims=(0, None))(v0s, torch.tensor(2e4, dtype=torch.float64))
    ref = beam.copy()
    ref.set("initial_velocities", 2 * v0.numpy())
    np.testing.assert_array_equal(out[1].numpy(), ref.simulate(STEPS).positions)
    nested = torch.func.vmap(torch.func.vmap(_torch_sim(beam)))(es.reshape(1, 3).expand(2, 3))
    np.testing.assert_array_equal(nested[1, 2].numpy(), q[2].numpy())


def test_torch_vmap_over_an_empty_batch(beam):
    """Numpy's "need at least one array to stack" before; JAX returned the empty result."""
    es = torch.zeros(0, dtype=torch.float64, requires_grad=True)
    q = torch.func.vmap(_torch_sim(beam))(es)
    assert q.shape == (0, STEPS + 1, beam.n_vertices, 3)
    q.sum().backward()
    assert es.grad is not None and es.grad.shape == (0,)
    assert jax.vmap(lambda e: diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus": e}))(jnp.zeros(0)).shape == q.shape


def _loss(q):
    return ((q[-1] - 0.05) ** 2).mean() + q[:, :, 1].mean()


def test_torch_gradients_through_vmap_and_of_vmap(beam):
    es = torch.tensor(MODULI, dtype=torch.float64, requires_grad=True)
    # backward through a vmapped simulation: one vjp_batch
    torch.func.vmap(lambda e: _loss(_torch_sim(beam)(e)))(es).sum().backward()
    # per-item gradients: vmap of grad
    per_item = torch.func.vmap(torch.func.grad(lambda e: _loss(_torch_sim(beam)(e))))(es.detach())
    for k, e in enumerate(MODULI):
        x = torch.tensor(e, dtype=torch.float64, requires_grad=True)
        _loss(_torch_sim(beam)(x)).backward()
        assert float(es.grad[k]) == pytest.approx(float(x.grad), rel=1e-12)
        assert float(per_item[k]) == pytest.approx(float(x.grad), rel=1e-12)


def test_torch_gradient_of_an_unbatched_parameter_sums_over_the_vmap(beam):
    v0 = torch.tensor(beam.get("initial_velocities"))
    v0s = torch.stack([v0, 2 * v0, -v0])
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)

    def f(v, x):
        return _loss(diffsoft.torch.simulate(beam, STEPS, {"initial_velocities": v, "youngs_modulus": x}))

    torch.func.vmap(f, in_dims=(0, None))(v0s, e).sum().backward()
    total = 0.0
    for v in v0s:
        x = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
        f(v, x).backward()
        total += float(x.grad)
    assert float(e.grad) == pytest.approx(total, rel=1e-12)


def test_torch_jacrev_equals_a_loop_of_backwards(beam):
    e_t = torch.linspace(1e4, 4e4, beam.n_tets, dtype=torch.float64)

    def f(e):
        return diffsoft.torch.simulate(beam, STEPS, {"youngs_modulus_per_tet": e})[-1, :2].reshape(-1)

    jac = torch.func.jacrev(f)(e_t)
    assert jac.shape == (6, beam.n_tets)
    for i in range(6):
        x = e_t.clone().requires_grad_(True)
        (row,) = torch.autograd.grad(f(x)[i], x)
        np.testing.assert_allclose(jac[i].numpy(), row.numpy(), rtol=1e-12, atol=1e-300)
    assert bool(jac.abs().sum() > 0)


def test_torch_second_derivatives_raise_naming_the_alternative(beam):
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    (g,) = torch.autograd.grad(_loss(_torch_sim(beam)(e)), e, create_graph=True)
    with pytest.raises(NotImplementedError, match="finite differences"):
        g.backward()
    with pytest.raises(NotImplementedError, match="not implemented"):
        torch.func.hessian(lambda x: _loss(_torch_sim(beam)(x)))(e.detach())
    with pytest.raises(NotImplementedError, match="forward-mode"):
        torch.func.jacfwd(_torch_sim(beam))(e.detach())


# --- JAX -----------------------------------------------------------------------------------


def _jax_sim(scene, **kw):
    def f(e):
        return diffsoft.jax.simulate(scene, STEPS, {"youngs_modulus": e}, **kw)

    return f


def test_jax_vmap_equals_a_loop(beam):
    es = jnp.asarray(MODULI)
    q = jax.vmap(_jax_sim(beam))(es)
    assert q.shape == (len(MODULI), STEPS + 1, beam.n_vertices, 3)
    for k, e in enumerate(MODULI):
        np.testing.assert_array_equal(np.asarray(q[k]), _single(beam, e).positions)
    q_jit = jax.jit(jax.vmap(_jax_sim(beam)))(es)
    np.testing.assert_array_equal(np.asarray(q_jit), np.asarray(q))
    nested = jax.vmap(jax.vmap(_jax_sim(beam)))(jnp.stack([es, es]))
    np.testing.assert_array_equal(np.asarray(nested[1]), np.asarray(q))


def test_jax_per_item_gradients_and_jacrev_equal_loops(beam):
    es = jnp.asarray(MODULI)
    per_item = jax.vmap(jax.grad(lambda e: _loss(_jax_sim(beam)(e))))(es)
    for k, e in enumerate(MODULI):
        ref = jax.grad(lambda x: _loss(_jax_sim(beam)(x)))(jnp.asarray(e))
        assert float(per_item[k]) == pytest.approx(float(ref), rel=1e-12)

    e_t = jnp.linspace(1e4, 4e4, beam.n_tets)

    def f(e):
        return diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus_per_tet": e})[-1, :2].reshape(-1)

    jac = jax.jacrev(f)(e_t)
    assert jac.shape == (6, beam.n_tets)
    for i in range(6):
        row = jax.grad(lambda x, i=i: f(x)[i])(e_t)
        np.testing.assert_allclose(np.asarray(jac[i]), np.asarray(row), rtol=1e-12, atol=1e-300)
    # And PyTorch's jacrev agrees.
    jt = torch.func.jacrev(
        lambda e: diffsoft.torch.simulate(beam, STEPS, {"youngs_modulus_per_tet": e})[-1, :2].reshape(-1)
    )(torch.from_numpy(np.array(e_t)))
    np.testing.assert_allclose(np.asarray(jac), jt.numpy(), rtol=1e-12, atol=1e-300)


def test_jax_with_velocities(beam):
    def f(e):
        q, v = diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus": e}, with_velocities=True)
        return v[-1, :, 1].sum() + 0.5 * q[-1, :, 0].sum()

    run = _single(beam, 2e4)
    q, v = diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus": jnp.asarray(2e4)}, with_velocities=True)
    np.testing.assert_array_equal(np.asarray(v), run.velocities)
    np.testing.assert_array_equal(np.asarray(q), run.positions)
    g = jax.grad(f)(jnp.asarray(2e4))
    x = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    qt, vt = diffsoft.torch.simulate(beam, STEPS, {"youngs_modulus": x}, with_velocities=True)
    (vt[-1, :, 1].sum() + 0.5 * qt[-1, :, 0].sum()).backward()
    assert float(g) == pytest.approx(float(x.grad), rel=1e-12)


def test_jax_errors_carry_the_library_message(beam):
    with pytest.raises(diffsoft.InputError, match="unknown parameter 'youngs'"):
        diffsoft.jax.simulate(beam, STEPS, {"youngs": jnp.asarray(1.0)})
    with pytest.raises(diffsoft.InputError, match=r"initial_velocities: .*shape"):
        diffsoft.jax.simulate(beam, STEPS, {"initial_velocities": jnp.zeros((3, 3))})
    with pytest.raises(diffsoft.InputError, match="mode 'fast'"):
        diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus": jnp.asarray(2e4)}, mode="fast")

    # A failure inside the callback (a divergence) is re-raised as diffsoft's own exception.
    huge = np.random.default_rng(0).normal(size=(beam.n_vertices, 3)) * 1e200
    with pytest.raises(diffsoft.DivergenceError, match="non-finite"):
        diffsoft.jax.simulate(beam, STEPS, {"initial_velocities": jnp.asarray(huge)})

    # Under jit the values are known only inside the callback: the error still names them.
    @jax.jit
    def bad(e):
        return diffsoft.jax.simulate(beam, STEPS, {"youngs_modulus": e})

    with pytest.raises(Exception, match="Young's modulus must be finite and positive, got -1"):
        bad(jnp.asarray(-1.0))


def test_jax_second_derivatives_raise_naming_the_alternative(beam):
    def f(e):
        return _loss(_jax_sim(beam)(e))

    with pytest.raises(NotImplementedError, match="finite differences"):
        jax.grad(jax.grad(f))(jnp.asarray(2e4))
    with pytest.raises(NotImplementedError, match="finite differences"):
        jax.hessian(f)(jnp.asarray(2e4))
