"""PyTorch autograd through diffsoft simulations.

``simulate(scene, steps, params)`` returns the positions of every state as a float64 tensor of
shape ``(steps + 1, n, 3)``; it is differentiable with respect to every tensor in ``params``
(any parameter of ``diffsoft.SCALAR_PARAMETERS`` or ``diffsoft.ARRAY_PARAMETERS``). The
backward pass is diffsoft's own reverse mode (``Scene.vjp``) with the incoming gradient as a
cotangent on the trajectory, so any loss written in PyTorch differentiates through the
simulation. It reruns the forward pass from the parameters (checkpointing: memory is one state
per step).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch

from ._diffsoft import Scene, scalar_parameters

_SCALARS = frozenset(scalar_parameters())

__all__ = ["simulate"]


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


class _Simulate(torch.autograd.Function):
    @staticmethod
    def forward(ctx, scene, steps, names, mode, with_velocities, *tensors):
        s = _configured(scene, names, tensors)
        run = s.simulate(steps)
        ctx.scene, ctx.steps, ctx.names, ctx.mode = s, steps, names, mode
        ctx.with_velocities = with_velocities
        ctx.inputs = [(t.dtype, t.device, t.shape) for t in tensors]
        q = torch.from_numpy(run.positions)
        if with_velocities:
            return q, torch.from_numpy(run.velocities)
        return q

    @staticmethod
    def backward(ctx, *outs):
        cq = outs[0]
        cv = outs[1] if ctx.with_velocities else None
        zeros = (None,) * 5
        if not any(ctx.needs_input_grad[5:]):
            return zeros + (None,) * len(ctx.inputs)
        g = ctx.scene.vjp(
            ctx.steps,
            params=list(ctx.names),
            cotangent=cq.detach().to("cpu", torch.float64).numpy(),
            velocity_cotangent=None if cv is None else cv.detach().to("cpu", torch.float64).numpy(),
            mode=ctx.mode,
        )
        grads: list[torch.Tensor | None] = []
        for name, (dtype, device, shape), needed in zip(ctx.names, ctx.inputs, ctx.needs_input_grad[5:]):
            if not needed:
                grads.append(None)
                continue
            grads.append(torch.as_tensor(np.asarray(g[name]), dtype=dtype, device=device).reshape(shape))
        return zeros + tuple(grads)


def simulate(
    scene: Scene,
    steps: int,
    params: Mapping[str, torch.Tensor] | None = None,
    mode: str = "unrolled",
    with_velocities: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
    """Positions of every state, ``(steps + 1, n, 3)`` float64, differentiable in ``params``.

    ``params`` maps parameter names to tensors (0-d for scalars, the documented shapes for
    arrays); ``scene`` itself is not modified. ``mode`` is ``"unrolled"`` (exact for the
    solver's iterations) or ``"implicit"`` (exact at convergence). With ``with_velocities``,
    returns ``(positions, velocities)``.
    """
    params = dict(params or {})
    names = tuple(params)
    tensors = tuple(torch.as_tensor(params[n]) for n in names)
    return _Simulate.apply(scene, steps, names, mode, with_velocities, *tensors)
