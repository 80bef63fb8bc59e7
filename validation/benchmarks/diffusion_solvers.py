"""Benchmark: linear solvers for the implicit surface-diffusion step of the chemistry (theory §1.3).

The system of one chemical step is

    A c⁺ = b,   A = M (1 + β dt) + dt D K

with M the lumped P1 mass and K the P1 cotangent stiffness of the (deformed) surface
(femshell solves A = M + γ D K, γ = (1 − e^{−β dt})/β ≤ dt: the same pattern and kind of
spectrum, so the figures carry over with dt D replaced by γ D).
A is SPD, one unknown per vertex, ~7 non-zeros per row. The surface moves between
steps, so every step pays setup (factorisation / AMG hierarchy) + one solve.

Candidates: pyamg smoothed aggregation as a CG preconditioner (to rtol 1e-10), CG
with a Jacobi preconditioner (A is mass-dominated for small dt D / h^2), SuperLU
(splu, symmetric mode), and PARDISO through pypardiso (SPD, mtype 2) if importable.
Every solution is checked against the splu one.

Mesh: femshell.mesh.generators.sphere (R = 30), else an icosphere made here.
Run:  python3 validation/benchmarks/diffusion_solvers.py [--sizes 2500 10000 ...] [--dt 0.1 1 10]

Conclusion (docs/studies/benchmarks.md): pyamg smoothed aggregation is never the fastest (A is mass-dominated
and the hierarchy setup, paid every step on a moving surface, costs more than a direct solve); PARDISO (SPD, one
MKL thread) from ~25k vertices on; Jacobi-CG as the dependency-free alternative while dt D / h² ≲ 1. On a shared
machine set ``MKL_NUM_THREADS=1`` (or ``--mkl-threads 1``): spinning threads wait for cores other processes hold.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

# ----------------------------------------------------------------------------- meshes

def sphere_mesh(n_vertices, radius=30.0):
    """(points, triangles) of a sphere: femshell's gmsh generator if present, else an icosphere."""
    try:
        from femshell.mesh.generators import sphere
    except ImportError:
        return icosphere(n_vertices, radius)
    m = sphere(radius=radius, n_vertices=n_vertices)
    return np.asarray(m.points), np.asarray(m.triangles)


