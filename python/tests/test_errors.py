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


def test_values_numpy_would_quietly_convert_are_refused(beam):
    """None, bools, complex numbers, text, dates and masked entries are refused naming the
    parameter (numpy turned them into NaN, 0/1, the real part, parsed numbers, ticks and
    whatever lay under the mask); numbers of every real dtype still read."""
    n = beam.n_vertices
    masked = np.ma.masked_array(np.zeros((n, 3)))
    masked[0, 1] = np.ma.masked
    bad = {
        "None": None,
        "bools": np.ones((n, 3), dtype=bool),
        "complex numbers": np.zeros((n, 3)) + 1j,
        "text": np.full((n, 3), "1"),
        "dates or times": np.zeros((n, 3), dtype="timedelta64[s]"),
        "entry 4 \\(flat index\\) is None": [[0.0, 0.0, 0.0], [0.0, None, 0.0]] + [[0.0] * 3] * (n - 2),
        "a masked array with 1 masked entries": masked,
    }
    for what, value in bad.items():
        with pytest.raises(diffsoft.InputError, match=f"initial_velocities: .*{what}"):
            beam.set("initial_velocities", value)
    for scalar in (True, np.bool_(True), np.complex128(1e5 + 7e4j), np.array(True)):
        with pytest.raises(diffsoft.InputError, match="youngs_modulus: got"):
            beam.set("youngs_modulus", scalar)
    with pytest.raises(diffsoft.InputError, match="got None"):
        beam.vjp(2, ["density"], None)
    for good in (np.zeros((n, 3), dtype=np.float32), np.zeros((n, 3), dtype=np.int8), [[0] * 3] * n):
        beam.set("initial_velocities", good)
    beam.set("youngs_modulus", np.float32(2e4))
    assert beam.get("youngs_modulus") == 2e4


def test_configure_reads_numpy_numbers_and_names_the_setting(beam):
    beam.configure(tolerance=np.float32(0.5), max_iterations=np.int64(50))
    assert beam.settings["max_iterations"] == 50 and beam.settings["tolerance"] == float(np.float32(0.5))
    with pytest.raises(diffsoft.InputError, match=r"configure\(max_iterations\): integer too large for a double"):
        beam.configure(max_iterations=10**400)
    with pytest.raises(diffsoft.InputError, match="max_iterations"):
        beam.configure(max_iterations=2**64)
    assert beam.settings["max_iterations"] == 50


def test_a_parameter_named_twice_is_refused(beam):
    for call in (
        lambda: beam.grad(2, params=["density", "density"]),
        lambda: diffsoft.grad_batch(beam, 2, "final_com.y", ["density", "youngs_modulus", "density"], [{}]),
    ):
        with pytest.raises(diffsoft.InputError, match=r"params\[\d\]: 'density' is already params\[0\]"):
            call()


def test_an_overflowing_backward_pass_is_refused_naming_it(beam):
    """Cotangents too large for doubles: the adjoint overflows; the error says it is the
    backward pass and what to do (it blamed "a non-finite position" of the forward before), and
    no gradient with infinities comes back."""
    c = np.ones((3, beam.n_vertices, 3))
    for mode, scale in (("implicit", 1e160), ("unrolled", 1e308)):
        with pytest.raises(diffsoft.SimulationError, match="the backward pass overflowed") as e:
            beam.vjp(2, ["density"], c * scale, mode=mode)
        assert "position" not in str(e.value)
    beam.vjp(2, ["density"], c * 1e100, mode="implicit")


