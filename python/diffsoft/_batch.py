"""``grad_batch`` and ``simulate_batch`` with ``executor=``: items spread over any
``concurrent.futures.Executor`` (a ``ProcessPoolExecutor``, Dask's ``Client.get_executor()``,
...), each running in a worker on the pickled scene; without one, the native in-process pool.
Warnings a worker raises are raised again in the caller, errors carry the item's index."""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import Executor
from typing import Any

from . import _diffsoft
from ._diffsoft import Run, Scene

__all__ = ["grad_batch", "simulate_batch"]

_ITEM = re.compile(r"^values\[0\]: ")


def _caught(call: Any) -> tuple[Any, list[tuple[str, type[Warning]]]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = call()
    return out, [(str(w.message), w.category) for w in caught]


def _grad_item(
    scene: Scene, steps: int, loss: str, params: list[str], values: dict[str, Any], mode: str, allow_unconverged: bool
) -> tuple[tuple[float, dict[str, Any]], list[tuple[str, type[Warning]]]]:
    """One item of ``grad_batch`` in a worker."""
    out, caught = _caught(
        lambda: _diffsoft.grad_batch(scene, steps, loss, params, [values], mode, allow_unconverged)[0]
    )
    return out, caught


def _simulate_item(scene: Scene, steps: int, values: dict[str, Any]) -> tuple[Run, list[tuple[str, type[Warning]]]]:
    """One item of ``simulate_batch`` in a worker."""
    out, caught = _caught(lambda: _diffsoft.simulate_batch(scene, steps, [values])[0])
    return out, caught


def _collect(futures: Sequence[Any]) -> list[Any]:
    out = []
    for k, f in enumerate(futures):
        try:
            result, caught = f.result()
        except Exception as e:
            # The worker ran one item: name its index in the batch.
            text = str(e)
            if _ITEM.match(text):
                try:
                    renamed = type(e)(_ITEM.sub(f"values[{k}]: ", text))
                except Exception:
                    raise e from None
                raise renamed from e
            raise
        for message, category in caught:
            warnings.warn(message, category, stacklevel=3)
        out.append(result)
    return out


def _dicts(values: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """``values`` as a list of dicts; anything else is refused naming the argument (and the
    item), as the native module's own checks do."""
    if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
        raise TypeError(f"values must be a list of dicts, got {type(values).__name__} {values!r}")
    out = []
    for k, v in enumerate(values):
        if not isinstance(v, Mapping):
            raise TypeError(f"values[{k}] must be a dict, got {type(v).__name__} {v!r}")
        out.append(dict(v))
    return out


def _names(params: Sequence[str]) -> list[str]:
    """``params`` as a list of names: a bare str would otherwise be read as its letters."""
    if isinstance(params, str):
        raise TypeError(f"params must be a list of names, got str {params!r} (for one name, write [{params!r}])")
    return list(params)


def _submitter(executor: Any) -> Any:
    """``executor.submit``, or a ``TypeError`` naming the argument when there is none."""
    submit = getattr(executor, "submit", None)
    if not callable(submit):
        raise TypeError(
            f"executor must be a concurrent.futures.Executor (or None), got {type(executor).__name__} {executor!r}"
        )
    return submit


def grad_batch(
    scene: Scene,
    steps: int,
    loss: str,
    params: Sequence[str],
    values: Sequence[Mapping[str, Any]],
    mode: str = "unrolled",
    allow_unconverged: bool = False,
    executor: Executor | None = None,
) -> list[tuple[float, dict[str, Any]]]:
    """``[(loss, grads)]``, one per dict of ``values`` (each sets parameters on a copy of
    ``scene``). Without ``executor`` the items run in this process, in parallel on all cores;
    with one (any ``concurrent.futures.Executor``) each item is submitted to it with the
    pickled scene, and the results are the same numbers."""
    if executor is None:
        return _diffsoft.grad_batch(scene, steps, loss, _names(params), _dicts(values), mode, allow_unconverged)
    submit, items = _submitter(executor), _dicts(values)
    # Every other argument checked here as the native batch checks it (an empty one runs nothing).
    _diffsoft.grad_batch(scene, steps, loss, _names(params), [], mode, allow_unconverged)
    futures = [submit(_grad_item, scene, steps, loss, _names(params), v, mode, allow_unconverged) for v in items]
    return _collect(futures)


def simulate_batch(
    scene: Scene, steps: int, values: Sequence[Mapping[str, Any]], executor: Executor | None = None
) -> list[Run]:
    """``[Run]``, one per dict of ``values`` (each sets parameters on a copy of ``scene``);
    ``executor`` as in ``grad_batch``."""
    if executor is None:
        return _diffsoft.simulate_batch(scene, steps, _dicts(values))
    submit, items = _submitter(executor), _dicts(values)
    _diffsoft.simulate_batch(scene, steps, [])
    futures = [submit(_simulate_item, scene, steps, v) for v in items]
    return _collect(futures)
