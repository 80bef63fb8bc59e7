"""Which bound sets the coupled loop's time step: the stretch change per step, or the staggering's feedback?

The loop (``femshell.coupled``) takes the next dt as the smaller of two limits:

* Δs: dt · min(grow, safety · ds_max / Δs), Δs the largest change of the stretch s in one element over
  the step just made (accuracy of the quasi-static path);
* feedback: ``feedback_step_limit(g)``, the stability of the staggered (explicit) coupling for the source
  gain g estimated from that step.

An implicit coupling would lift only the second. This script runs a sphere scene step by step and
prints, per step, both limits and which one is the smaller, then the counts. Default: the
``sphere-spots`` scene at w = 120 (where spots cover the sphere), neo-Hookean, R = 15, 2 700
vertices, ds_max = 0.05: the model of the 25 000-vertex covering run at a quarter of its area.

``--resume DIR`` continues the run in DIR (a ``femshell run`` output: its scene.toml and checkpoint;
nothing in DIR is written) under that run's own scene and any ``--set``, e.g. another
``solver.dt_max`` or ``solver.source_rule`` from the same state. ``--save DIR`` writes the state
reached (scene.toml, checkpoint.npz) for a later ``--resume DIR`` of this script. A step that
``solver.dt_max`` caps below both limits is counted as "dt_max". The last line counts the steps
whose Newton solve needed 2 or more iterations past the quasi-Newton start (where the shape
rearranges locally; they cost several quiet steps each) and gives the wall time per unit of model
time (the first step's compilation included: a few seconds).

    MKL_NUM_THREADS=1 .venv/bin/python validation/benchmarks/step_bounds.py [--steps 400] \\
        [--n-vertices 2700] [--radius 15] [--set chemistry.w=120 ...] [--resume DIR] [--save DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from femshell.coupled import feedback_step_limit
from femshell.io import CheckpointError, atomic_write_text, load_checkpoint, save_checkpoint
from femshell.scene.build import load_scene, make_mesh, time_loop
from femshell.scene.schema import dump_toml

DEFAULTS = ["chemistry.w=120", "material.law='neo-hookean'", "solver.ds_max=0.05"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="sphere-spots")
    ap.add_argument("--n-vertices", type=int, default=2700)
    ap.add_argument("--radius", type=float, default=15.0)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    help=f"scene key=value, after the defaults {' '.join(DEFAULTS)} (with --resume: after the run's scene)")
    ap.add_argument("--resume", metavar="DIR", help="continue the femshell run in DIR (read only)")
    ap.add_argument("--save", metavar="DIR", help="write the state reached (scene.toml, checkpoint.npz) for --resume")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.n_vertices < 100 or args.radius <= 0:
        ap.error("--steps >= 1, --n-vertices >= 100 and --radius > 0")
    if args.save and ((Path(args.save) / "summary.json").exists()
                      or args.resume and Path(args.save).resolve() == Path(args.resume).resolve()):
        ap.error(f"--save {args.save}: a femshell run is there; save into another directory")
    t0 = time.perf_counter()
    if args.resume:
        run = Path(args.resume)
        if not (run / "scene.toml").is_file():
            ap.error(f"--resume {run}: no scene.toml of a femshell run there")
        scene = load_scene(str(run / "scene.toml"), overrides=args.overrides)
        if scene.kind != "time":
            ap.error(f"--resume {run}: a {scene.kind} run; this script follows the time loop")
        try:
            state, _ = load_checkpoint(run / "checkpoint.npz")
        except (CheckpointError, FileNotFoundError) as exc:
            ap.error(f"--resume {run}: {exc}")
        mesh = make_mesh(scene)
        loop = time_loop(scene, mesh, state=state)
        print(f"{run}, {mesh.n_vertices} vertices: continued from step {loop.step}, t = {loop.t:.6g}", flush=True)
    else:
        scene = load_scene(args.scene, overrides=DEFAULTS + [f"mesh.n_vertices={args.n_vertices}",
                                                             f"mesh.radius={args.radius}"] + args.overrides)
        mesh = make_mesh(scene)
        loop = time_loop(scene, mesh)
        print(f"{args.scene}, {mesh.n_vertices} vertices: initial equilibrium in {time.perf_counter() - t0:.1f} s",
              flush=True)
    st, p = loop.stepping, loop.params
    count = {"ds": 0, "feedback": 0, "dt_max": 0}
    hard, t_start, w_start = 0, loop.t, time.perf_counter()
    print(" step        t       dt       Δs     gain  feedback limit  Δs limit  smaller  spots  newton")
    for _ in range(args.steps):
        if loop.done:
            break
        rec = loop.advance()
        fb = feedback_step_limit(rec.feedback_gain, p.beta, st.feedback_amplification, exponential=True)
        # the loop's own rule (femshell.coupled, "next step"): never below 0.1 dt, no growth after a cut
        factor = max(min(st.grow, st.safety * st.ds_max / rec.ds) if rec.ds > 0 else st.grow, 0.1)
        ds = rec.dt * (min(factor, 1.0) if rec.cuts else factor)
        who = "dt_max" if min(fb, ds) > st.dt_max else "feedback" if fb < ds else "ds"
        count[who] += 1
        hard += rec.newton_iterations >= 2
        print(f"{rec.step:5d} {rec.t:8.4f} {rec.dt:8.2e} {rec.ds:8.2e} {rec.feedback_gain:8.3g} {fb:15.2e} "
              f"{ds:9.2e}  {who:8s} {rec.n_spots:5d}  {rec.newton_iterations:6d}", flush=True)
    n = sum(count.values())
    wall, span = time.perf_counter() - w_start, loop.t - t_start
    print(f"{n} steps to t = {loop.t:.4g} in {time.perf_counter() - t0:.0f} s: the Δs bound was the smaller in "
          f"{count['ds']}, the feedback bound in {count['feedback']}"
          + (f", both above dt_max in {count['dt_max']}" if count["dt_max"] else ""))
    if n and span > 0:
        print(f"from t = {t_start:.4g}: mean dt {span / n:.3g}, {hard} steps with >= 2 Newton iterations "
              f"({hard / span:.3g} per unit time), {wall / span:.4g} s of wall time per unit time")
    if args.save:
        out = Path(args.save)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out / "scene.toml", dump_toml(scene.data))
        save_checkpoint(out / "checkpoint.npz", loop.state_dict(), {"step": loop.step})
        print(f"state at t = {loop.t:.6g} saved in {out}/ (continue with --resume {out})")


if __name__ == "__main__":
    main()
