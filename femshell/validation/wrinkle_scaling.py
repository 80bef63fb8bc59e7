r"""Wrinkle wavelength of the seed paper's disk against thickness h and growth strain ε.

Reference: the Cerda-Mahadevan scaling λ ∝ h^{1/2} ε^{-1/4} (Cerda & Mahadevan, PRL 90, 074302, 2003; theory §1.5),
asked of the disk test of theory §1.6 by issue 4: the free disk of :mod:`femshell.validation.disk` (R1 = max(20, 5
R2), ν = 0.5) whose inner circle r < R2 grows by the stretch 1 + ε with thickness h/(1 + ε)². The exponents are
reported against 1/2 and −1/4 without a tolerance (the paper's are for far-from-threshold wrinkles of a spring
network); the pass criterion is that every measured state is a resolved stable equilibrium.

State (h, ε): the one the disk reaches when grown slowly from flat
(:func:`~femshell.validation.disk.branches.follow`: continuation, branch switching, relaxation where the shell
snaps); each h is grown once, to its largest ε (:func:`history_plan`), and the smaller ε of the ε sweep are
snapshots of that history. A state counts when it is an equilibrium (|∇Π| ≤ ``EQUILIBRIUM_RTOL`` of the flat
disk's), stable (no negative eigenvalue) and resolved (no mid-edge normal turned by 80° or more). Each finished
history is checkpointed (:func:`growth_history`). Mesh: the grown region refined throughout (edge
R2/``resolution``); law: neo-Hookean on the full level, St Venant-Kirchhoff on the quick one.

Measure: the deflection w (best-fit plane removed) on the circles r = ``RIM_RADII`` · R2 around the rim; the
state is wrinkled when its largest azimuthal amplitude with k ≥ 2 is at least ``REL_TOL`` of the axisymmetric
one; n is that k and λ = 2π R2 / n. The far field, where the free sheet bends as a whole, is left out.

Fit: log λ = a + p log h (and against log ε) over the wrinkled states, weighted least squares with the rounding
of n as each point's error, σ(log λ) = 1/(n √12); σ_p scaled by √(χ²/dof) when that exceeds 1.

:func:`seeded_state` (ramps from a seeded dome with azimuthal waves) serves the seed studies
(validation/wrinkle_seeds_study.py, validation/wrinkle_modes_study.py).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from ..io import save_checkpoint
from ..shell.element import EDGE_UNKNOWN
from ..shell.model import FOLD_LIMIT_DEG
from ..solvers.linear import LinearSolverError
from .common import saved_state
from .disk import EQUILIBRIUM_RTOL, Disk, follow, stable_state, warm_up
from .framework import Row, timed

NAME = "wrinkle-scaling"
DESCRIPTION = ("the paper's disk (inner circle r < R2 grown by eps, volume-conserving thickness): wrinkle "
               "wavelength 2 pi R2/n of the stable states reached by growing from flat (continuation, branch "
               "switching) against h and eps, fitted exponents vs 1/2 and -1/4")
SOURCE = ("Cerda & Mahadevan, Geometry and physics of wrinkling, PRL 90, 074302 (2003): lambda ~ h^(1/2) "
          "eps^(-1/4); Zakharov & Dasbiswas section 4 (theory §1.5, §1.6). Exponents reported, no tolerance; "
          "pass criterion: every measured state is a stable equilibrium")

R2 = 3.0
#: pseudo-random phases of the seed's azimuthal waves
SEED = 1
SEED_MODES = np.arange(2, 17)
#: seed amplitudes in units of h: dome at the centre, azimuthal waves on the rim band
SEED_DOME, SEED_WAVES = 0.6, 0.3
#: ε is raised to its value in steps of at most this
EPS_STEP = 0.05
#: circles (radius / R2) where the wavenumber is measured, and the wrinkled threshold
RIM_RADII = (0.7, 0.85, 1.0, 1.15, 1.3)
REL_TOL = 0.05
#: h sweep at ε = EPS_FIXED, ε sweep at h = h_fixed; mesh resolution (edges per R2, over the whole grown region),
#: membrane law; mesh_check: states (h, ε, resolution) measured again on another mesh to see whether n depends on it
EPS_FIXED = 0.5
LEVELS = {
    "quick": {"h": (1.0,), "eps": (0.3, 0.5), "h_fixed": 1.0, "resolution": 4, "law": "svk", "mesh_check": ()},
    "full": {"h": (0.25, 0.35, 0.5, 0.7, 1.0), "eps": (0.3, 0.4, 0.5), "h_fixed": 0.25, "resolution": 24,
             "law": "neo-hookean", "mesh_check": ((0.25, 0.5, 28), (0.5, 0.5, 28))},
}
REFERENCE = {"h": 0.5, "eps": -0.25}

_LAST = {}


def seed_shape(disk, seed=SEED, waves=SEED_WAVES, modes=SEED_MODES):
    """Out-of-plane displacement z of a seeded start: the dome SEED_DOME · h exp(−r²/R2²) plus azimuthal
    waves on a band around r = R2,

        z_waves = waves · h · exp(−(r − R2)²/(R2/2)²) · Σ_k cos(kφ + φ_k) / √len(modes),   k in ``modes``,

    with phases φ_k drawn from ``seed`` (module docstring). ``modes=(8,)`` seeds one wave of amplitude
    ``waves`` · h; ``waves=0`` the dome alone."""
    P = disk.points
    r, phi = np.hypot(P[:, 0], P[:, 1]), np.arctan2(P[:, 1], P[:, 0])
    phases = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, len(modes))
    azimuthal = sum(np.cos(k * phi + p) for k, p in zip(modes, phases)) / math.sqrt(len(modes))
    h, R = disk.h, disk.R2
    return waves * h * azimuthal * np.exp(-(((r - R) / (0.5 * R)) ** 2)) + SEED_DOME * h * np.exp(-((r / R) ** 2))


def seeded_state(disk, eps, eps_step=EPS_STEP, seed=SEED, waves=SEED_WAVES, checkpoint=None, modes=SEED_MODES):
    """A stable equilibrium of ``disk`` at growth ``eps`` reached from the start :func:`seed_shape` (by
    default broadband; ``waves=0``: the small dome alone, an axisymmetric start).
    Returns (u, n_newton_failures).

    With ``checkpoint`` (an .npz path) the state is saved after every ε step and a run resumes from
    the last saved step (a finished state is read back, not recomputed); a checkpoint of another
    disk, seed, seed modes or ε path, or one written with edge angles, is refused
    (ValueError naming the difference).
    """
    modes = [int(k) for k in modes]
    z = seed_shape(disk, seed, waves, modes)
    h, R = disk.h, disk.R2
    model = disk.model
    q = model.full(model.initial_unknowns())
    q[2: 3 * disk.n_vertices: 3] += z
    u = q[model.free]
    failures = 0
    n_steps = max(1, int(math.ceil(eps / eps_step - 1e-9)))
    meta = {"h": h, "R2": R, "R1": disk.R1, "n_vertices": disk.n_vertices, "n_unknowns": int(len(u)),
            "eps": float(eps), "n_steps": n_steps, "seed": seed, "waves": waves, "dome": SEED_DOME, "modes": modes,
            "edge_unknown": EDGE_UNKNOWN}
    done = 0
    state = saved_state(checkpoint, meta)
    if state is not None:
        u, failures, done = state["u"], state["failures"], state["step"]
    for step, e in enumerate(np.linspace(0.0, eps, n_steps + 1)[1:], start=1):
        if step <= done:
            continue
        u, iterations = stable_state(disk.problem, u, float(e), 300)
        failures += iterations is None      # the last iterate is kept; the stability row judges the end state
        if checkpoint is not None:
            save_checkpoint(checkpoint, {"u": u, "failures": failures, "step": step}, meta)
    disk.problem.set_parameter(float(eps))
    return u, failures


def seeded_sample(h, eps, resolution, seed=SEED, waves=SEED_WAVES, modes=SEED_MODES, checkpoint=None):
    """One seeded stable state of Disk(h, R2, resolution) at ``eps`` (:func:`seeded_state`) as a record:
    its rim wavenumber n and amplitude ``rel`` (:func:`rim_wavenumber`), energy, negative eigenvalues
    (``None`` with ``error`` saying why when the factorisation fails), Newton failures and wall time (of
    this call: a sample resumed from ``checkpoint`` counts only the rest)."""
    d = Disk(h, R2, resolution)
    t0 = time.perf_counter()
    u, failures = seeded_state(d, eps, EPS_STEP, seed=seed, waves=waves, checkpoint=checkpoint, modes=modes)
    n, rel = rim_wavenumber(d, d.deflection(u))
    try:
        n_negative, why = int(d.n_negative(u, eps)), None
    except LinearSolverError as exc:    # seen at h = 2 before the element Hessians were symmetrised
        n_negative, why = None, f"stability not decided: {exc}"
    return {"h": h, "eps": eps, "resolution": resolution, "seed": seed, "n_vertices": d.n_vertices, "n": n,
            "rel": rel, "energy": float(d.model.energy(u)), "n_negative": n_negative, "error": why,
            "newton_failures": failures, "wall_s": time.perf_counter() - t0}


def rim_wavenumber(disk, w, radii=RIM_RADII, k_max=24):
    """Dominant azimuthal wavenumber k ≥ 2 of w on circles r = radii · R2 and its amplitude relative to
    the axisymmetric part (root of the summed powers). Returns (n, relative amplitude)."""
    return disk.rim_mode(w, radii, k_max)


def fit_exponent(x, n):
    """p ± σ_p of λ = 2π R2/n ∝ x^p by weighted least squares in logs, σ(log λ) = 1/(n √12) (rounding of
    n), σ_p scaled by √(χ²/dof) when above 1. (nan, nan) with fewer than two distinct x."""
    x, n = np.asarray(x, float), np.asarray(n, float)
    if len(np.unique(x)) < 2:
        return math.nan, math.nan
    X = np.column_stack([np.ones_like(x), np.log(x)])
    y = np.log(2.0 * math.pi * R2 / n)
    wts = (n * math.sqrt(12.0)) ** 2
    A = X.T @ (wts[:, None] * X)
    coef = np.linalg.solve(A, X.T @ (wts * y))
    cov = np.linalg.inv(A)
    dof = len(x) - 2
    if dof > 0:
        chi2 = float(np.sum(wts * (y - X @ coef) ** 2))
        cov = cov * max(1.0, chi2 / dof)
    return float(coef[1]), float(math.sqrt(cov[1, 1]))


def growth_history(h, eps_end, resolution, law, snapshots=(), checkpoint=None, log=None):
    """The stable states of Disk(h, R2, resolution, law, refine_inside=True) grown slowly from flat to ``eps_end``:
    :func:`~femshell.validation.disk_wrinkles.follow` (continuation, branch switching, relaxation where no branch
    goes on), with the states at the ``snapshots`` the relaxation passes on the way.

    Returns (disk, states, summary): states {ε: u} holds ``eps_end`` and every snapshot that was taken (one on a
    followed branch is not: follow to it instead); summary: eps_first (the flat disk's loss of stability, or
    None), n_first, switches (tried), folds, relaxed (the end state), wall_s (of the solve, also when read back).

    With ``checkpoint`` (an .npz path) the finished history is saved there and a later call reads it back instead
    of solving again; a checkpoint of another disk, ε, snapshots, law or unknown layout is refused (ValueError
    naming the difference)."""
    snapshots = sorted({float(e) for e in snapshots})
    meta = {"h": float(h), "R2": R2, "eps": float(eps_end), "resolution": int(resolution), "law": law,
            "refine_inside": True, "edge_unknown": EDGE_UNKNOWN}
    if snapshots:
        meta["snapshots"] = snapshots
    state = saved_state(checkpoint, meta, keys=("snapshots",))
    if state is not None:
        d = Disk(h, R2, resolution, law=law, refine_inside=True)
        n_unknowns = len(d.model.initial_unknowns())
        if len(state["u"]) != n_unknowns:
            raise ValueError(f"{checkpoint} has {len(state['u'])} unknowns, this mesh {n_unknowns}: another "
                             "mesh generator made it; remove it to start afresh")
        states = {float(eps_end): state["u"]}
        if "snap_eps" in state:       # a history without snapshots may have been saved without these
            states.update(zip(state["snap_eps"].tolist(), state["snap_u"]))
        summary = {k: np.asarray(state[k]).item()
                   for k in ("eps_first", "n_first", "switches", "folds", "relaxed", "wall_s")}
        summary["eps_first"] = None if summary["eps_first"] < 0 else summary["eps_first"]
        summary["n_first"] = None if summary["n_first"] < 0 else summary["n_first"]
        return d, states, summary
    out = follow(h, R2, resolution, log=log, law=law, refine_inside=True, eps_end=float(eps_end), snapshots=snapshots)
    first = out["first"]
    summary = {"eps_first": None if first is None else float(first.parameter), "n_first": out["n_first"],
               "switches": len(out["switch_points"]), "folds": len(out["folds"]), "relaxed": bool(out["relaxed"]),
               "wall_s": float(out["wall_s"])}
    taken = sorted(out["snapshots"])
    if checkpoint is not None:
        u = out["u"]
        stored = dict(summary, eps_first=-1.0 if first is None else summary["eps_first"],
                      n_first=-1 if out["n_first"] is None else int(out["n_first"]), u=u,
                      snap_eps=np.array(taken, float),
                      snap_u=np.array([out["snapshots"][e] for e in taken]).reshape(len(taken), len(u)))
        save_checkpoint(checkpoint, stored, meta)
    return out["disk"], {float(eps_end): out["u"], **out["snapshots"]}, summary


def evaluate(disk, u, eps, summary, log=None):
    """One state u of ``disk`` at ε as a record: its rim wavenumber and amplitude (:func:`rim_wavenumber`), energy,
    whether it counts (a resolved stable equilibrium, :meth:`~femshell.validation.disk_wrinkles.Disk.final_check`)
    and the history's ``summary`` (:func:`growth_history`)."""
    w = disk.deflection(u)
    n, rel = rim_wavenumber(disk, w)
    s = dict(summary, disk=disk, u=u, w=w, n=n, rel=rel, wrinkled=rel >= REL_TOL)
    s.update(disk.final_check(u, eps, log=log))
    disk.problem.set_parameter(float(eps))
    s["energy"] = float(disk.model.energy(u))
    return s


