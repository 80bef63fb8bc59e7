r"""Cylinder under axial compression (by axial growth between two symmetry planes): critical strain against
the classical result, by linear buckling and by continuation.

A cylindrical shell of radius R = 100 t (t = 1, E = 1, ν = 0.3) and length L = 2 l_cr (one full
axisymmetric wave), stress free as drawn, grows along its axis by 1 + g (target metric
ā = Eᵀ diag(1, 1, (1 + g)²) E per element, target curvature unchanged: an axial stretch leaves the
hoop curvature and the straight generators as they are). Both ends are symmetry planes z = 0 and
z = L (axial displacement and the edge's rotation held, radial motion free), so the cylinder is the
period cell of an infinite one: its prebuckling state is exactly a uniform axial compression
N = E t g (to first order in g; the hoop stress is zero, the radius grows by ν g R), without the
edge bending of real supports. The remaining rigid motions (translations in x, y, rotation about z)
are null vectors of the Hessian at every g: linear buckling deflates them
(:func:`~femshell.linear_buckling.shell_buckling_loads`), the continuation holds them by three pins.

Classical result (Lorenz 1908, Timoshenko 1910, Southwell 1914): the critical axial stress of a
long cylinder, σ_cr = E t / (R √(3 (1 − ν²))), i.e. g_cl = t / (R √(3 (1 − ν²))), reached by the
axisymmetric mode of half-wavelength l_cr = π √(R t) / (12 (1 − ν²))^(1/4) and by every
(m, n) mode on Koiter's circle; with symmetry planes L apart the axisymmetric mode cos(2π z/L) has
exactly that half-wavelength. Thin-shell corrections are O(t/R).

Rows per mesh: linear-buckling g_c / g_cl and the continuation's first instability (growth
parameter); the observed order and Richardson estimate of the linear ladder. As for the sphere, the faceted cylinder is an imperfect cylinder and the
nonlinear continuation feels it; its rows are reported.
"""

from __future__ import annotations

import math

import numpy as np

from ..linear_buckling import shell_buckling_loads
from ..mesh.generators import cylinder
from ..shell import Material, Prescribed, RestState, ShellModel, Symmetry
from ..solvers.continuation import GrowthParameter
from .framework import Row, timed
from .shell_buckling import convergence_rows, first_instability, instability_kind

NAME = "cylinder-axial-buckling"
DESCRIPTION = ("cylinder R/t = 100 compressed axially by growth between symmetry planes: critical strain vs "
               "t/(R sqrt(3(1-nu^2))), linear buckling ladder (order, Richardson) and continuation")
SOURCE = ("Timoshenko & Gere, Theory of Elastic Stability (1961) sec. 11.4; Brush & Almroth, Buckling of Bars, "
          "Plates and Shells (1975) sec. 5.3 (Koiter circle)")

RADIUS, THICKNESS, E, NU = 100.0, 1.0, 1.0, 0.3
G_CL = THICKNESS / (RADIUS * math.sqrt(3 * (1 - NU**2)))
HALF_WAVE = math.pi * math.sqrt(RADIUS * THICKNESS) / (12 * (1 - NU**2)) ** 0.25
LENGTH = 2 * HALF_WAVE
#: vertex counts of the linear-buckling ladder and of the continuation runs, per level
LEVELS = {"quick": {"linear": [800, 1600], "continuation": [800]},
          "full": {"linear": [800, 1600, 3200, 6400, 12800], "continuation": [800, 1600, 3200]}}
#: tolerances (finest linear buckling, Richardson estimate). Measured: 0.931 g_cl on 818 vertices; full level
#: 0.9799 on 12 750, Richardson 0.9811 with the order 2.29 of the values: the limit is 1.9 % below g_cl (O(t/R))
TOL = {"quick": (0.1, None), "full": (0.03, 0.02)}


def axial_growth(points, triangles, curvature, g):
    """The rest state grown by 1 + g along z: ā_ij = e_i · diag(1, 1, (1 + g)²) e_j, curvature unchanged."""
    x = np.asarray(points, float)[np.asarray(triangles)]
    e = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)          # (m, 2, 3)
    abar = np.einsum("mik,k,mjk->mij", e, np.array([1.0, 1.0, (1.0 + g) ** 2]), e)
    return RestState(abar, curvature, THICKNESS)


def cylinder_problem(n_vertices, seed=0, pinned=True):
    """(model, GrowthParameter in g) of the cylinder of about ``n_vertices`` vertices, stress free at g = 0;
    ``pinned``: three pins hold its rigid motions (two vertices on the bottom edge at x = ±R)."""
    mesh = cylinder(RADIUS, LENGTH, n_vertices=n_vertices, seed=seed)
    bcs = [Symmetry("z", 0.0), Symmetry("z", LENGTH)]
    if pinned:
        bottom = np.flatnonzero(np.abs(mesh.points[:, 2]) < 1e-9 * LENGTH)
        a = bottom[np.argmin(np.linalg.norm(mesh.points[bottom] - [RADIUS, 0, 0], axis=1))]
        b = bottom[np.argmin(np.linalg.norm(mesh.points[bottom] - [-RADIUS, 0, 0], axis=1))]
        bcs += [Prescribed(vertices=(int(a),), components=(0, 1)), Prescribed(vertices=(int(b),), components=(1,))]
    model = ShellModel(mesh, Material(E, NU), THICKNESS, bcs,
                       remove_rigid_modes=False)
    curvature = model.stress_free_rest_state().curvature        # the drawn cylinder is stress free
    problem = GrowthParameter(model, lambda g: axial_growth(mesh.points, mesh.triangles, curvature, g),
                              parameter_scale=G_CL, length_scale=THICKNESS)
    problem.set_parameter(0.0)
    return model, problem


def run(level):
    plan = LEVELS[level]
    tol_fine, tol_rich = TOL[level]
    rows, ladder = [], []
    for i, nv in enumerate(plan["linear"]):
        with timed() as t:
            model, problem = cylinder_problem(nv, pinned=False)
            g = shell_buckling_loads(problem, model.initial_unknowns(), k=4).parameters
        n = model.mesh.n_vertices
        ladder.append((n, g[0] / G_CL))
        rows.append(Row(f"linear buckling g_c / g_cl @ n={n}", g[0] / G_CL, 1.0,
                        tol_fine if i == len(plan["linear"]) - 1 else None, n, t()))
    ns, values = zip(*ladder)
    rows += convergence_rows("linear g_c / g_cl", ns, values, tol_rich)
    for nv in plan["continuation"]:
        with timed() as t:
            model, problem = cylinder_problem(nv)
            g, point = first_instability(problem, model.initial_unknowns(), 1.3 * G_CL)
        n = model.mesh.n_vertices
        rows.append(Row(f"continuation: first instability g / g_cl ({instability_kind(point)}) @ n={n}", g / G_CL,
                        1.0, None, n, t()))
        lin = dict(ladder).get(n)
        if lin is not None:
            rows.append(Row(f"continuation / linear buckling, same mesh @ n={n}", g / G_CL / lin, None, None, n, 0.0))
    return rows
