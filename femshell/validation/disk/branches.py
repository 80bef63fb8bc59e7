r"""The disk's equilibria followed in the growth strain ε and in the inner radius R2.

A case (h, R2) is followed from the flat disk at ε = 0 to ε = 0.5 (:func:`follow`):

1. the flat branch by pseudo-arclength continuation in ε with the inertia of the constrained Hessian at every
   accepted point, stopped at the first negative eigenvalue; the loss of stability is bisected on the inertia
   alone (:func:`loss_of_stability`: one LDLᵀ per trial ε, however many eigenvalues cross at once);
2. branch switching along the first critical mode, and again at each later loss of stability of the followed
   branch (at most ``MAX_SWITCHES`` times). A loss of stability where dλ/ds changes sign with the critical mode
   along the branch is a fold: nothing to switch to, the shell snaps;
3. where the last branch does not end stable at ε = 0.5, stable Newton with saddle escape relaxes it there; where
   the shell snaps it starts from the critical point pushed along its modes (:func:`pushed_starts`) and the
   lowest-energy result of those starts is the end state (:func:`~.measures.select_lowest`).

:func:`sweep_radius` follows a state in R2 at fixed ε by stable Newton on one mesh (the disk has no length of its
own, :meth:`~.model.Disk.radius_problem`), so a state keeps its n-branch while that is stable.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import scipy.sparse.linalg as spla

from ..._checks import finite
from ...io import save_checkpoint
from ...solvers.continuation import ContinuationError, SpecialPoint, continuation, switch_branch
from ...solvers.linear import factorize
from ...solvers.newton import NewtonError, minimize
from ..common import saved_state
from .measures import select_lowest
from .model import EPS_END, Disk, svk_ellipticity_stretch

#: branch switches after the first one (secondary bifurcations) at most
MAX_SWITCHES = 4
#: continuation settings: first step and largest step in the weighted arclength, steps per branch
DS, DS_MAX, MAX_STEPS = 0.4, 0.5, 80
#: distance of the first point of a switched branch from its branch point (weighted norm)
SWITCH_AMPLITUDE = 0.05


def _quiet(*a, **k):
    """A log that drops its lines."""
    return None


#: relative width (in ε) to which a loss of stability is bisected
LOCATE_RTOL = 1e-4
#: at most this many critical modes are computed at a loss of stability
MAX_MODES = 6
#: a loss of stability where dλ/ds changes sign is a fold when its critical mode is this parallel to the
#: branch (|cosine| in the arclength norm; near 1 at a fold)
FOLD_COSINE = 0.9


def _stop_on_loss(branch, row):
    """continuation callback: stop at the first point with a negative eigenvalue after a stable one."""
    rows = [r for r in branch.rows if not r["special"]]
    return row["n_negative"] > 0 and any(r["n_negative"] == 0 for r in rows[:-1])


def _follow_branch(d, start=None, log=None, eps_end=EPS_END, **opts):
    """Follow a branch to ε = ``eps_end`` with stability from the inertia of every accepted point; stop where it
    loses stability (the flat branch from ε = 0 when ``start`` is None, else the branch born at the
    SpecialPoint ``start``). No special-point location by the continuation itself (``detect=False``):
    see :func:`loss_of_stability`."""
    common = dict(lam_stop=eps_end, max_steps=MAX_STEPS, n_eigs=0, detect=False, record=d.record,
                  callback=_stop_on_loss, log=log)
    common.update(opts)
    if start is None:
        return continuation(d.problem, d.model.initial_unknowns(), 0.0, ds=DS, ds_max=DS_MAX, label="flat",
                            **common)
    return switch_branch(d.problem, start, amplitude=SWITCH_AMPLITUDE, ds=SWITCH_AMPLITUDE,
                         parameter_scale=EPS_END / 5.0, **common)


def loss_of_stability(d, branch):
    """Where a branch stopped by :func:`_stop_on_loss` loses stability, bisected on the inertia alone.

    Between the last stable and the first unstable accepted point, ε is bisected to ``LOCATE_RTOL``
    with Newton at fixed ε (from the stable side) and one LDLᵀ per trial point. This costs the same
    however many eigenvalues cross in one step, whereas locating each crossing eigenvalue needs all of
    them (a thick disk can lose stability in ~30 modes at once). The critical modes
    are the eigenvectors of the negative eigenvalues just past the crossing (at most ``MAX_MODES``);
    ``multiplicity`` is the number of negative eigenvalues there. Returns a SpecialPoint or None when
    the branch did not lose stability. Its kind is "fold" when dλ/ds changed sign over the same step
    and the critical mode is parallel to the branch there (|cosine| > ``FOLD_COSINE`` with the secant
    across the bracket, in ``info["mode_tangent_cosine"]``): the branch turned back where the
    eigenvalue crossed zero, a limit point. Else "branch" (usable by
    :func:`~femshell.solvers.continuation.switch_branch`).
    """
    prob = d.problem
    rows = [r for r in branch.rows if not r["special"]]
    if branch.status != "callback" or rows[-1]["n_negative"] == 0:
        return None
    (ua, ea), (ub, eb) = branch.states[-2], branch.states[-1]
    nb = rows[-1]["n_negative"]
    turned = rows[-2]["dlam_ds"] * rows[-1]["dlam_ds"] < 0

    def state(eps):
        prob.set_parameter(eps)
        for u0 in (ua, ub):
            try:
                u = minimize(prob, u0, stable=False, max_iter=40, log=None).u
                break
            except NewtonError:
                continue
        else:
            return None, None
        fac = factorize(d.model.hessian(u), kind="symmetric_indefinite")
        try:
            return u, int(fac.inertia[1])
        finally:
            fac.free()

    while abs(eb - ea) > LOCATE_RTOL * abs(eb):
        em = 0.5 * (ea + eb)
        um, nm = state(em)
        if um is None:
            break
        if nm == 0:
            ua, ea = um, em
        else:
            ub, eb, nb = um, em, nm
    prob.set_parameter(eb)
    K = d.model.hessian(ub)
    k = max(1, min(nb, MAX_MODES))
    vals, vecs = spla.eigsh(K, k=k, sigma=0.0, which="LM", v0=np.random.default_rng(0).standard_normal(K.shape[0]))
    order = np.argsort(vals)
    tu, tl = ub - ua, eb - ea
    w = prob.dof_weights()
    norm = math.sqrt(float(tu @ (w * tu)) / len(tu) + (tl / prob.parameter_scale) ** 2)
    # at a fold the critical mode is the branch's own direction: the secant across it is parallel to the mode
    phi = vecs[:, order[0]]
    along = float(tu @ (w * tu)) * float(phi @ (w * phi))
    cosine = abs(float(phi @ (w * tu))) / math.sqrt(along) if along > 0 else 0.0
    fold = turned and cosine > FOLD_COSINE
    return SpecialPoint(kind="fold" if fold else "branch", parameter=0.5 * (ea + eb), s=float("nan"), u=0.5 * (ua + ub),
                        tangent=(tu / norm, tl / norm), eigenvalues=vals[order], modes=vecs[:, order],
                        multiplicity=int(nb), n_negative_before=0, n_negative_after=int(nb), step=len(rows) - 1,
                        bracket=(ea, eb), weights=w, parameter_scale=prob.parameter_scale,
                        info={"mode_tangent_cosine": cosine})


def pushed_starts(d, sp, pushes):
    """Relaxation starts where the shell snaps at the special point ``sp``: [(push, u)] with u = sp.u ± a φ_j,
    in the order +φ₁, −φ₁, +φ₂, … (``pushes`` of them, at most two per critical mode computed), φ_j scaled to a
    largest position component of ``SWITCH_AMPLITUDE`` · h."""
    out = []
    for j in range(sp.modes.shape[1]):
        phi = sp.modes[:, j]
        step = SWITCH_AMPLITUDE * d.h * phi / np.abs(phi[: 3 * d.n_vertices]).max()
        out += [(f"+phi{j + 1}", sp.u + step), (f"-phi{j + 1}", sp.u - step)]
    return out[:pushes]


def stable_state(problem, u, parameter, max_iter, log=None, newton_log=None, at=None, max_step=None):
    """Stable Newton (:func:`~femshell.solvers.newton.minimize`, ``stable=True``, steps of at most ``max_step`` in
    the max-norm) from u at ``parameter`` of the parametrised ``problem``: (u, iterations). When Newton fails the
    last iterate is kept, with iterations None, and a line goes to ``log`` (``at`` names the point, default the
    parameter): the final check of the state then says whether it is a result. ``newton_log``: Newton's own
    lines (default none)."""
    problem.set_parameter(parameter)
    try:
        fit = minimize(problem, u, stable=True, max_iter=max_iter, log=newton_log, max_step=max_step)
        return fit.u, fit.iterations
    except NewtonError as exc:
        if log:
            log(f"    stable Newton failed at {at or f'parameter = {parameter:g}'}: {exc}")
        return (exc.result.u if exc.result is not None else u), None


def _relax(prob, u, eps, eps_end, snapshots, log):
    """Stable Newton from (u, ε) to ``eps_end`` in ε steps of at most 0.05 (and at the snapshots between):
    (u at ``eps_end``, {snapshot ε: u}). A step whose Newton fails keeps its last iterate (the final check
    reports it)."""
    steps = np.linspace(eps, eps_end, max(2, int(math.ceil(abs(eps_end - eps) / 0.05)) + 1))[1:]
    wanted = [e for e in snapshots if eps < e < eps_end]
    taken = {}
    for e in sorted(set(steps.tolist()) | set(wanted)):
        u, _ = stable_state(prob, u, float(e), 200, log, at=f"eps = {e:.4g}")
        if e in wanted:
            taken[e] = u.copy()
    return u, taken


def _check_follow_args(eps_end, snapshots, pushes):
    """The growth strains of ``snapshots``, sorted; a ValueError naming the argument and its range when one of
    :func:`follow`'s arguments is out of range."""
    if not (isinstance(pushes, int) and not isinstance(pushes, bool) and pushes >= 1):
        raise ValueError(f"pushes must be a whole number >= 1 (relaxation starts), got {pushes!r}")
    if not (isinstance(eps_end, (int, float)) and not isinstance(eps_end, bool) and 0.0 < eps_end <= 1.0):
        raise ValueError(f"eps_end must be a growth strain in (0, 1], got {eps_end!r}")
    snapshots = sorted({float(e) for e in snapshots})
    if any(not 0.0 < e < eps_end for e in snapshots):
        raise ValueError(f"snapshots must lie in (0, eps_end = {eps_end:g}), got {snapshots}")
    return snapshots


