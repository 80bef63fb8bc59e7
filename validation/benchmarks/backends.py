"""Linear-solver back-ends on a real shell problem: the Scordelis-Lo roof at three mesh sizes.

The same linear response (one Newton step from the stress-free roof, as in
``femshell validate scordelis-lo``) is solved with MKL PARDISO and with SciPy's SuperLU, each
in the two modes femshell uses: ``spd`` (Cholesky; the linear benchmarks) and
``symmetric_indefinite`` (LDLᵀ with inertia; every Newton iteration), plus the
refactorisation with new values on the same pattern that a Newton iteration pays. The error
against the Kirchhoff-Love value 0.3006 must agree between back-ends (same discretisation,
round-off differences only); the times differ.

    python validation/benchmarks/backends.py [--sizes 1.0 0.7 0.5] [--repeat 2]

Prints a markdown table (times: best of ``--repeat``; wall-clock on this machine, shared).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from femshell.mesh.generators import cylinder
from femshell.shell import AreaLoad, Material, Prescribed, ShellModel
from femshell.solvers.linear import factorize
from femshell.validation.scordelis_lo import GRAVITY, HALF_ANGLE, LENGTH, NU, REFERENCE, E, R, T


def roof(h):
    mesh = cylinder(R, LENGTH, edge_length=h, angle_range=(np.pi / 2 - HALF_ANGLE, np.pi / 2 + HALF_ANGLE))
    edge = mesh.topology.boundary_vertex_groups["side-a"]
    mid = int(edge[np.argmin(np.abs(mesh.points[edge, 2] - LENGTH / 2))])
    model = ShellModel(mesh, Material(E, NU), T,
                       [Prescribed("bottom", components=(0, 1)), Prescribed("top", components=(0, 1)),
                        Prescribed(vertices=(mid,), components=(2,))],
                       [AreaLoad(mesh, (0.0, -GRAVITY, 0.0))])
    return model, mid


def best(f, repeat):
    out, times = None, []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1.0, 0.7, 0.5])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    if args.repeat < 1 or not all(0 < h < 100 for h in args.sizes):
        ap.error(f"--repeat must be >= 1 and --sizes edge lengths in (0, 100), got {args.repeat} and {args.sizes}")
    print("| h | vertices | unknowns | nnz(K) | Hessian [s] | back-end | mode | factor [s] | refactor [s] | "
          "solve [s] | factor nnz | deflection | error vs 0.3006 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for h in args.sizes:
        model, mid = roof(h)
        u0 = model.initial_unknowns()
        model.hessian(u0)                     # compile / load the element kernels
        t_h, K = best(lambda: model.hessian(u0), args.repeat)
        f = -model.gradient(u0)
        first = True
        for backend in ("pardiso", "superlu"):
            for kind in ("spd", "symmetric_indefinite"):
                t_f, fac = best(lambda: factorize(K, kind=kind, backend=backend), args.repeat)
                t_r, _ = best(lambda: fac.refactor(K), args.repeat)
                t_s, du = best(lambda: fac.solve(f), args.repeat)
                w = -(model.positions(u0 + du)[mid, 1] - model.mesh.points[mid, 1])
                lead = (f"| {h:g} | {model.mesh.n_vertices} | {K.shape[0]} | {K.nnz} | {t_h:.2f} |" if first
                        else "| | | | | |")
                first = False
                print(f"{lead} {backend} | {kind} | {t_f:.3f} | {t_r:.3f} | {t_s:.4f} | {fac.factor_nnz} | "
                      f"{w:.10f} | {abs(w - REFERENCE) / REFERENCE:.3e} |", flush=True)
                fac.free()


if __name__ == "__main__":
    main()
