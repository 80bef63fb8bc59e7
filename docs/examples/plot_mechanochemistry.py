"""
A mechanochemical run, from the command line and from Python
=============================================================

The model of Zakharov & Dasbiswas on a real shell (:doc:`/theory`, §1.1–1.4): a chemical
c made where the shell bulges outward lowers the contractility, the tissue there grows,
the growth buckles the shell outward, and the bulge makes more chemical. This example
runs the twelve-spot scene ``sphere-seeded-spots`` at a reduced size with ``femshell run``, stops and
resumes it, reads its outputs, renders a movie, counts the spots with
:func:`femshell.analysis.find_spots`, and runs the same physics from Python with
:mod:`femshell.coupled`.

Writes ``run/`` (the ``femshell run`` directory) and ``results.json`` into ``--out``. By
default the sphere has 150 vertices and runs to t = 0.12 (under a minute); ``--full``
takes 800 vertices to t = 0.5.
"""

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
ap.add_argument("--full", action="store_true", help="800 vertices to t = 0.5 instead of 150 to t = 0.12")
ap.add_argument("--out", type=Path, default=Path("example-out/mechanochemistry"), help="output directory")
args = ap.parse_args()
out = args.out
out.mkdir(parents=True, exist_ok=True)
t_start = time.perf_counter()


def femshell(command, check=True):
    """Run a command line typed as in a shell ("femshell run ...") with this Python's femshell."""
    print("$", command, flush=True)
    argv = shlex.split(command)
    return subprocess.run([sys.executable, "-m", "femshell.cli", *argv[1:]], check=check).returncode


# %%
# The scenes
# ----------
# ``femshell scenes`` lists the embedded scenes; ``femshell scenes NAME`` prints one as
# TOML, the start of your own (:doc:`/guide/write-a-scene`). ``default`` is the README's:
# one seeded spot that spreads into spots over a sphere of radius 15 in a few minutes
# (:doc:`/regimes`). This example runs ``sphere-seeded-spots``: the same sphere,
# thickness h = 2, c* = 0.1, D = 0, seeded with twelve Gaussian spots at the vertices of an
# icosahedron, so that a run of seconds shows bulges. The other ``sphere-*`` scenes are the
# paper's scenarios at the paper's resolution (:doc:`/studies/sphere-patterns`) and the
# regimes of the continuum model (``sphere-regime-*``).

femshell("femshell scenes")

# %%
# Run, stop, resume
# -----------------
# ``--set KEY=VALUE`` overrides one key of the scene, ``--dry-run`` says what the run
# will build and computes nothing, ``--max-steps 2`` stops after two steps with a
# checkpoint (as Ctrl-C would), and ``--resume`` continues from it: the scene is read back
# from ``run/scene.toml``. A resumed time loop repeats the uninterrupted one bit for bit.
# ``--overwrite`` lets the script run again into the same directory.

run = out / "run"
n_vertices, t_final = (800, 0.5) if args.full else (150, 0.12)
size = f"--set mesh.n_vertices={n_vertices} --set solver.t_final={t_final}"
femshell(f"femshell run sphere-seeded-spots --out {run} {size} --dry-run")
femshell(f"femshell run sphere-seeded-spots --out {run} {size} --overwrite --max-steps 2")
femshell(f"femshell run --out {run} --resume")

# %%
# The outputs
# -----------
# ``summary.json`` holds the scene, every parameter, the status (``t_final``,
# ``stationary``, ``paused``, ``failed`` or ``interrupted``), the steps and the final
# state with the paper's pattern measures. ``series.pvd`` with ``series_NNNNNN.vtu`` is
# the time series for ParaView (colour by ``c`` and press play): each frame has the
# point fields c, H, Lambda and displacement and the cell fields stretch, thickness and
# the energy densities. ``pictures/`` has the top and side views.

