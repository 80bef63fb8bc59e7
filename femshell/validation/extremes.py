r"""Stiff and extreme inputs: large growth, steep sigmoids, huge production, diffusion and time steps.

Each row has a pass criterion (a tolerance) unless it only reports a measurement.

1. **Large incompatible growth.** The disk test of the seed paper (theory §1.6: flat disk of
   radius 10, free edge, ν = 0.5) with the growth pushed from s = 1.5 to s = 2 (area ×4,
   thickness /4 in the inner disk of radius 3). The stretch is stepped from 1 to 2
   (:func:`grow_in_steps`: a failed Newton solve halves the step and retries from the last
   converged state, at most 6 times in a row). Pass: s = 2 is reached, every accepted state
   is a stable equilibrium (inertia of the Hessian: no negative eigenvalue), no NaN/inf in
   the positions. Reported: Newton iterations, cuts, out-of-plane extent, number of rim
   waves.
2. **Frustrated spherical cap** (full level): a free cap of a sphere (R = 2, opening
   0.5 rad, h = 0.02) grows by s (ā = s² a0, b̄ = s² b0, h̄ = h/s²: it keeps wanting the
   curvature 1/R while its area grows — metric and curvature are incompatible, as in the
   coupled loop). Reported: the stretch reached with Newton converging to rtol 1e-8, and
   whether a Newton failure stopped it. Pass: every accepted state is a stable minimum.
3. **Steep sigmoid** Λ(c), s(c), ds/dc for b = 1 … 1000 and c − c* = ±2e3 under
   ``np.errstate(over/invalid/divide="raise")``. Pass: 0 non-finite values, 0 violations of
   monotonicity and bounds.
4. **Reaction–diffusion** with w up to 1e3, D up to 1e2, dt up to 100 on a sphere
   (600 vertices) that is stretched ×10 and back between steps. Pass: min c ≥ 0 without
   clipping, max c ≤ max(c0, P/β) (discrete maximum principle), 0 non-finite values.
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from ..chemistry import ReactionDiffusion, curvature_source
from ..growth import contractility, dstretch_dc, stretch
from ..mesh import SurfaceMesh
from ..mesh.generators import disk, sphere
from ..shell import Material, RestState, ShellModel, metric
from ..solvers.linear import factorize
from ..solvers.newton import NewtonError, minimize, secant_start
from .framework import Row

NAME = "extremes"
DESCRIPTION = ("extreme inputs: growth to s = 2 of the seed paper's disk (and a frustrated cap), steep sigmoid "
               "b <= 1000, production w <= 1e3, D <= 1e2, dt <= 100: converged, stable, finite, c >= 0")
SOURCE = ("pass criteria from the mathematics: stability from the Hessian inertia; Lambda in [Lmin, Lmax] and "
          "monotone; discrete maximum principle of the chemistry step on Delaunay meshes (0 <= c <= max(c0, P/beta))")

LEVELS = {
    "quick": {"disk_edge": 2.0, "disk_steps": 10, "cap": False},
    # full: edge 0.7 (833 vertices), minutes on one core
    "full": {"disk_edge": 0.7, "disk_steps": 10, "cap": True},
}


def grow_in_steps(model, rest_at, s_target, n_steps=10, max_cuts=6, callback=None, u0=None, **newton):
    """Equilibria while a growth stretch goes from 1 to ``s_target`` (``rest_at(s)`` gives the rest state).

    The stepping of :func:`femshell.solvers.newton.follow_load` for a parameter that enters
    through the rest state: each step starts from a secant prediction from the last two
    converged states, with one residual scale for all steps (the imbalance of the start under
    the full growth ``s_target``) unless ``residual_scale`` is given; a failed Newton
    solve halves the step and retries, at most ``max_cuts`` times in a row (a success resets
    the count and doubles the step again, up to the initial ``(s_target - 1) / n_steps``: a
    stretch of the path that needs small steps does not make the rest of the path small-stepped). Returns ``(s_reached, last NewtonResult, stats)``
    with stats = {"iterations", "cuts", "steps", "all_stable"}; a NewtonError after too many
    cuts leaves the model at the last converged stretch and carries it in ``stats`` of the
    error's ``.stats`` attribute.
    """
    s, u = 1.0, (model.initial_unknowns() if u0 is None else np.array(u0, float))
    if "residual_scale" not in newton:
        # one force scale for all steps: the imbalance of the start under the full growth. (minimize's
        # default, the imbalance at each step's start, shrinks as the predictor improves and then asks
        # for ever smaller absolute residuals.)
        model.set_rest_state(rest_at(s_target))
        newton["residual_scale"] = float(np.linalg.norm(model.gradient(u)))
    step = step0 = (s_target - 1.0) / n_steps
    cuts = 0
    res = None
    previous = None          # (s, u) of the converged step before: secant predictor as in follow_load
    stats = {"iterations": 0, "cuts": 0, "steps": 0, "all_stable": True, "s": 1.0, "unstable_at": []}
    while s < s_target - 1e-14:
        trial = min(s + step, s_target)
        model.set_rest_state(rest_at(trial))
        start = secant_start(model, u, s, trial, previous)
        try:
            res = minimize(model, start, log=None, **newton)
        except NewtonError as exc:
            stats["iterations"] += exc.result.iterations if exc.result is not None else 0
            cuts += 1
            stats["cuts"] += 1
            if cuts > max_cuts:
                model.set_rest_state(rest_at(s))
                exc.stats = stats
                exc.u = u
                raise
            step /= 2
            continue
        if cuts == 0:
            step = min(2.0 * step, step0)   # grow back after a cut stretch, one doubling per clean step
        cuts = 0
        previous = (s, u)
        u, s = res.u, trial
        stats["iterations"] += res.iterations
        stats["steps"] += 1
        stats["all_stable"] &= bool(res.stable) if res.stable is not None else False
        if not res.stable:
            stats["unstable_at"].append((s, res.n_negative))
        stats["s"] = s
        if callback:
            callback(s, res)
    return s, res, stats


# --------------------------------------------------------------------------- 1. disk

def _rim_waves(x, rim):
    """Number of waves of z around the rim: half the sign changes of z − mean(z), ordered by angle."""
    ang = np.arctan2(x[rim, 1], x[rim, 0])
    z = x[rim, 2][np.argsort(ang)]
    z = z - z.mean()
    return int(np.count_nonzero(np.sign(z) != np.sign(np.roll(z, 1))) // 2)


def _disk_rows(cfg):
    R1, R2, h, s_max = 10.0, 3.0, 0.5, 2.0
    mesh = disk(radius=R1, edge_length=cfg["disk_edge"], inner_radius=R2)
    a0 = metric(mesh.points, mesh.triangles)
    inner = np.linalg.norm(mesh.points[mesh.triangles].mean(1)[:, :2], axis=1) < R2

    def rest_at(s):
        se = np.where(inner, s, 1.0)
        return RestState(se[:, None, None] ** 2 * a0, np.zeros_like(a0), h / se**2)

    t0 = time.perf_counter()
    model = ShellModel(mesh, Material(1.0, 0.5), rest_at(1.0))
    # a tiny out-of-plane perturbation lets the flat state leave along its buckling modes
    q = model.full(model.initial_unknowns())
    q[2:3 * mesh.n_vertices:3] += 1e-3 * np.random.default_rng(0).standard_normal(mesh.n_vertices)
    finite = [True]
    s, res, st = grow_in_steps(model, rest_at, s_max, n_steps=cfg["disk_steps"], u0=q[model.free], stable=True,
                               max_iter=150,
                               rtol=1e-8, callback=lambda s, r: finite.append(bool(np.all(np.isfinite(r.u)))))
    wall = time.perf_counter() - t0
    x = model.positions(res.u)
    n = mesh.n_vertices
    tag = "disk R=10, inner R=3 grown to s=2 (h=0.5, nu=0.5, free)"
    return [
        Row(f"{tag}: stretch reached", s, s_max, 1e-12, n, wall),
        Row(f"{tag}: fraction of accepted steps that are stable minima", float(st["all_stable"]), 1.0, 0.0, n, wall),
        Row(f"{tag}: non-finite positions at any step", float(not all(finite)), 0.0, 0.0, n, wall),
        Row(f"{tag}: Newton iterations (all steps)", st["iterations"], None, None, n, wall),
        Row(f"{tag}: step cuts", st["cuts"], None, None, n, wall),
        Row(f"{tag}: accepted states that are not stable minima (first at s = "
            f"{st['unstable_at'][0][0] if st['unstable_at'] else float('nan'):.4g})", len(st["unstable_at"]), None,
            None, n, wall),
        Row(f"{tag}: out-of-plane extent max z - min z", float(np.ptp(x[:, 2])), None, None, n, wall),
        Row(f"{tag}: waves around the rim", _rim_waves(x, mesh.topology.boundary_vertex_groups["outer"]), None, None,
            n, wall),
    ]


# --------------------------------------------------------------------------- 2. cap

def _cap_rows():
    flat = disk(radius=1.0, edge_length=0.2)
    R, h = 2.0, 0.02
    r = np.linalg.norm(flat.points[:, :2], axis=1)
    phi = np.arctan2(flat.points[:, 1], flat.points[:, 0])
    psi = r / R
    cap = R * np.column_stack([np.sin(psi) * np.cos(phi), np.sin(psi) * np.sin(phi), np.cos(psi)])
    mesh = SurfaceMesh(cap, flat.triangles)
    model = ShellModel(mesh, Material(1.0, 0.5), h)
    rest0 = model.stress_free_rest_state()

    def rest_at(s):
        return RestState(s**2 * rest0.metric, s**2 * rest0.curvature, h / s**2)

    t0 = time.perf_counter()
    try:
        s, res, st = grow_in_steps(model, rest_at, 2.0, n_steps=10, max_cuts=3, stable=True, max_iter=60,
                                   rtol=1e-8)
        reason = 0.0
    except NewtonError as exc:
        st = exc.stats
        s, reason = st["s"], 1.0
    wall = time.perf_counter() - t0
    tag = "free spherical cap R=2, h=0.02, metric and curvature grown by s (frustrated)"
    n = mesh.n_vertices
    return [Row(f"{tag}: stretch reached with Newton rtol 1e-8 (documented limit, see docs)", s, None, None, n, wall),
            Row(f"{tag}: stopped by Newton failure (1) or reached s=2 (0)", reason, None, None, n, wall),
            Row(f"{tag}: accepted states all stable minima", float(st["all_stable"]), 1.0, 0.0, n, wall)]


# --------------------------------------------------------------------------- 3. sigmoid

def _sigmoid_rows():
    t0 = time.perf_counter()
    bad = nonmono = out = 0
    n_eval = 0
    lam_max, lam_min = 15.0, 10.0
    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
        for b, c_star in itertools.product((1.0, 10.0, 100.0, 1000.0), (0.1, -1e3, 1e3)):
            c = np.sort(np.concatenate([np.linspace(-2e3, 2e3, 40001), c_star + np.linspace(-5, 5, 2001) / b]))
            lam = contractility(c, lam_max, lam_min, b, c_star)
            s = stretch(c, None, lam_max, lam_min, b, c_star)
            ds = dstretch_dc(c, None, lam_max, lam_min, b, c_star)
            n_eval += 3 * c.size
            bad += sum(int((~np.isfinite(v)).sum()) for v in (lam, s, ds))
            nonmono += int((np.diff(lam) > 0).sum() + (np.diff(s) < 0).sum() + (ds < 0).sum())
            out += int(((lam < lam_min) | (lam > lam_max)).sum() + ((s < 1) | (s > lam_max / lam_min)).sum())
    wall = time.perf_counter() - t0
    tag = "steep sigmoid b=1..1000, c-c* up to +-2e3"
    return [Row(f"{tag}: non-finite values (of {n_eval})", bad, 0.0, 0.0, 0, wall),
            Row(f"{tag}: monotonicity violations", nonmono, 0.0, 0.0, 0, wall),
            Row(f"{tag}: values outside [Lmin, Lmax] or [1, Lmax/Lmin]", out, 0.0, 0.0, 0, wall)]


# --------------------------------------------------------------------------- 4. chemistry

def _chemistry_rows():
    m = sphere(radius=30.0, n_vertices=600, seed=0)
    pts, tri = m.points, m.triangles
    rng = np.random.default_rng(0)
    H = rng.uniform(-1.0, 10.0, len(pts))
    t0 = time.perf_counter()
    c_min, worst_ratio, nonfinite, clipped = np.inf, 0.0, 0, 0
    with np.errstate(over="raise", invalid="raise", divide="raise", under="ignore"):
        for D, dt, w in itertools.product((0.0, 1.5, 1e2), (0.01, 1.0, 100.0), (15.0, 1e3)):
            P = curvature_source(H, w=w, Hs=0.05)
            c = rng.uniform(0.0, 5.0, len(pts))
            bound = max(c.max(), P.max())
            rd = ReactionDiffusion(tri, len(pts), D=D, beta=1.0, points=pts, factorize=factorize)
            for k in range(20):
                c = rd.step(c, dt, source=P, points=pts * (1.0 + 9.0 * (k % 2)))
                nonfinite += int((~np.isfinite(c)).sum())
                c_min = min(c_min, float(c.min()))
                worst_ratio = max(worst_ratio, float(c.max()) / bound)
            clipped += rd.n_clipped
            rd.free()
    wall = time.perf_counter() - t0
    n = len(pts)
    tag = "reaction-diffusion w<=1e3, D<=1e2, dt<=100, surface stretched x10"
    return [Row(f"{tag}: min c", c_min, None, None, n, wall),
            Row(f"{tag}: max(0, -min c) (c >= 0)", max(0.0, -c_min), 0.0, 0.0, n, wall),
            Row(f"{tag}: negative values clipped", clipped, 0.0, 0.0, n, wall),
            Row(f"{tag}: max c / max(c0, P/beta) - 1 (maximum principle, <= 0)", max(worst_ratio - 1.0, 0.0), 0.0,
                1e-12, n, wall),
            Row(f"{tag}: non-finite values", nonfinite, 0.0, 0.0, n, wall)]


def run(level):
    cfg = LEVELS[level]
    rows = _sigmoid_rows() + _chemistry_rows() + _disk_rows(cfg)
    if cfg["cap"]:
        rows += _cap_rows()
    return rows


def plot(rows, fig):
    ax = fig.subplots(1, 1)
    ax.axis("off")
    lines = [f"{'PASS' if r.passed else ('FAIL' if r.passed is False else '    ')}  {r.quantity[:95]}: {r.value:.4g}"
             for r in rows]
    ax.text(0.0, 1.0, "\n".join(lines), family="monospace", fontsize=6.5, va="top")
