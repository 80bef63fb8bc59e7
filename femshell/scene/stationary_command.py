"""`femshell stationary --from DIR`: Newton on the stationary coupled system (theory §2.9) from the last
checkpoint of a time run, with the run's own scene and mesh.

Writes ``DIR/stationary.json`` (convergence history, distance of the root from the run's state) and
``DIR/stationary.vtu`` (the root's shape with c, H, displacement, and the change of c from the run's
state); prints one line per Newton step.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import io as fio
from ..mesh.io import write_mesh
from .build import time_loop
from .rundir import CHECKPOINT, RunDir, RunDirError
from .runner import _check_resumed_mesh, _scene_of_run, sized_mesh

RESULT_JSON, RESULT_VTU = "stationary.json", "stationary.vtu"


def _run_state(path: Path):
    """(scene, checkpoint state, its meta) of the time run in ``path``; RunDirError if there is none."""
    if not path.is_dir():
        raise RunDirError(f"--from {path}: no such directory (give the --out of a femshell run)")
    scene = _scene_of_run(None, path, True, ())
    if scene.kind != "time":
        raise RunDirError(f"--from {path}: a {scene.kind} run; stationary states are of the coupled time loop "
                          "(a scene with [solver] kind = \"time\")")
    try:
        state, meta = fio.load_checkpoint(path / CHECKPOINT)
    except (fio.CheckpointError, FileNotFoundError) as exc:
        raise RunDirError(f"--from {path}: no usable {CHECKPOINT}: {exc}") from None
    return scene, state, meta


def stationary_from_run(run_dir, tol: float = 1e-9, max_iter: int = 30, stream=None) -> int:
    """Newton from DIR's last accepted state; 0 when it converged, 1 otherwise (module docstring)."""
    from ..coupled import StationaryProblem, stationary_state      # deferred: jax

    stream = stream or sys.stdout
    path = Path(run_dir)
    scene, state, meta = _run_state(path)
    mesh = sized_mesh(scene, stream)
    _check_resumed_mesh(RunDir(path), meta, mesh)
    loop = time_loop(scene, mesh, state=state)
    print(f"{path}: the time run's state at t = {loop.t:.6g} (step {loop.step}), {mesh.n_vertices} vertices",
          file=stream)
    t0, cpu0 = time.perf_counter(), time.process_time()
    problem = StationaryProblem.of_loop(loop)
    result = stationary_state(loop, tol=tol, max_iter=max_iter, problem=problem)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    for k, (force, rate) in enumerate(result.history):
        print(f"  newton {k:2d}  force {force:.3e}  rate {rate:.3e}", file=stream)
    points = problem.shell.positions(result.u)
    dc = result.c - loop.c
    dx = float(np.abs(points - loop.points).max())
    print(f"{result.message}: max |c - c_run| {np.abs(dc).max():.3g} (max c {result.c.max():.4g}), "
          f"max |x - x_run| {dx:.3g}; {wall:.1f} s ({cpu:.1f} s CPU)", file=stream)
    _, H = problem.growth.mean_curvature(result.u)
    loop.growth.apply(loop.s)
    write_mesh(replace(mesh, points=points), path / RESULT_VTU,
               point_data={"c": result.c, "H": H, "displacement": points - mesh.points, "c_change": dc})
    fio.atomic_write_json(path / RESULT_JSON, {
        "converged": result.converged, "iterations": result.iterations, "message": result.message,
        "tol": tol, "history": [{"force": f, "rate": r} for f, r in result.history],
        "run_t": float(loop.t), "run_step": int(loop.step), "max_c": float(result.c.max()),
        "max_c_change": float(np.abs(dc).max()), "max_position_change": dx, "wall_s": wall, "cpu_s": cpu})
    print(f"wrote {path / RESULT_JSON} and {path / RESULT_VTU}", file=stream)
    return 0 if result.converged else 1