def _flat_branch(d, eps_end, log, clog, t0):
    """The flat branch from ε = 0 and its first loss of stability: (branch, first SpecialPoint or None, its
    azimuthal n, the smallest stretch current/target of the grown region there)."""
    branch = _follow_branch(d, None, log=clog, eps_end=eps_end)
    first = loss_of_stability(d, branch)
    n_first = d.mode_wavenumber(first.modes) if first is not None else None
    stretch_first = None
    if first is not None:
        d.problem.set_parameter(first.parameter)
        stretch_first = d.min_stretch(first.u)
    log(f"  h={d.h:g} R2={d.R2:g}: {d.n_vertices} vertices; flat branch: "
        + (f"first instability at eps = {first.parameter:.5g}, {first.multiplicity} negative eigenvalue(s) "
           f"past it, n = {n_first}, smallest stretch/target {stretch_first:.4f} (SVK limit "
           f"{svk_ellipticity_stretch():.4f})" if first else f"stable up to eps = {eps_end:g}")
        + f" ({time.perf_counter() - t0:.0f} s)")
    return branch, first, n_first, stretch_first


def _ends_stable(branch):
    """Whether ``branch`` reached its end parameter at a stable point."""
    return branch.status == "lam_stop" and [r for r in branch.rows if not r["special"]][-1]["n_negative"] == 0