def sweeps_of(cfg):
    """The states (h, ε, resolution) of a level's two sweeps: {"h": at ε = EPS_FIXED, "eps": at h = h_fixed}."""
    res = cfg["resolution"]
    return {"h": [(h, EPS_FIXED, res) for h in cfg["h"]], "eps": [(cfg["h_fixed"], e, res) for e in cfg["eps"]]}


def history_plan(cfg):
    """Which growth histories a level needs: {(h, resolution): (eps_end, snapshots)}, each h grown to the largest ε
    wanted of it, the smaller ones its snapshots (the h sweep at EPS_FIXED, the ε sweep at h_fixed, the mesh
    checks)."""
    wanted = {}
    sweeps = sweeps_of(cfg)
    for h, e, r in sweeps["h"] + sweeps["eps"] + list(cfg["mesh_check"]):
        wanted.setdefault((h, r), set()).add(e)
    return {k: (max(v), sorted(v - {max(v)})) for k, v in wanted.items()}


def measure_all(cfg, checkpoints=None, log=None):
    """Every state of a level (:func:`history_plan`): {(h, ε, resolution): record (:func:`evaluate`)}. A snapshot
    that fell on a followed branch is grown to on its own (:func:`growth_history` with ``eps_end`` = ε)."""
    log = log or (lambda *a, **k: None)

    def grow(h, e, r, snaps):
        tail = "-snap" + ",".join(f"{x:g}" for x in snaps) if snaps else ""
        ck = None if checkpoints is None else checkpoints / f"path-h{h:g}-eps{e:g}-res{r}-{cfg['law']}{tail}.npz"
        with timed() as t:
            d, got, summary = growth_history(h, e, r, cfg["law"], snaps, ck, log)
        summary["wall_s"] = max(summary["wall_s"], t())     # read back from a checkpoint: the solve's own time
        return d, got, summary

    states = {}
    for (h, r), (eps_end, snaps) in history_plan(cfg).items():
        d, got, summary = grow(h, eps_end, r, snaps)
        for e in [eps_end] + snaps:
            if e in got:
                dd, u, ss = d, got[e], dict(summary, relaxed=summary["relaxed"] or e != eps_end)
            else:
                log(f"  h={h:g} eps={e:g}: on a followed branch of the history to {eps_end:g}: grown to on its own")
                dd, one, ss = grow(h, e, r, [])
                u = one[e]
            states[(h, e, r)] = evaluate(dd, u, e, ss, log=lambda m: log(f"  h={h:g}:{m}"))
    return states


