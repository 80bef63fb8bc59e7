"""The grown disk of the linear reference: critical growth strain and critical grown radius.

A flat disk of radius R1 grown by g0 inside r < R2 (thickness h outside and h / (1 + g0)² inside
when ``thin_grown``): :func:`critical_growth_strain` gives ε_c = μ₁ g0 and the first mode's
wavenumber; :func:`critical_inner_radius` the R2 at which g0 buckles it (μ = 1).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .._checks import integer
from ..mesh import generators
from .eigenproblem import BucklingResult, buckling_loads
from .modes import mode_wavenumber
from .prestress import membrane_prestress

__all__ = ["critical_growth_strain", "CriticalGrowth", "critical_inner_radius", "CriticalRadius"]


@dataclass
class CriticalGrowth:
    """Linear critical growth of a disk with a grown inner region (:func:`critical_growth_strain`).

    ``eps_c = mu * g0``: the critical growth strain in the linear theory for the
    thickness field used (for ``thin_grown`` the grown region has the thickness
    h / (1 + g0)^2 of the nominal growth g0; eps_c is self-consistent only where mu ≈ 1).
    ``n`` is the azimuthal wavenumber of the first mode, ``ns`` of every returned mode.
    """

    eps_c: float
    mu: np.ndarray
    n: int
    ns: list
    wavelength: float
    result: BucklingResult
    n_vertices: int
    wall_s: float


def critical_growth_strain(R1, R2, h, g0=0.5, nu=0.5, E=1.0, thin_grown=True, bc="free",
                           resolution=8, edge_length=None, inner_edge_length=None, k=4, mesh=None,
                           seed=0, solver="splu"):
    """Linear critical growth strain of a flat disk grown by g0 inside r < R2.

    The disk has radius R1, thickness h outside and ``h / (1 + g0)^2`` inside (if
    ``thin_grown``; else h), isotropic linear eigenstrain g0 inside
    r < R2 and 0 outside. Its outer edge is ``bc`` ("free" as in the paper, or
    "clamped"; the same edge condition is used in plane and out of plane).

    Mesh: ``femshell.mesh.generators.disk(R1, edge_length, inner_radius=R2,
    inner_edge_length=...)`` with, by default, inner_edge_length = R2 / resolution and
    edge_length = 4 R2 / resolution within [R1 / 25, R1 / 5] (the gmsh size grows from the inner
    value near the circle to edge_length with gradient 0.3). In linear plate theory
    the only length that shapes the modes is R2 (and R1); h only scales mu as h^2,
    so the mesh follows R2. Or pass ``mesh`` (a SurfaceMesh or (points, triangles)
    whose edges follow the circle r = R2).

    Returns a :class:`CriticalGrowth` (eps_c = mu[0] * g0 and the wavenumber n of the
    first mode, from :func:`mode_wavenumber` on circles r in [0.3, 1.5] R2).
    """
    t0 = time.perf_counter()
    for name, v in (("R1", R1), ("R2", R2), ("h", h), ("g0", g0), ("E", E)):
        if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not R2 < R1:
        raise ValueError(f"R2 must be < R1, got R2 = {R2}, R1 = {R1}")
    resolution = integer("resolution", resolution, 1)
    if mesh is None:
        mesh = _disk_mesh(R1, R2, resolution, edge_length, inner_edge_length, seed)
    if hasattr(mesh, "points"):
        pts, tri = np.asarray(mesh.points)[:, :2], np.asarray(mesh.triangles)
    else:
        pts, tri = np.asarray(mesh[0])[:, :2], np.asarray(mesh[1])
    cen = pts[tri].mean(1)
    inside = np.hypot(cen[:, 0], cen[:, 1]) < R2
    g = np.where(inside, g0, 0.0)
    t = np.where(inside, h / (1.0 + g0) ** 2 if thin_grown else h, h)
    N = membrane_prestress(pts, tri, g, E=E, nu=nu, thickness=t, boundary="free" if bc == "free" else "clamped")
    res = buckling_loads(pts, tri, N, E=E, nu=nu, thickness=t, bc=bc, k=k, solver=solver)
    radii = R2 * np.array([0.3, 0.5, 0.7, 0.85, 1.0, 1.15, 1.3, 1.5])
    radii = radii[radii < 0.98 * R1]
    ns, wls, _ = mode_wavenumber(res, None, radii=radii) if len(res.mu) else ([], [np.inf], None)
    wl = wls[0]
    return CriticalGrowth(eps_c=float(res.mu[0] * g0), mu=res.mu, n=ns[0] if ns else -1, ns=ns,
                          wavelength=wl, result=res, n_vertices=len(pts),
                          wall_s=time.perf_counter() - t0)


def _disk_mesh(R1, R2, resolution=8, edge_length=None, inner_edge_length=None, seed=0, refine_inside=False):
    """(points (n, 2), triangles) of a disk of radius R1 with the circle R2 in its edges (``refine_inside``:
    the whole inner disk at the inner edge length, :func:`femshell.mesh.generators.disk`)."""
    if inner_edge_length is None:
        inner_edge_length = R2 / resolution
    if edge_length is None:
        edge_length = min(max(4.0 * R2 / resolution, R1 / 25.0), R1 / 5.0)
    m = generators.disk(R1, edge_length=edge_length, inner_radius=R2,
                        inner_edge_length=min(inner_edge_length, edge_length), seed=seed,
                        refine_inside=refine_inside)
    return np.asarray(m.points)[:, :2].copy(), np.asarray(m.triangles)


def _radial_morph(points, R2_from, R2_to, R1):
    """Move the circle r = R2_from to r = R2_to, keeping r = R1 and the centre fixed.

    Piecewise linear in r (scaling inside, affine in the annulus): the same triangulation
    at a nearby R2, so that mu(R2) is a smooth function for the root finder instead of
    jumping with every remeshing.
    """
    r = np.hypot(points[:, 0], points[:, 1])
    rn = np.where(r <= R2_from, r * (R2_to / R2_from),
                  R2_to + (r - R2_from) * (R1 - R2_to) / (R1 - R2_from))
    scale = np.where(r > 0, rn / np.where(r > 0, r, 1.0), 1.0)
    return points * scale[:, None]


@dataclass
class CriticalRadius:
    """Smallest grown radius R2 at which the disk buckles at growth g0 (mu = 1), linear theory.

    ``R2``: the root; ``mu``: mu of the target mode on the last mesh (≈ 1); ``n``: the
    target mode's azimuthal wavenumber (that of the first mode if no n was asked);
    ``history``: [(R2, mu_target)] of every evaluation; ``last``: the
    :class:`CriticalGrowth` of the last evaluation; ``converged``: |mu − 1| < rtol was
    reached within maxiter evaluations (if not, R2 is the last iterate, not a root).
    """

    R2: float
    mu: float
    n: int
    history: list
    last: CriticalGrowth
    n_vertices: int
    wall_s: float
    converged: bool = True


def critical_inner_radius(R1, h, g0=0.5, n=None, nu=0.5, E=1.0, thin_grown=True, bc="free",
                          resolution=8, R2_start=None, k=None, rtol=1e-3, maxiter=12, seed=0,
                          solver="splu"):
    """Smallest R2 where the disk of :func:`critical_growth_strain` buckles at growth g0.

    Solves ``mu_target(R2) = 1`` where mu_target is the first load factor (``n=None``)
    or the lowest one whose mode has ``n`` azimuthal waves, remeshing at every R2.
    The root is found in the variables (log R2, log mu): linear plate theory makes
    mu ∝ R2^-2 up to the weak dependence on R1 / R2, so the first step is the scaling
    step ``R2 <- R2 sqrt(mu)``, then a secant step, safeguarded by bisection of the
    bracket once the root is bracketed. Stops when |mu - 1| < rtol (a remeshing
    makes mu(R2) jump at the level of the discretisation error, so the mesh made at the first R2 is morphed radially to the next
    R2s, and remade only when R2 has moved by more than 20 %, which keeps mu(R2)
    smooth). ``k`` modes per evaluation (default 4, or 8 + 6 n for a
    target n; doubled if no mode with n waves is among them).
    """
    t0 = time.perf_counter()
    maxiter = integer("maxiter", maxiter, 1)
    kk = k if k is not None else (4 if n is None else 8 + 6 * n)
    converged = False
    x = np.log(R2_start if R2_start is not None else h)
    hist, pts = [], []
    lo = hi = None   # bracket: f(lo) > 0 (stable, mu > 1), f(hi) < 0
    last = None
    ref = None       # (R2 of the mesh, points, triangles): morphed, remeshed when R2 moved > 20 %
    for _ in range(maxiter):
        R2 = float(np.exp(x))
        if R2 >= 0.9 * R1:
            raise ValueError(f"no root below R2 = 0.9 R1 (R1 = {R1}); is g0 = {g0} too small? "
                             f"(R2, mu) so far: {hist}")
        if ref is None or not (1 / 1.2 < R2 / ref[0] < 1.2):
            ref = (R2,) + _disk_mesh(R1, R2, resolution, seed=seed)
        mesh = (_radial_morph(ref[1], ref[0], R2, R1), ref[2])
        while True:
            cg = critical_growth_strain(R1, R2, h, g0=g0, nu=nu, E=E, thin_grown=thin_grown, bc=bc,
                                        k=kk, mesh=mesh, solver=solver)
            if n is None:
                mu_t, n_t = float(cg.mu[0]), cg.n
                break
            hits = [i for i, m_ in enumerate(cg.ns) if m_ == n]
            if hits:
                mu_t, n_t = float(cg.mu[hits[0]]), n
                break
            if kk >= 200:
                raise RuntimeError(f"no mode with n = {n} among the first {kk} modes at R2 = {R2:.4g}")
            kk *= 2
        last = cg
        f = float(np.log(mu_t))
        hist.append((R2, mu_t))
        pts.append((x, f))
        if abs(mu_t - 1.0) < rtol:
            converged = True
            break
        if f > 0:
            lo = x if lo is None else max(lo, x)
        else:
            hi = x if hi is None else min(hi, x)
        if len(pts) >= 2 and pts[-1][1] != pts[-2][1]:
            (x1, f1), (x2, f2) = pts[-2], pts[-1]
            slope = (f2 - f1) / (x2 - x1)
            xn = x2 - f2 / slope if slope < 0 else x2 + f2 / 2.0
        else:
            xn = x + f / 2.0          # mu ∝ R2^-2
        xn = min(max(xn, x - np.log(2.0)), x + np.log(2.0))   # at most a factor 2 per step
        if lo is not None and hi is not None and not (min(lo, hi) < xn < max(lo, hi)):
            xn = 0.5 * (lo + hi)      # safeguard: bisection of the bracket
        x = xn
    return CriticalRadius(R2=hist[-1][0], mu=hist[-1][1], n=n_t, history=hist, last=last,
                          n_vertices=last.n_vertices, wall_s=time.perf_counter() - t0, converged=converged)
