"""The exception classes: each error the library raises is an instance of the most specific
class of ``diffsoft`` and of the built-in it stands for (``ValueError``, ``OSError``,
``RuntimeError``), triggered here from real inputs."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import diffsoft
from conftest import DATA, REPO

BRIDGESUS = REPO / "verification/paper/bridgesus/bridgesus.json"

CLASSES = {
    # class: (direct bases, built-in)
    diffsoft.DiffsoftError: ((Exception,), Exception),
    diffsoft.InputError: ((diffsoft.DiffsoftError, ValueError), ValueError),
    diffsoft.UnsupportedError: ((diffsoft.InputError,), ValueError),
    diffsoft.UncertifiedError: ((diffsoft.InputError,), ValueError),
    diffsoft.OutOfMemoryError: ((diffsoft.InputError, MemoryError), MemoryError),
    diffsoft.FileError: ((diffsoft.DiffsoftError, OSError), OSError),
    diffsoft.SimulationError: ((diffsoft.DiffsoftError, RuntimeError), RuntimeError),
    diffsoft.DivergenceError: ((diffsoft.SimulationError,), RuntimeError),
    diffsoft.ConvergenceError: ((diffsoft.SimulationError,), RuntimeError),
    diffsoft.SceneBusyError: ((diffsoft.DiffsoftError, RuntimeError), RuntimeError),
}


def raised(cls: type[Exception], builtin: type[Exception], f, *args, match: str | None = None) -> Exception:
    """Call `f(*args)`; it must raise exactly `cls` (not a subclass), a `DiffsoftError` and a
    `builtin`."""
    with pytest.raises(cls, match=match) as info:
        f(*args)
    e = info.value
    assert type(e) is cls, f"{type(e).__name__}: {e}"
    assert isinstance(e, diffsoft.DiffsoftError) and isinstance(e, builtin)
    return e


def test_hierarchy_and_exports():
    for cls, (bases, builtin) in CLASSES.items():
        assert cls.__bases__ == bases, cls
        assert issubclass(cls, builtin) and issubclass(cls, Exception)
        assert cls.__name__ in diffsoft.__all__ and getattr(diffsoft, cls.__name__) is cls
        assert cls.__module__ == "diffsoft" and cls.__doc__
    assert {n for n in diffsoft.__all__ if n.endswith("Error")} == {c.__name__ for c in CLASSES}


def test_errors_pickle_and_keep_their_message(tmp_path):
    e = raised(diffsoft.FileError, OSError, diffsoft.Scene.load, tmp_path / "nope.json")
    again = pickle.loads(pickle.dumps(e))
    assert type(again) is diffsoft.FileError and str(again) == str(e)
    assert "nope.json" in str(e)


def test_missing_files_are_file_errors(tmp_path):
    raised(diffsoft.FileError, OSError, diffsoft.Scene.load, tmp_path / "nope.json", match="nope.json")
    raised(diffsoft.FileError, OSError, diffsoft.bounds, tmp_path / "missing.obj", 1.0, 1.0, 0.01, match="missing.obj")


def test_initial_positions_set_from_python_get_the_scenes_start_checks(ground):
    """Positions given with ``set('initial_positions')`` are checked like a scene file's own
    start: a box pushed 5 m into the ground is an ``InputError`` naming the positions and the
    obstacle (it was run, and the first steps launched the box at hundreds of m/s); lifted
    clear of the ground it runs."""
    q = np.asarray(ground.get("initial_positions"))
    ground.set("initial_positions", q - [0.0, 5.0, 0.0])
    for run in (lambda: ground.simulate(2), lambda: ground.grad(2, "final_com.y", ["youngs_modulus"])):
        raised(diffsoft.InputError, ValueError, run, match="initial positions given.*inside obstacle")
    ground.set("initial_positions", q + [0.0, 0.5, 0.0])
    assert np.isfinite(np.asarray(ground.simulate(2).positions)).all()


def test_bad_input_is_input_error(beam, tmp_path):
    raised(diffsoft.InputError, ValueError, beam.set, "youngs", 1.0, match="unknown parameter 'youngs'")
    raised(diffsoft.InputError, ValueError, beam.grad, 3, "final_com.y", ["youngs"], match="unknown parameter")
    raised(diffsoft.InputError, ValueError, beam.grad, 3, "energy", match="unknown loss")
    raised(diffsoft.InputError, ValueError, beam.grad, 3, "final_com.y", None, "exact", match="mode 'exact'")
    raised(diffsoft.InputError, ValueError, lambda: beam.configure(tolerence=1e-3), match="unknown setting")
    raised(diffsoft.InputError, ValueError, beam.set, "initial_positions", np.zeros((20, 2)), match="shape")
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "schema": "diffsoft.scene/1",\n  "time_step": 0.01,\n  "bodies": [ { "name": 3 } ]\n}\n')
    raised(diffsoft.InputError, ValueError, diffsoft.Scene.load, bad, match="line 4")
    raised(diffsoft.InputError, ValueError, diffsoft.bounds, DATA / "beam.obj", -1.0, 1e4, 0.01, match="rho")
    raised(
        diffsoft.InputError,
        ValueError,
        diffsoft.simulate_batch,
        beam,
        3,
        [{"density": 1.0}, {"dens": 1.0}],
        match=r"^values\[1\]: unknown parameter 'dens'",
    )


def test_counts_are_named_when_refused(beam):
    # A count that is not an int is a TypeError, one below 1 or past a machine word an
    # InputError; either names the argument and the value it got. NumPy integers count.
    for bad, cls, words in [
        (-1, diffsoft.InputError, "steps must be at least 1, got -1"),
        (0, diffsoft.InputError, "steps must be at least 1, got 0"),
        (2**64, diffsoft.InputError, "steps must be at most 18446744073709551615"),
        (1.5, TypeError, "steps must be an int, got float 1.5"),
        ("3", TypeError, "steps must be an int, got str '3'"),
        (None, TypeError, "steps must be an int, got NoneType None"),
        (True, TypeError, "steps must be an int, got bool True"),
    ]:
        for call, args in (
            (beam.simulate, (bad,)),
            (beam.grad, (bad,)),
            (diffsoft.simulate_batch, (beam, bad, [{}])),
            (diffsoft.grad_batch, (beam, bad, "final_com.y", ["density"], [{}])),
        ):
            with pytest.raises(cls) as e:
                call(*args)
            assert words in str(e.value), (bad, str(e.value))
    with pytest.raises(diffsoft.InputError, match="iterations must be at least 1, got 0"):
        diffsoft.gradcheck(beam, 2, iterations=0)
    assert len(beam.simulate(np.int64(2)).positions) == 3


def test_lists_are_named_when_refused(beam):
    # A str where a list of names belongs would read as its letters; a list of dicts holding
    # something else names the item.
    hint = "params must be a list of names, got str 'density' (for one name, write ['density'])"
    for call, args in (
        (beam.grad, (2, "final_com.y", "density")),
        (diffsoft.grad_batch, (beam, 2, "final_com.y", "density", [{}])),
        (diffsoft.gradcheck, (beam, 2, "final_com.y", "density")),
    ):
        with pytest.raises(TypeError) as e:
            call(*args)
        assert hint in str(e.value)
    with pytest.raises(TypeError, match=r"params\[0\] must be a str, got int 3"):
        beam.grad(2, "final_com.y", [3])
    with pytest.raises(TypeError, match=r"values\[1\] must be a dict, got NoneType None"):
        diffsoft.simulate_batch(beam, 1, [{}, None])
    with pytest.raises(TypeError, match="values must be a list of dicts, got NoneType None"):
        diffsoft.grad_batch(beam, 1, "final_com.y", ["density"], None)
    with pytest.raises(TypeError, match=r"values\[0\] must be a dict, got int 3"):
        diffsoft.vjp_batch(beam, 1, ["density"], [3], [np.zeros((2, beam.n_vertices, 3))])
    # Tuples are lists too.
    assert len(diffsoft.simulate_batch(beam, 1, ({}, {}))) == 2


def test_input_refused_when_a_run_starts(beam):
    # A negative tolerance: refused by `configure` (settings are checked by name there) or, were
    # it let through, when the run starts; an InputError either way.
    def negative_tolerance():
        beam.configure(tolerance=-1.0)
        beam.simulate(2)

    raised(diffsoft.InputError, ValueError, negative_tolerance, match="tolerance")
    # Checked by the library when the rollout starts: its trajectory cannot fit in memory (an
    # OutOfMemoryError, which is also an InputError and a ValueError).
    e = raised(diffsoft.OutOfMemoryError, MemoryError, beam.simulate, 10**15, match="memory")
    assert isinstance(e, diffsoft.InputError) and isinstance(e, ValueError)


def test_unsupported_features(ground, tmp_path):
    # Unrolled gradients differentiate local-global iterations: not Newton's.
    ground.configure(solver="newton", tolerance=1e-12, max_iterations=200)
    raised(diffsoft.UnsupportedError, ValueError, ground.grad, 3, "final_com.x", None, "unrolled", match="Newton")
    stl = tmp_path / "part.stl"
    stl.write_text("solid part\nendsolid part\n")
    raised(
        diffsoft.UnsupportedError, ValueError, diffsoft.bounds, stl, 1000.0, 1e4, 0.01, match="unsupported mesh format"
    )


def test_a_time_step_certification_refuses():
    s = diffsoft.Scene.load(BRIDGESUS)
    s.configure(solver="split", certify="refuse")
    raised(diffsoft.UncertifiedError, ValueError, s.simulate, 1, match="certification")


def test_divergence():
    # The split iteration's spectral radius exceeds 1 at bridgesus's time step; without
    # certification it runs and diverges.
    s = diffsoft.Scene.load(BRIDGESUS)
    s.configure(solver="split", certify="off")
    raised(diffsoft.DivergenceError, RuntimeError, s.simulate, 5, match="diverged")


def test_a_non_finite_state_is_divergence(beam):
    beam.set("initial_velocities", np.random.default_rng(0).normal(size=(20, 3)) * 1e200)
    raised(diffsoft.DivergenceError, RuntimeError, beam.simulate, 3, match="non-finite")


def test_an_unconverged_gradient_is_a_convergence_error(beam):
    beam.set("youngs_modulus", 1e20)
    beam.configure(tolerance=1e-6, max_iterations=5)
    raised(diffsoft.ConvergenceError, RuntimeError, beam.grad, 10, "final_com.y", ["density"], match="did not converge")
    cot = np.ones((11, beam.n_vertices, 3))
    raised(diffsoft.ConvergenceError, RuntimeError, beam.vjp, 10, ["density"], cot, match="did not converge")
    raised(
        diffsoft.ConvergenceError,
        RuntimeError,
        diffsoft.grad_batch,
        beam,
        10,
        "final_com.y",
        ["density"],
        [{}],
        match="did not converge",
    )
