"""Tutorial: a mechanochemical run, from the command line and from Python (docs/tutorials/mechanochemistry.md).

    python docs/tutorials/mechanochemistry.py [--quick] [--out DIR]

Runs the README's default scene (a sphere of radius 15, h = 2, c* = 0.1, D = 0, twelve seeded
spots of chemical) at a reduced size with `femshell run`, stops it half way and continues it
with --resume, reads the outputs (summary.json, the ParaView series, pictures), renders a
movie with `femshell render`, counts the spots of the last frame with
femshell.analysis.find_spots, and finally runs the same physics from Python with
femshell.coupled (one spot at the pole, the paper's initial condition).

Writes into --out (default ./tutorial-out/mechanochemistry): run/ (the `femshell run`
directory, with series.pvd, series_*.vtu, summary.json, pictures/, movie.gif) and results.json.
"""

# %% [setup]
import argparse
import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np

from femshell.analysis import find_spots
from femshell.coupled import CoupledLoop, InitialSpot, MechanochemicalModel, TimeStepping
from femshell.io import read_frame, read_pvd
from femshell.mesh.generators import sphere

ap = argparse.ArgumentParser(description="A mechanochemical run from the command line and from Python.")
ap.add_argument("--quick", action="store_true", help="a tiny sphere and a short time (seconds)")
ap.add_argument("--out", type=Path, default=Path("tutorial-out/mechanochemistry"), help="output directory")
args = ap.parse_args()
out = args.out
out.mkdir(parents=True, exist_ok=True)
t_start = time.perf_counter()


def femshell(command, check=True):
    """Run a command line typed as in a shell ("femshell run ...") with this Python's femshell."""
    print("$", command, flush=True)
    argv = shlex.split(command)
    return subprocess.run([sys.executable, "-m", "femshell.cli", *argv[1:]], check=check).returncode


# %% [scenes]
femshell("femshell scenes")

# %% [run]
run = out / "run"
n_vertices, t_final = (150, 0.12) if args.quick else (800, 0.5)
size = f"--set mesh.n_vertices={n_vertices} --set solver.t_final={t_final}"
femshell(f"femshell run default --out {run} {size} --dry-run")
femshell(f"femshell run default --out {run} {size} --overwrite --max-steps 2")
femshell(f"femshell run --out {run} --resume")

# %% [summary]
summary = json.loads((run / "summary.json").read_text())
final = summary["final"]
print(f"status {summary['status']}, {summary['steps']} steps, resumed {summary['resumes']} time(s), "
      f"{summary['mesh']['n_vertices']} vertices, wall {summary['wall_s']:.0f} s")
print(f"final: t = {final['t']:.3g}, max c = {final['max_c']:.3f} (saturation w Hs/beta = {final['c_max_theory']}), "
      f"{final['pattern']['n_spots']} spot(s), distance from the centre "
      f"{final['radius_min']:.2f} ... {final['radius_max']:.2f}")
print("files:", ", ".join(sorted(p.name for p in run.iterdir())))

# %% [series]
frames = read_pvd(run / "series.pvd")              # [(time, path of the VTU frame), ...]
print(f"{len(frames)} frames, times {frames[0][0]:.3g} ... {frames[-1][0]:.3g}")
last = meshio.read(frames[-1][1])                  # any VTU reader works: meshio, ParaView, pyvista
print("point data:", ", ".join(last.point_data))
print("cell data:", ", ".join(last.cell_data))

# %% [spots]
frame = read_frame(frames[-1][1])                  # the deformed surface and its fields
c_star = summary["parameters"]["growth"]["c_star"]
spots = find_spots(frame.points, frame.triangles, frame.point_data["c"], c_star)
print(f"last frame: {spots.n_spots} regions with c > c* = {c_star} ({spots.kind}), "
      f"spot radius {spots.spot_radius:.2f}, spacing {spots.spacing:.2f}, "
      f"patterned fraction {spots.fraction_patterned:.3f}")

# %% [render]
femshell(f"femshell render {run} --every 2")

# %% [python api]
params = MechanochemicalModel(h0=2.0, c_star=0.1, D=0.0, membrane_law="neo-hookean")   # the scene's physics
mesh = sphere(15.0, n_vertices=n_vertices)
stepping = TimeStepping(t_final=t_final, ds_max=0.1, dt_max=0.5, ramp_ds=0.25)     # and its [solver] keys
loop = CoupledLoop(mesh, params, stepping, c0=InitialSpot())


def report(record, loop):
    print(f"  step {record.step}: t = {record.t:.3f}, max c = {record.max_c:.3f}, max stretch {record.max_s:.3f}, "
          f"{record.newton_iterations} Newton iterations")


result = loop.run(callback=report)
api_spots = find_spots(loop.points, mesh.triangles, loop.c, params.c_star)
print(f"Python API: {result.status}, {result.steps} steps, t = {result.t:.3g}, {api_spots.n_spots} spot(s), "
      f"max c = {loop.c.max():.3f}, largest outward bulge {np.linalg.norm(loop.points, axis=1).max() - 15.0:.3f}")

# %% [results]
results = {"n_vertices": summary["mesh"]["n_vertices"], "t_final": t_final, "status": summary["status"],
           "steps": summary["steps"], "resumes": summary["resumes"], "frames": len(frames),
           "n_spots_summary": final["pattern"]["n_spots"], "n_spots_last_frame": spots.n_spots,
           "max_c": float(frame.point_data["c"].max()), "spot_radius": spots.spot_radius,
           "api_status": result.status, "api_steps": result.steps, "api_n_spots": api_spots.n_spots,
           "api_max_c": float(loop.c.max()), "total_wall_s": time.perf_counter() - t_start}
(out / "results.json").write_text(json.dumps(results, indent=1))
print(f"done in {results['total_wall_s']:.0f} s; outputs in {out}/")
