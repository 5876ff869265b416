"""diffsoft: differentiable simulation of soft multi-body systems.

Tetrahedral soft bodies with embedded skeletons, pneumatic and muscle actuators, frictional
contact and cloth, simulated by projective dynamics with implicit Euler (Qiao et al.,
"Differentiable Simulation of Soft Multi-body Systems", NeurIPS 2021), with reverse-mode
gradients (unrolled or implicit) and a verification harness.

Quick start::

    import diffsoft
    scene = diffsoft.Scene.load("verification/paper/bridgesus/bridgesus.json")
    run = scene.simulate(50)                       # run.positions: (51, n, 3)
    loss, grads = scene.grad(50, loss="final_com.y", params=["youngs_modulus"])

PyTorch and JAX: ``diffsoft.torch.simulate`` and ``diffsoft.jax.simulate`` return the
trajectory as a differentiable tensor / array (imported on first use, so neither framework is
needed for the rest of the package).

Parameters are named as on the command line (``diffsoft.SCALAR_PARAMETERS``) plus the arrays of
``diffsoft.ARRAY_PARAMETERS`` (name, shape, meaning); both lists are read from the library's
parameter registry.

Errors: every exception the package raises derives from ``diffsoft.DiffsoftError`` and from the
built-in it stands for, so ``except ValueError`` / ``OSError`` / ``RuntimeError`` still work:

* ``InputError`` (``ValueError``): bad input (an unknown parameter, loss, mode or setting, a
  value out of range or of the wrong shape, a malformed scene or mesh file); its subclasses
  ``UnsupportedError`` (a feature the backward pass, the simulator or the mesh reader does not
  support), ``UncertifiedError`` (a time step the solver's certification refuses) and
  ``OutOfMemoryError`` (also a ``MemoryError``: a run too large for the process's memory,
  refused before anything is allocated);
* ``FileError`` (``OSError``): a scene or mesh file that cannot be read;
* ``SimulationError`` (``RuntimeError``): a run that failed (factorization, projections); its
  subclasses ``DivergenceError`` (divergence, a non-finite state) and ``ConvergenceError`` (a
  gradient refused because the forward pass did not converge or its replay deviates);
* ``SceneBusyError`` (``RuntimeError``): ``set``/``configure`` of a scene that a batch or
  ``gradcheck`` on another thread is reading (``simulate``, ``grad`` and ``vjp`` run on a copy,
  so a scene shared by threads is otherwise safe).

Warnings: ``ConvergenceWarning`` (a ``UserWarning``) when a simulation's steps missed a positive
tolerance, and ``UserWarning``s for gradients of limited accuracy; both at the caller's line.
"""

from __future__ import annotations

import importlib
from typing import Any

from . import _diffsoft
from ._batch import grad_batch, simulate_batch
from ._diffsoft import (
    Run,
    Scene,
    __version__,
    bounds,
    gradcheck,
    jacobians,
    vjp_batch,
)
from ._errors import (
    ConvergenceError,
    ConvergenceWarning,
    DiffsoftError,
    DivergenceError,
    FileError,
    InputError,
    OutOfMemoryError,
    SceneBusyError,
    SimulationError,
    UncertifiedError,
    UnsupportedError,
)

#: Names of the scalar parameters (``Scene.set``/``get``/``grad``), as the CLI's ``--set``
#: (from the library's parameter registry).
SCALAR_PARAMETERS: list[str] = list(_diffsoft.scalar_parameters())
#: ``(name, shape, meaning (unit))`` of the array parameters (from the registry).
ARRAY_PARAMETERS: list[tuple[str, str, str]] = list(_diffsoft.array_parameters())

__all__ = [
    "ARRAY_PARAMETERS",
    "SCALAR_PARAMETERS",
    "ConvergenceError",
    "ConvergenceWarning",
    "DiffsoftError",
    "DivergenceError",
    "FileError",
    "InputError",
    "OutOfMemoryError",
    "Run",
    "Scene",
    "SceneBusyError",
    "SimulationError",
    "UncertifiedError",
    "UnsupportedError",
    "__version__",
    "bounds",
    "grad_batch",
    "gradcheck",
    "jacobians",
    "simulate_batch",
    "vjp_batch",
]


def __getattr__(name: str) -> Any:
    # `diffsoft.torch` and `diffsoft.jax` import their framework only when first used
    # (`diffsoft.mesh`, the mesh helpers, likewise).
    if name in ("torch", "jax", "mesh"):
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'diffsoft' has no attribute '{name}'")
