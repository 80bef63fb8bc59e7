r"""Complete sphere under uniform external pressure: critical pressure and mode degree against the classical
result, by linear buckling and by continuation.

A complete sphere of radius R = 100 t (t = 1, E = 1, ν = 0.3), stress free as drawn
(:meth:`~femshell.shell.ShellModel.stress_free_rest_state`), under a follower pressure p pushing
inwards (:class:`~femshell.shell.FollowerPressure` with p < 0), held by nothing: the pressure on a
closed surface is self-equilibrated and rotation invariant, and linear buckling deflates the six rigid
motions (:func:`~femshell.linear_buckling.shell_buckling_loads`); the continuation holds them by the
statically determinate :func:`~femshell.shell.rigid_body_pins`, which leave the nonzero
inertia of the free sphere. The membrane prestress is uniform, N = −pR/2, and the sphere buckles in a
spherical harmonic of degree

    n(n + 1) ≈ √(12 (1 − ν²)) R/t  (n ≈ 17.7 at R/t = 100; all 2n + 1 orders, and neighbouring n, are
    critical within a fraction of a per cent: a cluster of dozens of modes)

at the classical pressure (Zoelly 1915; shallow-shell form of the minimum over n):

    p_cl = 2 E t² / (R² √(3 (1 − ν²))).

At R/t = 100 the discrete minimum over integer n lies 0.05 % above the continuous one, and the
thin-shell corrections are O(t/R); the reference is p_cl.

Procedure per mesh (a refinement ladder of gmsh spheres):

* linear buckling (:func:`~femshell.linear_buckling.shell_buckling_loads` in the load factor, from the
  unloaded sphere): the smallest λ with (K₀ + λ K₁) φ = 0, K₁ the derivative of the Hessian along
  the linear prebuckling path (including the follower-load stiffness), rigid motions deflated;
  the mode degree from the normal component w of the critical mode, rigid and degree-0/1 parts
  removed, as n(n + 1) = R² ⟨w, K w⟩ / ⟨w, M w⟩ with the P1 Laplace–Beltrami stiffness K and
  lumped mass M;
* continuation in the load factor (:class:`~femshell.solvers.continuation.LoadParameter`) from
  the unloaded sphere to its first instability (fold or branch point), which it locates.

Rows: both critical pressures / p_cl per mesh, the observed order of each ladder and its Richardson
extrapolation (error ∝ h^p with the observed p, h ∝ n_vertices^(−1/2)), the mode degree on the
finest mesh. The faceted sphere is not a perfect sphere: its discrete
curvature varies from element to element, an imperfection of amplitude ∝ h² that the nonlinear
continuation feels (spheres are imperfection sensitive) and the linear buckling does not, so the
continuation's first instability is a fold below the linear critical pressure on coarse meshes
(docs/studies/curved-buckling.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..chemistry import surface_mass_lumped, surface_stiffness
from ..mesh.generators import sphere
from ..linear_buckling import shell_buckling_loads
from ..shell import FollowerPressure, Material, ShellModel
from ..solvers.continuation import LoadParameter
from .framework import Row, timed
from .shell_buckling import convergence_rows, first_instability, instability_kind

NAME = "sphere-pressure-buckling"
DESCRIPTION = ("complete sphere R/t = 100 under external follower pressure: critical pressure vs "
               "p_cl = 2 E t^2/(R^2 sqrt(3(1-nu^2))) and mode degree, linear buckling ladder (order, Richardson) "
               "and continuation")
SOURCE = ("Zoelly (1915); Timoshenko & Gere, Theory of Elastic Stability (1961) sec. 11.6; Hutchinson, J. Appl. "
          "Mech. 34 (1967) 49 (imperfection sensitivity of spheres)")

RADIUS, THICKNESS, E, NU = 100.0, 1.0, 1.0, 0.3
P_CL = 2 * E * THICKNESS**2 / (RADIUS**2 * math.sqrt(3 * (1 - NU**2)))
#: n(n + 1) of the classical critical degree
N_CL = 0.5 * (-1 + math.sqrt(1 + 4 * math.sqrt(12 * (1 - NU**2)) * RADIUS / THICKNESS))
#: vertex counts of the linear-buckling ladder and of the continuation runs, per level (the full ladder stops at
#: 16 000 vertices: 32 000 would cost about as much again as the whole level, on 2 shared cores)
LEVELS = {"quick": {"linear": [1000, 2000], "continuation": [600]},
          "full": {"linear": [2000, 4000, 8000, 16000], "continuation": [2000, 4000, 8000]}}
#: tolerances (finest linear buckling, Richardson estimate, mode degree in absolute units of n). The
#: quick meshes do not resolve the wave (about 4 edges per wavelength at 2 000 vertices: 0.718 p_cl);
#: at 4 000 vertices linear buckling gives 0.926 p_cl
TOL = {"quick": (0.35, None, 4.0), "full": (0.05, 0.03, 2.0)}


def sphere_model(n_vertices, seed=0):
    """The stress-free sphere of about ``n_vertices`` vertices under the classical pressure at load factor 1."""
    mesh = sphere(RADIUS, n_vertices=n_vertices, seed=seed)
    model = ShellModel(mesh, Material(E, NU), THICKNESS, [],      # the drawn sphere is stress free
                       [FollowerPressure(-P_CL)])
    return model


def critical_loads(model, k=1):
    """(load factors ascending, vertex displacements (n, 3) of the lowest mode): linear buckling of the
    unloaded sphere in the load factor (:func:`femshell.linear_buckling.shell_buckling_loads`)."""
    model.load_factor = 0.0
    res = shell_buckling_loads(model, model.initial_unknowns(), k=k)
    model.load_factor = 1.0
    return res.parameters, res.displacements(0)


def mode_degree(model, displacement):
    """The spherical-harmonic degree n of a mode's normal displacement (vertex displacements (n, 3)):
    n(n + 1) = R² ⟨w, Kw⟩ / ⟨w, Mw⟩ after removing its degree-0 and degree-1 parts (a rigid translation
    is degree 1)."""
    x = model.mesh.points
    w = np.einsum("ij,ij->i", displacement, x / np.linalg.norm(x, axis=1)[:, None])
    m = surface_mass_lumped(x, model.mesh.triangles)
    low = np.column_stack([np.ones(len(x)), x])
    coef = np.linalg.solve(low.T @ (m[:, None] * low), low.T @ (m * w))
    w = w - low @ coef
    q = RADIUS**2 * float(w @ (surface_stiffness(x, model.mesh.triangles) @ w)) / float(w @ (m * w))
    return 0.5 * (-1 + math.sqrt(1 + 4 * q))


def run(level):
    plan = LEVELS[level]
    tol_fine, tol_rich, tol_degree = TOL[level]
    rows, ladder = [], []
    for i, nv in enumerate(plan["linear"]):
        with timed() as t:
            model = sphere_model(nv)
            lam, mode = critical_loads(model)
        n = model.mesh.n_vertices
        finest = i == len(plan["linear"]) - 1
        ladder.append((n, lam[0]))
        rows.append(Row(f"linear buckling p_cr / p_cl @ n={n}", lam[0], 1.0, tol_fine if finest else None, n, t()))
        if finest:
            rows.append(Row(f"mode degree of the critical mode (classical {N_CL:.2f}) @ n={n}",
                            mode_degree(model, mode), N_CL, tol_degree / N_CL, n, 0.0))
    ns, values = zip(*ladder)
    rows += convergence_rows("linear p_cr / p_cl", ns, values, tol_rich)
    folds = []
    for nv in plan["continuation"]:
        with timed() as t:
            model = sphere_model(nv)
            model.load_factor = 0.0
            lam, point = first_instability(LoadParameter(model, length_scale=THICKNESS), model.initial_unknowns(),
                                           1.3)
        n = model.mesh.n_vertices
        rows.append(Row(f"continuation: first instability p / p_cl ({instability_kind(point)}) @ n={n}", lam, 1.0,
                        None, n, t()))
        folds.append((n, lam))
        lin = dict(ladder).get(n)
        if lin is not None:
            rows.append(Row(f"continuation / linear buckling, same mesh @ n={n}", lam / lin, None, None, n, 0.0))
    ns, values = zip(*folds)
    return rows + convergence_rows("continuation p / p_cl", ns, values, None)
