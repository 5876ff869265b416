"""Loading, parameters, settings, simulation and the errors a user sees."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import diffsoft
from conftest import DATA, central


def test_load_both_formats(beam, bridgesus):
    assert beam.n_vertices == 20 and beam.n_tets == 24
    assert bridgesus.n_vertices > 100 and bridgesus.dt == pytest.approx(1 / 200)
    assert "Scene(" in repr(beam)


def test_simulate_shapes_and_initial_state(beam):
    run = beam.simulate(5)
    assert run.positions.shape == (6, 20, 3) and run.positions.dtype == np.float64
    assert run.velocities.shape == (6, 20, 3)
    np.testing.assert_array_equal(run.positions[0], beam.get("initial_positions"))
    np.testing.assert_allclose(run.times, np.arange(6) * beam.dt, rtol=1e-12)
    # The run log's figures, not the whole file: no schema is claimed that it would not meet.
    assert "schema" not in run.stats and {"summary", "certificate", "settings", "steps"} <= run.stats.keys()
    assert len(run.stats["steps"]) == 5 and run.stats["summary"]["steps"] == 5
    # The beam moves upwards (initial velocity 0.5 m/s) against gravity.
    assert run.positions[1, :, 1].mean() > run.positions[0, :, 1].mean()


def test_simulate_reports_convergence(bridgesus):
    run = bridgesus.simulate(3)
    assert run.stats["unconverged_steps"] == 0
    assert all(s["converged"] for s in run.stats["steps"])


def test_scalar_set_get_changes_the_run(beam):
    assert beam.get("youngs_modulus") == pytest.approx(2e4)
    soft = beam.simulate(10).positions
    beam.set("youngs_modulus", 2e5)
    assert beam.get("youngs_modulus") == pytest.approx(2e5)
    stiff = beam.simulate(10).positions
    assert np.abs(soft - stiff).max() > 1e-4


def test_array_parameters_round_trip(beam):
    q = beam.get("initial_positions") + np.array([0.0, 0.1, 0.0])
    beam.set("initial_positions", q)
    np.testing.assert_array_equal(beam.get("initial_positions"), q)
    e = np.linspace(1e4, 3e4, beam.n_tets)
    beam.set("youngs_modulus_per_tet", e)
    np.testing.assert_allclose(beam.get("youngs_modulus_per_tet"), e, rtol=1e-12)
    t = beam.get("attachment_targets")
    assert t.shape == (beam.n_attachments, 3)
    beam.set("attachment_targets", t + 0.01)
    np.testing.assert_allclose(beam.get("attachment_targets"), t + 0.01)
    assert beam.get("activations") is None


def test_per_tet_moduli_stay_in_force_until_the_scalar_is_set(beam):
    e = np.linspace(1e4, 5e4, beam.n_tets)
    beam.set("youngs_modulus_per_tet", e)
    # The Poisson ratio, even to its own value or to another, keeps every tet's modulus.
    beam.set("poisson_ratio", beam.get("poisson_ratio"))
    np.testing.assert_allclose(beam.get("youngs_modulus_per_tet"), e, rtol=1e-12)
    beam.set("poisson_ratio", 0.25)
    np.testing.assert_allclose(beam.get("youngs_modulus_per_tet"), e, rtol=1e-12)
    # The scalar is not the one in force, and `get` says so rather than return it.
    with pytest.raises(diffsoft.InputError, match="per-tet values are in force"):
        beam.get("youngs_modulus")
    # Setting the scalar gives every tet that value again.
    beam.set("youngs_modulus", 3e4)
    np.testing.assert_allclose(beam.get("youngs_modulus_per_tet"), 3e4, rtol=1e-12)
    assert beam.get("youngs_modulus") == pytest.approx(3e4)
    # A bool is not a modulus.
    with pytest.raises(diffsoft.InputError, match="bool"):
        beam.set("youngs_modulus", True)


def test_initial_velocity_scalar_updates_array(beam):
    beam.set("initial_velocities", np.zeros((20, 3)))
    beam.set("initial_velocity.y", 2.0)
    np.testing.assert_array_equal(beam.get("initial_velocities")[:, 1], 2.0)


def test_copy_is_independent(beam):
    c = beam.copy()
    c.set("density", 500.0)
    assert beam.get("density") == pytest.approx(1000.0)
    np.testing.assert_allclose(c.masses.sum() * 2, beam.masses.sum(), rtol=1e-12)


def test_configure(beam):
    beam.configure(solver="split", dt=0.005)
    assert beam.settings["solver"] == "split" and beam.dt == 0.005
    with pytest.raises(ValueError, match="unknown setting 'tolerence'"):
        beam.configure(tolerence=1e-3)
    with pytest.raises(ValueError, match="settings"):
        beam.configure(solver="fastest")
    # Fractions of the length scale beyond reason: refused, naming the setting, unchanged.
    for name, value in [("tolerance", 1e300), ("inner_tolerance", 1.0), ("contact_margin", 2.0)]:
        before = beam.settings[name]
        with pytest.raises(ValueError, match=f"{name} must be"):
            beam.configure(**{name: value})
        assert beam.settings[name] == before


def test_parameter_names_are_documented():
    assert "youngs_modulus" in diffsoft.SCALAR_PARAMETERS
    names = [a[0] for a in diffsoft.ARRAY_PARAMETERS]
    assert {"initial_positions", "activations", "torques", "youngs_modulus_per_tet"} <= set(names)


def test_missing_file_is_oserror(tmp_path):
    with pytest.raises(OSError, match="nope.json"):
        diffsoft.Scene.load(tmp_path / "nope.json")


def test_malformed_scene_is_valueerror_with_line(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{\n  "schema": "diffsoft.scene/1",\n  "time_step": 0.01,\n  "bodies": [ { "name": 3 } ]\n}\n')
    with pytest.raises(ValueError, match=r"bad.json.*line 4"):
        diffsoft.Scene.load(p)


def test_bad_parameters_are_valueerrors(beam):
    with pytest.raises(ValueError, match="unknown parameter 'youngs'"):
        beam.set("youngs", 1.0)
    with pytest.raises(ValueError, match="finite"):
        beam.set("youngs_modulus", float("nan"))
    with pytest.raises(ValueError, match=r"shape \[20, 2\], expected \(20, 3\)"):
        beam.set("initial_positions", np.zeros((20, 2)))
    with pytest.raises(ValueError, match="tet 3"):
        e = np.full(beam.n_tets, 1e4)
        e[3] = -1.0
        beam.set("youngs_modulus_per_tet", e)
    with pytest.raises(ValueError, match="no actuators"):
        beam.set("activations", np.zeros((3, 1)))
    with pytest.raises(ValueError, match="steps must be at least 1"):
        beam.simulate(0)
    # A failed set leaves the scene as it was.
    assert beam.get("youngs_modulus") == pytest.approx(2e4)


def test_divergence_is_runtimeerror(beam):
    # Pushing every vertex 1e200 m/s apart overflows: the solver must say so, not return NaN.
    v = np.random.default_rng(0).normal(size=(20, 3)) * 1e200
    beam.set("initial_velocities", v)
    with pytest.raises(RuntimeError, match="non-finite"):
        beam.simulate(3)


def test_a_run_that_cannot_fit_in_memory_is_refused(beam):
    with pytest.raises(ValueError, match=r"10+ steps of 20 vertices: needs .* of memory"):
        beam.simulate(10**15)


def test_an_unconverged_forward_is_refused_unless_allowed(beam):
    """A body so stiff the local-global iteration cannot meet its tolerance: its loss and
    gradient would be those of an unconverged run, so they are refused unless asked for."""
    stiff = beam.copy()
    stiff.set("youngs_modulus", 1e20)
    stiff.configure(tolerance=1e-6, max_iterations=5)
    with pytest.raises(RuntimeError, match="did not converge"):
        stiff.grad(10, params=["density"])
    with pytest.raises(RuntimeError, match="did not converge"):
        diffsoft.grad_batch(stiff, 10, "final_com.y", ["density"], [{}])
    loss, grads = stiff.grad(10, params=["density"], allow_unconverged=True)
    assert math.isfinite(loss) and math.isfinite(grads["density"])


def test_materials_report_the_model_and_the_projective_response(beam, tmp_path):
    (m,) = beam.materials
    assert m["model"] == "projective"
    e, nu = m["youngs_modulus"], m["poisson_ratio"]
    assert m["effective_youngs_modulus"] == pytest.approx(e / (1 + 2 * nu / 3), rel=1e-14)
    assert m["effective_poisson_ratio"] == pytest.approx(nu / (3 + 2 * nu), rel=1e-14)
    # The same beam in a hyperelastic model: exact moduli, Newton by default, implicit gradients.
    scene = json.loads((DATA / "beam.json").read_text())
    scene["bodies"][0]["material"]["model"] = "neo_hookean"
    scene["solver"]["solver"] = "auto"
    scene["bodies"][0]["mesh"] = str(DATA / "beam.obj")
    path = tmp_path / "neo.json"
    path.write_text(json.dumps(scene))
    neo = diffsoft.Scene.load(path)
    (m,) = neo.materials
    assert m["model"] == "neo_hookean" and m["effective_youngs_modulus"] is None
    run = neo.simulate(3)
    assert run.stats["summary"]["converged_steps"] == 3
    loss, grads = neo.grad(3, loss="final_com.y", params=["youngs_modulus"], mode="implicit")
    h = 1e-4 * e
    fd = central(lambda x: _loss_at(neo, x), e, h)
    assert grads["youngs_modulus"] == pytest.approx(fd, rel=1e-4)


def _loss_at(scene, e):
    s = scene.copy()
    s.set("youngs_modulus", e)
    return s.grad(3, loss="final_com.y", params=[], mode="implicit")[0]
