"""
A stationary spot followed in the production rate
=================================================

A time run (:doc:`/theory`, §2.8) that ends in a stationary spot answers one question: what
the spot looks like at these parameters. How it changes with a parameter, and where it stops
existing, are answered by treating the spot as a root of the stationary system of theory
§2.9 and following that root: a threshold is then located to round-off, with the stability
on both sides, where time runs only bracket it. This example

1. runs the time loop until the spot is stationary,
2. finds the stationary state to round-off by Newton on the coupled system
   (:func:`~femshell.coupled.stationary_state`) and checks that it is the time run's spot,
3. computes its stability in the coupled dynamics (the eigenvalues μ of S v = μ M v),
4. follows it in the production rate w (:func:`~femshell.coupled.pattern_continuation.continue_pattern`)
   to a fold, and draws the bifurcation diagram and the critical mode.

Writes ``results.json``, ``bifurcation.png``, ``critical-mode.png`` and the branch's files
(``pattern/``) into ``--out``. By default a sphere of radius 5 with 300 vertices (about a
minute); ``--full`` takes 600 vertices (a few minutes).
"""

import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from femshell.coupled import (CoupledLoop, InitialSpot, MechanochemicalModel, StationaryProblem,  # noqa: E402
                              TimeStepping, coupled_stability, stationary_state)
from femshell.coupled.pattern_continuation import continue_pattern, critical_mode_fields  # noqa: E402
from femshell.mesh.generators import sphere  # noqa: E402
from femshell.scene.pattern_output import pattern_measures, write_pattern_branch  # noqa: E402
from femshell.viz import view_grid  # noqa: E402

ap = argparse.ArgumentParser(description="A stationary spot followed in the production rate w.")
ap.add_argument("--full", action="store_true", help="600 vertices instead of 300")
ap.add_argument("--out", type=Path, default=Path("example-out/pattern-continuation"), help="output directory")
args = ap.parse_args()
out = args.out
out.mkdir(parents=True, exist_ok=True)
cpu = {}

# %%
# A stationary spot from a time run
# ---------------------------------
# A small sphere (R = 5, h0 = 0.5) with a milder contractility ratio than the paper's
# (Λmax/Λmin = 15/13.5) and some diffusion (D = 0.1), seeded with a spot at the north pole
# (theory §1.4). The loop stops when c and the shape change by less than 1e-3 per unit time
# (``stationary_rate_c``, ``stationary_rate_x``): that is "stationary" to the time run. On
# 600 vertices (``--full``) the spot's edge still flickers at t = 80 and the run ends there.

R = 5.0
n_vertices = 600 if args.full else 300
params = MechanochemicalModel(h0=0.5, radius=R, lam_min=13.5, D=0.1)
mesh = sphere(R, n_vertices=n_vertices, seed=0)
stepping = TimeStepping(t_final=80.0, dt_initial=0.05, ramp_ds=0.2)
loop = CoupledLoop(mesh, params, stepping, c0=InitialSpot(amplitude=0.3, width=1.0), log=None)
t0 = time.process_time()
result = loop.run()
cpu["time_run"] = time.process_time() - t0
print(f"{mesh.n_vertices} vertices: {result.status} at t = {result.t:.3g} after {result.steps} steps, "
      f"max c {loop.c.max():.4f} ({cpu['time_run']:.0f} s CPU)")

# %%
# Newton on the stationary system
# -------------------------------
# :class:`~femshell.coupled.StationaryProblem` is the residual F(u, c) of theory §2.9 (mechanical
# equilibrium and the chemistry at rest on the deformed surface) with its exact Jacobian J.
# Newton from the loop's last state converges in a few steps, to round-off. How far may the
# root be from the time run's state? Near a stable root the distance decays like e^{μ₀ t},
# μ₀ < 0 the slowest decay rate, so a rate below r (per unit time, relative to max c) means a
# distance of about r · max c / (−μ₀). That is the time run's stationarity tolerance as a
# distance, and Newton's root is within it.

problem = StationaryProblem.of_loop(loop)
t0 = time.process_time()
root = stationary_state(loop, problem=problem)
if not root.converged:
    raise SystemExit(f"Newton found no stationary state near the time run's end: {root.message}")
