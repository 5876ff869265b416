"""JAX autodiff through diffsoft simulations (``jax.custom_vjp``).

``simulate(scene, steps, params)`` returns the positions of every state, shape
``(steps + 1, n, 3)``, as a JAX array that ``jax.grad``/``jax.vjp`` differentiate with respect
to every entry of ``params`` (any parameter of ``diffsoft.SCALAR_PARAMETERS`` or
``diffsoft.ARRAY_PARAMETERS``). The simulation runs on the host through
``jax.pure_callback``, so it also works under ``jax.jit``. Enable 64-bit floats
(``jax.config.update("jax_enable_x64", True)``) to keep diffsoft's double precision; without
them results are rounded to float32.
"""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from ._diffsoft import Scene, scalar_parameters

_SCALARS = frozenset(scalar_parameters())

__all__ = ["simulate"]


def _configured(scene: Scene, names, values) -> Scene:
    s = scene.copy()
    # Scalars first, so a per-tet array in the same dict overrides its scalar whatever the
    # dict's order (the forward does not depend on it).
    for name, v in sorted(zip(names, values), key=lambda p: p[0] not in _SCALARS):
        a = np.asarray(v, dtype=np.float64)
        s.set(name, float(a) if a.ndim == 0 else a)
    return s


def simulate(
    scene: Scene,
    steps: int,
    params: Mapping[str, jax.Array] | None = None,
    mode: str = "unrolled",
) -> jax.Array:
    """Positions of every state, ``(steps + 1, n, 3)``, differentiable in ``params``.

    ``params`` maps parameter names to arrays (scalars for scalar parameters); ``scene`` itself
    is not modified. ``mode`` is ``"unrolled"`` or ``"implicit"``.
    """
    params = dict(params or {})
    names = tuple(params)
    dtype = jnp.result_type(float)
    out = jax.ShapeDtypeStruct((steps + 1, scene.n_vertices, 3), dtype)

    def forward_host(*values):
        return np.asarray(_configured(scene, names, values).simulate(steps).positions, dtype=dtype)

    def backward_host(cotangent, *values):
        g = _configured(scene, names, values).vjp(
            steps, params=list(names), cotangent=np.asarray(cotangent, dtype=np.float64), mode=mode
        )
        return tuple(np.asarray(g[n], dtype=dtype).reshape(np.shape(v)) for n, v in zip(names, values))

    @jax.custom_vjp
    def run(*values):
        return jax.pure_callback(forward_host, out, *values)

    def run_fwd(*values):
        return run(*values), values

    def run_bwd(values, cotangent):
        specs = tuple(jax.ShapeDtypeStruct(jnp.shape(v), dtype) for v in values)
        return tuple(jax.pure_callback(backward_host, specs, cotangent, *values))

    run.defvjp(run_fwd, run_bwd)
    return run(*(jnp.asarray(params[n], dtype=dtype) for n in names))
