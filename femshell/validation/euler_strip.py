r"""Euler buckling of a growing strip: critical growth strain against the column formula, by continuation.

A long plate strip (length L = 10, width W = 1, thickness t = 0.05, E = 1, **ν = 0**) on a
structured mesh, ends clamped (or pinned: positions held, rotation free), long edges free,
grows along its axis only: the target metric is ā = Eᵀ diag((1 + g)², 1, 1) E per element
(E the element's edge vectors), so only the axial rest length grows. The ends hold it,
so the flat strip carries a uniform axial compression and buckles like a column in
cylindrical bending:

    clamped ends  N_cr = 4 π² D / L²          (second crossing 8.183 π² D / L², ratio 2.046)
    pinned ends   N_cr = π² D / L²            (second crossing 4 π² D / L², ratio 4)

with D = E t³ / 12. ν = 0 removes the plate/beam ambiguity: with free long edges a strip in
cylindrical bending is a beam of stiffness E t³/12 per width exactly when ν = 0 (no
anticlastic curvature, no Poisson stress across the width), and the uniform compressed
state is then exact.

Strain and force: for this energy (theory §1.2) the flat strip's Cauchy membrane force is
N = E t (1 − s⁻²)/(2 s) and its bending stiffness D/s³ per current area (s = 1 + g), so the
exact continuum buckling condition is ε := ((1 + g)² − 1)/2 = N_cr / (E t): the compressive
force is N = E t ε (reported, toleranced), or N = E t g to first order in g (also reported;
the two differ by g/2 ≈ 4e-5).

Post-buckling (clamped): after switching onto the buckled branch, the force stays at N_cr to
leading order, so the excess axial growth goes into arc length: the mode
w = (A/2)(1 − cos 2πx/L) has ∫ w'²/2 dx = π² A²/(4 L) = L (g − g_c)/(1 + g_c), i.e.
A = (2 L/π) √((g − g_c)/(1 + g_c)) (corrections O((A/L)², g)), checked with the g_c of the
same mesh.
"""

from __future__ import annotations

import math

import numpy as np

from ..mesh.generators import strip
from ..shell import Clamped, Material, RestState, ShellModel, SimplySupported
from ..solvers.continuation import GrowthParameter, continuation, switch_branch
from .clamped_plate_growth_buckling import convergence_axes, diagram_table, draw_diagram, warm_up
from .common import order_row
from .framework import Row, timed

NAME = "euler-strip"
DESCRIPTION = ("strip growing along its axis, clamped/pinned ends, nu = 0: critical growth strain vs "
               "N_cr = 4 pi^2 D/L^2 (pi^2 D/L^2), second crossing, post-buckled amplitude")
SOURCE = ("Timoshenko & Gere, Theory of Elastic Stability (1961), sec. 2.1-2.3 (Euler column: "
          "clamped 4 pi^2 EI/L^2, first antisymmetric mode 8.183 pi^2 EI/L^2 (tan(kL/2) = kL/2), "
          "pinned pi^2 EI/L^2 and 4 pi^2 EI/L^2); inextensional post-buckling: end shortening = "
          "integral of w'^2/2")

LENGTH, WIDTH, THICKNESS = 10.0, 1.0, 0.05
#: quick meshes stay at <= 256 triangles: the element kernels run in chunks of 256 elements, then 4096
LEVELS = {"quick": [0.5, 1 / 3], "full": [1.0, 0.5, 0.25, 0.125, 0.0625]}
TOL = {"quick": (0.02, 0.05, 0.02), "full": (0.005, 0.01, 0.005)}   # first, second crossing, post-buckling
D = THICKNESS**3 / 12.0
#: kL/2 of the first antisymmetric clamped-clamped mode: tan(x) = x
X_ANTI = 4.493409457909064
CASES = {
    "clamped": (lambda: [Clamped("left"), Clamped("right")], 4 * math.pi**2 * D / LENGTH**2,
                (2 * X_ANTI) ** 2 / (4 * math.pi**2)),
    "pinned": (lambda: [SimplySupported("left"), SimplySupported("right")], math.pi**2 * D / LENGTH**2, 4.0),
}
_LAST = {}


def axial_growth(points, triangles, thickness, g) -> RestState:
    """Target metric with the x direction grown by 1 + g: ā_ij = e_i · diag((1+g)², 1, 1) e_j; flat, thickness t."""
    x = np.asarray(points, float)[np.asarray(triangles)]
    e = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)          # (m, 2, 3)
    G = np.diag([(1.0 + g) ** 2, 1.0, 1.0])
    abar = np.einsum("mik,kl,mjl->mij", e, G, e)
    return RestState(abar, np.zeros_like(abar), thickness)


def green_strain(g):
    return 0.5 * ((1.0 + g) ** 2 - 1.0)


