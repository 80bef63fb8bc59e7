"""One Newton iteration, today's path against the new ones: wall and CPU seconds, ratios, and the parts.

Rows for ``validation/benchmarks/speed.py --newton`` (issue 63: "a Newton iteration ≤ 2 s on 2
idle cores at 25k"), also runnable alone. Each path runs in a fresh process of its own (MKL's
threading layer is fixed when MKL loads), one after the other, on the grown, bumped sphere of
:func:`speed_solve.grown_sphere`: a stable Newton solve from the bumped state, then a second one
after the cap's growth is raised by 1 % (a step of a stepping), on the same factorisations.

* old: the JAX element Hessian, a fresh factorisation of every iterate's Hessian
  (``minimize(linear_solver="direct")``), MKL sequential on one thread (the reproducible mode,
  ``femshell.configure(reproducible=True)``, which was the default);
* new: the default path: the compiled C element Hessian, MKL and the kernels on every core,
  ``minimize``'s default linear solver ("direct");
* new, Krylov: the same with ``linear_solver="krylov"`` (the coupled loop's and the continuation
  corrector's default: Krylov steps on the held factorisation).

Per Newton iteration (the two solves' time over their iterations; the convergence test's Hessian and
factorisation at the solution included): wall and CPU seconds (``time.process_time``: all the
process's threads) of each path, the ratio old/new, and the share of each part: element Hessian,
assembly (scatter into the CSR matrix), factorisation (analysis, numerical factorisation and
refactorisation, failed Cholesky attempts and shifts included), back-substitution, Krylov solve
(with its back-substitutions), energy and gradient (the line search), eigenvalues (saddle
escapes), other (the rest of Newton). A part's time excludes the wrapped parts it calls.

    python validation/benchmarks/speed_newton.py [--vertices 6000] [--paths old new krylov]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from speed_solve import load

HERE = Path(__file__).resolve().parent
#: path name: (label, reproducible mode, Hessian kernel, minimize's linear solver)
PATHS = {"old": ("old: JAX, direct, MKL sequential", True, "jax", "direct"),
         "new": ("new: C, direct, threads", False, "compiled", "direct"),
         "krylov": ("new: C, Krylov, threads", False, "compiled", "krylov")}
#: the parts of an iteration, in print order
#: issue 63's target for a Newton iteration at 25k vertices on 2 idle cores, wall seconds
TARGET_WALL_S = 2.0
PARTS = ("element Hessian", "assembly", "factorisation", "back-substitution", "Krylov", "energy, gradient",
         "eigenvalues", "other")


class Profile:
    """CPU and wall seconds per named part, each part's own time (nested wrapped calls excluded, except
    inside an ``absorb`` part, which keeps everything it calls)."""

    def __init__(self):
        self.cpu = dict.fromkeys(PARTS, 0.0)
        self.wall = dict.fromkeys(PARTS, 0.0)
        self._stack = []            # [name, absorb, cpu at resume, wall at resume]
        self.analyses = 0           # PARDISO symbolic analyses (phase 11)

    def _charge(self, frame, c, w):
        self.cpu[frame[0]] += c - frame[2]
        self.wall[frame[0]] += w - frame[3]

    def wrap(self, name, fn, absorb=False):
        def timed(*args, **kwargs):
            if self._stack and self._stack[-1][1]:
                return fn(*args, **kwargs)
            c, w = time.process_time(), time.perf_counter()
            if self._stack:
                self._charge(self._stack[-1], c, w)
            self._stack.append([name, absorb, c, w])
            try:
                return fn(*args, **kwargs)
            finally:
                c, w = time.process_time(), time.perf_counter()
                self._charge(self._stack.pop(), c, w)
                if self._stack:
                    self._stack[-1][2:] = [c, w]
        return timed


def instrument(model, profile):
    """Wrap the model's and the solvers' entry points so that ``profile`` times them."""
    import femshell.solvers.krylov as krylov
    import femshell.solvers.linear as linear
    import femshell.solvers.negative_curvature as curvature
    import femshell.solvers.pardiso as pardiso

    model.hessian = profile.wrap("element Hessian", model.hessian)
    model.assembler.matrix = profile.wrap("assembly", model.assembler.matrix)
    for name in ("energy", "gradient", "energy_and_gradient"):
        setattr(model, name, profile.wrap("energy, gradient", getattr(model, name)))
    linear.Factorization.refactor = profile.wrap("factorisation", linear.Factorization.refactor)
    linear.Factorization.solve = profile.wrap("back-substitution", linear.Factorization.solve)
    krylov.preconditioned_solve = profile.wrap("Krylov", krylov.preconditioned_solve, absorb=True)
    curvature.smallest_eigenvalues = profile.wrap("eigenvalues", curvature.smallest_eigenvalues, absorb=True)
    factor = pardiso._Pardiso.factor

    def counted(self, U, analyse):
        profile.analyses += bool(analyse)
        return factor(self, U, analyse)

    pardiso._Pardiso.factor = counted


def run_path(path, n_vertices, rtol=1e-8) -> dict:
    """In this process (configured for ``path``): the two Newton solves, their times and parts."""
    import numpy as np
    import scipy.sparse as sp

    import speed_solve
    from femshell.solvers.linear import Refactorizer, factorize
    from femshell.solvers.newton import minimize

    _, _, kernel, solver = PATHS[path]
    factorize(sp.identity(10, format="csr") * 2.0).free()          # loads MKL: not in the first solve's time
    model, u = speed_solve.grown_sphere(n_vertices)
    model.hessian_kernel = model.gradient_kernel = kernel
    model.energy(u), model.gradient(u), model.energy_and_gradient(u), model.hessian(u)   # compiled before timing
    profile = Profile()
    instrument(model, profile)
    pair = (Refactorizer(), Refactorizer())
    solves = []
    c0, w0 = time.process_time(), time.perf_counter()
    for k in range(2):
        if k:         # a step of a stepping
            speed_solve._grow_cap(model, 1.01)
        c, w = time.process_time(), time.perf_counter()
        before = [dict(f.counts) for f in pair], profile.analyses
        res = minimize(model, u, rtol=rtol, stable=True, factorizers=pair, linear_solver=solver, log=None)
        u = res.u
        kinds = {f"{which}{name}": f.counts[name] - n0[name] for which, f, n0 in zip(("", "shifted "), pair, before[0])
                 for name in f.counts if f.counts[name] > n0[name]}
        solves.append({"kinds": kinds, "analyses": profile.analyses - before[1], "cpu": time.process_time() - c,
                       "wall": time.perf_counter() - w, "iterations": res.iterations,
                       "factorizations": res.factorizations, "krylov_iterations": res.krylov_iterations,
                       "stable": bool(res.stable)})
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    for f in pair:
        f.free()
    profile.cpu["other"] += cpu - sum(profile.cpu.values())
    profile.wall["other"] += wall - sum(profile.wall.values())
    return {"vertices": model.mesh.n_vertices, "unknowns": model.n_free, "cpu": cpu, "wall": wall,
            "solves": solves, "parts_cpu": profile.cpu, "parts_wall": profile.wall,
            "threads": os.environ.get("MKL_NUM_THREADS", ""), "u_max": float(np.abs(u).max()), "u": u.tolist()}


def child(path, n_vertices, rtol):
    import femshell

    femshell.configure(reproducible=PATHS[path][1])
    sys.path.insert(0, str(HERE))
    print(json.dumps(run_path(path, n_vertices, rtol)))


def measure_paths(n_vertices, paths, rtol=1e-8) -> dict:
    """Each path's :func:`run_path` in a fresh process, one after the other; with the load before and after."""
    out = {}
    for path in paths:
        env = {k: v for k, v in os.environ.items() if k not in ("MKL_THREADING_LAYER", "MKL_CBWR", "MKL_NUM_THREADS",
                                                                 "FEMSHELL_THREADS")}
        before = load()
        done = subprocess.run([sys.executable, str(Path(__file__)), "--child", path,
                               "--vertices", str(n_vertices), "--rtol", str(rtol)],
                              env=env, capture_output=True, text=True)
        if done.returncode:
            raise RuntimeError(f"the {path} path failed:\n{done.stderr[-3000:]}")
        out[path] = json.loads(done.stdout.strip().splitlines()[-1])
        out[path]["load"] = (before, load())
    return out


