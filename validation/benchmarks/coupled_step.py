"""Wall time of the coupled mechanochemical loop: per step and per run, spots scenario, ~2 500 / 10 000 / 25 000 vertices.

The scenario is the embedded scene ``sphere-spots`` (theory §1.5: sphere R = 30,
h = 2 volume-conserving, c* = 0.1, D = 0, Λmax/Λmin = 15/10, b = 100, w = 15, Hs = 0.05,
β = 1, ν = 0.5; t_final = 100, ds_max = 0.05, dt_max = 1, stationary stop) with only
``mesh.n_vertices`` changed. The loop is the library's own: ``femshell.scene.load_scene``
-> ``make_mesh`` -> ``time_loop`` (a ``femshell.coupled.CoupledLoop``) -> ``loop.run``.
Nothing of the loop is reimplemented here; its pieces are wrapped with timers:

* growth: ``GrowthRestState.stretch`` + ``apply`` (s(c), rest state, ``set_rest_state``);
* predictor: the secant predictor (two energy evaluations);
* Newton (``minimize(stable=True)``), split into Hessian assembly, energy + gradient at
  the start, LDLᵀ factorisation (numerical refactorisation; gives the inertia, i.e. the
  stability check), back-substitution, line search, saddle escapes (eigenvector of the
  most negative eigenvalue + trial energies; the rest of the stability check);
* curvature H (``GrowthRestState.mean_curvature``) and the strain energy of the new state;
* chemistry (``ReactionDiffusion.step``; D = 0: the exact exponential update);
* record: the step record (``count_spots``), the stationarity measures, the rest.

Rejected attempts (step cuts) are included in the step that needed them. Each size runs
in its own process (so the peak RSS, ``resource.getrusage``, is that size's); the load
average (``os.getloadavg``) is printed at the start and end of each size. Output frames
and checkpoints of ``femshell run`` are not written (that is I/O, not the loop).

Whole run: ``--full SIZE`` runs that size to the scene's stop (stationary pattern or
t_final; capped by ``--wall-limit`` seconds). The other sizes run ``--warmup`` steps,
then ``--steps`` timed steps, and their whole run is ESTIMATED from the full run's
counts: setup(N) + S_full × (per-step cost outside Newton)(N) + I_full × (cost per
Newton iteration)(N) + S_full × (per-solve Newton overhead)(N), with S_full accepted
steps (their rejected attempts are in their time) and I_full Newton iterations of the full
run; a full run cut by ``--wall-limit`` is first extended to t_final at its last 20 steps'
mean dt (printed as an extrapolation), and so are its counts. It assumes the
finer mesh needs the same steps and iterations as the coarse one (ds_max bounds the
largest change of s per element, which does not depend much on the mesh, but the
Newton iterations per step do depend on the phase of the run and on the mesh).

    .venv/bin/python validation/benchmarks/coupled_step.py \\
        [--sizes 2500 10000 25000] [--full 2500] [--warmup 3] [--steps 6] [--wall-limit 1500] \\
        [--profile SIZE] [--set solver.step_control=error ...] [--json out.json]

Results (per-step cost by phase, whole runs, threads) are in docs/studies/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

# femshell is imported in the functions that run a size: the parent process only starts one child per size
# (its own peak memory and thread settings) and does not load femshell, JAX or MKL itself

CATS = ("growth", "predictor", "newton", "hessian", "eg_start", "quasi_newton", "factorize", "check", "solve",
        "line_search", "escape", "curvature", "energy", "chemistry", "record")


class Timers:
    """Cumulative wall time per category and call counts; ``snapshot`` for differences."""

    def __init__(self):
        self.t = dict.fromkeys(CATS, 0.0)
        self.last = {}  # duration of the last call per category
        self.n = {"factorizations": 0, "escapes": 0, "newton_solves": 0, "newton_failed": 0, "iterations": 0,
                  "qn_iterations": 0, "shift_searches": 0}

    def wrap(self, obj, name, cat, count=None):
        f = getattr(obj, name)

        def timed(*a, **k):
            t0 = time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                dt = time.perf_counter() - t0
                self.t[cat] += dt
                self.last[cat] = dt
                if count:
                    self.n[count] += 1

        setattr(obj, name, timed)

    def snapshot(self):
        return dict(self.t), dict(self.n), time.perf_counter()


def instrument(loop, timers):
    """Timed wrappers around the loop's parts (instance attributes and the Newton module's helpers)."""
    import femshell.coupled as coupled_mod
    import femshell.solvers.newton as newton_mod

    timers.wrap(loop.growth, "stretch", "growth")
    timers.wrap(loop.growth, "apply", "growth")
    timers.wrap(loop.growth, "mean_curvature", "curvature")
    # _update_curvature = H + strain energy of the new state; "energy" is the difference (see summarise)
    timers.wrap(loop, "_update_curvature", "energy")
    timers.wrap(loop.shell, "hessian", "hessian")
    timers.wrap(loop.chemistry, "step", "chemistry")
    timers.wrap(loop, "_predict", "predictor")
    timers.wrap(newton_mod, "escape_saddle", "escape", count="escapes")
    timers.wrap(newton_mod, "_factorize", "factorize", count="factorizations")
    # the shift search factorises K + tau D by Cholesky attempts of its own, not through _factorize
    timers.wrap(newton_mod, "shift_to_positive", "factorize", count="shift_searches")

    newton = loop._newton

    def timed_newton(u, *args, **kwargs):      # the snap after a fold passes max_iter=, residual_scale=, stall=
        t0 = time.perf_counter()
        h0 = timers.t["hessian"]
        e0 = timers.t["escape"]
        res = None
        timers.last.clear()
        try:
            res = newton(u, *args, **kwargs)
            return res
        except newton_mod.NewtonError as exc:
            res = exc.result
            timers.n["newton_failed"] += 1
            raise
        finally:
            timers.t["newton"] += time.perf_counter() - t0
            timers.n["newton_solves"] += 1
            if res is not None:
                tm = res.times
                timers.t["eg_start"] += max(tm.get("assembly", 0.0) - (timers.t["hessian"] - h0), 0.0)
                timers.t["solve"] += tm.get("solve", 0.0)
                timers.t["quasi_newton"] += tm.get("quasi_newton", 0.0)
                timers.n["qn_iterations"] += int(res.quasi_newton_iterations)
                timers.t["line_search"] += max(tm.get("line_search", 0.0) - (timers.t["escape"] - e0), 0.0)
                timers.n["iterations"] += int(res.iterations)
                if res.converged:
                    # the Hessian + LDLᵀ at the converged point serve only the convergence/stability
                    # check (inertia = no negative eigenvalue): the stability check's cost
                    timers.t["check"] += timers.last.get("hessian", 0.0) + timers.last.get("factorize", 0.0)

    loop._newton = timed_newton
    timers.wrap(loop, "record", "record")
    return coupled_mod


def rss_gb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2


def load():
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def one_size(n, full, warmup, steps, wall_limit, profile, overrides=()):
    """Run one size in this process (``overrides``: scene key=value after the size); returns a dict of results."""
    from femshell.scene import build

    out = {"n_request": n, "load_start": load()}
    t0 = time.perf_counter()
    scene = build.load_scene("sphere-spots", [f"mesh.n_vertices={n}", *overrides])
    mesh = build.make_mesh(scene)
    out["t_mesh"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    loop = build.time_loop(scene, mesh)  # includes the initial (ramped) stable equilibrium
    out["t_setup"] = time.perf_counter() - t0
    out["vertices"] = int(mesh.n_vertices)
    out["unknowns"] = int(loop.shell.n_free)
    out["initial_newton"] = int(loop.newton_total)
    timers = Timers()
    instrument(loop, timers)
    records = []
    snaps = [timers.snapshot()]

    def cb(rec, lp):
        snaps.append(timers.snapshot())
        records.append(rec.as_dict())
        wall = snaps[-1][2] - snaps[-2][2]
        print(f"  [{out['vertices']}] step {rec.step:4d} t {rec.t:8.4g} dt {rec.dt:8.3g} newton {rec.newton_iterations:2d} "
              f"cuts {rec.cuts} max c {rec.max_c:.3f} spots {rec.n_spots:3d} {wall:7.2f}s  load {load()}",
              file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    prof = None
    if full:
        result = loop.run(callback=cb, wall_time=wall_limit, max_steps=100000)
    else:
        result = loop.run(callback=cb, max_steps=warmup)
        if result.status == "max_steps":
            if profile:
                import cProfile
                prof = cProfile.Profile()
                prof.enable()
            result = loop.run(callback=cb, max_steps=steps)
            if prof:
                prof.disable()
    out["t_loop"] = time.perf_counter() - t0
    out["status"], out["message"] = result.status, result.message
    out["t_final_reached"] = float(loop.t)
    out["t_final"] = float(loop.stepping.t_final)
    out["n_spots"] = records[-1]["n_spots"] if records else None
    out["rejected"] = int(loop.n_rejected)
    out["load_end"] = load()
    out["rss_gb"] = rss_gb()
    # per-step differences of the timers
    per = []
    for k, rec in enumerate(records):
        (ta, na, wa), (tb, nb, wb) = snaps[k], snaps[k + 1]
        d = {c: tb[c] - ta[c] for c in CATS}
        d.update({c: nb[c] - na[c] for c in nb})
        d["wall"] = wb - wa  # callback to callback: the step record (count_spots) is outside rec.wall_s
        d["step"], d["t"], d["dt"], d["cuts"] = rec["step"], rec["t"], rec["dt"], rec["cuts"]
        per.append(d)
    out["steps"] = per
    first = 0 if full else min(warmup, len(per))
    out["timed_from"] = first
    if prof:
        import io
        import pstats
        s = io.StringIO()
        pstats.Stats(prof, stream=s).sort_stats("tottime").print_stats(20)
        s2 = io.StringIO()
        pstats.Stats(prof, stream=s2).sort_stats("cumulative").print_stats(25)
        out["profile"] = s.getvalue() + "\n" + s2.getvalue()
    return out


def summarise(r):
    """Mean per timed step of each category (s) and the derived costs."""
    st = r["steps"][r["timed_from"]:]
    k = max(len(st), 1)
    m = {c: sum(s.get(c, 0.0) for s in st) / k for c in CATS + ("wall",)}
    m["energy"] -= m["curvature"]
    for c in ("factorizations", "escapes", "newton_solves", "iterations", "qn_iterations", "cuts"):
        m[c] = sum(s.get(c, 0) for s in st) / k
    m["n"] = len(st)
    m["other"] = m["wall"] - sum(m[c] for c in ("growth", "predictor", "newton", "curvature", "energy",
                                                 "chemistry", "record"))
    m["newton_other"] = m["newton"] - sum(m[c] for c in ("hessian", "eg_start", "quasi_newton", "factorize",
                                                          "solve", "line_search", "escape"))
    it = max(m["iterations"], 1e-300)
    # a Newton solve of i iterations does i+1 Hessians and factorisations and i solves/line searches
    m["per_iter"] = (m["newton"] - m["eg_start"]) / (it + m["newton_solves"]) if m["newton_solves"] else 0.0
    m["per_solve_fixed"] = m["eg_start"] / max(m["newton_solves"], 1)
    return m


def _extension(r):
    """(factor on the step count to reach t_final, recent mean dt, extra steps) of a run cut by wall time."""
    st = r["steps"]
    recent = st[-20:]
    dt_recent = sum(s["dt"] for s in recent) / max(len(recent), 1)
    extra = max(r.get("t_final", 100.0) - r["t_final_reached"], 0.0) / max(dt_recent, 1e-300)
    return (len(st) + extra) / max(len(st), 1), dt_recent, extra


def print_table(results):
    print()
    print("per accepted step, mean over the timed steps (s); Newton = Hess + E+g0 + qN + factor + solve + lsearch + "
          "escape; qN = quasi-Newton on the held factorisation (its line searches included); check = the part of "
          "Hess + factor spent at the converged point (stability check)")
    hdr = (f"{'vertices':>8} {'unknowns':>8} {'steps':>5} {'its/st':>6} {'qN/st':>5} {'fact/st':>7} {'growth':>7} "
           f"{'pred':>6} {'Newton':>7} {'Hess':>7} {'E+g0':>6} {'qN':>6} {'factor':>7} {'check':>6} {'solve':>6} {'lsearch':>7} {'escape':>6} "
           f"{'H':>6} {'energy':>6} {'chem':>7} {'record':>6} {'other':>6} {'step':>7} {'RSS GB':>6} load start/end")
    print(hdr)
    for r in results:
        m = summarise(r)
        print(f"{r['vertices']:>8} {r['unknowns']:>8} {m['n']:>5} {m['iterations']:>6.2f} {m['qn_iterations']:>5.2f} "
              f"{m['factorizations']:>7.2f} {m['growth']:>7.4f} {m['predictor']:>6.3f} {m['newton']:>7.2f} "
              f"{m['hessian']:>7.2f} {m['eg_start']:>6.3f} {m['quasi_newton']:>6.2f} {m['factorize']:>7.2f} {m['check']:>6.2f} {m['solve']:>6.3f} {m['line_search']:>7.3f} "
              f"{m['escape']:>6.3f} {m['curvature']:>6.3f} {m['energy']:>6.3f} {m['chemistry']:>7.5f} "
              f"{m['record']:>6.3f} {m['other']:>6.3f} {m['wall']:>7.2f} {r['rss_gb']:>6.2f} "
              f"{r['load_start']} / {r['load_end']}")
    ref = next((r for r in results if r["vertices"] and r.get("full")), None)
    print()
    print("whole run (s): mesh, setup (model + initial stable equilibrium), loop; estimates marked ~")
    for r in results:
        m = summarise(r)
        if r.get("full"):
            I = sum(s["iterations"] for s in r["steps"])
            print(f"{r['vertices']:>8}: mesh {r['t_mesh']:.1f}  setup {r['t_setup']:.1f}  loop {r['t_loop']:.1f}  "
                  f"total {r['t_mesh'] + r['t_setup'] + r['t_loop']:.1f} s = {(r['t_mesh'] + r['t_setup'] + r['t_loop']) / 60:.1f} min "
                  f"[{r['status']}: {r['message']}; {len(r['steps'])} steps, {r['rejected']} rejected, "
                  f"{I} Newton iterations, {sum(s['newton_solves'] for s in r['steps'])} solves, t = {r['t_final_reached']:.4g}, "
                  f"{r['n_spots']} spots]")
            if r["status"] == "wall_time":
                f, dt_recent, extra = _extension(r)
                loop_est = r["t_loop"] * f
                print(f"{'':>8}  cut by --wall-limit at t = {r['t_final_reached']:.4g} of {r.get('t_final', 100.0):g}: "
                      f"at the last 20 steps' mean dt = {dt_recent:.3g} another ~{extra:.0f} steps; ~total "
                      f"{(r['t_mesh'] + r['t_setup'] + loop_est) / 60:.0f} min (an EXTRAPOLATION: dt may grow or the "
                      f"pattern may become stationary earlier)")
        elif ref is not None:
            Sref = len(ref["steps"])
            Iref = sum(s["iterations"] for s in ref["steps"])
            solves_ref = sum(s["newton_solves"] for s in ref["steps"])
            if ref["status"] == "wall_time":
                # the full run was cut: extend its counts to t_final at its last 20 steps' mean dt
                f = _extension(ref)[0]
                Sref, Iref, solves_ref = round(Sref * f), round(Iref * f), round(solves_ref * f)
            outside = m["wall"] - m["newton"]
            est_b = r["t_mesh"] + r["t_setup"] + Sref * outside + (Iref + solves_ref) * m["per_iter"] + \
                solves_ref * m["per_solve_fixed"]
            walls = sorted(x["wall"] for x in r["steps"][r["timed_from"]:]) or [0.0]
            median = walls[len(walls) // 2] if len(walls) % 2 else 0.5 * (walls[len(walls) // 2 - 1] + walls[len(walls) // 2])
            est_a = r["t_mesh"] + r["t_setup"] + Sref * median
            how = "extrapolated to t_final, see above" if ref["status"] == "wall_time" else "measured"
            print(f"{r['vertices']:>8}: mesh {r['t_mesh']:.1f}  setup {r['t_setup']:.1f}  "
                  f"per Newton iteration {m['per_iter']:.2f}  outside Newton {outside:.2f}/step  "
                  f"~total {est_b:.0f} s = ~{est_b / 60:.0f} min (ESTIMATE from {Sref} steps, {Iref} iterations, {solves_ref} "
                  f"solves of the {ref['vertices']}-vertex run, {how}); ~{est_a / 60:.0f} min as {Sref} x the median "
                  f"timed step ({median:.1f} s)")
        else:
            print(f"{r['vertices']:>8}: mesh {r['t_mesh']:.1f}  setup {r['t_setup']:.1f}  (no full run to estimate from)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2500, 10000, 25000])
    ap.add_argument("--full", type=int, nargs="*", default=[2500], help="sizes run to the scene's stop")
    ap.add_argument("--warmup", type=int, default=3, help="untimed steps before the timed ones (other sizes)")
    ap.add_argument("--steps", type=int, default=6, help="timed steps (other sizes)")
    ap.add_argument("--wall-limit", type=float, default=1500.0, help="cap of a full run's loop (s)")
    ap.add_argument("--profile", type=int, nargs="*", default=[], help="sizes whose timed steps run under cProfile")
    ap.add_argument("--json", help="write all results here")
    ap.add_argument("--from-json", nargs="*", default=[], help="only print the table of earlier --json files")
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    help="scene key=value for every size, e.g. solver.step_control=error")
    ap.add_argument("--_child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--_out", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a._child is not None:
        full = a._child in a.full
        r = one_size(a._child, full, a.warmup, a.steps, a.wall_limit, a._child in a.profile, a.overrides)
        r["overrides"] = a.overrides
        r["full"] = full
        with open(a._out, "w") as f:
            json.dump(r, f)
        return
    if any(n < 100 for n in a.sizes):
        ap.error(f"--sizes must be vertex counts >= 100, got {a.sizes}")
    if a.json and not a.from_json:      # checked before hours of runs, not after the first size
        from femshell.io import check_writable_dir
        try:
            check_writable_dir(Path(a.json).resolve().parent, "--json directory")
        except ValueError as exc:
            ap.error(str(exc))
    results = []
    for p in a.from_json:
        with open(p) as f:
            results += json.load(f)
    if not a.from_json:
        import tempfile
        print(f"sphere-spots, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
              f"MKL_NUM_THREADS={os.environ.get('MKL_NUM_THREADS', 'unset')}, load {load()}"
              + (f", --set {' '.join(a.overrides)}" if a.overrides else ""), flush=True)
        for n in a.sizes:
            with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tf:
                path = tf.name
            cmd = [sys.executable, __file__, "--_child", str(n), "--_out", path, "--warmup", str(a.warmup),
                   "--steps", str(a.steps), "--wall-limit", str(a.wall_limit), "--full", *map(str, a.full),
                   "--profile", *map(str, a.profile), *(f"--set={o}" for o in a.overrides)]
            try:
                subprocess.run(cmd, check=True)
                with open(path) as f:
                    r = json.load(f)
            finally:
                os.unlink(path)
            results.append(r)
            if a.json:
                from femshell.io import atomic_write_json
                atomic_write_json(a.json, results)
            if r.get("profile"):
                print(f"\ncProfile of the timed steps, {r['vertices']} vertices:\n{r['profile']}")
            print_table(results)
    else:
        print_table(results)


if __name__ == "__main__":
    main()