def test_a_capped_step_that_makes_energy_is_named():
    """A near-incompressible neo-Hookean box landing on the ground: a step stopped at the cap
    multiplies its energy; the ConvergenceWarning names the step and the energy (the same box
    at nu = 0.3 is capped too, without it)."""

    def box(nu: float) -> diffsoft.Scene:
        material = {"youngs_modulus": 1e5, "poisson_ratio": nu, "model": "neo_hookean"}
        body = {"name": "b", "mesh": diffsoft.mesh.box((2, 2, 2), (0.2, 0.2, 0.2)), "density": 1000}
        body.update(translate=[0, 0.05, 0], initial_velocity=[0, -1, 0], material=material)
        ground = {"name": "ground", "plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}, "friction": 0.3}
        return diffsoft.Scene.from_dict(
            {"time_step": 0.01, "gravity": [0, -9.81, 0], "bodies": [body], "obstacles": [ground]}
        )

    for nu, named in ((0.4999999, True), (0.3, False)):
        with pytest.warns(diffsoft.ConvergenceWarning) as seen:
            box(nu).simulate(30)
        said = [str(w.message) for w in seen]
        assert any("raised the total energy" in m for m in said) == named, said
    # A batch names the first run that made energy (here the second: values[1]).
    with pytest.warns(diffsoft.ConvergenceWarning) as seen:
        diffsoft.simulate_batch(box(0.3), 30, [{}, {"poisson_ratio": 0.4999999}])
    said = [str(w.message) for w in seen if "raised the total energy" in str(w.message)]
    assert len(said) == 1 and "run 1 of the batch (values[1])" in said[0], said


def test_box_cells_and_arguments_are_read_exactly():
    for cells, message in (
        ((2.7, 1, 1), r"cells\[0\] must be an integer, got float 2.7"),
        ((True, 1, 1), r"cells\[0\] must be an integer, got a bool"),
        (("3", 1, 1), r"cells\[0\] must be an integer, got str '3'"),
        ("222", "cells takes three values, got str '222'"),
        ((-1, 1, 1), r"cells\[0\] must be at least 1, got -1"),
        ((1, 1), "cells takes three values, got 2"),
    ):
        with pytest.raises(diffsoft.InputError, match=message):
            diffsoft.mesh.box(cells, (1, 1, 1))
    with pytest.raises(diffsoft.InputError, match=r"origin\[0\] = 1e\+308 lies more than 1e8 box sizes"):
        diffsoft.mesh.box((1, 1, 1), (1, 1, 1), origin=(1e308, 0, 0))
    with pytest.raises(diffsoft.InputError, match=r"size\[1\] must be a real number, got complex"):
        diffsoft.mesh.box((1, 1, 1), (1, 1j, 1))
    assert diffsoft.mesh.box((np.int64(2), 1, 1), (1, 1, 1))["tets"].shape == (12, 4)


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


def test_a_parameter_that_applies_to_nothing_is_refused():
    """A scene with cloth alone has no body: setting or differentiating a body's material or
    density changed nothing and returned a zero derivative (get() already refused)."""
    flag = diffsoft.Scene.load(REPO / "verification/scenes/ball_on_cloth.json").to_dict()
    flag["bodies"] = []
    flag.pop("collisions")
    cloth = diffsoft.Scene.from_dict(flag)
    for name in ("density", "youngs_modulus", "poisson_ratio"):
        with pytest.raises(diffsoft.InputError, match=f"nothing that '{name}' applies to"):
            cloth.set(name, 1000.0 if name != "poisson_ratio" else 0.3)
        with pytest.raises(diffsoft.InputError, match=f"nothing that '{name}' applies to"):
            cloth.grad(2, params=[name])
    _, d = cloth.grad(2, params=["gravity.y"])
    assert d["gravity.y"] != 0.0


def test_per_step_controls_are_checked_when_set_and_their_rows_when_run():
    """`set` checks what it can at once (the range of each activation, torques on coordinates
    of joints that are not one-DoF); a run refuses rows that are not one per step (more were
    dropped without a word, and the gradient came back with fewer rows)."""
    octo = diffsoft.Scene.load(REPO / "verification/paper/octopus/octopus.json")
    groups = len(octo.actuator_groups)
    bad = np.full((2, groups), 0.3)
    bad[1, 3] = 1.5
    with pytest.raises(diffsoft.InputError, match=r"activations\[1, 3\]: actuator '.*': activation 1.5 out of range"):
        octo.set("activations", bad)
    assert octo.get("activations") is None
    baymax = diffsoft.Scene.load(REPO / "verification/scenes/baymax_skeleton.json")
    torques = np.zeros((2, baymax.joint_dofs))
    torques[0, 0] = 1.0
    with pytest.raises(diffsoft.InputError, match=r"torques\[0, 0\]: .*bone 'torso' has a free joint"):
        baymax.set("torques", torques)
    octo.set("activations", np.full((3, groups), 0.3))
    cot = np.zeros((3, octo.n_vertices, 3))
    for run in (
        lambda: octo.simulate(2),
        lambda: octo.grad(2, params=["activations"]),
        lambda: octo.vjp(2, ["activations"], cot),
        lambda: diffsoft.grad_batch(octo, 2, "final_com.y", ["activations"], [{}]),
    ):
        with pytest.raises(diffsoft.InputError, match="activations: 3 rows for a run of 2 steps"):
            run()


def test_runtime_errors_of_a_batch_name_the_item(beam):
    """A run of a batch that fails names its item, keeping its class, with or without an
    executor (input errors did already)."""
    from concurrent.futures import ThreadPoolExecutor

    values = [{}, {"gravity.y": 1e308}]
    cots = [np.zeros((3, beam.n_vertices, 3))] * 2
    with ThreadPoolExecutor(2) as ex:
        for call in (
            lambda: diffsoft.simulate_batch(beam, 2, values),
            lambda: diffsoft.simulate_batch(beam, 2, values, executor=ex),
            lambda: diffsoft.grad_batch(beam, 2, "final_com.y", ["density"], values),
            lambda: diffsoft.grad_batch(beam, 2, "final_com.y", ["density"], values, executor=ex),
            lambda: diffsoft.vjp_batch(beam, 2, ["density"], values, cots),
        ):
            raised(diffsoft.DivergenceError, RuntimeError, call, match=r"^values\[1\]: .*non-finite")


def test_batches_check_their_arguments_before_running_any_item(beam):
    """An empty batch still checks the loss and parameters (it returned []), with an executor
    too; an executor without `submit` is a TypeError naming it (an AttributeError before)."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as ex:
        for executor in (None, ex):
            with pytest.raises(diffsoft.InputError, match="unknown loss 'bogus'"):
                diffsoft.grad_batch(beam, 2, "bogus", ["density"], [], executor=executor)
            with pytest.raises(diffsoft.InputError, match="torques: the scene has no skeleton"):
                diffsoft.grad_batch(beam, 2, "final_com.y", ["torques"], [], executor=executor)
            with pytest.raises(TypeError, match="steps must be an int"):
                diffsoft.simulate_batch(beam, "2", [], executor=executor)
    for call in (
        lambda: diffsoft.grad_batch(beam, 2, "final_com.y", ["density"], [{}], executor=5),
        lambda: diffsoft.simulate_batch(beam, 2, [], executor=5),
    ):
        with pytest.raises(TypeError, match="executor must be a concurrent.futures.Executor .*got int 5"):
            call()


@pytest.mark.parametrize("exc", [KeyboardInterrupt(), MemoryError("out of memory"), ZeroDivisionError("user code")])
def test_an_exception_of_a_values_own_conversion_propagates(exc):
    """Ctrl-C, a MemoryError or a user's error raised while a value converts reaches the caller
    as raised (it became ``InputError: density: expected a number`` or ``TypeError: steps must
    be an int``, so ``except KeyboardInterrupt`` never saw it)."""
    scene = diffsoft.Scene.load(DATA / "beam.json")

    class Scalar:
        def __float__(self):
            raise exc

    class Count:
        def __index__(self):
            raise exc

    class Array:
        def __array__(self, dtype=None, copy=None):
            raise exc

    for call in (
        lambda: scene.set("density", Scalar()),
        lambda: scene.simulate(Count()),
        lambda: scene.set("initial_velocities", Array()),
        lambda: diffsoft.bounds(DATA / "beam.obj", Scalar(), 1e4, 0.01),
    ):
        with pytest.raises(type(exc)) as info:
            call()
        assert info.value is exc
    assert scene.get("density") == diffsoft.Scene.load(DATA / "beam.json").get("density")


def test_a_value_that_is_not_a_number_is_named_with_the_original_as_its_cause():
    scene = diffsoft.Scene.load(DATA / "beam.json")

    class NotNumber:
        def __float__(self):
            raise TypeError("no float here")

        def __index__(self):
            raise ValueError("no int here")

    with pytest.raises(diffsoft.InputError, match="density: expected a number") as info:
        scene.set("density", NotNumber())
    assert isinstance(info.value.__cause__, TypeError) and "no float here" in str(info.value.__cause__)
    with pytest.raises(TypeError, match="steps must be an int") as info:
        scene.simulate(NotNumber())
    assert isinstance(info.value.__cause__, ValueError)
    with pytest.raises(diffsoft.InputError, match="density: expected a number"):
        scene.set("density", 10**400)


def test_a_malformed_pickle_state_is_an_input_error():
    """A state whose entries are not what a pickled scene holds: ``InputError`` naming the entry
    (``SimulationError`` or a bare ``TypeError`` before)."""
    beam = diffsoft.Scene.load(DATA / "beam.json")
    paper = diffsoft.Scene.load(BRIDGESUS)
    cases = [
        (beam, "document", "{not json", "'document' is not JSON"),
        (beam, "document", 3, "'document'"),
        (beam, "settings", "[1, 2]", "'settings' are not solver settings"),
        (beam, "notes", 5, "'notes'"),
        (beam, "sets", 5, "'sets' is not a list"),
        (beam, "sets", [5], "not a \\(name, value\\) pair"),
        (beam, "version", "two", "'version'"),
        (paper, "paper", 5, "'paper' is not a dict"),
    ]
    for scene, key, bad, message in cases:
        state = scene.__reduce__()[1][0]
        state[key] = bad
        with pytest.raises(diffsoft.InputError, match=message):
            diffsoft._diffsoft._scene_from_state(state)
    state = paper.__reduce__()[1][0]
    state["paper"]["files"] = {"x.obj": "text"}
    with pytest.raises(diffsoft.InputError, match=r"'paper.files'\['x.obj'\] is not bytes"):
        diffsoft._diffsoft._scene_from_state(state)


def test_scene_load_takes_a_str_or_a_path_like_and_names_anything_else():
    import os
    import pathlib

    class Where(os.PathLike):
        def __fspath__(self):
            return str(DATA / "beam.json")

    for path in (str(DATA / "beam.json"), pathlib.Path(DATA / "beam.json"), Where()):
        assert diffsoft.Scene.load(path).n_vertices > 0
    for bad in (os.fsencode(DATA / "beam.json"), 3, None):
        with pytest.raises(TypeError, match=r"Scene.load: path must be a str or an os.PathLike .*, got "):
            diffsoft.Scene.load(bad)
