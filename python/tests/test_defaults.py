"""Honest defaults: warnings at the caller's line (once per call site), ``allow_unconverged`` in
the wrappers, eager ``configure`` checks, outputs on the inputs' device and dtype, and a scene
shared by threads."""

from __future__ import annotations

import copy
import inspect
import pickle
import sys
import threading
import time
import warnings

import numpy as np
import pytest

import diffsoft
from conftest import REPO, central

torch = pytest.importorskip("torch")
jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402


def _line() -> int:
    """The caller's line number (``_line() + 1``: the next line's)."""
    frame = inspect.currentframe()
    assert frame is not None and frame.f_back is not None
    return frame.f_back.f_lineno


@pytest.fixture
def loose(beam):
    """The beam with a tolerance its few iterations cannot meet: every step is unconverged."""
    s = beam.copy()
    s.set("youngs_modulus", 1e20)
    s.configure(tolerance=1e-6, max_iterations=5)
    return s


def test_an_unconverged_simulation_warns_once_per_call_site_at_the_callers_line(loose, beam):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        for _ in range(3):
            line = _line() + 1
            loose.simulate(3)
        other = _line() + 1
        loose.simulate(3)
    got = [(w.category, w.filename, w.lineno) for w in caught]
    assert got == [(diffsoft.ConvergenceWarning, __file__, line), (diffsoft.ConvergenceWarning, __file__, other)]
    assert "unconverged_steps" in str(caught[0].message)
    # A run that converges, or a fixed iteration count (tolerance 0), does not warn.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        beam.simulate(3)
        diffsoft.simulate_batch(beam, 3, [{}, {}])
    with pytest.warns(diffsoft.ConvergenceWarning):
        diffsoft.simulate_batch(loose, 3, [{}, {}])


def test_the_wrappers_warn_at_the_callers_line(loose, ground):
    e = torch.tensor(1e20, dtype=torch.float64)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = _line() + 1
        diffsoft.torch.simulate(loose, 3, {"youngs_modulus": e})
        jline = _line() + 1
        diffsoft.jax.simulate(loose, 3, {"youngs_modulus": jnp.asarray(1e20)})
        vline = _line() + 1
        jax.jit(jax.vmap(lambda x: diffsoft.jax.simulate(loose, 3, {"youngs_modulus": x})))(jnp.asarray([1e20, 2e20]))
    # The batch's run at E = 2e20 also makes energy in a capped step: named too, at the same line.
    gained = [w for w in caught if "raised the total energy" in str(w.message)]
    assert [(w.category, w.filename, w.lineno) for w in gained] == [(diffsoft.ConvergenceWarning, __file__, vline)]
    assert [(w.category, w.filename, w.lineno) for w in caught if w not in gained] == [
        (diffsoft.ConvergenceWarning, __file__, line),
        (diffsoft.ConvergenceWarning, __file__, jline),
        (diffsoft.ConvergenceWarning, __file__, vline),
    ]

    # Unrolled mode through steps that converged in one iteration: the backward's warning points
    # at the user's backward() and is shown once for a loop under the default filter.
    ground.configure(tolerance=1e-10, max_iterations=2000)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        for _ in range(2):
            x = torch.tensor(ground.get("youngs_modulus"), dtype=torch.float64, requires_grad=True)
            q = diffsoft.torch.simulate(ground, 5, {"youngs_modulus": x})
            line = _line() + 1
            q[-1, :, 1].sum().backward()
    first = [w for w in caught if "first iteration" in str(w.message)]
    assert [(w.filename, w.lineno) for w in first] == [(__file__, line)]


def test_the_wrappers_take_allow_unconverged(loose):
    e = torch.tensor(1e20, dtype=torch.float64, requires_grad=True)
    with pytest.warns(diffsoft.ConvergenceWarning):
        q = diffsoft.torch.simulate(loose, 3, {"youngs_modulus": e})
    with pytest.raises(diffsoft.ConvergenceError, match="allow_unconverged"):
        q[-1].sum().backward()
    with pytest.warns(diffsoft.ConvergenceWarning):
        q = diffsoft.torch.simulate(loose, 3, {"youngs_modulus": e}, allow_unconverged=True)
    q[-1].sum().backward()
    assert e.grad is not None and np.isfinite(float(e.grad))

    def f(x, allow):
        return diffsoft.jax.simulate(loose, 3, {"youngs_modulus": x}, allow_unconverged=allow)[-1].sum()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", diffsoft.ConvergenceWarning)
        with pytest.raises(diffsoft.ConvergenceError, match="allow_unconverged"):
            jax.grad(lambda x: f(x, False))(jnp.asarray(1e20))
        g = jax.grad(lambda x: f(x, True))(jnp.asarray(1e20))
    assert np.isfinite(float(g)) and float(g) == pytest.approx(float(e.grad), rel=1e-12)


