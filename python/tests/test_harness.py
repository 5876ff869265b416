"""The verification harness from Python returns the CLI's reports."""

from __future__ import annotations

import numpy as np
import pytest

import diffsoft
from conftest import DATA, REPO


def test_bounds_report():
    r = diffsoft.bounds(DATA / "beam.obj", rho=1000.0, mu=1e4, dt=0.01)
    assert r["schema"].startswith("diffsoft.bounds/")
    assert r["mesh"]["vertices"] == 20
    with pytest.raises(ValueError, match="rho"):
        diffsoft.bounds(DATA / "beam.obj", rho=-1.0, mu=1e4, dt=0.01)
    with pytest.raises(OSError):
        diffsoft.bounds(DATA / "missing.obj", rho=1.0, mu=1.0, dt=0.01)


def test_gradcheck_on_a_user_scene(beam):
    r = diffsoft.gradcheck(beam, 5, params=["youngs_modulus", "initial_velocities"], iterations=10)
    assert r["passes"], r
    assert r["steps"] == 5 and r["vertices"] == 20


def test_jacobians_report_holds():
    r = diffsoft.jacobians()
    assert r["verdicts"] and all(v["holds"] for v in r["verdicts"])


def test_gradcheck_refuses_parameters_the_scene_lacks_and_an_empty_list(beam):
    """Torques without a skeleton panicked (an empty V-curve); activations without actuators and
    no parameter at all passed with nothing checked. All are refused as `Scene.grad` refuses."""
    for params, message in (
        (["torques"], "torques: the scene has no skeleton"),
        (["activations"], "activations: the scene has no actuators"),
        ([], "params: no parameter to check"),
    ):
        with pytest.raises(diffsoft.InputError, match=message):
            diffsoft.gradcheck(beam, 2, params=params)
    with pytest.raises(diffsoft.InputError, match="torques: the scene has no skeleton"):
        beam.grad(2, params=["torques"])


def test_gradcheck_checks_activations_the_schedules_give():
    """Activations left to the schedules: the check perturbs the schedules' values (it
    panicked on an empty V-curve)."""
    s = diffsoft.Scene.load(REPO / "verification/paper/droneman/droneman.json")
    r = diffsoft.gradcheck(s, 2, params=["activations"], iterations=5)
    assert r["passes"] and r["error"] is None, r
    assert r["modes"][0]["groups"][0]["v_curve"]


def test_gradcheck_bounds_its_counts_and_reads_numbers_exactly(beam):
    with pytest.raises(diffsoft.InputError, match=r"iterations must be at most 1000 .*got 1000000000000"):
        diffsoft.gradcheck(beam, 2, params=["density"], iterations=10**12)
    for call in (lambda: diffsoft.gradcheck(beam, 2, params=["density"], seed=-1), lambda: diffsoft.jacobians(-1)):
        with pytest.raises(diffsoft.InputError, match="seed must be at least 0, got -1"):
            call()
    with pytest.raises(diffsoft.InputError, match="rho: got a bool"):
        diffsoft.bounds(DATA / "beam.obj", True, 1e4, 0.01)


def test_gradcheck_raises_what_grad_raises(beam):
    """Input errors of the case were reported as a failed check (`passes: False`)."""
    with pytest.raises(diffsoft.OutOfMemoryError, match="do not fit in memory|memory"):
        diffsoft.gradcheck(beam, 10**15, params=["density"])
    s = diffsoft.Scene.load(REPO / "verification/paper/droneman/droneman.json")
    s.set("activations", np.full((1, len(s.actuator_groups)), 1.0))
    for call in (lambda: s.grad(2, params=["activations"]), lambda: diffsoft.gradcheck(s, 2, params=["activations"])):
        with pytest.raises(diffsoft.InputError, match="activations: 1 rows for a run of 2 steps"):
            call()
