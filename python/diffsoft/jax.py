"""JAX autodiff through diffsoft simulations (``jax.custom_vjp``).

``simulate(scene, steps, params)`` returns the positions of every state, shape
``(steps + 1, n, 3)``, as a JAX array that ``jax.grad``/``jax.vjp``/``jax.jacrev`` differentiate
with respect to every entry of ``params`` (any parameter of ``diffsoft.SCALAR_PARAMETERS`` or
``diffsoft.ARRAY_PARAMETERS``). The simulation runs on the host (CPU, float64) through
``jax.pure_callback``, so it also works under ``jax.jit``; under ``jax.vmap`` the callbacks
receive the whole batch and run ``diffsoft.simulate_batch`` / ``diffsoft.vjp_batch`` (the items
in parallel). Enable 64-bit floats (``jax.config.update("jax_enable_x64", True)``) to keep
diffsoft's double precision; without them results are rounded to float32, and a trajectory or
gradient beyond float32's range raises ``InputError`` naming the dtype and the largest
magnitude instead of coming back as inf.

Errors: parameters, shapes, values and the mode are checked before the callback where their
values are known (outside ``jit``), raising diffsoft's own exceptions; an error inside a
callback is re-raised as diffsoft's exception where JAX runs it at once (outside ``jit``), and
under ``jit`` JAX's ``JaxRuntimeError`` carries its message. Second derivatives and forward mode
(``jax.hessian``, ``jacfwd``, ``grad`` of ``grad``) raise ``NotImplementedError``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Callable

import jax
import jax.numpy as jnp
import numpy as np

from ._diffsoft import Scene, _trajectory_steps, scalar_parameters, simulate_batch, vjp_batch
from ._errors import InputError
from ._real import check_range, flag, parameters

_SCALARS = frozenset(scalar_parameters())

__all__ = ["simulate"]

_SECOND = (
    "second derivatives and forward mode through diffsoft are not implemented (jax.hessian, jacfwd, "
    "jvp, grad of grad: its backward pass is diffsoft's own reverse mode, not JAX operations): use "
    "jax.grad/jacrev, and for second derivatives take finite differences of first derivatives "
    "(check those with diffsoft.gradcheck)"
)


def _configured(scene: Scene, names: tuple[str, ...], values: Any) -> Scene:
    s = scene.copy()
    # Scalars first, so a per-tet array in the same dict overrides its scalar whatever the
    # dict's order (the forward does not depend on it).
    for name, v in sorted(zip(names, values), key=lambda p: p[0] not in _SCALARS):
        a = np.asarray(v, dtype=np.float64)
        s.set(name, float(a) if a.ndim == 0 else a)
    return s


def _validate(scene: Scene, names: tuple[str, ...], values: tuple[Any, ...], mode: str) -> None:
    """Diffsoft's own errors before any callback: the mode, and every parameter set on a copy
    of the scene (its value where known, else the shape of its current value)."""
    if mode not in ("unrolled", "implicit"):
        raise InputError(f"mode '{mode}': expected 'unrolled' or 'implicit'")
    known = [not isinstance(v, jax.core.Tracer) for v in values]
    s = scene.copy()
    for name, v, k in sorted(zip(names, values, known), key=lambda p: p[0] not in _SCALARS):
        if k:
            a = np.asarray(v, dtype=np.float64)
            s.set(name, float(a) if a.ndim == 0 else a)
            continue
        current = s.get(name)  # an unknown name raises here
        if current is not None and np.shape(current) != jnp.shape(v):
            raise InputError(f"{name}: shape {jnp.shape(v)}, expected {np.shape(current)}")


def _leading(arrays: tuple[Any, ...], shapes: tuple[tuple[int, ...], ...]) -> tuple[int, ...]:
    """The batch dims a vmapped callback's arrays have in front of one item's shape."""
    for a, s in zip(arrays, shapes):
        return tuple(np.shape(a)[: np.ndim(a) - len(s)])
    return ()


def _flat(a: Any, shape: tuple[int, ...], count: int) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).reshape(count, *shape)


def _item(a: np.ndarray) -> Any:
    return float(a) if a.ndim == 0 else a


def _output(a: Any, dtype: Any, what: str) -> np.ndarray:
    """``a`` (float64 results) as an array of ``dtype``, JAX's default float type; ``InputError``
    naming ``what``, the dtype and the largest magnitude when a value lies beyond a lower
    precision's range (it would come back as inf), as the PyTorch wrapper does."""
    a = np.asarray(a, dtype=np.float64)
    if np.dtype(dtype) != np.float64:
        check_range(
            a,
            dtype,
            float(jnp.finfo(dtype).max),
            caller="diffsoft.jax.simulate",
            what=what,
            advice='enable 64-bit floats (jax.config.update("jax_enable_x64", True))',
        )
    return np.asarray(a, dtype=dtype)