def flat_branch(h, bc, lam_stop_ratio, log=None):
    """Continuation along the flat strip in the axial growth strain. Returns (mesh, model, problem, branch, record)."""
    bcs, ncr, _ = CASES[bc]
    mesh = strip(LENGTH, WIDTH, edge_length=h, structured=True)
    model = ShellModel(mesh, Material(E=1.0, nu=0.0), axial_growth(mesh.points, mesh.triangles, THICKNESS, 0.0),
                       bcs())
    eps_c = ncr / THICKNESS
    problem = GrowthParameter(model, lambda g: axial_growth(mesh.points, mesh.triangles, THICKNESS, g),
                              parameter_scale=eps_c, length_scale=THICKNESS)

    def record(u):
        z = model.positions(u)[:, 2]
        return {"w_max": float(z[np.argmax(np.abs(z))])}

    branch = continuation(problem, model.initial_unknowns(), 0.0, ds=0.25, ds_max=0.5,
                          lam_stop=lam_stop_ratio * eps_c, record=record, n_eigs=3, label=f"flat ({bc})", log=log)
    return mesh, model, problem, branch, record


def run(level, log=None):
    warm_up(level)        # JIT and MKL start-up outside the timed rows
    rows = []
    tol1, tol2, tolp = TOL[level]
    sizes = LEVELS[level]
    for bc, (_, ncr, ratio2) in CASES.items():
        for i, h in enumerate(sizes):
            finest = i == len(sizes) - 1
            with timed() as t:
                mesh, model, problem, branch, record = flat_branch(h, bc, 1.08 * ratio2, log=log)
            nv = mesh.n_vertices
            bps = [p for p in branch.special_points if p.kind == "branch"]
            g1 = bps[0].parameter if bps else math.nan
            rows.append(Row(f"{bc}: N_c = E t eps_c over N_cr @ h={h:.4g}", THICKNESS * green_strain(g1) / ncr, 1.0,
                            tol1 if finest else None, nv, t()))
            rows.append(Row(f"{bc}: E t g_c over N_cr @ h={h:.4g}", THICKNESS * g1 / ncr, 1.0,
                            tol1 if finest else None, nv, t()))
            g2 = bps[1].parameter if len(bps) > 1 else math.nan
            rows.append(Row(f"{bc}: second crossing / first ({ratio2:.4f}) @ h={h:.4g}",
                            green_strain(g2) / green_strain(g1) / ratio2, 1.0, tol2 if finest else None, nv, t()))
            if finest and bps:
                _LAST[bc] = [branch]
                rows += _post_buckling(bc, problem, bps[0], record, float(f"{h:.4g}"), nv, tolp, log)
        rows += order_row(f"{bc}: N_c = E t eps_c over N_cr", rows)
    return rows


def _post_buckling(bc, problem, bp, record, h, nv, tol, log):
    """Follow the buckled branch to g = 1.2 g_c and compare the amplitude with the inextensional estimate."""
    gc = bp.parameter
    with timed() as t:
        nb = switch_branch(problem, bp, amplitude=0.05, ds=0.1, ds_max=0.5, lam_stop=1.2 * gc, max_steps=40,
                           record=record, n_eigs=2, label=f"buckled ({bc})", log=log)
    _LAST[bc].append(nb)
    pts = [r for r in nb.rows if not r["special"]]
    end = pts[-1]
    g = end["parameter"]
    A_ref = 2 * LENGTH / math.pi * math.sqrt(max(g - gc, 0.0) / (1.0 + gc))
    stable = [bool(r["stable"]) for r in pts if r["stable"] is not None]
    return [
        Row(f"{bc}: post-buckled amplitude / (2L/pi) sqrt((g-g_c)/(1+g_c)) at g = 1.2 g_c @ h={h}",
            abs(end["w_max"]) / A_ref if A_ref > 0 else math.nan, 1.0, tol, nv, t()),
        Row(f"{bc}: buckled branch reaches g = 1.2 g_c @ h={h}", float(nb.status == "lam_stop"), 1.0, 0.0, nv, t()),
        Row(f"{bc}: buckled branch: fraction of stable points @ h={h}", np.mean(stable) if stable else math.nan,
            1.0, 0.0, nv, t()),
    ]


def plot(rows, fig):
    """Error against vertices and wall time; bifurcation diagram (clamped, finest mesh)."""
    convergence_axes(fig.add_subplot(1, 3, 1), fig.add_subplot(1, 3, 2), rows,
                     lambda q: "fraction" not in q and "reaches" not in q)
    ax = fig.add_subplot(1, 3, 3)
    branches = _LAST.get("clamped", [])
    ncr = CASES["clamped"][1]
    table = diagram_table(branches, lambda r, st: THICKNESS * green_strain(r["parameter"]) / ncr,
                          lambda r, st: r["w_max"] / THICKNESS)
    draw_diagram(ax, table, "N / N_cr = E t eps / (4 pi^2 D / L^2)", "max deflection / t",
                 "clamped strip, axial growth")