def run(level, out_dir=None, log=None):
    log = log or (lambda *a, **k: None)
    warm_up()
    cfg = LEVELS[level]
    checkpoints = None
    if level == "full":       # an hour: every finished growth history is checkpointed, a second call resumes
        checkpoints = Path(out_dir or "validation-out") / "wrinkle-scaling-checkpoints"
        checkpoints.mkdir(parents=True, exist_ok=True)
        log(f"  checkpoints in {checkpoints}")
    h_fixed = cfg["h_fixed"]
    sweeps = sweeps_of(cfg)
    states = measure_all(cfg, checkpoints, log)
    for key, s in states.items():
        log(f"  h={key[0]:g} eps={key[1]:g} resolution {key[2]}: {s['disk'].n_vertices} vertices; flat disk unstable "
            + ("nowhere" if s["eps_first"] is None else f"from eps = {s['eps_first']:.4g} (n = {s['n_first']})")
            + f"; {s['switches']} branch switch(es) tried, {s['folds']} fold(s), " + ("relaxed" if s["relaxed"] else
                                                                                 "on a followed branch")
            + f"; n = {s['n']}, rim amplitude {s['rel']:.3g}, energy {s['energy']:.8g}, {s['n_negative']} negative "
            f"eigenvalues, {s['over_folded']} over-folded edges (history {s['wall_s']:.0f} s)")
    rows = []
    for (h, eps, r), s in states.items():
        at = f" @ h={h:g} eps={eps:g} resolution {r}"
        nv, wall = s["disk"].n_vertices, s["wall_s"]
        rows.append(Row("non-axisymmetric rim amplitude / axisymmetric (wrinkled when >= "
                        f"{REL_TOL:g})" + at, s["rel"], None, None, nv, wall))
        rows.append(Row("dominant rim wavenumber n (k >= 2)" + at, s["n"], None, None, nv, wall))
        rows.append(Row("eps where the flat disk loses stability (on the path; nan: nowhere below eps)" + at,
                        math.nan if s["eps_first"] is None else s["eps_first"], None, None, nv, wall))
        rows.append(Row("end state reached on a followed branch (0) or by stable Newton past a fold or failed switch "
                        "(1)" + at, float(s["relaxed"]), None, None, nv, wall))
        rows.append(Row("negative eigenvalues of the constrained Hessian (0: stable)" + at
                        + ("" if s["n_negative"] is not None else ": not decided, the Hessian is not finite"),
                        math.nan if s["n_negative"] is None else s["n_negative"], 0.0, 0.0, nv, wall))
        rows.append(Row(f"|grad| / |grad| of the flat disk at the same eps (an equilibrium: <= {EQUILIBRIUM_RTOL:g})"
                        + at, s["residual"], 0.0, EQUILIBRIUM_RTOL, nv, wall))
        rows.append(Row(f"mid-edge normals turned by {FOLD_LIMIT_DEG:g} degrees or more (0: the mesh carries the "
                        "state's folds)" + at, s["over_folded"], 0.0, 0.0, nv, wall))
        rows.append(Row("largest turn of a mid-edge normal from its faces (degrees, < 90)" + at,
                        s["largest_turn"], None, None, nv, wall))
    # the mesh-check states that belong to each sweep; those of the h sweep are fitted again on their own
    checks = {"h": [k for k in cfg["mesh_check"] if k[1] == EPS_FIXED],
              "eps": [k for k in cfg["mesh_check"] if k[0] == h_fixed]}
    series = [("h", sweeps["h"], f"eps={EPS_FIXED:g}"), ("eps", sweeps["eps"], f"h={h_fixed:g}")]
    if len({k[2] for k in checks["h"]}) == 1:
        series.append(("h", checks["h"], f"eps={EPS_FIXED:g}, resolution {checks['h'][0][2]}"))
    for var, keys, fixed in series:
        ok = [k for k in keys if states[k]["wrinkled"] and states[k]["result"]]
        x = [k[0] if var == "h" else k[1] for k in ok]
        p, sp = fit_exponent(x, [states[k]["n"] for k in ok])
        measurable = not math.isnan(p)
        rows.append(Row(f"wrinkled states that count (resolved stable equilibria, rim amplitude >= {REL_TOL:g}) in the "
                        f"{var} sweep at {fixed}"
                        + ("" if measurable else " (fewer than 2 distinct values: exponent not measurable)"),
                        len(ok), None, None))
        if measurable:      # no NaN in a result file: the row above says why there is no exponent
            rows.append(Row(f"fitted exponent of lambda vs {var} at {fixed} (+- {sp:.2g}; Cerda-Mahadevan "
                            f"{REFERENCE[var]:g})", p, REFERENCE[var], None))
    _LAST.update(states=states, sweeps=sweeps, checks=checks)
    return rows