stability = coupled_stability(problem, root.u, root.c, k=4)
cpu["newton_and_stability"] = time.process_time() - t0
mu0 = stability.leading.real
distance_c = float(np.abs(root.c - loop.c).max())
tolerance_c = stepping.stationary_rate_c * max(loop.c.max(), 1e-2 * params.c_max) / abs(mu0)
print(f"Newton: {root.message}; residuals (force, rate) {root.history[0][0]:.1e}, {root.history[0][1]:.1e} "
      f"-> {root.history[-1][0]:.1e}, {root.history[-1][1]:.1e}")
print(f"max |c_Newton - c_time run| = {distance_c:.2e}; the time run's tolerance as a distance {tolerance_c:.2e}"
      + ("" if result.status == "stationary" else f" (but the run ended by {result.status}, not stationary)"))
print("leading eigenvalues mu of the coupled dynamics: " + ", ".join(f"{m.real:.4f}" for m in stability.eigenvalues)
      + f"; stable: {stability.stable}")

# %%
# All μ are negative: the spot is stable, as it must be, since the time run went there.
# The slowest, μ₀ ≈ −0.6, is slower than the chemistry's own decay β = 1: the spot's
# feedback (more c, more growth, more curvature, more c) holds a perturbation longer.
#
# Continuation in w
# -----------------
# :func:`~femshell.coupled.pattern_continuation.continue_pattern` follows the root in w by
# pseudo-arclength continuation; every point carries the leading μ. It locates the fold
# where the branch turns back and goes on along the other side. ``pattern_measures`` adds
# the spot's radius and patterned area to each row, and
# :func:`~femshell.scene.pattern_output.write_pattern_branch` writes the branch (CSV, JSON)
# and the fold's state with its critical mode (VTU, for ParaView) into ``pattern/``.

t0 = time.process_time()
branch = continue_pattern(problem, root.u, root.c, "w", ds=0.02, lam_stop=17.0, max_steps=17, n_modes=2,
                          record=lambda z: pattern_measures(problem, z))
cpu["continuation"] = time.process_time() - t0
print(f"{len(branch.rows)} points, {branch.status} ({cpu['continuation']:.0f} s CPU)")
print("     w      max c   spot radius    mu_0     stable")
for r in branch.rows:
    print(f"{r['parameter']:8.4f} {r['max_c']:8.4f} {r['spot_radius']:9.3f} {r['mu_0']:+10.5f}   {r['stable']}"
          + ("   <- fold" if r["special"] == "LP" else ""))
files = write_pattern_branch(branch, problem, out / "pattern", parameter="w", pictures=False)

# %%
# The bifurcation diagram
# -----------------------
# Stable states solid, unstable dashed. The spot grows with w until the fold, where the
# branch turns back as an unstable spot. The leading μ crosses zero exactly there: at a
# fold J is singular, and with the shell itself stable (its Hessian K_uu positive definite)
# det J = det K_uu · det S vanishes only where S has a zero eigenvalue (theory §2.9). The
# continuation finds the fold from the sign of dw/ds alone; μ comes from the separate
# eigenproblem, so their agreement is a check of both.

rows = branch.rows
w = np.array([r["parameter"] for r in rows])
fig, (ax_c, ax_mu) = plt.subplots(2, 1, figsize=(6, 5.5), sharex=True)
for ax, key in ((ax_c, "max_c"), (ax_mu, "mu_0")):
    y = np.array([r[key] for r in rows])
    stable = np.array([bool(r["stable"]) for r in rows])
    for i in range(len(rows) - 1):
        ax.plot(w[i:i + 2], y[i:i + 2], "-" if stable[i] and stable[i + 1] else "--", color="C0", lw=1.8)
    fold = [i for i, r in enumerate(rows) if r["special"] == "LP"]
    ax.plot(w[fold], y[fold], "v", color="C3", ms=9, label="fold")
ax_mu.axhline(0.0, color="k", lw=0.8, ls=":")
ax_c.set_ylabel("max c")
ax_mu.set_ylabel("leading eigenvalue μ₀")
ax_mu.set_xlabel("production rate w")
ax_c.legend()
fig.tight_layout()
fig.savefig(out / "bifurcation.png", dpi=110)
plt.close(fig)