def _switch_branches(d, branch, sp, eps_end, pushes, log, clog, t0):
    """Branch switching from the loss of stability ``sp`` of ``branch`` on, at most ``MAX_SWITCHES`` times after
    the first: a dict of branches (the ones switched onto), switch_points, folds, failed (why a switch failed, or
    None), starts ([(push, u)] of the relaxations: the last branch's end, or the pushed starts where the shell
    snaps), eps (their growth strain) and end_stable (the last branch ended stable at ``eps_end``)."""
    u, eps = branch.last
    out = dict(branches=[], switch_points=[], folds=[], failed=None, starts=[(None, u)], eps=eps,
               end_stable=_ends_stable(branch))
    switches = out["switch_points"]
    while sp is not None and len(switches) <= MAX_SWITCHES:
        if sp.kind == "fold":
            out["folds"].append(sp)
            log(f"    the branch turns back at a fold at eps = {sp.parameter:.5g} (dλ/ds changes sign where the "
                f"eigenvalue crosses zero, mode n = {d.mode_wavenumber(sp.modes)}): nothing to switch to, the shell "
                "snaps")
        else:
            switches.append(sp)
            try:
                branch = _follow_branch(d, sp, log=clog, eps_end=eps_end, label=f"switch {len(switches)}")
            except ContinuationError as exc:
                out["failed"] = f"branch switching at eps = {sp.parameter:.5g} failed ({exc})"
                log("    " + out["failed"])
        if sp.kind == "fold" or out["failed"]:
            # no branch to follow from here: relax from the critical point pushed along its modes
            out.update(starts=pushed_starts(d, sp, pushes), eps=sp.parameter, end_stable=False)
            break
        out["branches"].append(branch)
        rows = [r for r in branch.rows if not r["special"]]
        u, eps = branch.last
        out.update(starts=[(None, u)], eps=eps, end_stable=_ends_stable(branch))
        sp = loss_of_stability(d, branch)
        log(f"    {branch.label} at eps = {switches[-1].parameter:.5g}: {branch.status}, {len(rows)} points, "
            f"eps end {rows[-1]['parameter']:.4g}, negative eigenvalues {rows[-1]['n_negative']}, wrinkles "
            f"{rows[-1]['wrinkles']}" + (f"; loses stability at eps = {sp.parameter:.5g} ({sp.multiplicity} "
                                         f"mode(s), n = {d.mode_wavenumber(sp.modes)})" if sp else "")
            + f" ({time.perf_counter() - t0:.0f} s)")
    return out


