r"""The uniform stationary state of the mechanochemical sphere followed in w, against its scalar reduction.

A sphere of radius R with a flat natural curvature (``rest_curvature = "k0"``, k0 = 0) and a uniform
concentration c stays a sphere: every element has the stretch s = s(c), the target metric s² ā0, the
target curvature s² k0 ā0 and the thickness h0/s² (theory §1.1, §2.7). On a sphere of radius ρ
(a = (ρ/R)² ā0, b = (ρ/R²) ā0 in the drawn sphere's parametrisation) the energy of theory §1.2 is,
with q = ρ/(sR), κ = ρ/(s²R²) − k0 and h̄ = h0/s²,

    U(ρ) = 4πR² s² (α + β_E) [ (h̄/2)(q² − 1)² + (h̄³/6) κ² ],

whose minimum dU/dρ = 0 gives ρ(s) (the Lamé factor cancels: ρ does not depend on E or ν); for
k0 = 0, κ = q/(sR) and q² = 1 − h̄²/(6 s² R²) in closed form (the metric-form bending term, ā⁻¹b
growing with ρ, pulls the sphere slightly inside sR). The
mean curvature measured from k0 is H = 1/ρ − k0 and the uniform stationary c solves the scalar
equation βc = P(H(ρ(s(c)))) (theory §1.3; D plays no part). Both are solved by brentq to 1e-14.

That branch has no fold in any parameter: P is increasing in H, H = 1/ρ decreasing in s (ρ =
sR q with q growing with s, k0 = 0) and s(c) increasing, so βc − P(H(c)) is
strictly increasing in c, its root unique, and w(c) = βc (1 + H/Hs)/H increasing. What the FEM
continuation is checked on is the branch itself: the continuation of the stationary system
(:mod:`femshell.coupled.pattern_continuation`) in w from 1 to 15 on a ladder of unstructured
meshes, the mass-weighted mean of c and the mean radius against the reduction at every point of the
branch, their observed order in the mesh size, and the absence of special points. The switch is
made smooth (b = 10): with the paper's b = 100 the uniform state turns unstable near c = c* (the
onset of patterning) and the mesh's irregularity breaks its symmetry there.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ..coupled import CoupledLoop, MechanochemicalModel, StationaryProblem, TimeStepping, stationary_state
from ..coupled.pattern_continuation import PatternParameter
from ..mesh.generators import sphere
from ..solvers.continuation import continuation
from .framework import Row, timed

NAME = "uniform-sphere-pattern"
DESCRIPTION = ("continuation in w of the uniform stationary state of a growing sphere (flat natural curvature) "
               "against its scalar reduction: mean c and radius along the branch, no special point")
SOURCE = ("scalar reduction (this module's docstring): the sphere's radius from dU/drho = 0 of the theory §1.2 "
          "energy of a uniformly grown sphere, and beta c = P(1/rho(s(c))), both by brentq")

RADIUS, H0, K0, B_SWITCH = 5.0, 0.5, 0.0, 10.0
W_START, W_STOP = 1.0, 15.0
LEVELS = {"quick": {"n_vertices": [200, 400, 800]}, "full": {"n_vertices": [200, 400, 800, 1600]}}
#: the reduction's c and ρ are met to C (h/R)² (h the mean edge length): P1 curvature and mass on a
#: faceted sphere err by O(h²)
ERROR_C = 0.1
ORDER_TOL = 0.25


def model(w=W_START) -> MechanochemicalModel:
    return MechanochemicalModel(h0=H0, k0=K0, rest_curvature="k0", D=0.0, w=w, b=B_SWITCH)


def sphere_radius(s, params, R=RADIUS) -> float:
    """ρ(s): the root of dU/dρ of the module docstring."""
    hb = params.h0 / s**2 if params.thickness_mode == "volume" else params.h0
    k0 = params.natural_curvature

    def dU(rho):
        q, kappa = rho / (s * R), rho / (s * s * R * R) - k0
        return 2 * hb * q * (q * q - 1) / (s * R) + hb**3 / 3 * kappa / (s * s * R * R)

    return brentq(dU, 0.1 * s * R, 4 * s * R, xtol=1e-14, rtol=1e-15)


def uniform_concentration(w, params, R=RADIUS) -> float:
    """The root c of βc = P(H(ρ(s(c)))) at production rate w (unique, module docstring)."""
    p = model(w) if params is None else params

    def g(c):
        H = 1.0 / sphere_radius(float(p.stretch(c)), p, R) - p.natural_curvature
        return w * H / (1 + H / p.Hs) / p.beta - c

    return brentq(g, 0.0, w * p.Hs / p.beta * (1 + 1e-9) + 1e-300, xtol=1e-15, rtol=1e-15)


def _branch(n_vertices):
    """(mesh, problem, branch) of the FEM continuation from W_START to W_STOP."""
    mesh = sphere(RADIUS, n_vertices=n_vertices, seed=0)
    p = model()
    c0 = uniform_concentration(W_START, p)
    loop = CoupledLoop(mesh, p, TimeStepping(), c0=np.full(mesh.n_vertices, c0), log=None)
    problem = StationaryProblem.of_loop(loop)
    root = stationary_state(loop, problem=problem)
    if not root.converged:
        raise RuntimeError(f"the uniform state at w = {W_START} did not converge: {root.message}")
    pp = PatternParameter(problem, "w", parameter_scale=1.0, stability=False)
    branch = continuation(pp, problem.join(root.u, root.c), W_START, ds=0.5, lam_stop=W_STOP, max_steps=200,
                          record=lambda z: {}, log=None)
    return mesh, problem, branch


def _errors(problem, branch):
    """Largest relative errors of the mean c and the mean radius over the branch's points."""
    err_c = err_r = 0.0
    for z, w in branch.states:
        u, c = problem.split(z)
        points = problem.shell.positions(u)
        mass = problem.chemistry.mass_lumped(points)
        c_ref = uniform_concentration(w, problem.params)
        rho = sphere_radius(float(problem.params.stretch(c_ref)), problem.params)
        err_c = max(err_c, abs(float(mass @ c) / mass.sum() - c_ref) / c_ref)
        err_r = max(err_r, abs(float(np.linalg.norm(points - points.mean(axis=0), axis=1).mean()) - rho) / rho)
    return err_c, err_r