summary = json.loads((run / "summary.json").read_text())
final = summary["final"]
print(f"status {summary['status']}, {summary['steps']} steps, resumed {summary['resumes']} time(s), "
      f"{summary['mesh']['n_vertices']} vertices, wall {summary['wall_s']:.0f} s")
print(f"final: t = {final['t']:.3g}, max c = {final['max_c']:.3f} (saturation w Hs/beta = {final['c_max_theory']}), "
      f"{final['pattern']['n_spots']} spot(s), distance from the centre "
      f"{final['radius_min']:.2f} ... {final['radius_max']:.2f}")
print("files:", ", ".join(sorted(p.name for p in run.iterdir())))

frames = read_pvd(run / "series.pvd")              # [(time, path of the VTU frame), ...]
print(f"{len(frames)} frames, times {frames[0][0]:.3g} ... {frames[-1][0]:.3g}")
last = meshio.read(frames[-1][1])                  # any VTU reader works: meshio, ParaView, pyvista
print("point data:", ", ".join(last.point_data))
print("cell data:", ", ".join(last.cell_data))

# %%
# Counting spots
# --------------
# :func:`~femshell.analysis.find_spots` finds the connected regions where c > c* on a
# surface (here the deformed one of the last frame) and returns the paper's measures: the
# number of spots, their radius √(A_l/(π N_sp)) and spacing, the patterned fraction, and
# each region with its shape, a spot or a ridge.

frame = read_frame(frames[-1][1])                  # the deformed surface and its fields
c_star = summary["parameters"]["growth"]["c_star"]
spots = find_spots(frame.points, frame.triangles, frame.point_data["c"], c_star)
print(f"last frame: {spots.n_spots} regions with c > c* = {c_star} ({spots.kind}), "
      f"spot radius {spots.spot_radius:.2f}, spacing {spots.spacing:.2f}, "
      f"patterned fraction {spots.fraction_patterned:.3f}")

# %%
# Pictures and a movie
# --------------------
# ``femshell render DIR`` draws a top view of every (``--every N``: every N-th) frame on
# one colour range, a side view of the last one and ``DIR/movie.gif``. The top view is the
# paper's: the spot at the pole in the centre. On this coarse sphere two seeds' regions
# may touch; with 800 vertices (``--full``) all twelve are separate bulges.

femshell(f"femshell render {run} --every 2")

# %%
# The same physics from Python
# ----------------------------
# :mod:`femshell.coupled` is what the scene runner drives:
# :class:`~femshell.coupled.MechanochemicalModel` holds the physical parameters (defaults:
# the paper's), :class:`~femshell.coupled.TimeStepping` the controls of the time loop,
# :class:`~femshell.coupled.InitialSpot` the paper's initial condition (one Gaussian spot
# at the pole) and :class:`~femshell.coupled.CoupledLoop` the staggered loop: chemistry on
# the current surface, growth, a stable mechanical equilibrium, curvature. ``run`` calls
# the callback after every accepted step.

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

# %%
# One spot, one bulge: by this time the spot has not spread. With D = 0 it spreads only
# through the mechanics, as the bulge's rim curves outward and starts making chemical,
# which takes times of order tens and a finer mesh (the spots are about 2h across).

results = {"n_vertices": summary["mesh"]["n_vertices"], "t_final": t_final, "status": summary["status"],
           "steps": summary["steps"], "resumes": summary["resumes"], "frames": len(frames),
           "n_spots_summary": final["pattern"]["n_spots"], "n_spots_last_frame": spots.n_spots,
           "max_c": float(frame.point_data["c"].max()), "spot_radius": spots.spot_radius,
           "api_status": result.status, "api_steps": result.steps, "api_n_spots": api_spots.n_spots,
           "api_max_c": float(loop.c.max()), "total_wall_s": time.perf_counter() - t_start}
(out / "results.json").write_text(json.dumps(results, indent=1))
print(f"done in {results['total_wall_s']:.0f} s; outputs in {out}/")
