"""Refactorise only when it pays: factorisations and CPU time of Newton, old (direct) and new (Krylov) path.

Rows for ``validation/benchmarks/speed.py`` (issue 63), also runnable alone. On the grown, bumped
sphere :func:`grown_sphere` (R = 30, h = 2, polar cap grown by 5 %), in one process:

* factor: PARDISO's first factorisation (analysis + numerical) and a refactorisation of the
  Hessian, LDLᵀ and Cholesky, CPU seconds;
* newton: a stable Newton solve from the bumped state, then a second solve after the cap's growth
  is raised by 1 % on the same factorisations (a step of a stepping), with
  ``minimize(linear_solver="direct")`` and ``"krylov"``: iterations, factorisations, Krylov solves
  and iterations, CPU seconds per solve and per Newton iteration, old/new ratios, and how far apart
  the two paths' results are (max |Δu| over the Newton tolerance's displacement scale);
* coupled: ``--coupled-steps`` steps of the ``sphere-spots`` scene's coupled loop at this size with
  ``TimeStepping.linear_solver`` "direct" and "krylov" (quasi-Newton start on, as by default), and
  "krylov" without the quasi-Newton start.

CPU time is ``time.process_time`` (all threads of the process), with the load average printed, as
the machine may be shared.

    python validation/benchmarks/speed_solve.py [--sizes 6000 12000] [--coupled-steps 4]
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np

import shell_newton
from femshell.shell import RestState
from femshell.solvers.linear import Refactorizer, factorize
from femshell.solvers.newton import minimize

PATHS = ("direct", "krylov")
#: the coupled loop's Newton: the two paths with its quasi-Newton start (the default), and Krylov without it
COUPLED_PATHS = ("direct", "krylov", "krylov no-quasi-newton")


def grown_sphere(n_vertices):
    """:func:`shell_newton.grown_sphere` neo-Hookean, the cap grown by 5 %, a bump of 0.1 h."""
    return shell_newton.grown_sphere(n_vertices, growth=1.05, law="neo-hookean", bump=0.1)


def load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def cpu(f):
    """(CPU seconds of f(), its value)."""
    t = time.process_time()
    out = f()
    return time.process_time() - t, out


def factor_rows(model, u) -> dict:
    """CPU seconds of PARDISO's first factorisation and of a refactorisation, LDLᵀ and Cholesky, of the
    Hessian at u (a stable equilibrium: positive definite)."""
    K = model.hessian(u)
    out = {"nnz": int(K.nnz)}
    for kind in ("ldlt", "cholesky"):
        t_first, fac = cpu(lambda: factorize(K, kind="symmetric_indefinite" if kind == "ldlt" else "spd"))
        t_re, _ = cpu(lambda: fac.refactor(K))
        t_solve, _ = cpu(lambda: fac.solve(np.ones(K.shape[0])))
        out[kind] = {"first": t_first, "refactor": t_re, "solve": t_solve, "factor_nnz": fac.factor_nnz}
        fac.free()
    return out


def _grow_cap(model, factor):
    """Scale the rest state's growth on the grown cap by ``factor`` (a step of a growth stepping)."""
    rest = model.rest
    s = np.where(rest.thickness < rest.thickness.max() * (1 - 1e-9), factor, 1.0)
    model.set_rest_state(RestState(rest.metric * s[:, None, None] ** 2, rest.curvature * s[:, None, None] ** 2,
                                   rest.thickness / s**2))


def newton_rows(n_vertices, rtol=1e-8) -> dict:
    """Two successive stable Newton solves per path (module docstring), CPU time and counts."""
    rows = {}
    for path in PATHS:
        model, u0 = grown_sphere(n_vertices)
        model.energy(u0), model.gradient(u0), model.hessian(u0)          # compiled before timing
        pair = (Refactorizer(), Refactorizer())
        solves = []
        u = u0
        for k in range(2):
            if k:
                _grow_cap(model, 1.01)
            t, res = cpu(lambda: minimize(model, u, rtol=rtol, stable=True, factorizers=pair,
                                          linear_solver=path, log=None))
            u = res.u
            solves.append({"cpu": t, "iterations": res.iterations, "factorizations": res.factorizations,
                           "krylov_solves": res.krylov_solves, "krylov_iterations": res.krylov_iterations,
                           "stable": res.stable, "u": res.u, "times": res.times})
        for f in pair:
            f.free()
        rows[path] = solves
        rows["model"] = model
    # agreement: both paths' states to the Newton tolerance (displacements of the two solves)
    rows["max_du"] = [float(np.abs(a["u"] - b["u"]).max()) for a, b in zip(rows["direct"], rows["krylov"])]
    return rows


