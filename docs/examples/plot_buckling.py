"""
Buckling of a growing plate by continuation
===========================================

A flat disk clamped at its edge grows uniformly. The edge holds it back, so the growth
becomes a uniform in-plane compression; at a critical growth strain the flat state stops
being stable and the disk buckles into a dome. This example follows the flat state by
pseudo-arclength continuation (:mod:`femshell.solvers.continuation`), lets the solver find
the branch point, compares it with plate theory, switches onto the buckled branch and
draws the bifurcation diagram. Then it runs the same study from the embedded scene file
``clamped-plate-buckling`` with ``femshell run``.

Writes into ``--out``: ``results.json``, ``flat.csv`` and ``buckled.csv`` (one row per
continuation point), ``bifurcation.png``, ``critical-mode.vtu`` (the buckling mode, for
ParaView) and ``scene/`` (the output of ``femshell run``). By default the mesh has 81
vertices (about 35 s); ``--full`` takes 410 (about 40 s).
"""

import argparse
import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from femshell.io import write_branch_csv
from femshell.mesh.generators import disk
from femshell.mesh.io import write_mesh
from femshell.shell import Clamped, Material, ShellModel, uniform_growth
from femshell.solvers.continuation import GrowthParameter, continuation, switch_branch
from femshell.validation.clamped_plate_growth_buckling import azimuthal_wavenumber
from femshell.viz import bifurcation_diagram

ap = argparse.ArgumentParser(description="Buckling of a growing clamped disk by continuation.")
ap.add_argument("--full", action="store_true", help="the finer mesh (410 vertices instead of 81)")
ap.add_argument("--out", type=Path, default=Path("example-out/buckling"), help="output directory")
args = ap.parse_args()
out = args.out
out.mkdir(parents=True, exist_ok=True)
t_start = time.perf_counter()

# %%
# The problem and the theory value
# --------------------------------
# Disk radius a = 1, thickness t = 0.01, ν = 0.3, E = 1. Uniform growth by the stretch
# 1 + g is the target metric (1 + g)² ā0 (:func:`femshell.shell.uniform_growth`; the
# thickness stays t). The mesh is a gmsh disk of target edge length ``h``, clamped on its
# boundary curve ``"outer"``.

a, t, nu = 1.0, 0.01, 0.3                    # radius, thickness, Poisson ratio (E = 1)
h = 0.1 if args.full else 0.25               # target edge length of the mesh
mesh = disk(radius=a, edge_length=h)
model = ShellModel(mesh, Material(E=1.0, nu=nu), uniform_growth(mesh.points, mesh.triangles, t, 0.0),
                   [Clamped("outer")])
print(f"mesh: {mesh.n_vertices} vertices, {len(mesh.triangles)} triangles (edge length {h})")

# %%
# A clamped circular plate under uniform radial compression N buckles when
# N a²/D = k², k the first zero of J₁ (k² = 14.682, an axisymmetric mode; Timoshenko &
# Gere, *Theory of Elastic Stability*, 9.7). With N = E t ε/(1 − ν) that is the critical
# strain ε_c = k² t² / (12 (1 + ν) a²). The strain that enters the model exactly is the
# Green strain of the growth, ((1 + g)² − 1)/2, which differs from g by g/2 relative:
# 5e-5 here.

k2 = 14.682                                   # first zero of J1, squared: the axisymmetric mode
eps_c = k2 * t**2 / (12 * (1 + nu) * a**2)    # critical growth strain of the clamped disk
print(f"theory: eps_c = {eps_c:.5e}")

# %%
# Continuation along the flat branch
# ----------------------------------
# :class:`~femshell.solvers.continuation.GrowthParameter` turns the model into a
# problem with one parameter, λ = g, which sets the rest state. ``parameter_scale``
# measures steps in units of ε_c and ``length_scale`` weights displacements by the
# thickness (the scale on which buckles grow). The continuation computes the inertia of
# the Hessian at every step, so it knows where the state is stable, and locates every
# change of inertia as a branch point, with its critical modes and multiplicity.
# ``record`` adds a column to the branch table: the deflection of the centre.

problem = GrowthParameter(model, lambda g: uniform_growth(mesh.points, mesh.triangles, t, g),
                          parameter_scale=eps_c, length_scale=t)
centre = int(np.argmin(np.hypot(mesh.points[:, 0], mesh.points[:, 1])))


def record(u):
    """Extra columns of the branch table: the deflection of the centre."""
    return {"w_centre": float(model.positions(u)[centre, 2])}


flat = continuation(problem, model.initial_unknowns(), 0.0, ds=0.25, ds_max=0.25, lam_stop=2.0 * eps_c,
                    record=record, n_eigs=3, label="flat", log=None)
print(flat)
for p in flat.special_points:
    print("  ", p.summary())

# %%
# The branch point against theory
# -------------------------------
# ``bp.modes`` holds the critical eigenvectors on the free unknowns;
# ``model.mode_displacements`` turns one into a displacement per vertex, and
# :func:`~femshell.validation.clamped_plate_growth_buckling.azimuthal_wavenumber` reads
# its number of waves around the disk (0: axisymmetric). The mode is written for ParaView.

