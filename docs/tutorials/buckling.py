"""Tutorial: buckling of a growing clamped disk by continuation (docs/tutorials/buckling.md).

    python docs/tutorials/buckling.py [--quick] [--out DIR]

A flat disk (radius a = 1, thickness t = 0.01, nu = 0.3, E = 1), clamped at its edge, grows
uniformly. Continuation in the growth strain g follows the flat state, finds where it loses
stability (a branch point), compares it with plate theory, switches onto the buckled branch
and draws the bifurcation diagram. Then the same study runs from the embedded scene file
``clamped-plate-buckling`` through ``femshell run``.

Writes into --out (default ./tutorial-out/buckling): results.json, flat.csv, buckled.csv,
bifurcation.png, critical-mode.vtu and scene/ (the `femshell run` output directory).
"""

# %% [setup]
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
ap.add_argument("--quick", action="store_true", help="a tiny mesh (81 vertices instead of 410)")
ap.add_argument("--out", type=Path, default=Path("tutorial-out/buckling"), help="output directory")
args = ap.parse_args()
out = args.out
out.mkdir(parents=True, exist_ok=True)
t_start = time.perf_counter()

# %% [model]
a, t, nu = 1.0, 0.01, 0.3                    # radius, thickness, Poisson ratio (E = 1)
h = 0.25 if args.quick else 0.1              # target edge length of the mesh
mesh = disk(radius=a, edge_length=h)
model = ShellModel(mesh, Material(E=1.0, nu=nu), uniform_growth(mesh.points, mesh.triangles, t, 0.0),
                   [Clamped("outer")])
print(f"mesh: {mesh.n_vertices} vertices, {len(mesh.triangles)} triangles (edge length {h})")

# %% [theory]
k2 = 14.682                                   # first zero of J1, squared: the axisymmetric mode
eps_c = k2 * t**2 / (12 * (1 + nu) * a**2)    # critical growth strain of the clamped disk
print(f"theory: eps_c = {eps_c:.5e}")

# %% [continuation]
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

# %% [branch point]
bp = next(p for p in flat.special_points if p.kind == "branch")
g_c = bp.parameter
green = ((1 + g_c) ** 2 - 1) / 2              # the Green strain of the growth stretch 1 + g
modes_z = np.array([model.mode_displacements(m)[:, 2] for m in bp.modes.T])   # z of every vertex, per mode
n_wave, _ = azimuthal_wavenumber(mesh.points, modes_z)
print(f"branch point: g_c = {g_c:.5e}, Green strain {green:.5e} = {green / eps_c:.4f} x theory, "
      f"multiplicity {bp.multiplicity}, azimuthal wavenumber n = {n_wave}")
write_mesh(mesh, out / "critical-mode.vtu", point_data={"mode_z": modes_z[0]})

# %% [switch branch]
buckled = switch_branch(problem, bp, amplitude=0.02, ds=0.05, ds_max=0.3, lam_stop=1.25 * eps_c, max_steps=40,
                        record=record, n_eigs=2, label="buckled", log=None)
print(buckled)
u_end, g_end = buckled.last
w_end = record(u_end)["w_centre"] / t
stable = [r["stable"] for r in buckled.rows if not r["special"]]
print(f"buckled branch: w0/t = {w_end:.3f} at g = {g_end / eps_c:.3f} eps_c, "
      f"{sum(stable)} of {len(stable)} points stable")

# %% [diagram]
rows = [{"x": r["parameter"] / eps_c, "y": r["w_centre"] / t, "stable": r["stable"], "branch": "flat",
         "special": r["special"]} for r in flat.rows]
rows.append({"x": g_c / eps_c, "y": 0.0, "stable": None, "branch": "buckled", "special": ""})
rows += [{"x": r["parameter"] / eps_c, "y": r["w_centre"] / t, "stable": r["stable"], "branch": "buckled",
          "special": r["special"]} for r in buckled.rows]
bifurcation_diagram(rows, x="x", y="y", path=out / "bifurcation.png", xlabel="growth strain g / eps_c (theory)",
                    ylabel="centre deflection w0 / t", title="clamped disk, uniform growth")
write_branch_csv(flat, out / "flat.csv")
write_branch_csv(buckled, out / "buckled.csv")

# %% [results]
results = {"edge_length": h, "n_vertices": mesh.n_vertices, "eps_c_theory": eps_c, "g_c": g_c,
           "green_strain_c": green, "ratio_to_theory": green / eps_c, "multiplicity": bp.multiplicity,
           "wavenumber": n_wave, "buckled_status": buckled.status, "w0_over_t_at_1.25": w_end,
           "buckled_stable_fraction": float(np.mean(stable)), "api_wall_s": time.perf_counter() - t_start}
(out / "results.json").write_text(json.dumps(results, indent=1))


# %% [scene]
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