def coupled_rows(n_vertices, steps) -> dict:
    """``steps`` coupled steps of sphere-spots per path: CPU seconds per step, factorisations, Newton iterations."""
    from femshell.scene import build
    import femshell.solvers.newton as newton_mod

    scene = build.load_scene("sphere-spots", [f"mesh.n_vertices={n_vertices}"])
    mesh = build.make_mesh(scene)
    out = {}
    for path in COUPLED_PATHS:
        loop = build.time_loop(scene, mesh)
        solver, _, qn = path.partition(" ")
        loop.stepping = replace(loop.stepping, linear_solver=solver, **({"quasi_newton": 0} if qn else {}))
        loop.run(max_steps=1)                            # first step: compiles, holds a factor
        counts = {"factorizations": 0, "iterations": 0, "krylov_iterations": 0}
        real = newton_mod.minimize

        def counted(*a, **k):
            res = real(*a, **k)
            counts["factorizations"] += res.factorizations
            counts["iterations"] += res.iterations + res.quasi_newton_iterations
            counts["krylov_iterations"] += res.krylov_iterations
            return res

        import femshell.coupled.equilibrium as eq
        eq.minimize = counted
        try:
            t, _ = cpu(lambda: loop.run(max_steps=steps))
        finally:
            eq.minimize = real
        out[path] = {"cpu_per_step": t / steps, **counts, "u": np.asarray(loop.u).copy(), "t": float(loop.t)}
    out["max_du"] = float(np.abs(out["direct"]["u"] - out["krylov"]["u"]).max())
    return out


def print_rows(n_vertices, coupled_steps):
    print(f"--- {n_vertices} vertices, load {load()}")
    r = newton_rows(n_vertices)
    f = factor_rows(r["model"], r["krylov"][-1]["u"])
    print(f"factor (CPU s, nnz(K) {f['nnz']}): " + "; ".join(
        f"{k} first {v['first']:.2f} refactor {v['refactor']:.2f} solve {v['solve']:.3f} (factor nnz {v['factor_nnz']})"
        for k, v in f.items() if k != "nnz"))
    print(f"{'solve':>6} {'path':>7} {'iters':>5} {'factor.':>7} {'krylov':>6} {'kr.its':>6} {'CPU s':>7} "
          f"{'CPU/it':>7} {'stable':>6}")
    for k in range(2):
        for path in PATHS:
            s = r[path][k]
            print(f"{k + 1:>6} {path:>7} {s['iterations']:>5} {s['factorizations']:>7} {s['krylov_solves']:>6} "
                  f"{s['krylov_iterations']:>6} {s['cpu']:>7.2f} {s['cpu'] / max(s['iterations'], 1):>7.2f} "
                  f"{str(s['stable']):>6}")
        d, kr = r["direct"][k], r["krylov"][k]
        print(f"{'':>6} {'old/new':>7} {'':>5} {d['factorizations'] / max(kr['factorizations'], 1):>7.2f} {'':>6} "
              f"{'':>6} {d['cpu'] / kr['cpu']:>7.2f} {'':>7}  max|Δu| {r['max_du'][k]:.1e}")
    if coupled_steps:
        c = coupled_rows(n_vertices, coupled_steps)
        for path in COUPLED_PATHS:
            s = c[path]
            print(f"coupled {path:>23}: {s['cpu_per_step']:.2f} CPU s/step, {s['factorizations']} factorisations, "
                  f"{s['iterations']} Newton (+quasi) iterations, {s['krylov_iterations']} Krylov its over "
                  f"{coupled_steps} steps (t = {s['t']:.4g})")
        print(f"coupled old/new CPU per step {c['direct']['cpu_per_step'] / c['krylov']['cpu_per_step']:.2f}, "
              f"max|Δu| {c['max_du']:.1e}")
    print(f"--- load {load()}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[6000, 12000])
    ap.add_argument("--coupled-steps", type=int, default=4)
    args = ap.parse_args()
    if any(n < 100 for n in args.sizes) or args.coupled_steps < 0:
        ap.error("--sizes must be vertex counts >= 100 and --coupled-steps >= 0")
    for n in args.sizes:
        print_rows(n, args.coupled_steps)


if __name__ == "__main__":
    import femshell

    femshell.configure()
    main()