bp = next(p for p in flat.special_points if p.kind == "branch")
g_c = bp.parameter
green = ((1 + g_c) ** 2 - 1) / 2              # the Green strain of the growth stretch 1 + g
modes_z = np.array([model.mode_displacements(m)[:, 2] for m in bp.modes.T])   # z of every vertex, per mode
n_wave, _ = azimuthal_wavenumber(mesh.points, modes_z)
print(f"branch point: g_c = {g_c:.5e}, Green strain {green:.5e} = {green / eps_c:.4f} x theory, "
      f"multiplicity {bp.multiplicity}, azimuthal wavenumber n = {n_wave}")
write_mesh(mesh, out / "critical-mode.vtu", point_data={"mode_z": modes_z[0]})

# %%
# The critical strain converges from below at second order in the mesh size: 0.90 ×
# theory at h = 0.25, 0.98 at h = 0.1 (``--full``), 0.995 at h = 0.05 (the validation
# case ``clamped-plate-growth-buckling``). For 1 % take h ≤ 0.07, about 800 vertices.
#
# Switching branch
# ----------------
# :func:`~femshell.solvers.continuation.switch_branch` starts from the branch point along
# the critical mode and follows the new branch, here to g = 1.25 ε_c.

buckled = switch_branch(problem, bp, amplitude=0.02, ds=0.05, ds_max=0.3, lam_stop=1.25 * eps_c, max_steps=40,
                        record=record, n_eigs=2, label="buckled", log=None)
print(buckled)
u_end, g_end = buckled.last
w_end = record(u_end)["w_centre"] / t
stable = [r["stable"] for r in buckled.rows if not r["special"]]
print(f"buckled branch: w0/t = {w_end:.3f} at g = {g_end / eps_c:.3f} eps_c, "
      f"{sum(stable)} of {len(stable)} points stable")

# %%
# The bifurcation diagram
# -----------------------
# :func:`femshell.viz.bifurcation_diagram` draws stable pieces solid, unstable ones
# dashed and circles the branch points. The flat branch is stable up to the first branch
# point and unstable after it; the buckled branch rises steeply from it and is stable: a
# supercritical pitchfork. The second branch point on the flat branch is the double
# n = 1 crossing (cos θ and sin θ).

rows = [{"x": r["parameter"] / eps_c, "y": r["w_centre"] / t, "stable": r["stable"], "branch": "flat",
         "special": r["special"]} for r in flat.rows]
rows.append({"x": g_c / eps_c, "y": 0.0, "stable": None, "branch": "buckled", "special": ""})
rows += [{"x": r["parameter"] / eps_c, "y": r["w_centre"] / t, "stable": r["stable"], "branch": "buckled",
          "special": r["special"]} for r in buckled.rows]
bifurcation_diagram(rows, x="x", y="y", path=out / "bifurcation.png", xlabel="growth strain g / eps_c (theory)",
                    ylabel="centre deflection w0 / t", title="clamped disk, uniform growth")
write_branch_csv(flat, out / "flat.csv")
write_branch_csv(buckled, out / "buckled.csv")
results = {"edge_length": h, "n_vertices": mesh.n_vertices, "eps_c_theory": eps_c, "g_c": g_c,
           "green_strain_c": green, "ratio_to_theory": green / eps_c, "multiplicity": bp.multiplicity,
           "wavenumber": n_wave, "buckled_status": buckled.status, "w0_over_t_at_1.25": w_end,
           "buckled_stable_fraction": float(np.mean(stable)), "api_wall_s": time.perf_counter() - t_start}
(out / "results.json").write_text(json.dumps(results, indent=1))

# %%
# The same study from a scene file
# --------------------------------
# The embedded scene ``clamped-plate-buckling`` describes this problem in TOML:
# ``femshell scenes clamped-plate-buckling`` prints it, and saved as a file it is the
# start of your own (:doc:`/guide/write-a-scene`). ``--set mesh.edge_length=...``
# overrides one key, ``--overwrite`` reruns into the same directory, ``--quiet`` hides
# the progress lines. ``femshell(...)`` runs a command line as you would type it.


def femshell(command):
    """Run a command line typed as in a shell ("femshell run ...") with this Python's femshell."""
    print("$", command, flush=True)
    argv = shlex.split(command)
    subprocess.run([sys.executable, "-m", "femshell.cli", *argv[1:]], check=True)


scene_dir = out / "scene"
femshell(f"femshell run clamped-plate-buckling --out {scene_dir} --overwrite --quiet --set mesh.edge_length={h}")
summary = json.loads((scene_dir / "summary.json").read_text())
bp_scene = next(s for s in summary["final"]["special_points"] if s["kind"] == "branch")
print(f"scene: branch point at growth.strain = {bp_scene['parameter']:.5e} "
      f"({bp_scene['parameter'] / g_c:.6f} x the API value), status {summary['status']}")
results["scene_g_c"] = bp_scene["parameter"]
results["total_wall_s"] = time.perf_counter() - t_start
(out / "results.json").write_text(json.dumps(results, indent=1))
print(f"done in {results['total_wall_s']:.0f} s; outputs in {out}/")

# %%
# ``scene/`` holds ``series.pvd`` (one frame per continuation point: step through the
# branch in ParaView), ``branch.csv``, ``scene.toml`` (the scene as run),
# ``checkpoint.npz`` (what ``--resume`` continues from), ``special/`` (each branch point
# with its modes), ``summary.json`` and ``pictures/``. Its bifurcation diagram plots the
# largest out-of-plane displacement against the growth strain in units of
# ``solver.parameter_scale``. Load-driven problems use
# :class:`~femshell.solvers.continuation.LoadParameter` instead of ``GrowthParameter``;
# folds are located like branch points (``LP`` in the table).