def _relax_starts(d, starts, eps, eps_end, relaxed, snapshots, log, t0):
    """Each start relaxed from ε to ``eps_end`` (when ``relaxed``) and checked: (candidates, [(u, snapshots,
    final check)]) in the order of ``starts``."""
    candidates, ends = [], []
    for push, u0 in starts:
        u, taken = _relax(d.problem, u0, eps, eps_end, snapshots, log) if relaxed else (u0, {})
        check = d.final_check(u, eps_end, log=log)
        candidates.append(dict(push=push, count=d.count(d.deflection(u)), energy=float(d.model.energy(u)),
                               result=check["result"], n_negative=check["n_negative"], residual=check["residual"],
                               largest_turn=check["largest_turn"]))
        ends.append((u, taken, check))
        if push is not None:
            c = candidates[-1]
            log(f"    push {push}: {c['count']} wrinkles, energy {c['energy']:.8g}, "
                + ("a resolved stable equilibrium" if c["result"] else "not a result")
                + f" ({time.perf_counter() - t0:.0f} s)")
    if relaxed:
        log(f"    relaxed by stable Newton from eps = {eps:.4g} to {eps_end:g}"
            + (f" from {len(starts)} starts" if len(starts) > 1 else ""))
    return candidates, ends


def follow(h, R2, resolution, log=None, verbose=False, law="svk", refine_inside=False, eps_end=EPS_END,
           snapshots=(), R1=None, pushes=1):
    """Flat branch, branch switching, secondary switches, stable state at ε = ``eps_end`` (the module
    docstring's steps 1-3; the paper's 0.5 by default).

    ``verbose``: also pass ``log`` to the continuation (one line per step); ``law``: the membrane
    law (:class:`~femshell.shell.Material`); ``snapshots``: growth strains below ``eps_end`` at which the
    relaxation also stops and records its state (a snapshot that falls on a followed branch, before the
    relaxation starts, is not recorded: follow to that ε instead); ``R1``: the outer radius (default
    :func:`~.model.outer_radius`); ``pushes``: where the shell snaps, the number of relaxation starts
    (:func:`pushed_starts`); the end state is the lowest-energy one that is a result
    (:func:`~.measures.select_lowest`; the first start's when none is).
    Returns a dict: disk, branches (list of Branch), switch_points (SpecialPoint list), folds (the
    fold SpecialPoints where the shell snapped), failed (why a switch failed, or None), first (the
    first loss of stability of the flat state or None), n_first, stretch_first, u, w, count, spectrum, rim
    (:meth:`~.model.Disk.rim_mode`), relaxed, n_negative_final (None when the Hessian is not finite), residual,
    over_folded, largest_turn, result (:meth:`~.model.Disk.final_check` at ``eps_end``), energy, wall_s,
    snapshots ({ε: u} of the snapshots the relaxation passed), candidates (one dict per relaxation start: push,
    count, energy, result, n_negative, residual, largest_turn; one entry, push None, when no relaxation was needed)
    and chosen (the index of the end state among them).
    """
    snapshots = _check_follow_args(eps_end, snapshots, pushes)
    t0 = time.perf_counter()
    log = log or _quiet
    clog = log if verbose else None
    d = Disk(h, R2, resolution, R1=R1, law=law, refine_inside=refine_inside)
    branch, first, n_first, stretch_first = _flat_branch(d, eps_end, log, clog, t0)
    path = _switch_branches(d, branch, first, eps_end, pushes, log, clog, t0)
    eps = path["eps"]
    relaxed = not (abs(eps - eps_end) < 1e-12 and path["end_stable"])
    candidates, ends = _relax_starts(d, path["starts"], eps, eps_end, relaxed, snapshots, log, t0)
    chosen = select_lowest(candidates)
    u, taken, check = ends[chosen]
    check = dict(check)
    n_neg = check.pop("n_negative")
    w = d.deflection(u)
    out = dict(disk=d, branches=[branch] + path["branches"], switch_points=path["switch_points"],
               folds=path["folds"], first=first, n_first=n_first, u=u, failed=path["failed"],
               stretch_first=stretch_first,
               w=w, count=d.count(w), spectrum=d.spectrum(w), rim=d.rim_mode(w), relaxed=relaxed,
               n_negative_final=n_neg, **check,
               energy=float(d.model.energy(u)), wall_s=time.perf_counter() - t0, snapshots=taken,
               candidates=candidates, chosen=chosen)
    log(f"    eps = {eps_end:g}: {out['count']} wrinkles, {n_neg} negative eigenvalues, residual "
        f"{out['residual']:.2g} of the flat disk's, energy {out['energy']:.8g}, {out['wall_s']:.0f} s")
    return out