def simulate(
    scene: Scene,
    steps: int,
    params: Mapping[str, Any] | None = None,
    mode: str = "unrolled",
    with_velocities: bool = False,
    allow_unconverged: bool = False,
) -> Any:
    """Positions of every state, ``(steps + 1, n, 3)``, differentiable in ``params``.

    ``params`` maps parameter names to arrays (scalars for scalar parameters); ``scene`` itself
    is not modified. ``mode`` is ``"unrolled"`` or ``"implicit"``. With ``with_velocities``,
    returns ``(positions, velocities)``. A forward whose steps miss a positive tolerance warns
    (``ConvergenceWarning``) and its gradient raises ``ConvergenceError`` unless
    ``allow_unconverged``.
    """
    with_velocities = flag("with_velocities", with_velocities)
    allow_unconverged = flag("allow_unconverged", allow_unconverged)
    params = parameters(params)
    names = tuple(params)
    dtype = jnp.result_type(float)
    values = tuple(jnp.asarray(params[n], dtype=dtype) for n in names)
    # Read and checked as Scene.simulate does (its type, and the trajectory's memory before JAX
    # allocates it).
    steps = _trajectory_steps(scene, steps)
    _validate(scene, names, values, mode)
    shapes = tuple(tuple(jnp.shape(v)) for v in values)
    traj = (steps + 1, scene.n_vertices, 3)
    spec = jax.ShapeDtypeStruct(traj, dtype)
    out = (spec, spec) if with_velocities else spec
    failures: list[BaseException] = []

    def kept(host: Callable[..., Any]) -> Callable[..., Any]:
        # JAX wraps a callback's exception in an INTERNAL JaxRuntimeError; keep the original
        # to re-raise where the call returns to this module.
        def run_host(*args: Any) -> Any:
            try:
                return host(*args)
            except Exception as e:
                failures.append(e)
                raise

        return run_host

    def items(args: tuple[Any, ...], lead: tuple[int, ...]) -> list[dict[str, Any]]:
        count = math.prod(lead)
        flat = [_flat(a, s, count) for a, s in zip(args, shapes)]
        return [{n: _item(f[k]) for n, f in zip(names, flat)} for k in range(count)]

    def forward_host(*args: Any) -> Any:
        lead = _leading(args, shapes)
        if lead == ():
            run = _configured(scene, names, args).simulate(steps)
            q, v = run.positions, run.velocities
        else:
            runs = simulate_batch(scene, steps, items(args, lead))
            q = np.stack([r.positions for r in runs]).reshape(*lead, *traj)
            v = np.stack([r.velocities for r in runs]).reshape(*lead, *traj)
        if with_velocities:
            return _output(q, dtype, "positions"), _output(v, dtype, "velocities")
        return _output(q, dtype, "positions")

    def backward_host(cq: Any, cv: Any, *args: Any) -> Any:
        lead = _leading((cq,), (traj,))
        if lead == ():
            g = _configured(scene, names, [_flat(a, s, 1)[0] for a, s in zip(args, shapes)]).vjp(
                steps,
                params=list(names),
                cotangent=np.asarray(cq, dtype=np.float64),
                velocity_cotangent=None if cv is None else np.asarray(cv, dtype=np.float64),
                mode=mode,
                allow_unconverged=allow_unconverged,
            )
            return tuple(_output(g[n], dtype, f"gradients of {n}").reshape(s) for n, s in zip(names, shapes))
        count = math.prod(lead)
        # Parameters the vmap did not batch come with the batch broadcast in front.
        wide = tuple(np.broadcast_to(np.asarray(a), (*lead, *s)) for a, s in zip(args, shapes))
        gs = vjp_batch(
            scene,
            steps,
            list(names),
            items(wide, lead),
            list(_flat(cq, traj, count)),
            None if cv is None else list(_flat(cv, traj, count)),
            mode=mode,
            allow_unconverged=allow_unconverged,
        )
        stacked = {n: np.stack([np.asarray(g[n], dtype=np.float64) for g in gs]) for n in names}
        return tuple(_output(stacked[n], dtype, f"gradients of {n}").reshape(*lead, *s) for n, s in zip(names, shapes))

    def call(host: Callable[..., Any], result: Any, *args: Any) -> Any:
        try:
            return jax.pure_callback(kept(host), result, *args, vmap_method="broadcast_all")
        except jax.errors.JaxRuntimeError:
            if failures:
                raise failures[-1] from None
            raise

    @jax.custom_jvp
    def gradients(cq: Any, cv: Any, *vals: Any) -> Any:
        specs = tuple(jax.ShapeDtypeStruct(s, dtype) for s in shapes)
        if cv is None:
            return call(lambda q, *a: backward_host(q, None, *a), specs, cq, *vals)
        return call(backward_host, specs, cq, cv, *vals)

    @gradients.defjvp
    def gradients_jvp(primals: Any, tangents: Any) -> Any:
        raise NotImplementedError(_SECOND)

    @jax.custom_vjp
    def run(*vals: Any) -> Any:
        return call(forward_host, out, *vals)

    def run_fwd(*vals: Any) -> Any:
        return run(*vals), vals

    def run_bwd(vals: Any, cot: Any) -> Any:
        cq, cv = cot if with_velocities else (cot, None)
        return tuple(gradients(cq, cv, *vals))

    run.defvjp(run_fwd, run_bwd)
    try:
        return run(*values)
    except TypeError as e:
        # jax.jvp/jacfwd/hessian of a custom_vjp function.
        if "custom_vjp" in str(e):
            raise NotImplementedError(_SECOND) from e
        raise
