#!/usr/bin/env python3
"""Independent reference values for `diffsoft bounds` (numpy/scipy; not run by CI).

Builds random Delaunay tet meshes (not diffsoft's generator), writes each one in a different
format diffsoft reads (OBJ with 0-based `t` lines, TetGen 1-based with comments, Gmsh 2.2 and 4.1
with non-tet elements and unused nodes), and computes, by a separate code path:

* lumped mass rho V / 4 and L = sum mu V A^T A, A = [-P^-T s, P^-T] (seed Eqs. 22-23);
* h*_19 = 1 / sqrt(lambda_max) of the generalized problem L x = lambda M x;
* rho(G19) and rho(G21) at dt from generalized symmetric eigenproblems
  (G21: -dt^2 (L - D) x = mu (M + dt^2 D) x);
* h*_21 by bisection of rho(G21)(h) = 1 (no closed form used).

Writes meshes/*.{obj,node,ele,msh} and values.json next to this script.
Usage: python3 verification/reference/independent.py   (needs numpy, scipy)
"""
import json
import os

import numpy as np
import scipy.linalg as sl
from scipy.spatial import Delaunay

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "meshes")


def delaunay_mesh(seed, n_points, shape):
    rng = np.random.default_rng(seed)
    pts = []
    while len(pts) < n_points:
        p = rng.uniform(-1, 1, 3)
        if shape == "ball" and np.linalg.norm(p) > 1:
            continue
        if shape == "cylinder" and np.hypot(p[0], p[1]) > 1:
            continue
        pts.append(p * np.array([1.0, 0.7, 1.6]))
    pts = np.array(pts)
    tets = Delaunay(pts).simplices
    # Drop slivers (normalised volume < 0.05): leaves some points unused on purpose.
    keep = []
    for t in tets:
        P = np.stack([pts[t[k]] - pts[t[0]] for k in (1, 2, 3)], axis=1)
        e2 = [np.sum((pts[t[a]] - pts[t[b]]) ** 2) for a in range(4) for b in range(a + 1, 4)]
        q = 6 * np.sqrt(2) * abs(np.linalg.det(P)) / 6 / np.mean(e2) ** 1.5
        if q > 0.05:
            keep.append(t)
    return pts, np.array(keep)


def system(V, T, rho, mu):
    used = np.unique(T)
    remap = -np.ones(len(V), dtype=int)
    remap[used] = np.arange(len(used))
    V, T = V[used], remap[T]
    n = len(V)
    M = np.zeros(n)
    L = np.zeros((n, n))
    for t in T:
        P = np.stack([V[t[k]] - V[t[0]] for k in (1, 2, 3)], axis=1)
        vol = abs(np.linalg.det(P)) / 6
        Pit = np.linalg.inv(P).T
        A = np.hstack([-Pit @ np.ones((3, 1)), Pit])
        K = mu * vol * A.T @ A
        for a in range(4):
            M[t[a]] += rho * vol / 4
            for b in range(4):
                L[t[a], t[b]] += K[a, b]
    return M, L


def rho21(M, L, h):
    D = np.diag(np.diag(L))
    ev = sl.eigh(-h * h * (L - D), np.diag(M) + h * h * D, eigvals_only=True)
    return float(np.abs(ev).max())


def h21_bisect(M, L):
    lo, hi = 1e-9, 1e6
    if rho21(M, L, hi) < 1:
        return None
    while hi / lo > 1 + 1e-13:
        mid = np.sqrt(lo * hi)
        if rho21(M, L, mid) < 1:
            lo = mid
        else:
            hi = mid
    return float(np.sqrt(lo * hi))


def write_obj(path, V, T):
    with open(path, "w") as f:
        f.write("# random Delaunay mesh (independent.py)\n")
        for v in V:
            f.write("v %.17g %.17g %.17g\n" % tuple(v))
        for t in T:
            f.write("t %d %d %d %d\n" % tuple(t))