folds = [sp for sp in branch.special_points if sp.kind == "fold" and sp.located]
if not folds:
    raise SystemExit(f"no fold located on the branch ({branch.status}: {branch.message})")
lp = folds[0]
at_fold = next(r for r in rows if r["special"] == "LP")
print(f"fold at w = {lp.parameter:.5f}: mu_0 = {at_fold['mu_0']:+.2e}, max c {at_fold['max_c']:.4f}")

# %%
# The critical mode
# -----------------
# At the fold, J's null vector is the direction in which the spot is lost: its
# concentration part δc and the normal displacement of its shape part, drawn beside c
# from above the pole.

mode = critical_mode_fields(problem, lp.u, lp.modes[:, 0])
c_fold = problem.split(lp.u)[1]
points = problem.shell.positions(problem.split(lp.u)[0])
view_grid(points, mesh.triangles, {"c at the fold": c_fold, "mode: c": mode["mode_c"],
                                   "mode: normal displacement": mode["mode_normal"]},
          out / "critical-mode.png", view="top")
peak = int(np.argmax(np.abs(mode["mode_c"])))
element_c = c_fold[mesh.triangles].mean(axis=1)               # the element means that set the stretch s
switching = np.abs(params.b * (params.c_star - element_c)) < 3     # inside the steep part of s(c)
around = np.flatnonzero((mesh.triangles == peak).any(axis=1))
print(f"{np.count_nonzero(np.abs(mode['mode_c']) > 0.1)} vertices carry over 10 % of the mode's c; at its peak "
      f"c = {c_fold[peak]:.3f}, and the element means around it are "
      + ", ".join(f"{x:.3f}" for x in element_c[around]) + f" (c* = {params.c_star})")
print(f"elements inside the switch of s(c) (|b (c* - c_e)| < 3): {np.count_nonzero(switching)} of "
      f"{len(element_c)}, {np.count_nonzero(switching[around])} of them around the peak")

# %%
# The mode sits on one vertex at the spot's rim, where the only elements of the mesh whose
# mean c is just below c* meet. With the paper's steep switch (b = 100) an element's stretch
# jumps from 1 to 1.11 as its mean crosses c*: at the fold the spot would have to switch
# those elements on, and instead it is lost. That fold is a property of the mesh, not the
# spot's spreading threshold: on 600 vertices (``--full``) the spot is twice as wide and its
# fold is at w = 16.16. What the example shows is the method: a threshold located as a
# bifurcation, to round-off, with its critical mode and the stability on both sides.
# :doc:`/guide/pattern-continuation` reads the result further.

summary = {"n_vertices": mesh.n_vertices, "time_status": result.status, "time_t": result.t,
           "time_steps": result.steps, "stationary_rate_c": stepping.stationary_rate_c,
           "newton_converged": root.converged, "newton_iterations": root.iterations,
           "newton_residuals": list(root.history[-1]), "max_c_time": float(loop.c.max()),
           "max_c_newton": float(root.c.max()), "distance_c": distance_c, "tolerance_c": tolerance_c,
           "mu_root": [float(m.real) for m in stability.eigenvalues], "stable_root": stability.stable,
           "branch_status": branch.status,
           "rows": [{k: r[k] for k in ("parameter", "max_c", "spot_radius", "mu_0", "mu_0_imag", "stable",
                                       "n_negative_mechanical", "dlam_ds", "special")} for r in rows],
           "fold_w": lp.parameter, "fold_located": lp.located, "fold_mu_0": at_fold["mu_0"],
           "mode_peak_c": float(c_fold[peak]), "switching_elements": int(np.count_nonzero(switching)),
           "switching_elements_at_peak": int(np.count_nonzero(switching[around])), "beta": params.beta, "w0": params.w,
           "cpu_s": cpu, "files": sorted(str(Path(p).relative_to(out)) for p in [files["csv"], files["json"],
                                                                               *files["special_points"]])}
(out / "results.json").write_text(json.dumps(summary, indent=1))
