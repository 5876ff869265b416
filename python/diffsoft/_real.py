"""Refusing values a framework would quietly turn into real numbers, or refuse without naming
them: ``True`` read as 1, a complex number read as its real part, text parsed as a number,
``None``. The wrappers read their ``params`` with ``parameters``, which calls ``check_real`` on
each value before converting it to a float64 tensor or array (the package's own readers refuse
the same). On the way back, ``check_range`` refuses float64 results that a lower-precision
output dtype would turn into inf."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ._errors import InputError


def check_real(name: str, value: Any) -> None:
    """Raise ``InputError`` naming ``name`` when ``value`` is ``None``, text, a bool or complex
    (a Python, NumPy, PyTorch or JAX scalar or array of either)."""
    if value is None or isinstance(value, (bool, complex, str, bytes)):
        raise InputError(f"{name}: got {type(value).__name__} {value!r}, expected real numbers")
    dtype = getattr(value, "dtype", None)
    if getattr(dtype, "kind", "") in ("U", "S"):
        raise InputError(f"{name}: got text (dtype {dtype}), expected real numbers")
    dtype = str(dtype or "")
    if dtype.endswith("bool") or "complex" in dtype:
        raise InputError(f"{name}: got values of dtype {dtype}, expected real numbers")


def parameters(params: Mapping[str, Any] | None) -> dict[str, Any]:
    """The wrappers' ``params`` as a dict, each value checked by ``check_real``; anything but a
    mapping (or ``None``) is a ``TypeError`` naming the argument."""
    if params is None:
        return {}
    if not isinstance(params, Mapping):
        raise TypeError(f"params must be a dict of parameter names to values, got {type(params).__name__} {params!r}")
    out = dict(params)
    for name, value in out.items():
        check_real(name, value)
    return out


def flag(name: str, value: Any) -> bool:
    """A bool argument of the wrappers (``with_velocities``, ``allow_unconverged``), refused with a
    ``TypeError`` naming it before anything runs (the backward pass, where it is used, would be
    the first to notice)."""
    numpy_bool = type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")
    if not (isinstance(value, bool) or numpy_bool):
        raise TypeError(f"{name} must be a bool, got {type(value).__name__} {value!r}")
    return bool(value)


def check_range(
    a: np.ndarray, dtype: Any, limit: float, *, caller: str, what: str, advice: str | Callable[[float], str]
) -> None:
    """Raise ``InputError`` when a value of ``a`` (the float64 results) lies beyond ``limit``, the
    largest finite value of ``dtype``, the output dtype: naming the caller, ``what`` the values
    are (``positions``, ``gradients of density``), the dtype, the largest magnitude and the
    ``advice`` (text, or a function of the largest magnitude that gives it). Cast to ``dtype``
    they would come back as inf, silently."""
    if not a.size:
        return
    largest = float(np.max(np.abs(a)))
    if largest > limit:
        text = advice(largest) if callable(advice) else advice
        raise InputError(
            f"{caller}: the {what} reach magnitude {largest:.6g}, beyond {dtype}'s largest finite value "
            f"{limit:.6g} (they would come back as inf); {text}"
        )
