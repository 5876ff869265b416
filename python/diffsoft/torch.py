"""PyTorch autograd through diffsoft simulations.

``simulate(scene, steps, params)`` returns the positions of every state as a tensor of shape
``(steps + 1, n, 3)``; it is differentiable with respect to every tensor in ``params`` (any
parameter of ``diffsoft.SCALAR_PARAMETERS`` or ``diffsoft.ARRAY_PARAMETERS``). The backward pass
is diffsoft's own reverse mode (``Scene.vjp``) with the incoming gradient as a cotangent on the
trajectory, so any loss written in PyTorch differentiates through the simulation. It reruns the
forward pass from the parameters (checkpointing: memory is one state per step).

Devices and dtypes: the simulation runs on the CPU in float64 whatever the inputs; the output
comes back on the device of the parameter tensors (all must share one) and in their promoted
floating dtype (float64 when a parameter is float64 or none is a tensor), and the gradients in
each parameter's own device and dtype.

Transforms: ``torch.func.vmap`` maps to ``diffsoft.simulate_batch`` (and the backward to
``diffsoft.vjp_batch``), so ``vmap``, ``jacrev`` and ``vmap(grad(...))`` run their items in
parallel. Second derivatives and forward mode (``jvp``, ``jacfwd``, ``hessian``, double
backward) raise ``NotImplementedError``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ._diffsoft import Scene, scalar_parameters, simulate_batch, vjp_batch
from ._errors import InputError
from ._real import check_range, flag, parameters

_SCALARS = frozenset(scalar_parameters())

__all__ = ["simulate"]

_SECOND = (
    "second derivatives through diffsoft are not implemented (its backward pass is diffsoft's own "
    "reverse mode, not PyTorch operations): take finite differences of first derivatives, and "
    "check those with torch.autograd.gradcheck or diffsoft.gradcheck"
)
_FORWARD_MODE = (
    "forward-mode differentiation (torch.func.jvp, jacfwd, hessian) through diffsoft is not "
    "implemented: use reverse mode (backward, torch.func.vjp, jacrev)"
)


@dataclass(frozen=True)
class _Call:
    """Everything of a call but its tensors (the non-tensor argument of the functions)."""

    scene: Scene
    steps: int
    names: tuple[str, ...]
    mode: str
    with_velocities: bool
    allow_unconverged: bool
    device: torch.device
    dtype: torch.dtype

    def output(self, a: np.ndarray, what: str) -> torch.Tensor:
        return _cast(a, self.dtype, self.device, what)


def _cast(a: np.ndarray, dtype: torch.dtype, device: torch.device, what: str) -> torch.Tensor:
    """``a`` (float64) as a tensor of ``dtype`` on ``device``; ``InputError`` naming ``what``, the
    dtype and the largest magnitude when a finite value lies beyond the dtype's range (it would
    come back as inf)."""
    a = np.ascontiguousarray(a)
    if dtype.is_floating_point and dtype != torch.float64:
        check_range(
            a,
            dtype,
            torch.finfo(dtype).max,
            caller="diffsoft.torch.simulate",
            what=what,
            advice=_range_advice,
        )
    return torch.from_numpy(a).to(device=device, dtype=dtype)


def _range_advice(largest: float) -> str:
    """The dtypes that would hold a magnitude ``largest``: float64 alone past float32's range."""
    if largest <= torch.finfo(torch.float32).max:
        return "pass the parameters as float32 or float64"
    return "pass the parameters as float64"


def _numpy(t: torch.Tensor) -> np.ndarray | float:
    a = t.detach().to(device="cpu", dtype=torch.float64).numpy()
    return float(a) if a.ndim == 0 else a


def _configured(scene: Scene, names: tuple[str, ...], tensors: tuple[torch.Tensor, ...]) -> Scene:
    s = scene.copy()
    # Scalars first, so a per-tet array in the same dict overrides its scalar whatever the
    # dict's order (the forward does not depend on it).
    for name, t in sorted(zip(names, tensors), key=lambda p: p[0] not in _SCALARS):
        s.set(name, _numpy(t))
    return s


def _items(names: tuple[str, ...], tensors: tuple[torch.Tensor, ...], batch: int) -> list[dict[str, Any]]:
    """One parameter dict per item of a batch (every tensor has the batch as its first dim)."""
    return [{n: _numpy(t[k]) for n, t in zip(names, tensors)} for k in range(batch)]