def _mean_edge(mesh):
    e = mesh.points[mesh.triangles[:, [1, 2, 0]]] - mesh.points[mesh.triangles]
    return float(np.linalg.norm(e, axis=2).mean())


def run(level: str = "quick") -> list:
    rows, hs, errs = [], [], []
    for n in LEVELS[level]["n_vertices"]:
        with timed() as t:
            mesh, problem, branch = _branch(n)
        wall = t()
        h = _mean_edge(mesh)
        err_c, err_r = _errors(problem, branch)
        hs.append(h)
        errs.append((err_c, err_r))
        tol = ERROR_C * (h / RADIUS) ** 2
        nv = mesh.n_vertices
        rows += [Row(f"branch reached w = {W_STOP:g} (1 = yes) @ h={h:.4f}", float(branch.status == "lam_stop"), 1.0,
                     0.0, nv, wall),
                 Row(f"largest |mean c - c_reduction| / c_reduction over {len(branch.rows)} points, w in "
                     f"[{W_START:g}, {W_STOP:g}] @ h={h:.4f}", err_c, 0.0, tol, nv, wall),
                 Row(f"largest |mean radius - rho_reduction| / rho_reduction @ h={h:.4f}", err_r, 0.0, tol, nv, wall),
                 Row(f"special points on the branch (the reduction has none) @ h={h:.4f}",
                     float(len(branch.special_points)), 0.0, 0.0, nv, wall)]
    for k, name in enumerate(("mean c", "mean radius")):
        e = np.array([x[k] for x in errs])
        order = float(np.polyfit(np.log(hs), np.log(e), 1)[0]) if np.all(e > 0) else math.nan
        rows.append(Row(f"observed order in h of the {name} error", order, 2.0, ORDER_TOL, 0, 0.0))
    return rows
