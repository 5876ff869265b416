"""Refusing values a framework would quietly turn into real numbers: ``True`` read as 1, a
complex number read as its real part. The wrappers call ``check_real`` on each parameter before
converting it to a float64 tensor or array (the package's own readers refuse the same)."""

from __future__ import annotations

from typing import Any

from ._errors import InputError


def check_real(name: str, value: Any) -> None:
    """Raise ``InputError`` naming ``name`` when ``value`` is a bool or complex (a Python,
    NumPy, PyTorch or JAX scalar or array of either)."""
    if isinstance(value, (bool, complex)):
        raise InputError(f"{name}: got {type(value).__name__} {value!r}, expected real numbers")
    dtype = str(getattr(value, "dtype", ""))
    if dtype.endswith("bool") or "complex" in dtype:
        raise InputError(f"{name}: got values of dtype {dtype}, expected real numbers")