def sweep_radius(d, u, radii, eps=EPS_END, log=None, checkpoint=None, meta=None):
    r"""Quasi-static sweep of the inner radius at growth strain ``eps``: the state u of disk ``d`` (at d.R2)
    carried through ``radii`` (R2 values in order, R1/R2 fixed) by stable Newton steps on d's mesh
    (:meth:`Disk.radius_problem`).

    At each radius the last state is relaxed to a stable equilibrium (:func:`~femshell.solvers.newton.minimize`,
    ``stable=True``; past a fold of its branch it descends into the next stable state, as a slowly growing disk
    snaps) and checked as a case's final state is (:meth:`Disk.final_check` on the radius problem).
    So the sweep follows an n-branch while it is stable and shows where it gives way; where the count changes
    differs up and down (hysteresis), and two sweeps through the same radii compare the branches' energies.
    Pseudo-arclength continuation in R2 would stop at every fold: the wrinkled states' branches turn back every
    0.04-1 in R2/h (the pattern re-pins against the mesh, count unchanged).

    Returns (rows, states): per radius a dict R2, count, rim (:meth:`Disk.rim_mode`), energy
    (:meth:`Disk.radius_energy`; count, rim, energy and residual None for a state that is not finite), n_negative,
    residual, over_folded, largest_turn, result (a resolved stable equilibrium), iterations, wall_s; and the states
    (mesh units, a 2-D array). With ``checkpoint`` (an .npz path) every step is saved, and a later call with the same
    ``meta`` and ``eps`` whose ``radii`` begin with the saved ones resumes after the last (so a sweep can be
    extended); other radii are refused (ValueError).
    """
    log = log or _quiet
    radii = [finite("R2", r, 0.0, lo_open=True, text="(0, inf)") for r in radii]
    meta = dict(meta or {}, eps=float(eps))
    rows, states = [], []
    saved = saved_state(checkpoint, meta) if checkpoint is not None else None
    if saved is not None:
        rows, states = json.loads(str(saved["rows"])), list(saved["states"])
        done = [r["R2"] for r in rows]
        if radii[: len(done)] != done:
            raise ValueError(f"{checkpoint} swept the radii {done}, which these radii do not begin with; remove it "
                             "to start afresh")
        u = states[-1]
        log(f"    resumed after R2 = {rows[-1]['R2']:g} ({len(rows)} of {len(radii)} radii)")
    prob = d.radius_problem(eps)
    for radius in radii[len(rows):]:
        t0 = time.perf_counter()
        u, iterations = stable_state(prob, u, radius, 400, log, at=f"R2 = {radius:g}")
        check = d.final_check(u, radius, log=log, problem=prob)
        energy = d.radius_energy(prob, u)
        finite_state = math.isfinite(check["residual"]) and math.isfinite(energy)
        w = d.deflection(u)
        rows.append(dict(R2=radius, count=int(d.count(w)) if finite_state else None,
                         rim=int(d.rim_mode(w)[0]) if finite_state else None,
                         energy=energy if finite_state else None, n_negative=check["n_negative"],
                         residual=check["residual"] if finite_state else None, over_folded=check["over_folded"],
                         largest_turn=check["largest_turn"], result=finite_state and check["result"],
                         iterations=iterations, wall_s=time.perf_counter() - t0))
        states.append(np.array(u))
        r = rows[-1]
        log(f"    R2 = {radius:.5g}: {r['count']} wrinkles, energy {energy:.8g}, {r['n_negative']} negative "
            f"eigenvalues, residual {check['residual']:.1e}, largest turn {r['largest_turn']:.0f} deg, "
            f"{r['wall_s']:.0f} s")
        if checkpoint is not None:
            save_checkpoint(checkpoint, {"states": np.array(states), "rows": json.dumps(rows, allow_nan=False)}, meta)
    return rows, np.array(states)

