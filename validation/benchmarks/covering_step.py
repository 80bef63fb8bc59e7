"""CPU seconds per phase of the covering run's coupled steps, the old path and the new one side by side.

The covering run is ``femshell run sphere-spots --set chemistry.w=120 --set material.law=neo-hookean``
(R = 30, 25 007 vertices; docs/studies/accuracy-and-cost.md, "What bounds a run that covers the
sphere"). One process builds the scene's loop once, from a checkpoint of such a run (``--from DIR``,
a ``femshell run --out DIR`` of the same scene) or from its initial equilibrium, takes ``--warmup``
steps, and then, for each path in ``--paths``, goes back to that same state (``load_state_dict``)
and takes ``--steps`` steps as ``femshell run`` does: the loop's step, then a frame every
``output.every`` steps and a checkpoint every ``output.checkpoint_every`` steps (written into a
temporary directory). The paths therefore take the same steps from the same state.

The time of each phase is the process's CPU time (``time.process_time``: every thread), so load
from other jobs blurs it less than wall time; the load average is printed at the start and the end
of each path. Phases (each the time spent in no other phase):

* chemistry, growth (s(c), rest state), predictor (the secant's own work);
* Newton: quasi-Newton start (its own work: the L-BFGS recursion and line searches), Hessian
  (element Hessians + assembly), factorisation (Cholesky/LDLᵀ, the shift search), back-substitutions
  (wherever they are made), Krylov, energies and gradients (wherever they are evaluated), Newton's
  line search, the rest;
* diagnostics (H, strain energy, non-elliptic elements, over-folded edges of the new state),
  step error, stationarity rates, record (spot count), commit (the state copy before it);
* frame (fields + VTU), checkpoint (state + .npz), the rest of the step.

Paths: "old" takes the element energies and gradients from JAX (``ShellModel.gradient_kernel =
"jax"``, the code before they were compiled), "new" from the compiled kernel (the default); the
element Hessians are compiled in both. Run:

    PYTHONPATH=. .venv/bin/python validation/benchmarks/covering_step.py --from runs/covering \\
        [--warmup 1] [--steps 6] [--paths old new] [--set KEY=VALUE ...] [--profile]

Results: docs/studies/accuracy-and-cost.md, "A covering step's CPU time, phase by phase".
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

PHASES = ("chemistry", "growth", "predictor", "quasi_newton", "hessian", "factorize", "solve", "krylov",
          "energy_gradient", "line_search", "newton_rest", "diagnostics", "step_error", "stationarity", "record", "commit", "frame", "checkpoint",
          "rest")
COVERING = ("chemistry.w=120", "material.law='neo-hookean'")


class CpuTimers:
    """Exclusive CPU time per phase: a phase entered inside another is subtracted from the outer one."""

    def __init__(self):
        self.t = dict.fromkeys(PHASES, 0.0)
        self.n = {"solves": 0, "factorizations": 0, "hessians": 0, "qn_iterations": 0, "newton_iterations": 0}
        self._stack = []

    def wrap(self, owner, name, phase, count=None):
        f = getattr(owner, name)

        def timed(*a, **k):
            self._stack.append(0.0)
            t0 = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent = time.process_time() - t0
                inner = self._stack.pop()
                self.t[phase] += spent - inner
                if self._stack:
                    self._stack[-1] += spent
                if count:
                    self.n[count] += 1

        timed.__wrapped__ = f
        setattr(owner, name, timed)

    def unwrap_all(self, pairs):
        for owner, name in pairs:
            f = getattr(owner, name)
            setattr(owner, name, getattr(f, "__wrapped__", f))


def instrument(loop, timers):
    """Wrap the loop's phases (instance attributes and the solver modules' functions); returns what to unwrap."""
    import femshell.solvers.linear as linear_mod
    import femshell.solvers.newton as newton_mod
    import femshell.solvers.quasi_newton as qn_mod

    pairs = [(loop.chemistry, "step", "chemistry", None), (loop.growth, "stretch", "growth", None),
             (loop.growth, "apply", "growth", None), (loop, "_predict", "predictor", None),
             (loop, "_newton", "newton_rest", None), (newton_mod, "lagged_quasi_newton", "quasi_newton", None),
             (loop.shell, "hessian", "hessian", "hessians"), (newton_mod, "_factorize", "factorize", "factorizations"),
             (newton_mod, "shift_to_positive", "factorize", None), (newton_mod, "_krylov_direction", "krylov", None),
             (newton_mod, "line_search", "line_search", None), (linear_mod.Factorization, "solve", "solve", "solves"),
             (loop.shell, "energy_and_gradient", "energy_gradient", None), (loop.shell, "energy", "energy_gradient", None),
             (loop.shell, "gradient", "energy_gradient", None),
             (loop, "_update_curvature", "diagnostics", None), (loop, "_stretch_error", "step_error", None),
             (loop, "_follow_stationarity", "stationarity", None), (loop, "record", "record", None),
             (loop, "state_dict", "commit", None)]
    for owner, name, phase, count in pairs:
        timers.wrap(owner, name, phase, count)
    return [(o, n) for o, n, _, _ in pairs]


def load():
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def run_path(loop, scene, snapshot, steps, out_dir):
    """``steps`` steps from ``snapshot``, as ``femshell run`` takes them; returns (timers, records, load before, after)."""
    from femshell import io as fio
    from femshell.scene.frames import frame_fields

    loop.load_state_dict(snapshot)
    out = scene.output
    writer = fio.TimeSeriesWriter(out_dir, loop.mesh, "series")
    timers = CpuTimers()
    pairs = instrument(loop, timers)
    records = []
    load_start = load()
    wall0 = time.perf_counter()
    try:
        for _ in range(steps):
            t0 = time.process_time()
            sum0 = sum(timers.t.values())
            rec = loop.advance()
            records.append(rec)
            step = rec.step
            t1 = time.process_time()
            if step % out.every == 0:
                pts, pd, cd = frame_fields(out.fields, model=loop.shell, u=loop.u, s=loop.s, H_vertex=loop.H_vertex,
                                           c=loop.c, contractility=loop.params.contractility)
                writer.write(loop.t, points=pts, point_data=pd, cell_data=cd)
            t2 = time.process_time()
            if step % out.checkpoint_every == 0:
                fio.save_checkpoint(Path(out_dir) / "checkpoint.npz", type(loop).state_dict(loop), {"step": step})
            t3 = time.process_time()
            timers.t["frame"] += t2 - t1
            timers.t["checkpoint"] += t3 - t2
            timers.t["rest"] += (t3 - t0) - (sum(timers.t.values()) - sum0)
    finally:
        timers.unwrap_all(pairs)
        timers.wall = time.perf_counter() - wall0
    return timers, records, load_start, load()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="from_dir", help="a femshell run directory of the covering scene to start from")
    ap.add_argument("--warmup", type=int, default=1, help="untimed steps before the snapshot")
    ap.add_argument("--steps", type=int, default=6, help="timed steps per path")
    ap.add_argument("--paths", nargs="+", default=["old", "new"], choices=("old", "new"),
                    help="old: element energies and gradients by JAX; new: compiled (the default)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], help="scene key=value")
    ap.add_argument("--profile", action="store_true", help="cProfile (CPU clock) of each path's timed steps")
    a = ap.parse_args()

    from femshell.io import load_checkpoint
    from femshell.scene import build

    print(f"covering run's steps, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
          f"nice {os.nice(0)}, load {load()}", flush=True)
    scene = build.load_scene("sphere-spots", [*COVERING, *a.overrides])
    mesh = build.make_mesh(scene)
    t0 = time.process_time()
    state = load_checkpoint(Path(a.from_dir) / "checkpoint.npz")[0] if a.from_dir else None
    loop = build.time_loop(scene, mesh, state=state)
    print(f"{mesh.n_vertices} vertices, {loop.shell.n_free} unknowns; set-up {time.process_time() - t0:.1f} CPU s "
          f"(from {'step ' + str(loop.step) if state else 'the initial equilibrium'})", flush=True)
    for _ in range(a.warmup):
        loop.advance()
    from femshell.scene.frames import frame_fields
    frame_fields(scene.output.fields, model=loop.shell, u=loop.u, s=loop.s, H_vertex=loop.H_vertex, c=loop.c,
                 contractility=loop.params.contractility)      # compiles the frame's kernels, as a run's first frame
    for path in a.paths:                                        # each path's kernels compiled before any timing
        PATHS[path](loop)
        loop.shell.energy(loop.u), loop.shell.energy_and_gradient(loop.u)
    snapshot = loop.state_dict()
    print(f"snapshot at step {loop.step}, t = {loop.t:.5g}", flush=True)

    results = {}
    for path in a.paths:
        prof = None
        if a.profile:
            import cProfile
            prof = cProfile.Profile(time.process_time)
            prof.enable()
        PATHS[path](loop)
        with tempfile.TemporaryDirectory() as tmp:
            timers, records, l0, l1 = run_path(loop, scene, snapshot, a.steps, tmp)
        if prof is not None:
            import pstats
            prof.disable()
            print(f"cProfile of {path} (CPU s, {a.steps} steps):")
            pstats.Stats(prof).sort_stats("tottime").print_stats(30)
        results[path] = (timers, records, l0, l1)
        tot = sum(timers.t.values())
        print(f"  {path}: {len(records)} steps, {tot / len(records):.2f} CPU s and {timers.wall / len(records):.2f} wall s "
              f"per step, load {l0} -> {l1}; "
              + ", ".join(f"step {r.step} newton {r.newton_iterations} cuts {r.cuts}" for r in records), flush=True)
    _print_table(results)


def _old_path(loop):
    """Element energies and gradients by JAX (the path before the compiled ones; Hessians compiled in both)."""
    loop.shell.gradient_kernel = "jax"


def _new_path(loop):
    """Element energies and gradients by the compiled kernel (the default)."""
    loop.shell.gradient_kernel = "compiled"


PATHS = {"old": _old_path, "new": _new_path}


def _print_table(results):
    names = list(results)
    steps = {p: max(len(results[p][1]), 1) for p in names}
    head = f"{'phase (CPU s per step)':<24}" + "".join(f"{p:>10}" for p in names)
    if len(names) == 2:
        head += f"{names[0] + '/' + names[1]:>12}"
    print(head)
    for ph in PHASES + ("total",):
        vals = [(sum(results[p][0].t.values()) if ph == "total" else results[p][0].t[ph]) / steps[p] for p in names]
        line = f"{ph:<24}" + "".join(f"{v:>10.3f}" for v in vals)
        if len(vals) == 2:
            line += f"{vals[0] / vals[1]:>12.2f}" if vals[1] > 0 else f"{'–':>12}"
        print(line)
    for key in ("solves", "factorizations", "hessians"):
        print(f"{key + ' per step':<24}" + "".join(f"{results[p][0].n[key] / steps[p]:>10.2f}" for p in names))
    if len(names) == 2:
        r0, r1 = results[names[0]][1][-1], results[names[1]][1][-1]
        print(f"last step: t {r0.t:.6g} / {r1.t:.6g}, max c {r0.max_c:.6g} / {r1.max_c:.6g}, "
              f"spots {r0.n_spots} / {r1.n_spots}, energy {r0.energy:.10g} / {r1.energy:.10g}")


if __name__ == "__main__":
    sys.exit(main())
