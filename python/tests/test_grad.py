"""Gradients and vector-Jacobian products against central differences."""

from __future__ import annotations

import numpy as np
import pytest

import diffsoft
from conftest import central


def final_com_y(scene: diffsoft.Scene, steps: int) -> float:
    q = scene.simulate(steps).positions[-1]
    m = scene.masses
    return float((m * q[:, 1]).sum() / m.sum())


def test_grad_loss_matches_python_loss(beam):
    loss, grads = beam.grad(8, loss="final_com.y", params=["youngs_modulus"])
    assert loss == pytest.approx(final_com_y(beam, 8), rel=1e-12)
    assert set(grads) == {"youngs_modulus"}


@pytest.mark.parametrize(
    "name,x,h", [("youngs_modulus", 2e4, 20.0), ("density", 1000.0, 1.0), ("gravity.y", -9.81, 1e-3)]
)
def test_scalar_grads_match_central_differences(beam, name, x, h):
    _, grads = beam.grad(8, params=[name])

    def f(v):
        s = beam.copy()
        s.set(name, v)
        return s.grad(8)[0]

    fd = central(f, x, h)
    assert grads[name] == pytest.approx(fd, rel=1e-5, abs=1e-12)


def test_array_grad_matches_directional_difference(beam):
    _, grads = beam.grad(8, params=["initial_velocities", "youngs_modulus_per_tet", "attachment_targets"])
    rng = np.random.default_rng(1)
    for name, scale in [("initial_velocities", 1e-4), ("youngs_modulus_per_tet", 1.0), ("attachment_targets", 1e-5)]:
        x0 = beam.get(name)
        u = rng.normal(size=x0.shape)

        def f(e, name=name, x0=x0, u=u, scale=scale):
            s = beam.copy()
            s.set(name, x0 + e * scale * u)
            return s.grad(8)[0]

        fd = central(f, 0.0, 1.0) / scale
        ad = float((grads[name] * u).sum())
        assert ad == pytest.approx(fd, rel=1e-5), name


@pytest.mark.parametrize("mode", ["unrolled", "implicit"])
def test_vjp_matches_directional_difference(beam, mode):
    steps = 6
    if mode == "implicit":
        beam.configure(tolerance=1e-12, max_iterations=500)
    rng = np.random.default_rng(2)
    c = rng.normal(size=(steps + 1, beam.n_vertices, 3))
    g = beam.vjp(steps, params=["youngs_modulus", "initial_positions"], cotangent=c, mode=mode)

    def f(e):
        s = beam.copy()
        s.set("youngs_modulus", e)
        return float((c * s.simulate(steps).positions).sum())

    assert g["youngs_modulus"] == pytest.approx(central(f, 2e4, 20.0), rel=1e-5)
    q0 = beam.get("initial_positions")
    u = rng.normal(size=q0.shape)

    def fq(e):
        s = beam.copy()
        s.set("initial_positions", q0 + e * 1e-5 * u)
        return float((c * s.simulate(steps).positions).sum())

    assert float((g["initial_positions"] * u).sum()) == pytest.approx(central(fq, 0.0, 1.0) / 1e-5, rel=1e-5)


def test_vjp_with_a_com_cotangent_equals_grad(beam):
    steps = 5
    m = beam.masses
    c = np.zeros((steps + 1, beam.n_vertices, 3))
    c[-1, :, 1] = m / m.sum()
    g = beam.vjp(steps, params=["youngs_modulus", "initial_velocities"], cotangent=c)
    _, ref = beam.grad(steps, loss="final_com.y", params=["youngs_modulus", "initial_velocities"])
    assert g["youngs_modulus"] == pytest.approx(ref["youngs_modulus"], rel=1e-10)
    np.testing.assert_allclose(g["initial_velocities"], ref["initial_velocities"], rtol=1e-10, atol=1e-16)


def test_velocity_cotangent(beam):
    steps = 4
    rng = np.random.default_rng(3)
    cv = rng.normal(size=(steps + 1, beam.n_vertices, 3))
    g = beam.vjp(steps, params=["density"], cotangent=np.zeros_like(cv), velocity_cotangent=cv)

    def f(rho):
        s = beam.copy()
        s.set("density", rho)
        return float((cv * s.simulate(steps).velocities).sum())

    assert g["density"] == pytest.approx(central(f, 1000.0, 1.0), rel=1e-5)


def test_grad_with_contact(ground):
    _, grads = ground.grad(10, loss="final_com.x", params=["initial_velocity.x"])

    def f(v):
        s = ground.copy()
        s.set("initial_velocity.x", v)
        return s.grad(10, loss="final_com.x")[0]

    assert grads["initial_velocity.x"] == pytest.approx(central(f, 0.5, 1e-5), rel=1e-4)


def test_cotangent_shape_errors(beam):
    with pytest.raises(ValueError, match=r"expected \(steps \+ 1, n, 3\) = \(4, 20, 3\)"):
        beam.vjp(3, params=["density"], cotangent=np.zeros((3, 20, 3)))
    with pytest.raises(ValueError, match="mode 'exact'"):
        beam.grad(3, mode="exact")
    with pytest.raises(ValueError, match="unknown loss"):
        beam.grad(3, loss="energy")


