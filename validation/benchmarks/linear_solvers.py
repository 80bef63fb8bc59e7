"""Benchmark of femshell.solvers.linear on a shell-like SPD matrix (factor, refactor, solve).

The test matrix imitates a shell Hessian: on a sphere mesh, the scalar operator

    S = L M⁻¹ L + L / R² + M / R⁴          (bilaplacian + membrane-like + mass; SPD)

with L the P1 cotangent Laplacian and M the lumped mass, coupled between 4
unknowns per vertex by a 4×4 SPD block B: K = S ⊗ B. L M⁻¹ L has the 2-ring
stencil of a Kirchhoff bending element; K has ~75 non-zeros per row (a real
Morley-type shell Hessian has ~55).

Rows: PARDISO SPD (mtype 2) first factorisation (analysis + numerical), a
refactorisation with new values on the same pattern (numerical only: what a Newton
iteration pays), one solve; PARDISO symmetric-indefinite (mtype −2, with and
without scaling/matching) on the same matrix and on K − σI with 10 negative
eigenvalues (inertia printed); pypardiso's default (mtype 11, full matrix) for
reference; SuperLU in symmetric mode.

Run:  python3 validation/benchmarks/linear_solvers.py [--sizes 2500 10000 25000] [--superlu-max 30000]

Results (PARDISO SPD and indefinite, pypardiso, SuperLU at 2.5k-25k vertices) are in docs/studies/benchmarks.md.
femshell loads MKL's sequential layer unless MKL_THREADING_LAYER is set (bit-for-bit resumes); set
MKL_THREADING_LAYER=GNU to measure threaded factorisations.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp

from femshell.chemistry import P1Assembler
from femshell.mesh.generators import sphere
from femshell.solvers.linear import available_backends, factorize, smallest_eigenvalues
from femshell.solvers.sparse_matrix import _canonical_csr, _check_values


def factor_mb(fac):
    """Size of the factor's values in MB (non-zeros x 8 B; the indices come on top). The change of the
    process's resident memory around a factorisation misses the peak and hides behind reused pages
    (it printed 52, 19 and 1 MB for three factors of 3.5 M non-zeros each)."""
    return fac.factor_nnz * 8 / 1e6


def sphere_mesh(n_vertices, radius=30.0):
    m = sphere(radius=radius, n_vertices=n_vertices, seed=0)
    return m.points, m.triangles


def shell_like_matrix(points, triangles, radius=30.0):
    asm = P1Assembler(triangles, len(points))
    L = asm.stiffness(points)
    m = asm.mass_lumped(points)
    S = (L @ sp.diags(1.0 / m) @ L + L / radius**2 + sp.diags(m) / radius**4).tocsr()
    # a full 4×4 SPD coupling block (diagonally dominant)
    B = np.array([[4.0, 1, 0.3, 0.5], [1, 3, 1, 0.2], [0.3, 1, 3, 1], [0.5, 0.2, 1, 4]])
    K = sp.kron(S, B, format="csr")
    K.sort_indices()
    return K


def timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def bench(n_target, superlu_max, rows):
    pts, tri = sphere_mesh(n_target)
    K = shell_like_matrix(pts, tri)
    n = K.shape[0]
    nv = len(pts)
    print(f"\n== {nv} vertices: {n} unknowns, {K.nnz / 1e6:.2f} M non-zeros ({K.nnz / n:.0f} per row)")
    rng = np.random.default_rng(0)
    b = rng.normal(size=n)
    # new values on the same pattern, as in a Newton iteration: the points move a little
    K2 = shell_like_matrix(pts * (1.0 + 0.01 * rng.uniform(size=(len(pts), 1))), tri)
    assert np.array_equal(K2.indptr, K.indptr) and np.array_equal(K2.indices, K.indices)

    def record(name, fac, t_first, K_used, t_refactor=None):
        _, t_solve = timed(fac.solve, b)
        x = fac.solve(b)
        res = np.linalg.norm(K_used @ x - b) / np.linalg.norm(b)
        rows.append(dict(vertices=nv, unknowns=n, solver=name, first=t_first, analysis=fac.analysis_time,
                         refactor=t_refactor, solve=t_solve, residual=res, factor_nnz=fac.factor_nnz,
                         inertia=fac.inertia))
        print(f"  {name:<38} first {t_first:7.2f} s  refactor {'' if t_refactor is None else f'{t_refactor:6.2f} s'}"
              f"  solve {t_solve:6.3f} s  residual {res:.1e}  inertia {fac.inertia}")

    # the symmetry check costs one sparse transpose: time it separately
    _, t_check = timed(_check_values, _canonical_csr(K), True)
    print(f"  input checks (finite, zero rows, symmetry): {t_check:.2f} s")

    if "pardiso" in available_backends():
        for kind, matching, label in (("spd", True, "pardiso spd (mtype 2)"),
                                      ("symmetric_indefinite", True, "pardiso indefinite (mtype -2, matching)"),
                                      ("symmetric_indefinite", False, "pardiso indefinite (mtype -2, no matching)")):
            fac, t_first = timed(factorize, K, kind, "pardiso", pardiso_matching=matching)
            mem = factor_mb(fac)
            t_analysis = fac.analysis_time
            t0 = time.perf_counter()
            fac.refactor(K2)
            t_ref = time.perf_counter() - t0
            assert fac.n_analyses == 1, "refactor on the same pattern must not re-analyse"
            record(label, fac, t_first, K2, t_ref)
            rows[-1]["mem_mb"] = mem
            rows[-1]["analysis"] = t_analysis
            print(f"  {'':<38} analysis {t_analysis:.2f} s of the first; factor values {mem:.0f} MB "
                  f"(nnz {fac.factor_nnz / 1e6:.1f} M x 8 B)")
            fac.free()
        # an indefinite matrix: shift past the 10 smallest eigenvalues
        ev = smallest_eigenvalues(K, k=11, return_vectors=False)
        sigma = 0.5 * (ev[9] + ev[10])
        Ks = (K - sigma * sp.identity(n, format="csr")).tocsr()
        fac, t_first = timed(factorize, Ks, "symmetric_indefinite", "pardiso")
        record("pardiso indefinite, K - sigma I", fac, t_first, Ks)
        print(f"  {'':<38} expected 10 negative eigenvalues")
        fac.free()

        import pypardiso

        s = pypardiso.PyPardisoSolver()
        _, t_first = timed(s.factorize, K)
        _, t_solve = timed(s.solve, K, b)
        s.free_memory(everything=True)
        rows.append(dict(vertices=nv, unknowns=n, solver="pypardiso default (mtype 11)", first=t_first,
                         analysis=None, refactor=None, solve=t_solve, residual=None, factor_nnz=None, inertia=None))
        print(f"  {'pypardiso default (mtype 11)':<38} first {t_first:7.2f} s  solve {t_solve:6.3f} s")

    if nv <= superlu_max:
        fac, t_first = timed(factorize, K, "spd", "superlu")
        mem = factor_mb(fac)
        t0 = time.perf_counter()
        fac.refactor(K2)
        t_ref = time.perf_counter() - t0
        record("superlu symmetric mode (spd)", fac, t_first, K2, t_ref)
        rows[-1]["mem_mb"] = mem
        print(f"  {'':<38} factor values {mem:.0f} MB (nnz {fac.factor_nnz / 1e6:.1f} M x 8 B)")
        fac.free()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2500, 10000, 25000])
    ap.add_argument("--superlu-max", type=int, default=30000, help="skip SuperLU above this many vertices")
    args = ap.parse_args()
    rows = []
    for nv in args.sizes:
        bench(nv, args.superlu_max, rows)
    print("\n| vertices | unknowns | solver | first factor [s] | of which analysis | refactor [s] | solve [s] |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        f = (lambda v, fmt: "" if v is None else format(v, fmt))
        print(f"| {r['vertices']} | {r['unknowns']} | {r['solver']} | {r['first']:.2f} | {f(r['analysis'], '.2f')} | "
              f"{f(r['refactor'], '.2f')} | {r['solve']:.3f} |")


if __name__ == "__main__":
    main()
