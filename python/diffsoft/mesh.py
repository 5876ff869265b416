"""Meshes for scenes built in code: ``box`` (the library's structured generator) and
``tetrahedralize`` (a closed triangle surface to tets, through the optional ``tetgen`` package:
``pip install "./python[mesh]"`` from a checkout), with the surface checks that make a bad surface an
``InputError`` naming the problem. Both return ``{"vertices": (n, 3), "tets": (m, 4)}``, what a
body's ``mesh`` takes in ``diffsoft.Scene.from_dict``::

    body = {"name": "b", "mesh": diffsoft.mesh.box((4, 1, 1), (0.4, 0.1, 0.1)), ...}
"""

from __future__ import annotations

import operator
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _diffsoft
from ._errors import InputError, UnsupportedError

__all__ = ["box", "check_surface", "tetrahedralize"]

# The most tets ``tetrahedralize`` is asked for through ``max_volume`` (the library's own
# scenes reach 5e4; a bound that needs more than this is a unit slip, not a mesh).
_MAX_TETS = 5e7

# How far above ``max_volume`` a tet of ``tetrahedralize`` may be before the bound counts as
# not met (TetGen's optimisation after refinement leaves a few tets up to ~1.3 times above it).
_VOLUME_SLACK = 2.0


def box(
    cells: Sequence[int],
    size: Sequence[float],
    origin: Sequence[float] = (0.0, 0.0, 0.0),
    split: str = "kuhn",
) -> dict[str, NDArray[Any]]:
    """A box of ``cells[0] x cells[1] x cells[2]`` hexahedral cells with edge lengths ``size``
    and its minimum corner at ``origin``, each cell split into six tets around its diagonal
    (``split="kuhn"``) or five (``"five"``): ``{"vertices": (n, 3) float64, "tets": (m, 4)
    int64}``."""
    c = [_cell_count(x, k) for k, x in enumerate(_three(cells, "cells"))]
    s = [_real(x, f"size[{k}]") for k, x in enumerate(_three(size, "size"))]
    o = [_real(x, f"origin[{k}]") for k, x in enumerate(_three(origin, "origin"))]
    extent = max(abs(x) for x in s) if all(np.isfinite(s)) else 0.0
    far = [k for k in range(3) if not abs(o[k]) <= 1e8 * extent]
    if far and extent > 0:
        raise InputError(
            f"box: origin[{far[0]}] = {o[far[0]]:g} lies more than 1e8 box sizes ({extent:g}) from 0: "
            "the vertices would lose the box's shape in rounding"
        )
    vertices, tets = _diffsoft.mesh_box((c[0], c[1], c[2]), (s[0], s[1], s[2]), (o[0], o[1], o[2]), split)
    return {"vertices": vertices, "tets": tets}


def _three(values: Any, name: str) -> list[Any]:
    """Three values of a box argument, refusing a string (whose characters would be read as
    the values) and any other length."""
    if isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray)):
        raise InputError(f"box: {name} takes three values, got {type(values).__name__} {values!r}")
    out = list(values)
    if len(out) != 3:
        raise InputError(f"box: {name} takes three values, got {len(out)}")
    return out


def _cell_count(x: Any, k: int) -> int:
    """A cell count: an integer (a NumPy one too) of at least 1, never a bool, a float or a
    string (``int()`` would truncate 2.7 to 2 and read ``"3"``)."""
    if isinstance(x, (bool, np.bool_)):
        raise InputError(f"box: cells[{k}] must be an integer, got a bool")
    try:
        n = operator.index(x)
    except TypeError:
        raise InputError(f"box: cells[{k}] must be an integer, got {type(x).__name__} {x!r}") from None
    if n < 1:
        raise InputError(f"box: cells[{k}] must be at least 1, got {n}")
    return n


