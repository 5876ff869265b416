"""The exceptions of diffsoft (exported from the package: ``diffsoft.InputError``, ...).

Every class derives from ``DiffsoftError`` and from the built-in exception that the package
raised before these classes existed, so ``except ValueError`` / ``OSError`` / ``RuntimeError``
still catch them::

    DiffsoftError(Exception)
    |-- InputError(DiffsoftError, ValueError)
    |   |-- UnsupportedError
    |   |-- UncertifiedError
    |   `-- OutOfMemoryError(InputError, MemoryError)
    |-- FileError(DiffsoftError, OSError)
    |-- SimulationError(DiffsoftError, RuntimeError)
    |   |-- DivergenceError
    |   `-- ConvergenceError
    `-- SceneBusyError(DiffsoftError, RuntimeError)

and one warning, ``ConvergenceWarning(UserWarning)``.

The native module raises them (``python/src/errors.rs`` maps each of the library's error
variants to the most specific class); the message is the library's, naming the file, line,
element, parameter or setting.
"""

from __future__ import annotations

__all__ = [
    "ConvergenceError",
    "ConvergenceWarning",
    "DiffsoftError",
    "DivergenceError",
    "FileError",
    "InputError",
    "OutOfMemoryError",
    "SceneBusyError",
    "SimulationError",
    "UncertifiedError",
    "UnsupportedError",
]


class DiffsoftError(Exception):
    """Base class of every error that diffsoft raises."""


class InputError(DiffsoftError, ValueError):
    """Bad input: an unknown parameter, loss, mode or setting; a value out of range, non-finite
    or of the wrong shape; a malformed scene or mesh file; a run too large for memory; a feature
    a solver does not support (the library reports those as bad input)."""


class UnsupportedError(InputError):
    """A well-formed request for something this version does not do: a feature the backward
    pass does not differentiate (e.g. unrolled mode through Newton's method), a scene feature
    the simulator does not simulate, a mesh format it does not read."""


class UncertifiedError(InputError):
    """The solver's certification refused the time step (``certify="refuse"``, or no global
    solver can run with ``solver="auto"``): the requested iteration would diverge or need more
    inner iterations than its cap. Use a smaller time step, another solver, or
    ``certify="fallback"``."""


class OutOfMemoryError(InputError, MemoryError):
    """An input whose size (steps, vertices, a memory setting) needs more memory than the
    process has: its free memory, address-space limit (``ulimit -v``) or control group's limit,
    checked before anything is allocated, so the interpreter lives on."""


class FileError(DiffsoftError, OSError):
    """A scene or mesh file that cannot be read (missing, unreadable)."""


class SimulationError(DiffsoftError, RuntimeError):
    """A run, gradient or report that failed: a failed factorization, a constraint or actuator
    projection that failed, a trajectory that is not differentiable."""


class DivergenceError(SimulationError):
    """The simulation diverged: a non-finite (NaN or infinite) state, or an iteration whose
    iterates grow without bound."""


class ConvergenceError(SimulationError):
    """A gradient refused because the forward pass did not converge: steps that missed their
    tolerance (pass ``allow_unconverged=True`` to accept them), or an unrolled replay that
    deviates from the forward pass."""


class SceneBusyError(DiffsoftError, RuntimeError):
    """``Scene.set`` or ``Scene.configure`` on a scene that a call running on another thread is
    reading (a batch, ``gradcheck``). ``simulate``, ``grad`` and ``vjp`` run on a copy and never
    cause it; change a copy (``Scene.copy()``) or wait for the call to return."""


class ConvergenceWarning(UserWarning):
    """A simulation whose steps stopped at ``max_iterations`` before meeting the solver's
    tolerance (``Run.stats["unconverged_steps"]`` counts them). Raised at the caller's line,
    once per call site under Python's default filter; a gradient through such a run raises
    ``ConvergenceError`` unless ``allow_unconverged=True``."""


# Shown (tracebacks, reprs) and pickled as `diffsoft.X`, where the package exports them.
for _cls in (
    DiffsoftError,
    InputError,
    UnsupportedError,
    UncertifiedError,
    OutOfMemoryError,
    FileError,
    SimulationError,
    DivergenceError,
    ConvergenceError,
    SceneBusyError,
    ConvergenceWarning,
):
    _cls.__module__ = "diffsoft"
del _cls
