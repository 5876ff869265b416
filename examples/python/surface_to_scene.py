"""From a surface mesh to an identified material: an STL surface is tetrahedralised, built into a
scene in code, and its Young's modulus recovered from a target sag.

A 0.4 m bar, given as an ASCII STL surface (what CAD tools export: triangles with their own
corners), is read, its corners merged, checked (closed, manifold, oriented, not
self-intersecting) and filled with tets by TetGen (``diffsoft.mesh.tetrahedralize``; needs
``pip install "./python[mesh]"`` from a checkout). The bar is clamped at one end and sags under gravity. A target
is simulated at E = 50 kPa; starting from 200 kPa, Newton's method on log E (the derivative from
``Scene.grad``) recovers E from the bar's final centre-of-mass height.

Run from anywhere:  python examples/python/surface_to_scene.py
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

import diffsoft

STEPS = 30
TRUE_E = 5e4


def write_box_stl(path: Path, size: tuple[float, float, float]) -> None:
    """An ASCII STL of a box (12 triangles, outward normals), as a CAD tool writes one."""
    lx, ly, lz = size
    v = np.array([[x, y, z] for x in (0, lx) for y in (-ly / 2, ly / 2) for z in (-lz / 2, lz / 2)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines = ["solid bar"]
    for a, b, c, d in quads:
        for tri in ((a, b, c), (a, c, d)):
            p = v[list(tri)]
            n = np.cross(p[1] - p[0], p[2] - p[0])
            n /= np.linalg.norm(n)
            lines += [f"facet normal {n[0]:e} {n[1]:e} {n[2]:e}", "outer loop"]
            lines += [f"vertex {x!r} {y!r} {z!r}" for x, y, z in p.tolist()]
            lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid bar", ""]))


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of an ASCII STL, corners shared by several triangles merged."""
    corners = np.array(
        [
            [float(x) for x in line.split()[1:4]]
            for line in path.read_text().splitlines()
            if line.strip().startswith("vertex")
        ]
    )
    vertices, faces = np.unique(corners, axis=0, return_inverse=True)
    return vertices, faces.reshape(-1, 3)


def bar_scene(mesh: dict[str, np.ndarray]) -> diffsoft.Scene:
    return diffsoft.Scene.from_dict(
        {
            "time_step": 0.01,
            "gravity": [0, -9.81, 0],
            "bodies": [
                {
                    "name": "bar",
                    "mesh": mesh,
                    "material": {"youngs_modulus": TRUE_E, "poisson_ratio": 0.3},
                    "density": 1000,
                    "fixed": {"box": {"min": [-1, -1, -1], "max": [1e-9, 1, 1]}},
                }
            ],
            "solver": {"solver": "direct", "tolerance": 0.0, "max_iterations": 20},
        }
    )


def main() -> None:
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        stl = Path(tmp) / "bar.stl"
        write_box_stl(stl, (0.4, 0.1, 0.1))
        vertices, faces = read_stl(stl)
    print(f"surface: {len(vertices)} vertices, {len(faces)} triangles")
    mesh = diffsoft.mesh.tetrahedralize(vertices, faces, max_volume=2e-5)
    scene = bar_scene(mesh)
    print(f"tets: {scene.n_vertices} vertices, {scene.n_tets} tets; surface {len(scene.surface_triangles)} triangles")

    target = scene.simulate(STEPS).positions[-1, :, 1] @ scene.masses / scene.masses.sum()
    print(f"target: final centre of mass y = {target:.6f} m at E = {TRUE_E:.6g} Pa")
    log_e = math.log(4 * TRUE_E)
    print(f"{'iter':>4} {'E (Pa)':>12} {'com y - target (m)':>19}")
    for it in range(1, 21):
        scene.set("youngs_modulus", math.exp(log_e))
        com, grads = scene.grad(STEPS, loss="final_com.y", params=["youngs_modulus"])
        residual = com - target
        print(f"{it:4d} {math.exp(log_e):12.6g} {residual:19.3e}")
        if abs(residual) < 1e-12:
            break
        # Newton's step on log E: d(com)/d(log E) = E d(com)/dE.
        log_e -= residual / (math.exp(log_e) * grads["youngs_modulus"])
    e = math.exp(log_e)
    rel = abs(e - TRUE_E) / TRUE_E
    print(f"recovered E = {e:.8g} Pa (true {TRUE_E:.8g}), relative error {rel:.2e}, {time.perf_counter() - t0:.1f} s")
    if rel > 1e-4:
        raise SystemExit("the identification did not converge")


if __name__ == "__main__":
    main()