def _rebatched(info: Any, in_dims: tuple[int | None, ...], batch: int | None, tensors: tuple[Any, ...]):
    """The tensors of a vmap level folded into one batch: each gets the level's dim first
    (broadcast where it has none), and an inner batch folds into it. Returns the tensors and
    the new batch size (``None`` entries stay ``None``)."""
    size = info.batch_size
    out: list[Any] = []
    for t, d in zip(tensors, in_dims):
        if t is None:
            out.append(None)
            continue
        t = t.unsqueeze(0).expand(size, *t.shape) if d is None else t.movedim(d, 0)
        if batch is not None:
            t = t.reshape(size * batch, *t.shape[2:])
        out.append(t)
    return tuple(out), size * (batch or 1)


def _unfolded(info: Any, batch: int | None, t: torch.Tensor) -> torch.Tensor:
    return t if batch is None else t.reshape(info.batch_size, batch, *t.shape[1:])


class _Forward(torch.autograd.Function):
    """The trajectory of one parameter set (``batch`` None) or of a batch of them (every tensor
    with the batch as its first dim)."""

    @staticmethod
    def forward(call: _Call, batch: int | None, *tensors: torch.Tensor) -> Any:
        if batch is None:
            run = _configured(call.scene, call.names, tensors).simulate(call.steps)
            q, v = run.positions, run.velocities
        else:
            runs = simulate_batch(call.scene, call.steps, _items(call.names, tensors, batch))
            # An empty batch too: (0, steps + 1, n, 3).
            empty = np.zeros((0, call.steps + 1, call.scene.n_vertices, 3))
            q = np.stack([r.positions for r in runs]) if runs else empty
            v = np.stack([r.velocities for r in runs]) if runs else empty
        if call.with_velocities:
            return call.output(q, "positions"), call.output(v, "velocities")
        return call.output(q, "positions")

    @staticmethod
    def setup_context(ctx: Any, inputs: tuple[Any, ...], output: Any) -> None:
        call, batch, *tensors = inputs
        ctx.call, ctx.batch = call, batch
        ctx.save_for_backward(*tensors)

    @staticmethod
    def backward(ctx: Any, *outs: torch.Tensor) -> Any:
        call: _Call = ctx.call
        tensors = ctx.saved_tensors
        needed = ctx.needs_input_grad[2:]
        if not any(needed):
            return (None, None) + (None,) * len(tensors)
        cq = outs[0]
        cv = outs[1] if call.with_velocities else None
        grads = _Backward.apply(call, ctx.batch, cq, cv, *tensors)
        return (None, None) + tuple(g if n else None for g, n in zip(grads, needed))

    @staticmethod
    def vmap(info: Any, in_dims: tuple[int | None, ...], call: _Call, batch: int | None, *tensors: torch.Tensor):
        folded, size = _rebatched(info, in_dims[2:], batch, tensors)
        out = _Forward.apply(call, size, *folded)
        if call.with_velocities:
            return (_unfolded(info, batch, out[0]), _unfolded(info, batch, out[1])), (0, 0)
        return _unfolded(info, batch, out), 0

    @staticmethod
    def jvp(ctx: Any, *tangents: Any) -> Any:
        raise NotImplementedError(_FORWARD_MODE)


