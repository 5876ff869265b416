"""Parameter names and solver settings come from the library: the registry's scalars and
arrays, and the one settings struct that ``configure`` sets by name and checks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import diffsoft


def test_parameter_lists_are_the_registry():
    scalars = diffsoft.SCALAR_PARAMETERS
    assert scalars[:3] == ["youngs_modulus", "poisson_ratio", "density"]
    assert {"initial_velocity.x", "gravity.y"} <= set(scalars)
    arrays = {name: (shape, meaning) for name, shape, meaning in diffsoft.ARRAY_PARAMETERS}
    assert arrays["initial_positions"] == ("(n, 3)", "positions of every vertex before the first step (m)")
    assert arrays["youngs_modulus_per_tet"][0] == "(tets,)"
    assert not set(scalars) & set(arrays)


def test_unknown_parameter_lists_the_registry(beam):
    with pytest.raises(ValueError) as e:
        beam.get("stiffness")
    for name in diffsoft.SCALAR_PARAMETERS + [a[0] for a in diffsoft.ARRAY_PARAMETERS]:
        assert name in str(e.value)


def test_every_scalar_reads_back_what_it_sets(beam):
    for name in diffsoft.SCALAR_PARAMETERS:
        s = beam.copy()
        v = s.get(name)
        new = 0.25 if v == 0.0 else 1.1 * v
        s.set(name, new)
        assert s.get(name) == pytest.approx(new, rel=1e-12), name


def test_configure_checks_each_setting_and_changes_nothing_on_error(beam):
    before = dict(beam.settings)
    for kwargs, message in [
        ({"dt": -1.0}, "time step must be finite and positive"),
        ({"tolerance": -1.0}, "tolerance must be finite and >= 0"),
        ({"dt": float("nan")}, r"configure\(dt=NaN\): must be a finite number"),
        ({"tolerance": float("inf")}, r"configure\(tolerance=inf\): must be a finite number"),
        ({"max_iterations": 50, "damping": 2.0}, "damping must be in"),
        ({"time_step": 0.005}, "unknown setting 'time_step'"),
    ]:
        with pytest.raises(ValueError, match=message):
            beam.configure(**kwargs)
        assert beam.settings == before, kwargs
    beam.configure(dt=0.002, eigen_method="dense", integrator="bdf2")
    assert (beam.dt, beam.settings["eigen_method"], beam.settings["integrator"]) == (0.002, "dense", "bdf2")


def test_a_scene_may_give_its_time_step_as_solver_dt(tmp_path, beam):
    source = Path(beam.path)
    scene = json.loads(source.read_text())
    del scene["time_step"]
    scene["solver"] = {**scene.get("solver", {}), "dt": 0.004}
    for body in scene["bodies"]:
        body["mesh"] = str((source.parent / body["mesh"]).resolve())
    p = tmp_path / "canonical.json"
    p.write_text(json.dumps(scene))
    assert diffsoft.Scene.load(p).dt == 0.004
    scene["time_step"] = 0.01
    p.write_text(json.dumps(scene))
    with pytest.raises(ValueError, match="given twice"):
        diffsoft.Scene.load(p)