@pytest.mark.parametrize(
    "setting, value, message",
    [
        ("tolerance", -1.0, "tolerance must be finite and >= 0"),
        ("max_iterations", 0, "max_iterations"),
        ("dt", 0.0, "time step must be finite and positive"),
        ("damping", 1.5, "damping must be in"),
        ("no_such_setting", 1, "unknown setting 'no_such_setting'"),
    ],
)
def test_configure_refuses_bad_settings_at_once(beam, setting, value, message):
    before = beam.settings
    with pytest.raises(diffsoft.InputError, match=message):
        beam.configure(**{setting: value})
    assert beam.settings == before


def test_torch_outputs_follow_the_inputs_dtype_and_device(beam):
    e32 = torch.tensor(2e4, dtype=torch.float32, requires_grad=True)
    q32 = diffsoft.torch.simulate(beam, 3, {"youngs_modulus": e32})
    assert q32.dtype == torch.float32 and q32.device == e32.device
    q32[-1].sum().backward()
    assert e32.grad is not None and e32.grad.dtype == torch.float32
    # The simulation itself is float64: the float32 output is its rounding.
    ref = beam.simulate(3).positions
    np.testing.assert_array_equal(q32.detach().numpy(), ref.astype(np.float32))
    # float64 wins over float32, and numbers and no parameters give float64.
    v0 = torch.tensor(beam.get("initial_velocities"), dtype=torch.float32)
    assert diffsoft.torch.simulate(beam, 3, {"youngs_modulus": 2e4, "initial_velocities": v0}).dtype == torch.float64
    assert diffsoft.torch.simulate(beam, 3).dtype == torch.float64
    with pytest.raises(diffsoft.InputError, match=r"different devices \(youngs_modulus on cpu, density on meta\)"):
        diffsoft.torch.simulate(beam, 3, {"youngs_modulus": e32, "density": torch.empty((), device="meta")})


def test_torch_low_precision_outputs_beyond_their_range_are_refused(beam):
    """A float16 run whose (finite, float64) trajectory passes float16's largest value came back
    as inf, silently: refused, naming the dtype and the magnitude. One within range is the float64
    trajectory rounded, as float32 is."""
    ball = diffsoft.Scene.load(REPO / "verification/scenes/ball_drop.json")
    q0 = torch.tensor(ball.get("initial_positions") + [64000.0, 0, 0], dtype=torch.float16)
    v0 = torch.tensor(ball.get("initial_velocities") + [60000.0, 0, 0], dtype=torch.float16)
    with pytest.raises(
        diffsoft.InputError, match=r"positions reach magnitude .*torch.float16's largest finite value 65504"
    ):
        diffsoft.torch.simulate(ball, 10, {"initial_positions": q0, "initial_velocities": v0})
    e16 = torch.tensor(2e4, dtype=torch.float16)
    q16 = diffsoft.torch.simulate(beam, 3, {"youngs_modulus": e16})
    ref = beam.copy()
    ref.set("youngs_modulus", float(e16))
    np.testing.assert_array_equal(q16.numpy(), ref.simulate(3).positions.astype(np.float16))
    assert q16.shape == (4, beam.n_vertices, 3)


def test_torch_range_advice_names_only_dtypes_that_hold_the_values():
    """The refusal of an output beyond its dtype's range advises the dtypes that would hold it:
    float32 or float64 past float16's range, float64 alone past float32's."""
    torch = pytest.importorskip("torch")
    from diffsoft.torch import _cast

    cpu = torch.device("cpu")
    with pytest.raises(diffsoft.InputError, match=r"pass the parameters as float32 or float64"):
        _cast(np.array([1e5]), torch.float16, cpu, "positions")
    only_float64 = r"float32's largest finite value .*; pass the parameters as float64$"
    with pytest.raises(diffsoft.InputError, match=only_float64):
        _cast(np.array([0.0, 1e39]), torch.float32, cpu, "velocities")
    assert _cast(np.array([1e39]), torch.float64, cpu, "velocities").item() == 1e39