class _Backward(torch.autograd.Function):
    """The gradients of the pairing of cotangents ``cq`` (positions) and ``cv`` (velocities,
    or None) with the trajectory, one per tensor: ``Scene.vjp`` or ``vjp_batch``."""

    @staticmethod
    def forward(
        call: _Call, batch: int | None, cq: torch.Tensor, cv: torch.Tensor | None, *tensors: torch.Tensor
    ) -> Any:
        if batch is None:
            g = _configured(call.scene, call.names, tensors).vjp(
                call.steps,
                params=list(call.names),
                cotangent=_numpy(cq),
                velocity_cotangent=None if cv is None else _numpy(cv),
                mode=call.mode,
                allow_unconverged=call.allow_unconverged,
            )
            values = [np.asarray(g[n]) for n in call.names]
        else:
            gs = vjp_batch(
                call.scene,
                call.steps,
                list(call.names),
                _items(call.names, tensors, batch),
                [_numpy(cq[k]) for k in range(batch)],
                None if cv is None else [_numpy(cv[k]) for k in range(batch)],
                mode=call.mode,
                allow_unconverged=call.allow_unconverged,
            )
            values = [
                np.stack([np.asarray(g[n]) for g in gs]) if gs else np.zeros(t.shape)
                for n, t in zip(call.names, tensors)
            ]
        return tuple(
            _cast(np.asarray(a, dtype=np.float64), t.dtype, t.device, f"gradients of {n}").reshape(t.shape)
            for n, a, t in zip(call.names, values, tensors)
        )

    @staticmethod
    def setup_context(ctx: Any, inputs: tuple[Any, ...], output: Any) -> None:
        pass

    @staticmethod
    def backward(ctx: Any, *grads: Any) -> Any:
        raise NotImplementedError(_SECOND)

    @staticmethod
    def vmap(
        info: Any,
        in_dims: tuple[int | None, ...],
        call: _Call,
        batch: int | None,
        cq: torch.Tensor,
        cv: torch.Tensor | None,
        *tensors: torch.Tensor,
    ):
        folded, size = _rebatched(info, in_dims[2:], batch, (cq, cv, *tensors))
        grads = _Backward.apply(call, size, *folded)
        return tuple(_unfolded(info, batch, g) for g in grads), (0,) * len(grads)

    @staticmethod
    def jvp(ctx: Any, *tangents: Any) -> Any:
        raise NotImplementedError(_SECOND)


def _checked_tensor(name: str, t: torch.Tensor) -> None:
    """Refuse ``t``, naming the parameter, unless its values can be read: a meta tensor has none,
    and sparse and other layouts than strided are not read."""
    if t.is_meta:
        raise InputError(f"{name}: a tensor on the meta device has no values; give one with values")
    if t.layout != torch.strided:
        raise InputError(f"{name}: a tensor of layout {t.layout} is not read; give a dense one (.to_dense())")


def _placement(names: tuple[str, ...], tensors: tuple[torch.Tensor, ...]) -> tuple[torch.device, torch.dtype]:
    """The device and dtype of the output (see the module docs)."""
    devices = {t.device for t in tensors}
    if len(devices) > 1:
        where = ", ".join(f"{n} on {t.device}" for n, t in zip(names, tensors))
        raise InputError(f"diffsoft.torch.simulate: parameters on different devices ({where}); put them on one")
    device = devices.pop() if devices else torch.device("cpu")
    dtype = torch.float64
    floats = [t.dtype for t in tensors if t.is_floating_point()]
    if floats and len(floats) == len(tensors):
        dtype = floats[0]
        for d in floats[1:]:
            dtype = torch.promote_types(dtype, d)
    return device, dtype


def simulate(
    scene: Scene,
    steps: int,
    params: Mapping[str, torch.Tensor | float] | None = None,
    mode: str = "unrolled",
    with_velocities: bool = False,
    allow_unconverged: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    """Positions of every state, ``(steps + 1, n, 3)``, differentiable in ``params``.

    ``params`` maps parameter names to tensors (0-d for scalars, the documented shapes for
    arrays; numbers are float64 tensors); ``scene`` itself is not modified. ``mode`` is
    ``"unrolled"`` (exact for the solver's iterations) or ``"implicit"`` (exact at
    convergence). With ``with_velocities``, returns ``(positions, velocities)``. The output is
    on the parameters' device in their promoted floating dtype (module docs). A forward whose
    steps miss a positive tolerance warns (``ConvergenceWarning``) and its backward raises
    ``ConvergenceError`` unless ``allow_unconverged``.
    """
    if mode not in ("unrolled", "implicit"):
        # Checked before the forward runs, as the JAX wrapper does (its backward would refuse it).
        raise InputError(f"mode '{mode}': expected 'unrolled' or 'implicit'")
    # Checked before the forward runs: the backward is where they are used.
    with_velocities = flag("with_velocities", with_velocities)
    allow_unconverged = flag("allow_unconverged", allow_unconverged)
    params = parameters(params)
    names = tuple(params)
    tensors = tuple(
        v if isinstance(v, torch.Tensor) else torch.as_tensor(v, dtype=torch.float64) for v in params.values()
    )
    device, dtype = _placement(names, tensors)
    for n, t in zip(names, tensors):
        _checked_tensor(n, t)
    call = _Call(scene, steps, names, mode, with_velocities, allow_unconverged, device, dtype)
    return _Forward.apply(call, None, *tensors)