def icosphere(n_vertices, radius=1.0):
    """Subdivided icosahedron with about n_vertices vertices (10 4^k + 2), projected to the sphere."""
    t = (1 + 5 ** 0.5) / 2
    p = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    while len(p) < n_vertices:
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        edges, inv = np.unique(e, axis=0, return_inverse=True)
        mid = len(p) + inv.reshape(3, -1).T          # midpoint index of edges 01, 12, 20
        p = np.vstack([p, 0.5 * (p[edges[:, 0]] + p[edges[:, 1]])])
        a, b, c = f.T
        ab, bc, ca = mid.T
        f = np.concatenate([np.column_stack(x) for x in
                            ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    p = radius * p / np.linalg.norm(p, axis=1, keepdims=True)
    return p, f


# ----------------------------------------------------------------------------- P1 operators

def p1_mass_stiffness(points, triangles):
    """Lumped P1 mass (vector of vertex areas) and cotangent stiffness K (csr) of a triangulated surface."""
    p, t = np.asarray(points, float), np.asarray(triangles)
    n = len(p)
    x0, x1, x2 = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    cr = np.cross(x1 - x0, x2 - x0)
    area2 = np.linalg.norm(cr, axis=1)               # twice the triangle area
    mass = np.bincount(t.ravel(), np.repeat(area2 / 6.0, 3), minlength=n)
    rows, cols, vals = [], [], []
    for k in range(3):                               # angle at local vertex k, opposite edge (i, j)
        i, j, o = t[:, (k + 1) % 3], t[:, (k + 2) % 3], t[:, k]
        u, v = p[i] - p[o], p[j] - p[o]
        cot = np.einsum("ij,ij->i", u, v) / area2    # |u x v| = 2 area
        w = 0.5 * cot
        rows += [i, j, i, j]
        cols += [j, i, i, j]
        vals += [-w, -w, w, w]
    K = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return mass, K


# ----------------------------------------------------------------------------- solvers

def _solve_pyamg(A, b):
    import pyamg

    t0 = time.perf_counter()
    ml = pyamg.smoothed_aggregation_solver(A, symmetry="symmetric")
    t1 = time.perf_counter()
    res = []
    x = ml.solve(b, tol=1e-10, accel="cg", maxiter=500, residuals=res)
    return x, t1 - t0, time.perf_counter() - t1, len(res) - 1


def _solve_jacobi_cg(A, b):
    t0 = time.perf_counter()
    d = 1.0 / A.diagonal()
    P = spla.LinearOperator(A.shape, matvec=lambda r: d * r, dtype=float)
    t1 = time.perf_counter()
    its = [0]

    def cb(_):
        its[0] += 1

    x, info = spla.cg(A, b, rtol=1e-10, M=P, maxiter=5000, callback=cb)
    if info != 0:
        raise RuntimeError(f"Jacobi-CG did not converge (info {info})")
    return x, t1 - t0, time.perf_counter() - t1, its[0]


def _solve_splu(A, b):
    t0 = time.perf_counter()
    lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    t1 = time.perf_counter()
    x = lu.solve(b)
    return x, t1 - t0, time.perf_counter() - t1, None


def _solve_pardiso(A, b):
    import pypardiso

    ps = _solve_pardiso.ps
    if ps is None:
        ps = _solve_pardiso.ps = pypardiso.PyPardisoSolver(mtype=2)
        ps.set_statistical_info_off()
    Au = sp.triu(A, format="csr")
    Au.sort_indices()
    t0 = time.perf_counter()
    ps.factorize(Au)
    t1 = time.perf_counter()
    ps.set_phase(33)
    x = ps._call_pardiso(Au, b)   # solve on the stored factors (public solve() re-hashes A)
    return x, t1 - t0, time.perf_counter() - t1, None


_solve_pardiso.ps = None


def _set_mkl_threads(n):
    import ctypes

    import pypardiso

    if _solve_pardiso.ps is None:
        _solve_pardiso.ps = pypardiso.PyPardisoSolver(mtype=2)
        _solve_pardiso.ps.set_statistical_info_off()
    _solve_pardiso.ps.libmkl.MKL_Set_Num_Threads(ctypes.c_int(n))

SOLVERS = {"pyamg-sa-cg": _solve_pyamg, "jacobi-cg": _solve_jacobi_cg, "splu": _solve_splu,
           "pardiso": _solve_pardiso}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2500, 5000, 10000, 25000, 50000, 100000])
    ap.add_argument("--dt", type=float, nargs="+", default=[0.1, 1.0, 10.0])
    ap.add_argument("--D", type=float, default=1.0, help="diffusion constant (theory §1.5: 0..1.5)")
    ap.add_argument("--beta", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2, help="best of this many runs per solver")
    ap.add_argument("--mkl-threads", type=int, default=None,
                    help="set MKL's thread count for PARDISO (same as the MKL_NUM_THREADS variable)")
    args = ap.parse_args(argv)
    finite = all(math.isfinite(v) for v in (args.D, args.beta, *args.dt))
    if not finite or args.D < 0 or args.beta < 0 or min(args.dt) <= 0:
        ap.error(f"--D and --beta must be finite numbers >= 0 and --dt > 0, got D = {args.D}, beta = {args.beta}, "
                 f"dt = {args.dt}")
    if args.repeat < 1 or min(args.sizes) < 100:
        ap.error(f"--repeat must be >= 1 and --sizes vertex counts >= 100, got {args.repeat} and {args.sizes}")
    if args.mkl_threads is not None:
        _set_mkl_threads(args.mkl_threads)
    try:
        import pypardiso  # noqa: F401
        names = list(SOLVERS)
    except ImportError:
        names = [s for s in SOLVERS if s != "pardiso"]

    print("| vertices | dt | dt D / h^2 | solver | setup [s] | solve [s] | total [s] | iterations | error vs splu |")
    print("|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for nv in args.sizes:
        t0 = time.perf_counter()
        p, t = sphere_mesh(nv)
        mass, K = p1_mass_stiffness(p, t)
        t_ops = time.perf_counter() - t0
        h2 = float(np.mean(mass)) * 2 / np.sqrt(3)    # edge length^2 of an equilateral mesh
        c = np.clip(rng.random(len(p)), 0, 1)
        for dt in args.dt:
            A = (sp.diags(mass * (1 + args.beta * dt)) + dt * args.D * K).tocsr()
            b = mass * c
            ref = None
            results = {}
            for name in ["splu"] + [s for s in names if s != "splu"]:
                best = None
                for _ in range(args.repeat):
                    x, ts, tv, its = SOLVERS[name](A, b)
                    if best is None or ts + tv < best[1] + best[2]:
                        best = (x, ts, tv, its)
                results[name] = best
                if name == "splu":
                    ref = best[0]
            for name in names:
                x, ts, tv, its = results[name]
                err = np.linalg.norm(x - ref) / np.linalg.norm(ref)
                print(f"| {len(p)} | {dt:g} | {dt * args.D / h2:.3g} | {name} | {ts:.4f} | {tv:.4f} | {ts + tv:.4f} | "
                      f"{'' if its is None else its} | {err:.1e} |", flush=True)
            fastest = min(names, key=lambda s: results[s][1] + results[s][2])
            print(f"|   | | | fastest (setup + solve): **{fastest}** | | | | | mesh + operators {t_ops:.2f} s |",
                  flush=True)


if __name__ == "__main__":
    main()