def test_jax_float32_outputs_beyond_their_range_are_refused(beam):
    """Without 64-bit floats the JAX wrapper's results are float32, and a (finite, float64)
    trajectory or gradient past float32's largest value came back as inf, silently: refused as
    the PyTorch wrapper refuses them, naming the dtype and the magnitude, eagerly and under
    ``jit``. One within range is the float64 trajectory rounded."""
    fast = beam.copy()
    # Velocities beyond float32's range over a step so short that the positions stay near the
    # start (the parameter is set on the scene: a float32 input cannot hold it).
    fast.configure(dt=1e-40)
    fast.set("initial_velocity.x", 1e39)
    beyond = r"velocities reach magnitude 1e\+39, beyond float32's largest finite value 3.40282e\+38"
    with jax.enable_x64(False):
        with pytest.raises(diffsoft.InputError, match=beyond):
            diffsoft.jax.simulate(fast, 3, {"youngs_modulus": 2e4}, with_velocities=True)
        jitted = jax.jit(lambda e: diffsoft.jax.simulate(fast, 3, {"youngs_modulus": e}, with_velocities=True))
        with pytest.raises(jax.errors.JaxRuntimeError, match=beyond):
            jitted(jnp.asarray(2e4))
        # A cotangent within range whose gradient is not: every state's positions move with the
        # initial ones, so the gradient sums the cotangents of the four states.
        q0 = jnp.asarray(beam.get("initial_positions"), dtype=jnp.float32)
        q, pullback = jax.vjp(lambda x: diffsoft.jax.simulate(beam, 3, {"initial_positions": x}), q0)
        with pytest.raises(
            diffsoft.InputError, match=r"gradients of initial_positions reach magnitude .* float32's largest finite"
        ):
            pullback(jnp.full(q.shape, 3e38, dtype=jnp.float32))
        q32 = diffsoft.jax.simulate(beam, 3, {"youngs_modulus": 2e4})
    ref = beam.copy()
    ref.set("youngs_modulus", 2e4)
    assert q32.dtype == jnp.float32
    np.testing.assert_array_equal(np.asarray(q32), ref.simulate(3).positions.astype(np.float32))
    # With 64-bit floats the same run comes back whole.
    _, v = diffsoft.jax.simulate(fast, 3, {"youngs_modulus": 2e4}, with_velocities=True)
    assert v.dtype == jnp.float64 and float(jnp.max(jnp.abs(v))) == pytest.approx(1e39)


def test_torch_flags_and_unreadable_tensors_are_refused_before_the_forward(beam):
    """``allow_unconverged`` and ``with_velocities`` of the wrong type ran the whole forward and
    failed in ``backward()`` with pyo3's message; meta and sparse tensors failed inside torch
    without naming the parameter."""
    e = torch.tensor(2e4, dtype=torch.float64, requires_grad=True)
    for flag in ("allow_unconverged", "with_velocities"):
        for wrapper in (diffsoft.torch.simulate, diffsoft.jax.simulate):
            with pytest.raises(TypeError, match=rf"{flag} must be a bool, got str 'no'"):
                wrapper(beam, 3, {"youngs_modulus": 2e4}, **{flag: "no"})
    assert diffsoft.torch.simulate(beam, 3, {"youngs_modulus": e}, allow_unconverged=np.bool_(True)).shape[0] == 4
    with pytest.raises(diffsoft.InputError, match="youngs_modulus: a tensor on the meta device"):
        diffsoft.torch.simulate(beam, 3, {"youngs_modulus": torch.tensor(2e4, device="meta")})
    v0 = torch.tensor(beam.get("initial_velocities")).to_sparse()
    with pytest.raises(diffsoft.InputError, match="initial_velocities: a tensor of layout torch.sparse_coo"):
        diffsoft.torch.simulate(beam, 3, {"initial_velocities": v0})


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_torch_outputs_come_back_on_the_cuda_device(beam):
    e = torch.tensor(2e4, dtype=torch.float64, device="cuda", requires_grad=True)
    q = diffsoft.torch.simulate(beam, 3, {"youngs_modulus": e})
    assert q.device == e.device
    target = torch.zeros_like(q)
    ((q - target) ** 2).sum().backward()
    assert e.grad is not None and e.grad.device == e.device