def plot(rows, fig):
    """λ against h and ε (wrinkled states filled, the others hollow at their dominant n; grey: not a result, as
    unstable, unconverged or over-folded), and a top view of the non-axisymmetric part of w of the thinnest
    state that is a result."""
    states = _LAST.get("states", {})
    if not states:
        return
    ax1, ax2, ax3 = fig.subplots(1, 3)
    for ax, var in ((ax1, "h"), (ax2, "eps")):
        sel = [(k, states[k]) for k in _LAST["sweeps"][var]]
        for k, s in sel:
            x = k[0] if var == "h" else k[1]
            col = "tab:blue" if s["result"] else "tab:gray"
            ax.loglog([x], [2 * math.pi * R2 / s["n"]], "o", color=col, mfc=col if s["wrinkled"] else "none")
        for i, k in enumerate(_LAST["checks"][var]):       # the same state on the other mesh
            ax.loglog([k[0] if var == "h" else k[1]], [2 * math.pi * R2 / states[k]["n"]], "x",
                      color="tab:red" if states[k]["result"] else "tab:gray", label=None if i else f"resolution {k[2]}")
        xs = np.array(sorted({k[0] if var == "h" else k[1] for k, _ in sel}))
        if len(xs):
            ref = 2 * math.pi * R2 / max(s["n"] for _, s in sel)
            ax.loglog(xs, ref * (xs / xs[0]) ** REFERENCE[var], "k--", lw=0.8, label=f"slope {REFERENCE[var]:g}")
        ax.set_xticks(xs, [f"{x:g}" for x in xs], minor=False)    # the sweep's values, not crowded decades
        ax.set_xticks([], minor=True)
        ax.set_xlabel(var)
        ax.set_ylabel("lambda = 2 pi R2 / n")
        ax.legend(fontsize=6)
        ax.grid(True, which="both", alpha=0.3)
    swept = {k: states[k] for var in ("h", "eps") for k in _LAST["sweeps"][var]}
    # the thinnest, most grown state that is a result (else the thinnest of all, so marked)
    (h, eps, res), s = min(swept.items(), key=lambda kv: (not kv[1]["result"], kv[0][0], -kv[0][1]))
    d = s["disk"]
    P = d.points
    r = np.hypot(P[:, 0], P[:, 1])
    # the non-axisymmetric part: w minus its ring average
    bins = np.digitize(r, np.linspace(0.0, r.max(), 200))
    mean = np.bincount(bins, weights=s["w"]) / np.maximum(np.bincount(bins), 1)
    wa = s["w"] - mean[bins]
    lim = 2.0 * R2
    v = float(np.abs(wa[r < lim]).max()) or 1.0
    tpc = ax3.tripcolor(P[:, 0], P[:, 1], d.triangles, wa, shading="gouraud", cmap="RdBu_r", vmin=-v, vmax=v)
    ax3.set_xlim(-lim, lim)
    ax3.set_ylim(-lim, lim)
    ax3.set_aspect("equal")
    ax3.set_title(f"h={h:g} eps={eps:g} resolution {res}: w minus ring mean"
                  + ("" if s["result"] else " (not a result)"), fontsize=7)
    fig.colorbar(tpc, ax=ax3, fraction=0.046, pad=0.02).ax.tick_params(labelsize=5)
