"""Scenes across processes: a forked ``multiprocessing.Pool`` (rayon's pool does not survive
``fork``; the package builds the child its own), and the batches' ``executor=`` with a
``ProcessPoolExecutor`` and a Dask ``LocalCluster``: every result equals the in-process one."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
import pytest

import diffsoft
from conftest import DATA, REPO

#: Large enough that the solver's loops run on rayon's pool (a smaller scene runs them
#: serially, and a fork would not show the hang).
BAYMAX = REPO / "verification/scenes/baymax_ground.json"
PARAMS = ["youngs_modulus", "initial_velocities"]
_SCENE: diffsoft.Scene | None = None


def _grad_in_child(e: float) -> tuple[float, dict[str, Any]]:
    assert _SCENE is not None
    s = _SCENE.copy()
    s.set("youngs_modulus", e)
    return s.grad(3, params=PARAMS, allow_unconverged=True)


def same_grads(a: list[tuple[float, dict[str, Any]]], b: list[tuple[float, dict[str, Any]]]) -> None:
    assert len(a) == len(b)
    for (la, ga), (lb, gb) in zip(a, b):
        assert la == lb
        assert ga.keys() == gb.keys()
        for k in ga:
            np.testing.assert_array_equal(ga[k], gb[k])


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_forked_pool_computes_the_in_process_gradients():
    global _SCENE
    _SCENE = diffsoft.Scene.load(BAYMAX)
    moduli = [600.0, 800.0, 1000.0, 1200.0]
    # The parent runs the solver first, so rayon's global pool has started before the fork.
    expected = [_grad_in_child(e) for e in moduli]
    with multiprocessing.get_context("fork").Pool(2) as pool:
        # A hang is a failure after 120 s, not a stuck test run.
        got = pool.map_async(_grad_in_child, moduli).get(timeout=120)
    same_grads(expected, got)


def spawned(workers: int) -> ProcessPoolExecutor:
    """Workers started fresh (nothing inherited: the scene arrives only as its pickle; and no
    fork of a process that other tests filled with JAX's threads)."""
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def beam_values() -> list[dict[str, Any]]:
    return [{"youngs_modulus": e, "initial_velocity.y": 0.1 * k} for k, e in enumerate([1e4, 2e4, 3e4])]


def test_grad_batch_and_simulate_batch_on_a_process_pool():
    scene = diffsoft.Scene.load(DATA / "beam.json")
    scene.configure(tolerance=0.0, max_iterations=15)
    values = beam_values()
    expected = diffsoft.grad_batch(scene, 10, "final_com.y", PARAMS, values)
    with spawned(2) as ex:
        got = diffsoft.grad_batch(scene, 10, "final_com.y", PARAMS, values, executor=ex)
        runs = diffsoft.simulate_batch(scene, 10, values, executor=ex)
        bad = [values[0], {"youngs_modulus": -1.0}]
        with pytest.raises(diffsoft.InputError, match=r"^values\[1\]: "):
            diffsoft.grad_batch(scene, 10, "final_com.y", PARAMS, bad, executor=ex)
    same_grads(expected, got)
    for a, b in zip(diffsoft.simulate_batch(scene, 10, values), runs):
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.velocities, b.velocities)
        assert [k["iterations"] for k in a.stats["steps"]] == [k["iterations"] for k in b.stats["steps"]]


def test_warnings_of_workers_reach_the_caller():
    # The ball on the cloth meets its tolerance in one iteration on some steps: a warning.
    scene = diffsoft.Scene.load(REPO / "verification/scenes/ball_on_cloth.json")
    with pytest.warns(UserWarning, match="first iteration") as expected:
        diffsoft.grad_batch(scene, 3, "final_com.y", ["density"], [{}])
    with spawned(1) as ex, pytest.warns(UserWarning, match="first iteration") as got:
        diffsoft.grad_batch(scene, 3, "final_com.y", ["density"], [{}], executor=ex)

    def ours(caught: Any) -> list[str]:
        return [str(w.message) for w in caught if w.category is UserWarning]

    assert ours(expected) == ours(got) and len(ours(got)) >= 1


def test_grad_batch_on_a_dask_local_cluster():
    import distributed

    scene = diffsoft.Scene.load(DATA / "beam.json")
    scene.configure(tolerance=0.0, max_iterations=15)
    values = beam_values()
    expected = diffsoft.grad_batch(scene, 10, "final_com.y", PARAMS, values)
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        ex = client.get_executor()
        got = diffsoft.grad_batch(scene, 10, "final_com.y", PARAMS, values, executor=ex)
        runs = diffsoft.simulate_batch(scene, 10, values, executor=ex)
    same_grads(expected, got)
    for a, b in zip(diffsoft.simulate_batch(scene, 10, values), runs):
        np.testing.assert_array_equal(a.positions, b.positions)