def test_a_scene_shared_by_two_threads_serialises(beam):
    """``simulate`` runs on a copy: another thread's ``set`` during the run changes the scene,
    not the run, whose result is that of the value before or after the change."""
    steps = 1000
    old, new = beam.copy(), beam.copy()
    new.set("youngs_modulus", 3e4)
    results = {}
    thread = threading.Thread(target=lambda: results.setdefault("run", beam.simulate(steps)))
    thread.start()
    time.sleep(0.02)
    beam.set("youngs_modulus", 3e4)  # no "Already borrowed"
    thread.join()
    final = results["run"].positions[-1]
    refs = [old.simulate(steps).positions[-1], new.simulate(steps).positions[-1]]
    assert sum(np.array_equal(final, r) for r in refs) == 1
    assert beam.get("youngs_modulus") == 3e4


def test_setting_a_scene_that_a_batch_reads_raises_the_named_error(beam):
    """A batch reads the caller's scene on another thread: ``set`` and ``configure`` raise
    ``SceneBusyError`` (a ``RuntimeError``) until it returns, and change nothing."""
    done = threading.Event()
    thread = threading.Thread(target=lambda: (diffsoft.simulate_batch(beam, 5000, [{}]), done.set()))
    thread.start()
    busy = []
    while not done.is_set() and not busy:
        try:
            beam.configure(max_iterations=15)
        except diffsoft.SceneBusyError as e:
            busy.append(e)
    with pytest.raises(RuntimeError, match="in use by a call running on another thread"):
        if busy:
            raise busy[0]
    while not done.is_set():
        with pytest.raises(diffsoft.SceneBusyError, match=r"Scene.set: "):
            beam.set("youngs_modulus", 5e4)
        break
    thread.join()
    assert beam.get("youngs_modulus") == 2e4
    beam.set("youngs_modulus", 5e4)
    assert beam.get("youngs_modulus") == 5e4


def _ball_thrown_at(speed: float) -> diffsoft.Scene:
    """The ball on the pinned cloth with its scene velocity (1 m/s down) scaled by ``speed``."""
    scene = diffsoft.Scene.load(REPO / "verification/scenes/ball_on_cloth.json")
    scene.set("initial_velocities", speed * np.asarray(scene.get("initial_velocities")))
    return scene


