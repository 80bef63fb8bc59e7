r"""The seed paper's sphere scenarios: spots, ridges, decay, diffusion, thickness, size (theory §1.5).

Each scenario starts from the rest sphere with c = 0 except the Gaussian spot of theory §1.4
(amplitude c_max = w Hs/β, width h) at the north pole and runs the staggered loop of
:class:`~femshell.coupled.CoupledLoop` (stable equilibrium at every step) to ``t_final`` or to a
stationary pattern. At the end the paper's measures (:func:`~femshell.analysis.find_spots`) are
reported beside the paper's qualitative outcome:

=================  =======================================  ==========================================
scenario           parameters (others: theory §1.5)         the paper (section 3)
=================  =======================================  ==========================================
spots              R = 30, h = 2, c* = 0.1, D = 0           near-uniform spots over the whole sphere
ridges             c* = 0.2                                 ridge-like lines of bulges
decay              c* = 0.35                                the perturbation decays
single-bulge       h = 1, c* = 0.1                          a single bulge, no propagation
propagation        h = 1, c* = 0.1, D = 0.5                 propagates (D > 0.4)
large-spots        D = 1.5                                  larger spots, lower peak c
small-sphere       R = 15                                   same spacing, fewer spots
uniform-thickness  h = 1, uniform thickness                 propagates at smaller h than volume-conserving
icosahedral        Λmax/Λmin = 1.05, h = 4, c* = 0.05,      a few large spots, 12 at icosahedral positions
                   w = 100
=================  =======================================  ==========================================

The paper's outcomes come from a spring network; they are reported, not toleranced. What must
hold in every run (toleranced rows): c ≥ 0 and finite, no accepted step with a saddle (the
stable Newton solver's inertia check), the run does not fail, and where a D = 0 run ends
stationary the state is a fixed point of the chemistry, |P(H) − βc| ≤ 1 % of c_max at every
vertex (dc/dt = P(H) − βc with H from the shell: a check of the loop, not of the paper).

Levels: ``quick`` (CI, about two minutes) runs ``decay`` on a sphere R = 15 of ~1 500 vertices to
t = 15 (it ends stationary, so the fixed-point row is exercised) and ``spots`` on ~800 vertices to
t = 0.25; these meshes are coarser than the paper's (mean edge 1.5 and 2.0 against 0.72), so their outcomes
say nothing about the paper's (see "Resolution" below). ``full`` runs all nine at the paper's
resolution (25 000 vertices on R = 30, the same edge length on R = 15) to t = 100 or
stationarity. It writes a checkpoint per scenario every 10 steps into
``OUT_DIR/sphere-patterns-checkpoints`` and resumes from it when run again (a finished scenario is
not recomputed: its checkpoint records the end). validation/sphere_patterns_study.py runs the
scenarios on coarser spheres within a wall-time budget and tabulates them.

Resolution
----------
The seeded spot is resolved only on meshes fine enough for its grown disk to pop out into a cap, whose mean
curvature (≈ 1/d, d the seed's width) saturates the production P(H): then the bulge sustains itself for every c*
below about 0.65. On coarser meshes it decays. The paper's decay for c* > 0.3 is therefore not a
resolution-independent outcome of this continuum model with the theory §1.4 seed (docs/studies/sphere-patterns.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analysis import find_spots, polar_profile
from ..geometry import fold_angles
from ..coupled import CoupledError, CoupledLoop, InitialSpot, MechanochemicalModel, TimeStepping
from ..io import load_checkpoint, save_checkpoint
from ..mesh import sphere
from ..scene.build import loop_observers
from .framework import Row, short_reason

NAME = "sphere-patterns"
DESCRIPTION = ("the paper's sphere scenarios (spots, ridges, decay, D, thickness, R = 15, icosahedral): "
               "coupled runs from one seeded spot, pattern measures beside the paper's outcomes "
               "(full level: paper resolution, 10-12 h per scenario here, resumable)")
SOURCE = ("Zakharov & Dasbiswas, Mechanochemical induction of wrinkling morphogenesis on elastic shells, "
          "section 3 (spring network, ~25 000 nodes), outcomes listed in theory §1.5; reported beside ours "
          "without tolerance. Toleranced: c >= 0 and finite, no saddle accepted, no failed run, fixed point "
          "|P(H) - beta c| <= 1 % c_max at a stationary D = 0 end")


@dataclass(frozen=True)
class Scenario:
    """One run of the paper: model parameters that differ from theory §1.5 and its outcome."""

    name: str
    paper: str
    radius: float = 30.0
    model: dict = field(default_factory=dict)


SCENARIOS = {s.name: s for s in (
    Scenario("spots", "near-uniform spots over the whole sphere", model={"c_star": 0.1}),
    Scenario("ridges", "ridge-like lines of bulges", model={"c_star": 0.2}),
    Scenario("decay", "the perturbation decays, the sphere stays round", model={"c_star": 0.35}),
    Scenario("single-bulge", "a single bulge, no propagation", model={"h0": 1.0, "c_star": 0.1}),
    Scenario("propagation", "the bulge propagates (D > 0.4)", model={"h0": 1.0, "c_star": 0.1, "D": 0.5}),
    Scenario("large-spots", "larger spots, lower peak concentration", model={"c_star": 0.1, "D": 1.5}),
    Scenario("small-sphere", "same spot spacing, proportionally fewer spots", radius=15.0,
             model={"c_star": 0.1}),
    Scenario("uniform-thickness", "propagates at smaller h than with volume conservation",
             model={"h0": 1.0, "c_star": 0.1, "thickness_mode": "uniform"}),
    Scenario("icosahedral", "a few large spots, 12 at icosahedral positions",
             model={"h0": 4.0, "c_star": 0.05, "w": 100.0, "lam_min": 15.0 / 1.05}),
)}

#: per level: scenario -> (end time, vertices; None: the paper's edge length) and the sphere
#: radius of the quick level (None: the scenario's)
LEVELS = {
    "quick": {"runs": {"decay": (15.0, 1500), "spots": (0.25, 800)}, "radius": 15.0},
    "full": {"runs": {name: (100.0, None) for name in SCENARIOS}, "radius": None},
}
#: fixed-point tolerance of a stationary D = 0 end, relative to c_max (stationarity is declared at
#: |Δc|/(dt max c) < 1e-3 per unit time, so |P − βc| ≲ 1e-3 c_max there)
FIXED_POINT_TOL = 1e-2
PAPER_VERTICES_R30 = 25000

_LAST = {}   # name -> final state of the last run(), for plot()


def paper_vertices(radius: float) -> int:
    """Vertices on a sphere of this radius at the paper's resolution (25 000 nodes on R = 30)."""
    return int(round(PAPER_VERTICES_R30 * (radius / 30.0) ** 2))


