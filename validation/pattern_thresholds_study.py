r"""Thresholds of the mechanochemical model on the R = 15 sphere located as bifurcations of stationary patterns.

A time run of the ``sphere-small`` scene (one seeded spot, D = 0, volume-conserving thickness) ends in
one stationary bulge; Newton on the coupled stationary system (theory §2.9,
:func:`femshell.coupled.stationary_state`) makes it a root, and pseudo-arclength continuation
(:func:`femshell.coupled.pattern_continuation.continue_pattern`) follows it in

* ``spreading``: the source gain w upward, until the single-bulge branch loses stability in the coupled
  dynamics (a real μ of S v = μ M v through zero: a fold or a branch point of the stationary branch)
  or ``--stop``;
* ``decay``: the threshold c* upward, until the branch folds (the bulge ceases to exist) or ``--stop``.

It writes ``validation/results/studies/pattern-thresholds/<name>.json`` (the scene's settings, the
time run, the Newton root, the branch table, every special point with the place of its critical
mode, and the CPU seconds of each stage) and, per special point, the critical mode's concentration
and normal displacement as ``docs/images/pattern-thresholds/<name>-<k>-<kind>.png``.

    python validation/pattern_thresholds_study.py spreading --thickness 2          # w from 20
    python validation/pattern_thresholds_study.py spreading --thickness 1 --start 20
    python validation/pattern_thresholds_study.py decay --thickness 0.5 --start 0.2 \
        --membrane-law svk
    python validation/pattern_thresholds_study.py spreading --thickness 2 --from RUN_DIR   # a finished time run

``--from`` starts from the last checkpoint of a ``femshell run``/``femshell sweep`` point of the same
settings instead of running the time loop (its CPU time is then not counted). ``--edge 0.72`` is the
paper's mesh (about 6 250 vertices).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from femshell import io as fio
from femshell.io import atomic_write_json, finite_or_none

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "validation" / "results" / "studies" / "pattern-thresholds"
IMAGES = ROOT / "docs" / "images" / "pattern-thresholds"

#: what each threshold follows: the parameter, its start and stop defaults, the scene's fixed settings
THRESHOLDS = {
    "spreading": {"parameter": "w", "start": 20.0, "stop": 45.0, "c_star": 0.1},
    "decay": {"parameter": "c_star", "start": 0.2, "stop": 0.5, "w": 15.0},
}


def scene_overrides(args) -> list:
    """The ``--set`` overrides of the sphere-small scene (those of the sweeps the thresholds are compared with)."""
    t = THRESHOLDS[args.threshold]
    w = args.start if t["parameter"] == "w" else t["w"]
    c_star = args.start if t["parameter"] == "c_star" else t["c_star"]
    return [f"mesh.edge_length={args.edge}", f"material.law={args.membrane_law}", f"chemistry.D={args.D}",
            f"growth.c_star={c_star}", "shell.thickness_mode=volume", f"shell.thickness={args.thickness}",
            f"chemistry.w={w}", f"solver.t_final={args.t_final}"]


def run_name(args) -> str:
    law = {"neo-hookean": "nh", "svk": "svk"}[args.membrane_law]
    start = f"w{args.start:g}" if THRESHOLDS[args.threshold]["parameter"] == "w" else f"cstar{args.start:g}"
    return f"{args.threshold}-h{args.thickness:g}-D{args.D:g}-edge{args.edge:g}-{law}-from-{start}"


def start_loop(args, log):
    """The coupled loop at its stationary end: run here (time and CPU s measured) or read from ``--from``."""
    from femshell.scene.build import load_scene, time_loop
    from femshell.scene.rundir import CHECKPOINT
    from femshell.scene.runner import sized_mesh

    scene = load_scene("sphere-small", scene_overrides(args))
    mesh = sized_mesh(scene)
    if args.from_run:
        state, _ = fio.load_checkpoint(Path(args.from_run) / CHECKPOINT)
        loop = time_loop(scene, mesh, state=state)
        if loop.mesh.n_vertices != mesh.n_vertices:
            raise SystemExit(f"--from {args.from_run}: {loop.mesh.n_vertices} vertices, the scene has {mesh.n_vertices}")
        return loop, {"from": str(args.from_run), "t": float(loop.t), "cpu_s": None}
    loop = time_loop(scene, mesh)
    cpu = time.process_time()
    result = loop.run()
    info = {"status": result.status, "message": result.message, "t": float(loop.t), "steps": int(loop.step),
            "cpu_s": time.process_time() - cpu}
    log(f"time run: {result.status} at t = {loop.t:.4g} ({info['cpu_s']:.0f} s CPU): {result.message}")
    return loop, info


def angles_from(problem, vertex):
    """The sphere's radius and every rest vertex's angle from ``vertex`` seen from the centre (radians)."""
    rest = problem.shell.mesh.points
    r = np.linalg.norm(rest, axis=1)
    return float(r[0]), np.arccos(np.clip(rest @ rest[vertex] / (r * r[vertex]), -1.0, 1.0))


def branch_measures(problem, z) -> dict:
    """A row's columns: :func:`~femshell.scene.pattern_output.pattern_measures`, and the largest c farther
    than twice the spot radius from the peak (``max_c_far``, where a second spot would nucleate) with its
    angle from the peak (``far_angle_deg``)."""
    from femshell.scene.pattern_output import pattern_measures

    out = pattern_measures(problem, z)
    _, c = problem.split(z)
    radius, angle = angles_from(problem, int(np.argmax(c)))
    far = radius * angle > 2.0 * out["spot_radius"] if math.isfinite(out["spot_radius"]) else np.ones(len(c), bool)
    i = int(np.flatnonzero(far)[np.argmax(c[far])]) if np.any(far) else None
    out["max_c_far"] = math.nan if i is None else float(c[i])
    out["far_angle_deg"] = math.nan if i is None else math.degrees(float(angle[i]))
    return out


def mode_place(problem, z, mode) -> dict:
    """Where a critical mode lives: the vertex of its largest |δc|, its geodesic distance from the
    pattern's peak (the vertex of max c), that vertex's c, and how many vertices carry it (participation ratio)."""
    from femshell.coupled.pattern_continuation import critical_mode_fields

    u, c = problem.split(z)
    f = critical_mode_fields(problem, z, mode)
    points = problem.shell.positions(u)
    i = int(np.argmax(np.abs(f["mode_c"])))
    radius, angle = angles_from(problem, int(np.argmax(c)))
    participation = float(np.sum(f["mode_c"] ** 2) ** 2 / np.sum(f["mode_c"] ** 4))
    return {"vertex": i, "distance_from_peak": radius * float(angle[i]), "c_there": float(c[i]),
            "c_star": problem.params.c_star, "position": [float(v) for v in points[i]],
            "vertices_carrying_it": participation}


def picture(problem, z, mode, path, title):
    from femshell.coupled.pattern_continuation import critical_mode_fields
    from femshell.viz import view_grid

    u, c = problem.split(z)
    f = critical_mode_fields(problem, z, mode)
    points = problem.shell.positions(u)
    return view_grid(points, problem.triangles, {"c": c, "mode c": f["mode_c"], "mode w_n": f["mode_normal"]},
                     path, title=title)


def special_point(problem, parameter, k, point, args, name, with_modes) -> dict:
    """A special point's record; ``with_modes``: where its critical mode lives, the pattern there and a picture."""
    from femshell.coupled.pattern_continuation import PatternParameter

    entry = {"kind": point.kind, "located": point.located, "parameter": finite_or_none(point.parameter),
             "bracket": [finite_or_none(v) for v in point.bracket], "step": point.step,
             "stability": point.info.get("stability")}
    if with_modes and point.located and point.modes is not None and point.modes.size:
        pp = PatternParameter(problem, parameter)
        pp.set_parameter(point.parameter)
        entry["mode"] = mode_place(problem, point.u, point.modes[:, 0])
        entry["measures"] = branch_measures(problem, point.u)
        if not args.no_pictures:
            path = IMAGES / f"{name}-{k}-{point.kind}.png"
            picture(problem, point.u, point.modes[:, 0], path,
                    f"{point.kind} at {parameter} = {point.parameter:.6g} (h = {args.thickness:g})")
            entry["picture"] = str(path.relative_to(ROOT))
    return entry


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("threshold", choices=sorted(THRESHOLDS))
    ap.add_argument("--thickness", type=float, required=True, help="rest thickness h (volume-conserving)")
    ap.add_argument("--D", type=float, default=0.0, help="diffusion coefficient (default 0)")
    ap.add_argument("--edge", type=float, default=1.1, help="mesh edge length (1.1: ~2 800 vertices; 0.72: the paper's)")
    ap.add_argument("--membrane-law", default="neo-hookean", choices=("neo-hookean", "svk"))
    ap.add_argument("--start", type=float, help="the parameter of the time run the branch starts from "
                                                "(default w = 20 or c* = 0.2)")
    ap.add_argument("--stop", type=float, help="end of the continuation (default w = 45 or c* = 0.5)")
    ap.add_argument("--t-final", type=float, default=40.0, help="the time run's end if it is not stationary before")
    ap.add_argument("--ds", type=float, default=0.05, help="first arclength step")
    ap.add_argument("--ds-max", type=float, default=0.5, help="largest arclength step")
    ap.add_argument("--max-steps", type=int, default=60)
    ap.add_argument("--past", type=int, default=2, help="steps to go on after the branch turned unstable")
    ap.add_argument("--from", dest="from_run", help="a finished time run of the same settings to start from")
    ap.add_argument("--no-pictures", action="store_true")
    args = ap.parse_args(argv)
    t = THRESHOLDS[args.threshold]
    args.start = t["start"] if args.start is None else args.start
    args.stop = t["stop"] if args.stop is None else args.stop

    from femshell.coupled import StationaryProblem, stationary_state
    from femshell.coupled.pattern_continuation import continue_pattern

    def log(m):
        print(m, flush=True)

    name = run_name(args)
    loop, time_run = start_loop(args, log)
    cpu = time.process_time()
    problem = StationaryProblem.of_loop(loop)
    root = stationary_state(loop, problem=problem)
    newton_cpu = time.process_time() - cpu
    log(f"Newton: {root.message} ({newton_cpu:.0f} s CPU), max c {root.c.max():.4g}")
    if not root.converged:
        return 1
    z0 = problem.join(root.u, root.c)
    start = branch_measures(problem, z0)
    summary = {"threshold": args.threshold, "parameter": t["parameter"], "scene": "sphere-small",
               "overrides": scene_overrides(args), "n_vertices": int(loop.mesh.n_vertices), "time_run": time_run,
               "newton": {"message": root.message, "iterations": root.iterations, "cpu_s": newton_cpu, "start": start}}
    RESULTS.mkdir(parents=True, exist_ok=True)
    unstable_rows = [0]
    cpu = time.process_time()

    def write(branch, status, message, with_modes=False):
        atomic_write_json(RESULTS / f"{name}.json", {
            **summary, "continuation": {"status": status, "message": message, "points": len(branch.rows),
                                        "cpu_s": time.process_time() - cpu},
            "special_points": [special_point(problem, t["parameter"], k, p, args, name, with_modes)
                               for k, p in enumerate(branch.special_points)],
            "rows": [{k: finite_or_none(v) if isinstance(v, float) else v for k, v in r.items()} for r in branch.rows]})

    def after_step(branch, row):
        """Write what is found so far; stop ``--past`` unstable points after the first (at once if the bulge is gone)."""
        write(branch, "running", "")
        unstable_rows[0] += row.get("stable") is False
        return unstable_rows[0] > args.past or row.get("n_spots", 1) == 0

    branch = continue_pattern(problem, root.u, root.c, t["parameter"], ds=args.ds, ds_max=args.ds_max,
                              lam_stop=args.stop, max_steps=args.max_steps, n_modes=4,
                              record=lambda z: branch_measures(problem, z), callback=after_step, log=log)
    log(f"continuation: {branch.status}: {branch.message} ({time.process_time() - cpu:.0f} s CPU)")
    write(branch, branch.status, branch.message, with_modes=True)
    for k, p in enumerate(branch.special_points):
        log(f"special point {k}: {p.summary()}")
    log(f"wrote {RESULTS / name}.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