def test_grad_batch_equals_loop(beam):
    values = [{"youngs_modulus": e, "initial_velocity.y": 0.1 * k} for k, e in enumerate([1e4, 2e4, 4e4, 8e4])]
    batch = diffsoft.grad_batch(beam, 6, "final_com.y", ["youngs_modulus", "initial_velocities"], values)
    assert len(batch) == 4
    for v, (loss, grads) in zip(values, batch):
        s = beam.copy()
        for k, x in v.items():
            s.set(k, x)
        ref_loss, ref = s.grad(6, params=["youngs_modulus", "initial_velocities"])
        assert loss == ref_loss
        assert grads["youngs_modulus"] == ref["youngs_modulus"]
        np.testing.assert_array_equal(grads["initial_velocities"], ref["initial_velocities"])


def test_simulate_batch_equals_loop(beam):
    values = [{"density": 500.0}, {"density": 2000.0}]
    runs = diffsoft.simulate_batch(beam, 5, values)
    for v, r in zip(values, runs):
        s = beam.copy()
        s.set("density", v["density"])
        np.testing.assert_array_equal(r.positions, s.simulate(5).positions)
    with pytest.raises(ValueError, match=r"values\[1\]"):
        diffsoft.simulate_batch(beam, 5, [{"density": 1.0}, {"dens": 1.0}])


@pytest.mark.parametrize("mode", ["unrolled", "implicit"])
def test_bdf2_grads_match_central_differences(beam, mode):
    """BDF2 (scene key solver.integrator) is differentiated in both modes."""
    beam.configure(integrator="bdf2")
    if mode == "implicit":
        beam.configure(tolerance=1e-12, max_iterations=500)
    _, grads = beam.grad(8, params=["youngs_modulus"], mode=mode)

    def f(v):
        s = beam.copy()
        s.set("youngs_modulus", v)
        return s.grad(8, mode=mode)[0]

    assert grads["youngs_modulus"] == pytest.approx(central(f, 2e4, 20.0), rel=1e-5)


def test_bdf2_differs_from_implicit_euler_from_the_second_step(beam):
    euler = beam.simulate(2).positions
    beam.configure(integrator="bdf2")
    assert beam.settings["integrator"] == "bdf2"
    bdf2 = beam.simulate(2).positions
    np.testing.assert_allclose(bdf2[1], euler[1], rtol=0, atol=1e-12)
    assert np.abs(bdf2[2] - euler[2]).max() > 1e-9
    with pytest.raises(ValueError):
        beam.configure(integrator="rk4")


def test_newton_grads_with_contact(ground):
    """Newton's method (solver newton) with ground contact: implicit-mode gradients match central
    differences and the direct solver's converged gradient; unrolled mode is refused."""
    ground.configure(solver="newton", tolerance=1e-12, max_iterations=200)
    _, grads = ground.grad(10, loss="final_com.x", params=["initial_velocity.x", "youngs_modulus"], mode="implicit")

    def f(v):
        s = ground.copy()
        s.set("initial_velocity.x", v)
        return s.grad(10, loss="final_com.x", mode="implicit")[0]

    assert grads["initial_velocity.x"] == pytest.approx(central(f, 0.5, 1e-5), rel=1e-5)
    direct = ground.copy()
    direct.configure(solver="direct", max_iterations=100000)
    _, ref = direct.grad(10, loss="final_com.x", params=["initial_velocity.x", "youngs_modulus"], mode="implicit")
    assert grads["initial_velocity.x"] == pytest.approx(ref["initial_velocity.x"], rel=1e-7)
    assert grads["youngs_modulus"] == pytest.approx(ref["youngs_modulus"], rel=1e-6)
    with pytest.raises(Exception, match="Newton"):
        ground.grad(10, loss="final_com.x", mode="unrolled")


def test_unrolled_mode_warns_about_steps_converged_in_one_iteration(ground):
    """The box starts undeformed: with a tolerance its first step converges in one iteration, so
    unrolled mode's derivative through it is one iteration's; implicit mode and a fixed count
    do not warn."""
    ground.configure(tolerance=1e-10, max_iterations=2000)
    with pytest.warns(UserWarning, match="first iteration"):
        ground.grad(5, params=["youngs_modulus"], mode="unrolled")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ground.grad(5, params=["youngs_modulus"], mode="implicit")
        ground.configure(tolerance=0.0, max_iterations=30)
        ground.grad(5, params=["youngs_modulus"], mode="unrolled")


def test_statistics_are_returned_on_request(beam):
    """``stats=`` receives the gradient's statistics: at a tolerance the unrolled gradient's
    ``unrolled_leftover`` (the share of a step's derivative its iterations left out, warned
    above 1e-5), at a fixed iteration count 0, in implicit mode ``forward_gap``; ``vjp`` too."""
    import warnings

    fixed: dict = {"stale": 1}
    beam.grad(5, params=["youngs_modulus"], stats=fixed)
    assert "stale" not in fixed
    assert fixed["forward_iterations"] == 5 * 15 and fixed["unrolled_leftover"] == 0.0
    beam.configure(tolerance=1e-4, max_iterations=1000)
    loose: dict = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        beam.grad(5, params=["youngs_modulus"], stats=loose)
    assert loose["unrolled_leftover"] > 1e-5, loose
    assert any("unrolled_leftover" in str(w.message) for w in caught)
    implicit: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        beam.grad(5, params=["youngs_modulus"], mode="implicit", stats=implicit)
    assert implicit["unrolled_leftover"] == 0.0 and implicit["forward_gap"] > 0.0
    cot = np.zeros((6, beam.n_vertices, 3))
    cot[-1, :, 1] = 1.0
    from_vjp: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        beam.vjp(5, ["youngs_modulus"], cot, stats=from_vjp)
    assert from_vjp["unrolled_leftover"] > 1e-5
    with pytest.raises(TypeError):
        beam.grad(5, stats=[])