def model_of(scenario: Scenario, radius: float | None = None, membrane_law: str | None = None,
             thickness_mode: str | None = None) -> MechanochemicalModel:
    """The :class:`MechanochemicalModel` of a scenario (radius override for small test spheres;
    ``membrane_law`` overrides the default St Venant–Kirchhoff, e.g. ``"neo-hookean"``;
    ``thickness_mode`` the scenario's thickness law, ``"volume"`` or ``"uniform"``)."""
    kw = {"h0": 2.0, **scenario.model, **({"membrane_law": membrane_law} if membrane_law else {}),
          **({"thickness_mode": thickness_mode} if thickness_mode else {})}
    return MechanochemicalModel(radius=radius or scenario.radius, **kw)


def run_scenario(scenario: Scenario, *, t_final: float, n_vertices: int, radius: float | None = None,
                 checkpoint: Path | None = None, wall_time: float | None = None, max_steps: int | None = None,
                 seed: InitialSpot | None = None, membrane_law: str | None = None, thickness_mode: str | None = None,
                 stepping: dict | None = None, log=None) -> dict:
    """Run one scenario to ``t_final`` (or stationarity, ``wall_time`` seconds, ``max_steps`` steps); a dict.

    With ``checkpoint`` (an .npz path) the run resumes from it when it exists and saves
    to it every 10 steps and at the end. ``seed``: the initial spot (default theory §1.4's,
    amplitude c_max and width h). ``membrane_law``, ``thickness_mode``: see :func:`model_of`.
    ``stepping``: :class:`TimeStepping` fields instead of the scenarios' (ds_max = 0.05, dt_max = 1).
    """
    R = radius or scenario.radius
    params = model_of(scenario, R, membrane_law, thickness_mode)
    time_stepping = TimeStepping(t_final=t_final, **{"ds_max": 0.05, "dt_max": 1.0, **(stepping or {})})
    t0 = time.perf_counter()
    mesh = sphere(radius=R, n_vertices=n_vertices)
    meta = {"scenario": scenario.name, "radius": R, "n_vertices": mesh.n_vertices, "t_final": t_final,
            "membrane_law": params.membrane_law, "thickness_mode": params.thickness_mode}
    if seed is not None:
        meta["seed"] = [seed.amplitude, seed.width]
    if stepping:
        meta["stepping"] = dict(stepping)
    if checkpoint is not None and (checkpoint.exists() or checkpoint.with_name(checkpoint.name + ".prev").exists()):
        state, saved = load_checkpoint(checkpoint)
        same = [k for k in meta if k != "t_final"]   # a run may be continued to a later end time
        # checkpoints from before the law and the thickness mode were recorded
        saved = {"membrane_law": "svk", "thickness_mode": model_of(scenario, R).thickness_mode, **saved}
        if {k: saved.get(k) for k in same} != {k: meta[k] for k in same}:
            raise ValueError(f"{checkpoint} belongs to another run ({saved}); remove it to start afresh")
        loop = CoupledLoop.from_state_dict(mesh, params, state, time_stepping, log=log,
                                           observers=loop_observers(log))
        history = dict(saved.get("history", {}))
    else:
        loop = CoupledLoop(mesh, params, time_stepping, c0=seed or InitialSpot(), log=log,
                           observers=loop_observers(log))
        history = {}
    setup = time.perf_counter() - t0
    wall_before = float(history.get("wall_s", 0.0))     # the earlier calls of a resumed run
    counters = {"negative_c": max(0.0, -float(loop.c.min())), "non_finite": 0, "saddles": 0, "steps": 0, "snaps": 0,
                **history.get("counters", {})}

    def watch(rec, lp):
        counters["negative_c"] = max(counters["negative_c"], -float(lp.c.min()))
        counters["non_finite"] += int(not np.all(np.isfinite(lp.c))) + int(not np.all(np.isfinite(lp.u)))
        counters["saddles"] += int(rec.stable is False)
        counters["steps"] += 1
        counters["snaps"] += int(rec.snapped)

    def save(state, rec):
        save_checkpoint(checkpoint, state, {**meta, "history": {"counters": counters,
                                                                 "wall_s": wall_before + time.perf_counter() - t0}})

    result = loop.run(watch, checkpoint=save if checkpoint is not None else None, wall_time=wall_time,
                      max_steps=max_steps)
    pts = loop.points
    tri = mesh.triangles
    measures = find_spots(pts, tri, loop.c, params.c_star)
    fixed_point = None
    if result.status == "stationary" and params.D == 0 and math.isfinite(params.c_max):
        fixed_point = float(np.max(np.abs(loop.source - params.beta * loop.c))) / params.c_max
    out = {"scenario": scenario.name, "n_vertices": mesh.n_vertices, "status": result.status,
           "message": result.message, "t": float(loop.t), "wall_s": time.perf_counter() - t0, "setup_s": setup,
           "wall_s_total": wall_before + time.perf_counter() - t0,
           "measures": measures, "max_c": float(loop.c.max()), "c_star": params.c_star, "c_max": params.c_max,
           "max_H": float(loop.H_vertex.max()), "fixed_point": fixed_point, **counters,
           "non_elliptic": int(loop.non_elliptic),
           "max_fold_deg": float(fold_angles(pts, tri, mesh.topology.edge_faces).max()),
           "points": pts, "triangles": tri, "c": loop.c.copy(), "H": loop.H_vertex.copy(), "rest_radius": R,
           "profile_c": polar_profile(pts, loop.c, triangles=tri),
           "profile_H": polar_profile(pts, loop.H_vertex, triangles=tri)}
    return out