def write_tetgen(base, V, T):
    with open(base + ".node", "w") as f:
        f.write("# 1-based TetGen file with comments\n%d 3 0 0\n" % len(V))
        for i, v in enumerate(V):
            f.write("%d %.17g %.17g %.17g  # node\n" % (i + 1, *v))
    with open(base + ".ele", "w") as f:
        f.write("%d 4 0\n" % len(T))
        for i, t in enumerate(T):
            f.write("%d %d %d %d %d\n" % (i + 1, *(t + 1)))


def write_msh22(path, V, T):
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"body\"\n$EndPhysicalNames\n")
        f.write("$Nodes\n%d\n" % (len(V) + 1))
        f.write("99 100 100 100\n")  # a node no tet uses: dropped and counted
        for i, v in enumerate(V):
            f.write("%d %.17g %.17g %.17g\n" % (i + 101, *v))
        f.write("$EndNodes\n$Elements\n%d\n" % (len(T) + 2))
        f.write("1 15 2 0 1 101\n2 2 2 0 1 101 102 103\n")
        for i, t in enumerate(T):
            f.write("%d 4 2 1 1 %d %d %d %d\n" % (i + 3, *(t + 101)))
        f.write("$EndElements\n")


def write_msh41(path, V, T):
    n, m = len(V), len(T)
    half = n // 2
    with open(path, "w") as f:
        f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
        # The second block carries one extra node (tag n + 1) that no tet uses.
        f.write("$Nodes\n2 %d 1 %d\n" % (n + 1, n + 1))
        for (lo, hi, extra) in ((0, half, 0), (half, n, 1)):
            f.write("3 1 0 %d\n" % (hi - lo + extra))
            for i in range(lo, hi + extra):
                f.write("%d\n" % (i + 1))
            for i in range(lo, hi):
                f.write("%.17g %.17g %.17g\n" % tuple(V[i]))
            if extra:
                f.write("-5 -5 -5\n")
        f.write("$EndNodes\n$Elements\n2 %d 1 %d\n" % (m + 1, m + 1))
        f.write("2 1 2 1\n1 1 2 3\n3 1 4 %d\n" % m)
        for i, t in enumerate(T):
            f.write("%d %d %d %d %d\n" % (i + 2, *(t + 1)))
        f.write("$EndElements\n")


def main():
    os.makedirs(OUT, exist_ok=True)
    cases = [
        ("ball_obj", 11, 180, "ball", "obj", 2.0, 5e4, 1e-3),
        ("cylinder_tetgen", 12, 260, "cylinder", "tetgen", 900.0, 3e6, 5e-4),
        ("box_gmsh22", 13, 320, "box", "msh22", 1.0, 1e3, 2e-2),
        ("ball_gmsh41", 14, 420, "ball", "msh41", 50.0, 2e5, 1e-3),
    ]
    values = []
    for name, seed, npts, shape, fmt, rho, mu, dt in cases:
        V, T = delaunay_mesh(seed, npts, shape)
        if fmt == "obj":
            f = name + ".obj"
            write_obj(os.path.join(OUT, f), V, T)
        elif fmt == "tetgen":
            f = name + ".ele"
            write_tetgen(os.path.join(OUT, name), V, T)
        elif fmt == "msh22":
            f = name + ".msh"
            write_msh22(os.path.join(OUT, f), V, T)
        else:
            f = name + ".msh"
            write_msh41(os.path.join(OUT, f), V, T)
        M, L = system(V, T, rho, mu)
        lam = float(sl.eigh(L, np.diag(M), eigvals_only=True).max())
        values.append(
            {
                "name": name,
                "file": "meshes/" + f,
                "rho": rho,
                "mu": mu,
                "dt": dt,
                "vertices": int(len(M)),
                "tets": int(len(T)),
                "unused_nodes": int(len(V) - len(M)) + (1 if fmt in ("msh22", "msh41") else 0),
                "jacobi_critical_dt": 1 / np.sqrt(lam),
                "jacobi_spectral_radius": dt * dt * lam,
                "split_spectral_radius": rho21(M, L, dt),
                "split_critical_dt": h21_bisect(M, L),
            }
        )
        print(values[-1])
    with open(os.path.join(HERE, "values.json"), "w") as f:
        json.dump({"schema": "diffsoft.reference/1", "generator": "verification/reference/independent.py", "cases": values}, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