def test_bodies_passing_through_each_other_warn_and_refuse_gradients():
    """The ball thrown at the cloth at 1000 m/s is held by rounds past ``contact_rounds`` while
    the surfaces cross (``crossing_rounds``); with those switched off it crosses the cloth
    within a step: the run says so (a ``UserWarning`` at the caller's line,
    ``pair_crossings`` in the step log) and a gradient through it is refused; batches warn
    too."""
    scene = _ball_thrown_at(1000.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the ball folds through itself on impact
        held = scene.simulate(4)
    assert all(s["pair_crossings"] == 0 for s in held.stats["steps"])
    assert any(s["contact_rounds"] > 4 for s in held.stats["steps"])
    scene.configure(crossing_rounds=0)
    with pytest.warns(UserWarning, match="passing through each other") as caught:
        line = _line() + 1
        run = scene.simulate(4)
    assert caught[0].lineno == line and caught[0].filename == __file__
    assert any(s["pair_crossings"] > 0 for s in run.stats["steps"])
    assert run.stats["summary"]["steps_with_pair_crossings"] > 0
    with pytest.raises(diffsoft.SimulationError, match="passing through each other"):
        scene.grad(4, "final_com.y", ["youngs_modulus"])
    with pytest.warns(UserWarning, match="passing through each other"):
        diffsoft.simulate_batch(scene, 4, [{}])
    # At the scene's own speed nothing crosses and nothing is said.
    calm = diffsoft.Scene.load(REPO / "verification/scenes/ball_on_cloth.json")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = calm.simulate(40)
    assert all(s["pair_crossings"] == 0 for s in run.stats["steps"])
    assert run.stats["summary"]["steps_with_inverted_tets"] == 0
    assert not any("too soft to carry its own weight" in n for n in calm.notes)


def test_contacts_found_by_sweeping_hold_the_bodies_apart_and_refuse_gradients():
    """The ball thrown at the cloth at 30 m/s (15 cm per step): pairs that pass through each
    other within a contact round are found by sweeping its motion and kept apart, so no step
    ends crossed; the step log and summary count the steps that needed them, and a gradient
    through the first such step raises ``SimulationError`` naming it."""
    scene = _ball_thrown_at(30.0)
    run = scene.simulate(60)
    steps = run.stats["steps"]
    swept = [s["step"] for s in steps if s["swept_pairs"] > 0]
    assert swept and all(s["pair_crossings"] == 0 for s in steps)
    assert run.stats["summary"]["steps_with_swept_pairs"] == len(swept)
    assert run.stats["summary"]["steps_with_pair_crossings"] == 0
    with pytest.raises(diffsoft.SimulationError, match=rf"sweeping .*from step {swept[0]} on"):
        scene.grad(swept[0], "final_com.y", ["youngs_modulus"])


def test_a_step_held_by_rounds_past_contact_rounds_keeps_its_gradient():
    """The ball thrown at the cloth at 200 m/s: from the state after 3 steps, the next step
    needs a 5th contact round (its surfaces cross after the 4 ordinary ones; ``crossing_rounds``)
    and no swept pair, so its contacts are all linearised at the step's start and a gradient
    through it is allowed. Converged tightly, its implicit-mode gradient matches central
    differences at two relative steps to the project's rule (``1e-12 + 1e-6 |fd|``; measured
    2e-7), and the unrolled gradient through the step's 792 iterations and 180 contacts between
    bodies agrees with it to 1e-6 (measured 1e-8; about 1.3 s, the contact adjoint's factor kept
    across each contact round, docs/performance.md)."""
    scene = _ball_thrown_at(200.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the ball folds through itself on impact
        run = scene.simulate(3)
    scene.set("initial_positions", np.asarray(run.positions)[-1])
    scene.set("initial_velocities", np.asarray(run.velocities)[-1])
    scene.configure(tolerance=1e-10, max_iterations=500)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        step = scene.simulate(1).stats["steps"][0]
        assert step["contact_rounds"] > 4 and step["swept_pairs"] == 0
        assert step["pair_crossings"] == 0 and step["converged"]
        _, g = scene.grad(1, "final_com.y", ["youngs_modulus"], mode="implicit")
        e = float(scene.get("youngs_modulus"))

        def loss(x: float) -> float:
            scene.set("youngs_modulus", x)
            value, _ = scene.grad(1, "final_com.y", ["youngs_modulus"], mode="implicit")
            return value

        fds = [central(loss, e, h * e) for h in (1e-3, 1e-4)]
        scene.set("youngs_modulus", e)
        _, unrolled = scene.grad(1, "final_com.y", ["youngs_modulus"], mode="unrolled")
    analytic = float(g["youngs_modulus"])
    assert min(abs(analytic - fd) - 1e-6 * abs(fd) for fd in fds) < 1e-12, (analytic, fds)
    assert abs(float(unrolled["youngs_modulus"]) - analytic) <= 1e-6 * abs(analytic), (unrolled, analytic)


def test_a_gradient_through_stalled_contact_solves_follows_the_forwards_truncation():
    """A box dropped at 1.5 m/s on a fixed box without friction: every one of the first three
    steps stops a contact solve stalled, so a gradient needs ``allow_unconverged``. Those steps'
    linearized contact systems are then solved by Gauss-Seidel, whose truncation follows the
    forward's own, and the unrolled gradient stays within 2e-5 of central differences (measured
    1e-6); the exact solution of the fixed point the forward never reached is 2.6e-4 off here
    and of the wrong sign over 12 steps (docs/performance.md, "The contact adjoint by a kept
    LU")."""
    box = diffsoft.mesh.box((2, 2, 2), (0.1, 0.1, 0.1))
    material = {"youngs_modulus": 3e4, "poisson_ratio": 0.3}
    scene = diffsoft.Scene.from_dict(
        {
            "time_step": 0.01,
            "gravity": [0, -9.81, 0],
            "bodies": [
                {
                    "name": "lower",
                    "mesh": box,
                    "material": material,
                    "density": 1000.0,
                    "fixed": {"box": {"min": [-1, -1, -1], "max": [2, 0.001, 2]}},
                },
                {
                    "name": "upper",
                    "mesh": box,
                    "material": material,
                    "density": 1000.0,
                    "translate": [0.01, 0.11, -0.01],
                    "initial_velocity": [0, -1.5, 0],
                },
            ],
            "collisions": {"thickness": 0.001, "friction": 0.0},
            "solver": {"solver": "direct"},
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert all(s["capped_solves"] > 0 for s in scene.simulate(3).stats["steps"])
        with pytest.raises(diffsoft.ConvergenceError):
            scene.grad(3, "final_com.y", ["density"])
        _, g = scene.grad(3, "final_com.y", ["density"], allow_unconverged=True)

        def loss(rho: float) -> float:
            scene.set("density", rho)
            return scene.grad(3, "final_com.y", ["density"], allow_unconverged=True)[0]

        fds = [central(loss, 1000.0, h * 1000.0) for h in (1e-3, 1e-4)]
    analytic = float(g["density"])
    assert min(abs(analytic - fd) for fd in fds) <= 2e-5 * abs(fds[0]), (analytic, fds)


def test_a_body_folded_through_itself_warns():
    """The paper's cloth_ball: its ball (E = 2e-5 Pa) is far too soft to carry itself on the
    cloth, and its tets fold through themselves from step 103 on (the crossings with the cloth
    follow): the run says so with a ``UserWarning`` at the caller's line, and the
    step log and summary count the inverted tets."""
    scene = diffsoft.Scene.load(REPO / "verification/paper/cloth_ball/cloth_ball.json")
    with pytest.warns(UserWarning, match="folded through itself") as caught:
        line = _line() + 1
        run = scene.simulate(110)
    folded = [w for w in caught if "folded through itself" in str(w.message)]
    assert folded[0].lineno == line and folded[0].filename == __file__
    # The warning names the body the notes said was too soft, and Scene.notes says it first.
    assert "body 'ball_tet' too soft to carry its own weight" in str(folded[0].message)
    weight = [n for n in scene.notes if "too soft to carry its own weight" in n]
    assert len(weight) == 1 and weight[0].startswith("body 'ball_tet'") and "3.77e7" in weight[0]
    assert any(n.startswith("body 'ball_tet': the projective material") for n in scene.notes)
    # The notes follow the scene's parameters: at 2 kPa the ball carries itself.
    scene.set("youngs_modulus", 2000.0)
    assert not any("too soft to carry its own weight" in n for n in scene.notes)
    counts = [s["inverted_tets"] for s in run.stats["steps"]]
    assert counts[0] == 0 and 0 < max(counts) <= 80  # of the ball's 80 tets
    assert run.stats["summary"]["steps_with_inverted_tets"] == sum(c > 0 for c in counts)
    assert run.stats["summary"]["max_inverted_tets"] == max(counts)


def test_a_value_whose_conversion_uses_the_scene_being_set(beam):
    """``set`` reads its value before it takes the scene: a value whose ``__float__`` pickles,
    copies, reads or runs the same scene (a logging or caching hook) sees the scene as it was,
    instead of a Rust panic ("Already mutably borrowed") or pyo3's plain ``RuntimeError``."""
    seen = {}

    class Hooked:
        def __float__(self):
            seen["pickled"] = pickle.loads(pickle.dumps(beam)).get("youngs_modulus")
            seen["copied"] = copy.copy(beam).get("youngs_modulus")
            seen["get"] = beam.get("youngs_modulus")
            seen["n"] = beam.n_vertices
            seen["run"] = beam.simulate(1).positions.shape
            return 3e4

    beam.set("youngs_modulus", Hooked())
    assert seen == {"pickled": 2e4, "copied": 2e4, "get": 2e4, "n": beam.n_vertices, "run": (2, beam.n_vertices, 3)}
    assert beam.get("youngs_modulus") == 3e4

    class Reconfiguring(np.ndarray):
        def tolist(self):
            seen["settings"] = beam.settings["max_iterations"]
            seen["pickled again"] = pickle.loads(pickle.dumps(beam)).settings["max_iterations"]
            return 20

    beam.configure(max_iterations=np.array(20).view(Reconfiguring))
    assert seen["settings"] == seen["pickled again"] == 15 and beam.settings["max_iterations"] == 20


def test_readers_of_a_scene_that_another_thread_sets_see_no_borrow_error(beam):
    """One thread sets an array in a loop (numpy lets the interpreter switch threads while the
    value converts), another pickles, reads and runs the scene: nothing raises (pyo3's
    "Already mutably borrowed" ``RuntimeError``, or a panic from pickling, before)."""
    v0 = beam.get("initial_velocities")
    stop = threading.Event()
    errors: list[BaseException] = []

    def setter():
        while not stop.is_set():
            try:
                beam.set("initial_velocities", v0)
            except BaseException as e:  # noqa: BLE001 - every failure is the test's finding
                errors.append(e)

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    thread = threading.Thread(target=setter)
    thread.start()
    try:
        for _ in range(300):
            for call in (
                lambda: beam.simulate(1),
                lambda: beam.get("density"),
                lambda: beam.n_vertices,
                lambda: pickle.dumps(beam),
                lambda: beam.tets,
                lambda: beam.to_dict(),
            ):
                try:
                    call()
                except BaseException as e:  # noqa: BLE001
                    errors.append(e)
    finally:
        stop.set()
        thread.join()
        sys.setswitchinterval(interval)
    assert errors == []