def run(level: str = "quick", out_dir=None, log=None) -> list:
    cfg = LEVELS[level]
    rows = []
    _LAST.clear()
    ck_dir = None
    if level == "full":
        ck_dir = Path(out_dir or "validation-out") / "sphere-patterns-checkpoints"
        ck_dir.mkdir(parents=True, exist_ok=True)
    for name, (t_final, nv) in cfg["runs"].items():
        sc = SCENARIOS[name]
        R = cfg["radius"] or sc.radius
        nv = nv or paper_vertices(R)
        ck = None if ck_dir is None else ck_dir / f"{name}.npz"
        if log:
            log(f"  {name}: R = {R:g}, ~{nv} vertices, to t = {t_final:g} or stationary"
                + (f", checkpoint {ck}" if ck else ""))
        try:
            r = run_scenario(sc, t_final=t_final, n_vertices=nv, radius=R, checkpoint=ck, log=log)
        except CoupledError as exc:        # the initial equilibrium failed: the other scenarios still run
            rows.append(Row(f"{name}: run failed ({short_reason(exc)})", 1.0, 0.0, 0.0, nv, 0.0))
            continue
        if r["status"] == "interrupted":   # Ctrl-C: the run is checkpointed; stop the case, not one scenario
            raise KeyboardInterrupt
        _LAST[name] = r
        rows.extend(scenario_rows(sc, r))
    return rows