def per_iteration(r) -> int:
    return max(sum(s["iterations"] for s in r["solves"]), 1)


def print_table(rows: dict):
    """Per Newton iteration, each path's wall and CPU seconds per part and their shares, then the ratios."""
    import numpy as np

    paths = list(rows)
    first = rows[paths[0]]
    print(f"Newton iteration, {first['vertices']} vertices ({first['unknowns']} unknowns): two stable solves "
          "per path, seconds per iteration (share of the iteration's CPU)")
    for path in paths:
        r = rows[path]
        print(f"  {PATHS[path][0]:34} MKL threads {r['threads'] or 'default'}; load {r['load'][0]} -> {r['load'][1]}")
        for k, s in enumerate(r["solves"]):
            kinds = ", ".join(f"{v} {name}" for name, v in s["kinds"].items())
            print(f"    solve {k + 1}: {s['iterations']} iterations, {s['factorizations']} factorisations ({kinds}; "
                  f"{s['analyses']} analyses), {s['krylov_iterations']} Krylov iterations, "
                  f"{s['cpu']:.2f} CPU s, {s['wall']:.2f} wall s{'' if s['stable'] else ', UNSTABLE'}")
    head = "".join(f"{PATHS[p][0].split(':')[0] + (' Kr.' if p == 'krylov' else ''):>22}" for p in paths)
    print(f"{'':20}{head}")
    print(f"{'':20}" + "".join(f"{'wall s':>8}{'CPU s':>7}{'share':>7}" for _ in paths))
    for part in PARTS + ("Newton iteration",):
        cells = []
        for p in paths:
            r, n = rows[p], per_iteration(rows[p])
            c = r["cpu"] if part == "Newton iteration" else r["parts_cpu"][part]
            w = r["wall"] if part == "Newton iteration" else r["parts_wall"][part]
            cells.append(f"{w / n:>8.3f}{c / n:>7.3f}{100 * c / r['cpu']:>6.0f}%")
        print(f"{part:20}" + "".join(cells))
    old = rows.get("old")
    if old is not None:
        for p in paths[1:]:
            r = rows[p]
            parts = ", ".join(f"{part} {_ratio(old, r, 'parts_cpu', part):.2f}" for part in PARTS[:4])
            print(f"old/{p}: Newton iteration wall {_ratio(old, r, 'wall'):.2f}, CPU {_ratio(old, r, 'cpu'):.2f}; "
                  f"CPU per part: {parts}")
            du = np.abs(np.asarray(old["u"]) - np.asarray(r["u"])).max()
            print(f"  max |u_old - u_{p}| at the second solution {du:.1e} (max |u| {old['u_max']:.3g})")
    for p in paths:
        r, second = rows[p], rows[p]["solves"][-1]
        print(f"target (issue 63): a Newton iteration <= {TARGET_WALL_S:g} s of wall on 2 idle cores; {PATHS[p][0]}: "
              f"{r['wall'] / per_iteration(r):.2f} s over both solves, "
              f"{second['wall'] / max(second['iterations'], 1):.2f} s in the second (a step of a stepping); "
              f"load {r['load'][0]} -> {r['load'][1]}")


def _ratio(old, new, key, part=None) -> float:
    """old/new of a time per Newton iteration: ``key`` ("cpu", "wall") or a part of "parts_cpu"/"parts_wall"."""
    a, b = (old[key], new[key]) if part is None else (old[key][part], new[key][part])
    return (a / per_iteration(old)) / max(b / per_iteration(new), 1e-12)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=6000)
    ap.add_argument("--paths", nargs="+", choices=list(PATHS), default=list(PATHS))
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--child", choices=list(PATHS), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.vertices < 100:
        ap.error(f"--vertices must be a vertex count >= 100, got {args.vertices}")
    if args.child:
        child(args.child, args.vertices, args.rtol)
        return
    print_table(measure_paths(args.vertices, args.paths, args.rtol))


if __name__ == "__main__":
    main()