def _real(x: Any, name: str, function: str = "box") -> float:
    """A real number given to ``function`` as ``name`` (its range is checked by the caller or
    the library): never a bool, a string or a complex number, which ``float()`` would read."""
    if isinstance(x, (bool, np.bool_, str, bytes, complex, np.complexfloating)):
        raise InputError(f"{function}: {name} must be a real number, got {type(x).__name__} {x!r}")
    try:
        return float(x)
    except (TypeError, ValueError):
        raise InputError(f"{function}: {name} must be a real number, got {type(x).__name__} {x!r}") from None


def _surface_arrays(vertices: ArrayLike, faces: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InputError(f"surface vertices: shape {v.shape}, expected (n, 3) with n >= 1")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"surface faces: shape {f.shape}, expected (k, 3) triangles with k >= 1")
    if not np.issubdtype(f.dtype, np.integer):
        raise InputError(f"surface faces: dtype {f.dtype}, expected integer vertex indices")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise InputError(f"surface vertex {bad[0]} is not finite: {v[bad[0]].tolist()}")
    f = f.astype(np.int64)
    out = np.flatnonzero((f < 0).any(axis=1) | (f >= len(v)).any(axis=1))
    if len(out):
        raise InputError(f"surface face {out[0]}: {f[out[0]].tolist()} has an index out of range 0..{len(v)}")
    return v, f