def scenario_rows(sc: Scenario, r: dict) -> list:
    """Reported and toleranced rows of one finished scenario (see the module docstring)."""
    nv, wall, m = r["n_vertices"], r.get("wall_s_total", r["wall_s"]), r["measures"]   # all calls of a resumed run
    p = f"{sc.name}: "
    rows = [
        Row(p + f"spots N_sp at t={r['t']:.4g} ({r['status']}; paper: {sc.paper})", m.n_spots, n_vertices=nv,
            wall_s=wall),
        Row(p + f"of which ridges (pattern kind: {m.kind})", m.n_ridges, n_vertices=nv, wall_s=wall),
        Row(p + "fraction of the area patterned (c > c*)", m.fraction_patterned, n_vertices=nv, wall_s=wall),
        Row(p + f"max c / c* (c* = {r['c_star']:g})", r["max_c"] / r["c_star"], n_vertices=nv, wall_s=wall),
        Row(p + "max H (relative to 1/R)", r["max_H"], n_vertices=nv, wall_s=wall),
        Row(p + "accepted steps", r["steps"], n_vertices=nv, wall_s=wall),
    ] + invariant_rows(r, lambda q: p + q)
    if m.n_spots:        # undefined without spots
        rows[3:3] = [Row(p + "spot radius sqrt(A_l/(pi N_sp))", m.spot_radius, n_vertices=nv, wall_s=wall),
                     Row(p + "spot spacing 2(sqrt(A/(pi N))-sqrt(A_l/(pi N)))", m.spacing, n_vertices=nv,
                         wall_s=wall)]
    if r["fixed_point"] is not None:
        rows.append(Row(p + "stationary end: max |P(H) - beta c| / c_max", r["fixed_point"], 0.0, FIXED_POINT_TOL,
                        nv, wall))
    return rows


def invariant_rows(r: dict, label) -> list:
    """The toleranced invariants of one run (c ≥ 0 and finite, no saddle accepted, not failed), and
    three reported figures of the end state's trustworthiness: steps that snapped past a fold,
    elements where the membrane law is not elliptic (St Venant–Kirchhoff compressed past its limit),
    and the largest angle between neighbouring faces (near 90° or more: a fold finer than the mesh).
    In the last two cases that part of the shape is set by the mesh. ``label(quantity)`` gives each
    row its name."""
    nv, wall = r["n_vertices"], r["wall_s"]
    failed = r["status"] == "failed"
    return [Row(label("largest negative part of c (must be 0)"), r["negative_c"], 0.0, 0.0, nv, wall),
            Row(label("steps with non-finite c or shape"), r["non_finite"], 0.0, 0.0, nv, wall),
            Row(label("accepted steps whose equilibrium was a saddle"), r["saddles"], 0.0, 0.0, nv, wall),
            Row(label(f"run failed ({r['message'][:60]})" if failed else "run failed"), float(failed), 0.0, 0.0,
                nv, wall),
            Row(label("steps that snapped past a fold"), r["snaps"], None, None, nv, wall),
            Row(label("elements where the membrane law is not elliptic at the end"), r["non_elliptic"], None, None,
                nv, wall),
            Row(label("largest angle between neighbouring faces at the end (deg)"), r["max_fold_deg"], None, None,
                nv, wall)]


def draw_top_view(ax, r: dict, title: str):
    """c on the upper hemisphere seen from the seeded pole (like the paper's figures), colours 0 … c_max."""
    pts, tri = r["points"], r["triangles"]
    x, y, z = (pts - pts.mean(axis=0)).T
    top = tri[np.all(z[tri] > 0, axis=1)]
    ax.tripcolor(x, y, top, r["c"], shading="gouraud", cmap="viridis", vmin=0, vmax=max(r["c_max"], 1e-12))
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title(title, fontsize=7)


def plot(rows, fig):
    """Top view of c (upper hemisphere, like the paper's figures) and side view per scenario."""
    runs = list(_LAST.values())
    if not runs:
        fig.text(0.5, 0.5, "no runs", ha="center")
        return
    n = len(runs)
    for k, r in enumerate(runs):
        pts, tri = r["points"], r["triangles"]
        ctr = pts.mean(axis=0)
        x, y, z = (pts - ctr).T
        draw_top_view(fig.add_subplot(3, n, k + 1), r, f"{r['scenario']}\nt={r['t']:.3g}, N_sp={r['measures'].n_spots}")
        front = tri[np.all(y[tri] < 0, axis=1)]
        ax = fig.add_subplot(3, n, n + k + 1)
        ax.tripcolor(x, z, front, np.linalg.norm(pts - ctr, axis=1) / r["rest_radius"], shading="gouraud",
                     cmap="coolwarm")
        ax.set_aspect("equal")
        ax.set_axis_off()
        ax = fig.add_subplot(3, n, 2 * n + k + 1)
        pc, ph = r["profile_c"], r["profile_H"]
        ax.plot(np.degrees(pc.theta), pc.mean, "b-", label="c")
        ax.set_xlabel("polar angle [deg]", fontsize=7)
        ax2 = ax.twinx()
        ax2.plot(np.degrees(ph.theta), ph.mean, "r--", label="H")
        ax.tick_params(labelsize=6)
        ax2.tick_params(labelsize=6)
        if k == 0:
            ax.set_ylabel("c (blue), H (red)", fontsize=7)
