"""Wall time of the coupled mechanochemical loop: per step and per run, spots scenario, ~2 500 / 10 000 / 25 000 vertices.

The scenario is the embedded scene ``sphere-spots`` (design.md 1.5: sphere R = 30,
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
        [--profile SIZE] [--json out.json]

Measured 2026-11-23 12:09-12:58 UTC, 2 cores shared with other jobs (1-minute load average
3.4-5.1 during the run, so this process had roughly half the machine), PARDISO back-end,
MKL threads as femshell sets them (one below 2M stored non-zeros), command as above with
``--sizes 2500 10000 25000 --full 2500 --wall-limit 1500 --warmup 3 --steps 6``.
Seconds per accepted step, mean over the timed steps (2 505: all 402 steps of the run;
10 011 and 25 007: steps 4-9); "check" is the part of Hessian + factorisation spent at
the converged point, i.e. the stability (inertia) check:

| vertices | unknowns | its/step | LDLᵀ/step | Hessian | LDLᵀ | (check) | solve | line search | growth | H | chemistry | record | step (median) | peak RSS |
|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
| 2 505 | 15 018 | 3.13 | 4.30 | 1.61 | 1.65 | (0.70) | 0.05 | 0.24 | 0.006 | 0.011 | 0.0002 | 0.04 | 3.74 (3.38) | 0.77 GB |
| 10 011 | 60 054 | 4.33 | 9.00 | 9.04 | 23.84 | (4.10) | 0.33 | 1.06 | 0.027 | 0.05 | 0.0005 | 0.17 | 35.1 (19.3) | 1.56 GB |
| 25 007 | 150 030 | 2.00 | 3.00 | 15.09 | 35.46 | (15.43) | 0.44 | 0.97 | 0.077 | 0.11 | 0.001 | 0.65 | 53.7 (57.8) | 2.30 GB |

Per call: Hessian 0.39 / 1.7 / 5.0 s, LDLᵀ (incl. inertia) 0.38 / 2.65 / 11.8 s (≈ n^1.5, nested
dissection). Secant predictor 0.02 / 0.10 / 0.23 s, energy of the new state ≈ H. The 10k mean
includes one step (step 4) whose Hessian was indefinite away from the minimum: 12 iterations,
35 factorisations (shifted Newton), 117 s; the 2 505 run had 7 such steps in 402 (5.8-16 s).
Setup (ShellModel, JAX compilation, ramped initial stable equilibrium): 52 / 138 / 365 s.

Whole run. 2 505 vertices: cut by the 1500 s cap at t = 40.7 of t_final = 100 after 402
accepted steps (66 rejected by ds_max, no Newton failure), 1 257 Newton iterations, 25.9 min
with setup; dt grew from 0.01 to ~0.2-0.3 (mean 0.034 / 0.046 / 0.093 / 0.23 over steps
1-100 / -200 / -300 / -402) and the pattern was still the single seeded spot (max c 0.475,
not stationary). Extrapolated at the last 20 steps' mean dt (0.29): ~205 more steps, ~39 min.
10 011 and 25 007 vertices, ESTIMATES with the step and iteration counts of the (extrapolated)
2 505 run, 607 steps: ~200-280 min and ~590-750 min (~10-12 h) (lower: 607 × the median
timed step; upper: per-Newton-iteration cost × 1 897 iterations + 607 checks). A full
25k run under 1 hour here would need ≤ ~6 s per step at ~600 steps, about 10× less than
measured; the step is bounded by the LDLᵀ factorisations (2/3 of it at 25k) and the
Hessian assemblies (~1/4), of which one each per step is the stability check.

cProfile of two steps at 25 007 vertices (``--sizes 25000 --full --warmup 1 --steps 2
--profile 25000``, load 4.4-4.6, 48 s per step): PARDISO 61.6 of 96.6 s (14 calls); the
first factorisation of every Newton solve is a fresh ``Factorization`` (13.3 s: symbolic
analysis + ordering + symmetry check + numerical) against 9.0 s for a refactorisation,
because ``minimize`` starts each solve with no factorisation although the pattern never
changes during a run: ~4.3 s (~9 %) per coupled step, ~0.4 s (~10 %) at 2 505 vertices.
Hessian 4.6 s per call, of which the JAX element kernels ~3.7 s (``np.asarray`` waiting
for them) and the sparse scatter (``assembly.matrix``, pattern already cached) 0.77 s;
the step record's ``count_spots`` 0.74 s per step. Nothing else above 1 %.

Measured 2026-11-25 05:51-06:08 UTC on an idle machine (load 0.1-1.4), 25 007 vertices, steps
4-9, one process at a time: the code of the table above, 17.9 s per step (factorisations 11.5 s
for 3 LDLᵀ, Hessian 5.4 s); with the factorisations kept across Newton solves (the symbolic
analysis done once per run) and Cholesky tried before LDLᵀ (``Refactorizer``), 14.4 s (8.7 s,
4.7 s); with the quasi-Newton start on the held factorisation (``TimeStepping.quasi_newton``),
**6.7 s**: 5 quasi-Newton iterations, no Newton iteration, 1 Hessian (1.8 s) and 1 Cholesky
(2.9 s, both the stability check) per step, the rest the quasi-Newton back-substitutions and
line searches (1.6 s); setup 134 -> 79 s, peak RSS 2.3 GB. At 2 505 / 10 011 vertices (same
day, load 2.5-3.2: a 25 000-vertex run shared the machine) 0.69 / 4.3 s per step, setup 11 /
44 s (10 011: one step needed a Newton iteration after its quasi-Newton ones).

Whole runs with that code (2026-11-25, load 2-4: the two runs shared the machine). 2 505
vertices (``--sizes 2500 --full 2500 --wall-limit 1500``): t_final = 100 reached in 1 130
accepted steps (207 rejected by ds_max, 208 Newton iterations besides the quasi-Newton
ones), 0.79 s per step, setup 11.6 s, **15.0 min** in all; one spot at the end (max c 0.469).
25 007 vertices, the study's spots scenario (``validation/sphere_patterns_study.py --scenarios
spots --scale 1.0 --n-vertices 6250 --t-final 100``, same parameters and stop): t = 100 in 354 steps (54 cut),
7.2 s per step (median 6.5), **45.5 min** with setup; one spot, not stationary. The finer mesh
took a third of the coarse one's steps (mean dt 0.3-0.7 from t = 20 at 25k, 0.05-0.12 at
2.5k; why is not analysed), so the estimate above, which carries the coarse run's step count
over to the finer meshes, overestimates their whole run.

None of those runs became stationary: the staggered chemistry step oscillated at the spot's
edge (``femshell.coupled``, "Why the staggering limits dt"). With the loop's feedback bound on dt
(2026-11-25, load 1.7-4.4, the three runs partly sharing the machine) every size reaches a
stationary spot, measured whole (``--sizes 2500 10000 --full 2500 10000 --wall-limit 2400``;
25 007 through the study as above):

| vertices | ends | steps (rejected) | s per step | setup | whole run |
|---|---|---|---|---|---|
| 2 505 | stationary at t = 72.3 | 964 (102) | 0.78 | 11.5 s | **12.7 min** |
| 10 011 | stationary at t = 10.6 | 176 (12) | 2.66 | 43.3 s | **8.5 min** |
| 25 007 | stationary at t = 45.2 | 275 | 6-11 | ~170 s | **37.7 min** |

The step counts do not follow the mesh (the coarse spot creeps for longer), so whole runs are
measured, not estimated.

Threads (2026-11-25, idle, ``--sizes 25000 --full --warmup 3 --steps 6``): femshell selects
MKL's sequential layer (bit-for-bit resumes, ``femshell.solvers.linear``): 7.32 s per step
(Cholesky 3.16 s, Hessian 1.86 s, quasi-Newton 1.82 s), setup 82 s. With
``MKL_THREADING_LAYER=GNU`` in the environment the Cholesky runs on both cores: **5.58 s** per
step (1.59 s, 1.80 s, 1.74 s), setup 62 s. (Before the fix that pins the thread count for
every PARDISO phase, that setting segfaulted at 25 007 vertices.)

Element threads (2026-11-27, ``--sizes 25000 --full --warmup 3 --steps 6``, one run at a time,
load 1.4-2.8, MKL sequential): the element kernels' chunks on one thread (``FEMSHELL_THREADS=1``)
10.13 s per step (Hessian 2.46 s, quasi-Newton 2.56 s, Cholesky 4.34 s), setup 113 s; on two
(the default on 2 cores) **9.21 s** (1.97, 2.09, 4.59 s), setup 109 s. The results are the same
bit for bit (``femshell.shell.element.element_threads``).
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
    timers.wrap(newton_mod, "_escape_saddle", "escape", count="escapes")
    timers.wrap(newton_mod, "_factorize", "factorize", count="factorizations")
    # the shift search factorises K + tau D by Cholesky attempts of its own, not through _factorize
    timers.wrap(newton_mod, "_shift_to_positive", "factorize", count="shift_searches")

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


def one_size(n, full, warmup, steps, wall_limit, profile):
    """Run one size in this process; returns a dict of results."""
    from femshell.scene import build

    out = {"n_request": n, "load_start": load()}
    t0 = time.perf_counter()
    scene = build.load_scene("sphere-spots", [f"mesh.n_vertices={n}"])
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
    ap.add_argument("--_child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--_out", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a._child is not None:
        full = a._child in a.full
        r = one_size(a._child, full, a.warmup, a.steps, a.wall_limit, a._child in a.profile)
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
              f"MKL_NUM_THREADS={os.environ.get('MKL_NUM_THREADS', 'unset')}, load {load()}", flush=True)
        for n in a.sizes:
            with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tf:
                path = tf.name
            cmd = [sys.executable, __file__, "--_child", str(n), "--_out", path, "--warmup", str(a.warmup),
                   "--steps", str(a.steps), "--wall-limit", str(a.wall_limit), "--full", *map(str, a.full),
                   "--profile", *map(str, a.profile)]
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