def _segments_hit_triangles(p: NDArray[np.float64], q: NDArray[np.float64], tri: NDArray[np.float64]) -> NDArray[Any]:
    """Whether segment ``p[i]q[i]`` crosses the interior of triangle ``tri[i]`` (``(k, 3, 3)``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _crossings(p, q, tri)


def _crossings(p: NDArray[np.float64], q: NDArray[np.float64], tri: NDArray[np.float64]) -> NDArray[Any]:
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    dp = np.einsum("ij,ij->i", p - a, n)
    dq = np.einsum("ij,ij->i", q - a, n)
    scale = np.linalg.norm(n, axis=1) * np.maximum(np.linalg.norm(q - p, axis=1), 1e-300)
    eps = 1e-12 * scale
    crosses = ((dp > eps) & (dq < -eps)) | ((dp < -eps) & (dq > eps))
    t = dp / (dp - dq)
    x = p + t[:, None] * (q - p)
    s1 = np.einsum("ij,ij->i", np.cross(b - a, x - a), n)
    s2 = np.einsum("ij,ij->i", np.cross(c - b, x - b), n)
    s3 = np.einsum("ij,ij->i", np.cross(a - c, x - c), n)
    inside = ((s1 > 0) & (s2 > 0) & (s3 > 0)) | ((s1 < 0) & (s2 < 0) & (s3 < 0))
    result: NDArray[Any] = crosses & inside
    return result


def _self_intersections(v: NDArray[np.float64], f: NDArray[np.int64], chunk: int = 512) -> tuple[int, int] | None:
    """The first pair of triangles that share no vertex and cross each other, or ``None``."""
    tri = v[f]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    pad = 1e-12 * float(np.ptp(v, axis=0).max() or 1.0)
    for start in range(0, len(f), chunk):
        i = np.arange(start, min(start + chunk, len(f)))
        overlap = ((lo[i, None, :] <= hi[None, :, :] + pad) & (hi[i, None, :] + pad >= lo[None, :, :])).all(axis=2)
        overlap &= np.arange(len(f))[None, :] > i[:, None]
        ii, jj = np.nonzero(overlap)
        ii = i[ii]
        shared = (f[ii][:, :, None] == f[jj][:, None, :]).any(axis=(1, 2))
        ii, jj = ii[~shared], jj[~shared]
        if len(ii) == 0:
            continue
        hit = np.zeros(len(ii), dtype=bool)
        for first, second in ((ii, jj), (jj, ii)):
            for e in range(3):
                p, q = tri[first, e], tri[first, (e + 1) % 3]
                hit |= _segments_hit_triangles(p, q, tri[second])
        if hit.any():
            k = int(np.flatnonzero(hit)[0])
            return int(ii[k]), int(jj[k])
    return None


def check_surface(vertices: ArrayLike, faces: ArrayLike) -> None:
    """Check that ``faces`` (``(k, 3)`` vertex indices) bound a solid: triangles of positive
    area, every edge shared by exactly two triangles (closed, manifold), consistently oriented,
    and no two triangles crossing each other. Raises ``InputError`` naming the first problem."""
    v, f = _surface_arrays(vertices, faces)
    repeated = np.flatnonzero((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2]))
    if len(repeated):
        raise InputError(f"surface face {repeated[0]}: {f[repeated[0]].tolist()} repeats a vertex")
    area2 = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    scale = float(np.ptp(v, axis=0).max() or 1.0)
    flat = np.flatnonzero(area2 <= 1e-14 * scale * scale)
    if len(flat):
        raise InputError(f"surface face {flat[0]}: {f[flat[0]].tolist()} has zero area (degenerate triangle)")
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    undirected = np.sort(directed, axis=1)
    edges, counts = np.unique(undirected, axis=0, return_counts=True)
    if (counts == 1).any():
        e = edges[counts == 1]
        raise InputError(
            f"the surface is open: {len(e)} edges belong to one triangle only, e.g. {e[0].tolist()} "
            "(a solid needs a closed surface)"
        )
    if (counts > 2).any():
        e = edges[counts > 2]
        raise InputError(
            f"the surface is not manifold: {len(e)} edges are shared by more than two triangles, e.g. {e[0].tolist()}"
        )
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    if (dcounts > 1).any():
        raise InputError(
            "the surface is not consistently oriented: neighbouring triangles list a shared edge in the same direction"
        )
    pair = _self_intersections(v, f)
    if pair is not None:
        raise InputError(f"the surface intersects itself: faces {pair[0]} and {pair[1]} cross")


def tetrahedralize(
    vertices: ArrayLike,
    faces: ArrayLike,
    max_volume: float | None = None,
    min_ratio: float = 2.0,
    check: bool = True,
) -> dict[str, NDArray[Any]]:
    """Tets filling the closed triangle surface ``(vertices (n, 3), faces (k, 3))``, with TetGen
    (the ``tetgen`` package, an optional dependency: ``pip install "./python[mesh]"`` from a
    checkout) at quality (radius-edge ratio at most ``min_ratio``) and tets of volume at most
    ``max_volume`` (none by default; the bound steers TetGen's refinement, and its mesh
    optimisation can leave a few tets up to about a third above it; a tet more than twice above
    it raises ``InputError``). The surface is checked first (``check_surface``): open,
    non-manifold, inconsistently oriented or self-intersecting surfaces raise ``InputError``.
    Returns ``{"vertices": (n, 3) float64, "tets": (m, 4) int64}``."""
    v, f = _surface_arrays(vertices, faces)
    if max_volume is not None:
        max_volume = _real(max_volume, "max_volume", "tetrahedralize")
        if not (np.isfinite(max_volume) and max_volume > 0):
            raise InputError(f"tetrahedralize: max_volume must be finite and positive, got {max_volume}")
    min_ratio = _real(min_ratio, "min_ratio", "tetrahedralize")
    if not (np.isfinite(min_ratio) and min_ratio > 1.0):
        raise InputError(f"tetrahedralize: min_ratio must be finite and above 1, got {min_ratio}")
    if check:
        check_surface(v, f)
    if max_volume is not None:
        # The enclosed volume (divergence theorem over the closed surface) over the bound is the
        # fewest tets that can meet it.
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        enclosed = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum())) / 6.0
        if enclosed / max_volume > _MAX_TETS:
            raise InputError(
                f"tetrahedralize: max_volume {max_volume:g} would need at least {enclosed / max_volume:.3g} tets "
                f"for the enclosed volume {enclosed:.6g} (at most {_MAX_TETS:.0e})"
            )
    try:
        import tetgen  # type: ignore[import-not-found, import-untyped, unused-ignore]
    except ImportError as e:
        raise UnsupportedError(
            "tetrahedralize needs the optional 'tetgen' package: "
            'pip install "./python[mesh]" from a diffsoft checkout (or pip install tetgen)'
        ) from e
    t = tetgen.TetGen(v, f.astype(np.int32))
    try:
        nodes, elems, *_ = t.tetrahedralize(
            quality=True,
            minratio=float(min_ratio),
            fixedvolume=max_volume is not None,
            maxvolume=-1.0 if max_volume is None else float(max_volume),
        )
    except RuntimeError as e:
        raise InputError(f"TetGen could not tetrahedralize the surface: {e}") from e
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    elems = np.ascontiguousarray(elems, dtype=np.int64)
    if elems.ndim != 2 or elems.shape[1] != 4 or len(elems) == 0:
        raise InputError(f"TetGen returned no tets (elements of shape {elems.shape})")
    if max_volume is not None:
        p = nodes[elems]
        volumes = np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6.0
        worst = int(np.argmax(volumes))
        # The bound steers TetGen's refinement; its mesh optimisation afterwards moves vertices,
        # and leaves a few tets above it (a box bar at bounds 2e-5 to 1e-6: 4-45 tets, at most
        # 1.26 times the bound). A tet more than twice the bound was not refined to it.
        if volumes[worst] > _VOLUME_SLACK * max_volume:
            raise InputError(
                f"tetrahedralize: TetGen did not meet max_volume {max_volume:g}: tet {worst} has volume "
                f"{volumes[worst]:.6g}, more than {_VOLUME_SLACK:g} times the bound (of {len(elems)} tets)"
            )
    return {"vertices": nodes, "tets": elems}


def _meshio_scene(mesh: Any, scene: Mapping[str, Any] | None, body: Mapping[str, Any] | None) -> dict[str, Any]:
    """The scene dict of ``Scene.from_meshio``: one body whose mesh is ``mesh``'s tets."""
    points = getattr(mesh, "points", None)
    cells = getattr(mesh, "cells", None)
    if points is None or cells is None:
        raise InputError(f"from_meshio: expected a meshio.Mesh (with points and cells), got {type(mesh).__name__}")
    tets = [_tet_block(k, c.data) for k, c in enumerate(cells) if c.type == "tetra"]
    if not tets:
        kinds = sorted({str(c.type) for c in cells})
        hint = " (a surface: diffsoft.mesh.tetrahedralize makes tets of it)" if "triangle" in kinds else ""
        raise InputError(f"from_meshio: the mesh has no 'tetra' cells, only {kinds}{hint}")
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise InputError(f"from_meshio: points of shape {points.shape}, expected (n, 3)")
    if points.shape[1] == 2:
        raise InputError("from_meshio: the mesh is 2D (points of shape (n, 2)); a body needs 3D points")
    b: dict[str, Any] = {"name": "body"}
    b.update(body or {})
    if "mesh" in b:
        raise InputError("from_meshio: the body's mesh is the meshio mesh; do not pass mesh=")
    b["mesh"] = {"vertices": points, "tets": np.concatenate(tets)}
    d: dict[str, Any] = dict(scene or {})
    if "bodies" in d:
        raise InputError("from_meshio: `scene` holds the scene's other keys; the body is in the keyword arguments")
    d["bodies"] = [b]
    return d


def _tet_block(k: int, data: Any) -> NDArray[np.int64]:
    """The vertex indices of the meshio cell block ``cells[k]`` as int64, refusing what the
    cast would change: indices that are not integers (a float 2.7 read as 2) and integers past
    int64 (a uint64 2**64 - 1 read as -1)."""
    a = np.asarray(data)
    if not np.issubdtype(a.dtype, np.integer):
        raise InputError(f"from_meshio: cells[{k}] (tetra): vertex indices of dtype {a.dtype}, expected integers")
    past = np.argwhere(a > np.iinfo(np.int64).max) if a.dtype == np.uint64 else np.zeros((0, a.ndim))
    if len(past):
        at = tuple(int(i) for i in past[0])
        raise InputError(f"from_meshio: cells[{k}] (tetra), entry {at}: vertex index {a[at]} is out of range")
    return a.astype(np.int64)
