r"""Pseudo-arclength continuation: the predictor/corrector loop with step control.

:func:`continuation` follows r(u, λ) = 0 from (u0, λ0): predictor (u, λ) + ds·t, corrector on the
hyperplane ⟨(u, λ) − predictor, t⟩_W = 0 (:mod:`.corrector`), special points between accepted
points (:mod:`.special_points`). ds grows by ``grow`` after a corrector of at most
``fast_iterations`` iterations and halves after a failure; below ``ds_min`` the run stops. A step
that crosses more eigenvalues than one step locates, or in which a special point cannot be
located, is cut (halved) and retried, up to ``MAX_CUTS`` times per special point (if no shorter
step converges, the cut step is taken after all); what still cannot be located is reported as a
bracket (:class:`~femshell.solvers.branch.SpecialPoint` with ``located=False`` and no parameter).
The result is a :class:`~femshell.solvers.branch.Branch`: the caller writes it (:mod:`femshell.io`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .._checks import finite, integer
from .branch import Branch, ContinuationError
from .corrector import _Engine, _SingularTangent, _StepFailure, is_residual_problem
from .newton import NewtonError, check_unknowns, minimize
from .special_points import _Context

__all__ = ["continuation"]

#: retries with a halved step before a special point that cannot be located is reported as a bracket
MAX_CUTS = 5
#: the default ds_min, relative to the smaller of ds and the run's parameter span in the arclength
DS_MIN_FRACTION = 1e-5


def continuation(problem, u0, lam0, *, ds, ds_min=None, ds_max=None, lam_stop=None, max_steps=200, weights=None,
                 parameter_scale=None, direction=+1, record=None, callback=None, detect=True, log=print,
                 n_eigs=3, stop_at=(), initial_tangent=None, label="branch", keep_states=True,
                 rtol=1e-8, atol=0.0, xtol=1e-9, max_corrector_iterations=8, fast_iterations=3, grow=1.5,
                 max_turn_deg=35.0, locate_tol=1e-7, cluster_tol=0.01, dip_tol=0.1, fd_step=1e-6,
                 backend="auto") -> Branch:
    r"""Follow the equilibrium branch of ``problem`` through (u0, lam0) by pseudo-arclength continuation.

    Parameters
    ----------
    problem : a parametrized problem (module docstring).
    u0, lam0 : start; u0 is first corrected to an equilibrium at lam0 (Newton), or, with
        ``initial_tangent``, on the hyperplane through (u0, lam0) orthogonal to it.
    ds, ds_min, ds_max : first, smallest and largest step in the weighted arclength
        (defaults: ds_max = 10 ds; ds_min = 1e-5 × min(ds, |lam_stop − lam0| / parameter_scale),
        1e-5 ds without lam_stop).
    lam_stop : stop exactly at this parameter value (when a step crosses it).
    max_steps : number of accepted steps.
    weights : per-unknown weights of the norm, > 0 (default ``problem.dof_weights()`` or ones).
    parameter_scale : scale of λ in the norm (default ``problem.parameter_scale`` or 1).
    direction : +1 / -1: initial sense of λ (ignored with ``initial_tangent``).
    record : ``record(u) -> dict`` of extra columns (norms, point values); default:
        ``{"norm": weighted RMS norm of u}``.
    callback : ``callback(branch, row)`` after each accepted step; returning a true value stops.
    detect : locate folds, branch points and dips (needs ``n_eigs`` ≥ 1 for dips).
    n_eigs : eigenvalues of smallest magnitude recorded per step, ascending (0: none; the
        inertia, i.e. the number of negative eigenvalues, is always recorded). Ignored for a
        non-gradient problem (``residual``/``jacobian``): its rows carry the sign of det J and the
        columns of ``problem.stability(u)``.
    stop_at : kinds after whose detection to stop: "fold", "branch" (one, or a sequence).
    initial_tangent : (t_u, t_λ) to orient the start (used by :func:`switch_branch`).
    rtol, atol, xtol : corrector convergence, |r| ≤ rtol·scale + atol (scale: the largest
        predictor residual of the accepted steps, or |g_λ|·parameter_scale, seen on the branch)
        or a Newton correction ≤ xtol in the weighted norm.
    locate_tol : arclength tolerance of the location of special points.
    cluster_tol : relative parameter tolerance of the multiplicity count.
    dip_tol : an eigenvalue that dips below dip_tol × its neighbours' values flags "BP?".

    Returns
    -------
    Branch
    """
    t_start = time.perf_counter()
    u0 = check_unknowns(problem, u0)
    n = len(u0)
    weights = _checked_weights(problem, weights, n)
    if parameter_scale is None:
        parameter_scale = getattr(problem, "parameter_scale", 1.0)
    parameter_scale = finite("parameter_scale", parameter_scale, 0.0, lo_open=True, text="(0, inf)")
    lam0 = finite("lam0", lam0)
    if lam_stop is not None:
        lam_stop = finite("lam_stop", lam_stop, text="(-inf, inf), or None")
    ds, ds_min, ds_max = _checked_steps(ds, ds_min, ds_max, None if lam_stop is None
                                        else abs(lam_stop - lam0) / parameter_scale)
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    grow, max_turn_deg, rtol, atol, xtol, locate_tol, fd_step, cluster_tol, dip_tol = (
        finite(name, v, lo, hi) for name, v, lo, hi in (
            ("grow", grow, 1, 100), ("max_turn_deg", max_turn_deg, 1e-6, 180), ("rtol", rtol, 0, 1),
            ("atol", atol, 0, None), ("xtol", xtol, 0, 1), ("locate_tol", locate_tol, 0, None),
            ("fd_step", fd_step, 1e-14, 0.1), ("cluster_tol", cluster_tol, 0, 1), ("dip_tol", dip_tol, 0, 1)))
    max_steps, n_eigs, max_corrector_iterations, fast_iterations = (
        integer(name, v, lo, f"an integer in [{lo}, {hi}]", hi) for name, v, lo, hi in (
            ("max_steps", max_steps, 0, 10**7), ("n_eigs", n_eigs, 0, 1000),
            ("max_corrector_iterations", max_corrector_iterations, 1, 1000), ("fast_iterations", fast_iterations, 0, 1000)))
    n_eigs = min(n_eigs, n)   # a table column per eigenvalue: no more than there are
    if is_residual_problem(problem):
        n_eigs = 0            # J is not symmetric: its stability is the problem's (``problem.stability``)
    stop_at = _checked_stop_at(stop_at)
    log = log or None
    eng = _Engine(problem, weights, parameter_scale, backend=backend, rtol=rtol, atol=atol, xtol=xtol,
                  max_iter=max_corrector_iterations, fd_step=fd_step, n_eigs=n_eigs, log=log)
    branch = Branch(label, weights, parameter_scale)
    if record is None:
        def record(u):
            return {"norm": eng.norm(u, 0.0)}
    A = _first_point(eng, problem, u0, lam0, direction, initial_tangent, backend)
    branch._last = (A.u, A.lam)
    eng.rscale = max(eng.rscale, A.parameter_residual)
    if lam_stop is not None:
        _check_lam_stop(eng, A, lam_stop, label, log)
    ctx = _Context(eng, branch, record, keep_states, n_eigs, locate_tol, cluster_tol, dip_tol, log, t_start)
    ctx.add_row(A, 0.0, 0, ds=0.0)
    if log:
        log(f"  continuation '{label}': start at parameter {A.lam:.8g}, dλ/ds {A.t_lam:+.3g}, "
            f"negative eigenvalues {A.n_negative}")
    control = _StepControl(ds_min, ds_max, grow, fast_iterations, math.cos(math.radians(max_turn_deg)), max_steps,
                           lam_stop, stop_at, detect, callback, log)
    try:
        A, step, (branch.status, branch.message) = _follow(eng, ctx, problem, branch, A, ds, control)
    finally:
        try:
            eng.set(branch.last[1])     # a failed trial step may have left the problem at another parameter
        except _StepFailure:
            pass
        eng.release()
    if not keep_states and branch.states:
        branch.states[-1] = (A.u, A.lam)
    unlocated = [p for p in branch.special_points if not p.located]
    if unlocated:
        branch.message += (f"; {len(unlocated)} special point(s) detected but not located, reported as brackets: "
                           + ", ".join(f"{p.label} in [{p.bracket[0]:.8g}, {p.bracket[1]:.8g}]" for p in unlocated))
    branch.wall_s = time.perf_counter() - t_start
    branch.counts = dict(eng.counts)
    if log:
        log(f"  continuation '{label}': {branch.status}: {branch.message}; {step} steps, "
            f"{len(branch.special_points)} special points, {branch.wall_s:.1f} s")
    return branch


def _checked_weights(problem, weights, n):
    """The arclength weights, one per unknown, finite and > 0 (default ``problem.dof_weights()`` or ones)."""
    if weights is None:
        weights = problem.dof_weights() if hasattr(problem, "dof_weights") else np.ones(n)
    weights = np.asarray(weights, float)
    if weights.ndim and weights.shape != (n,):
        raise ValueError(f"weights must be a number or one per unknown (shape ({n},)), got shape {weights.shape}")
    weights = np.broadcast_to(weights, (n,)).copy()
    if not (np.all(weights > 0) and np.all(np.isfinite(weights))):
        # a zero weight would also leave its unknown out of the corrector's step test (xtol)
        raise ValueError("weights must be finite and > 0 (a small weight makes an unknown count little in the "
                         "arclength)")
    return weights


def _checked_steps(ds, ds_min, ds_max, span=None):
    """(ds, ds_min, ds_max) with the defaults 1e-5 min(ds, span) and 10 ds; 0 < ds_min <= ds <= ds_max < inf.

    ``span``: the run's parameter range in the arclength, |lam_stop − lam0| / parameter_scale
    (a fold or a cluster of branch points may need steps far below ds when ds is a fair part of it).
    """
    ds = finite("ds", ds, 0.0, lo_open=True, text="(0, inf)")
    if ds_min is None:
        ds_min = DS_MIN_FRACTION * (min(ds, span) if span else ds)
    ds_min = float(ds_min)
    ds_max = 10.0 * ds if ds_max is None else float(ds_max)
    if not (0 < ds_min <= ds <= ds_max < math.inf):
        raise ValueError(f"need 0 < ds_min <= ds <= ds_max < inf, got {ds_min}, {ds}, {ds_max}")
    return ds, ds_min, ds_max


def _checked_stop_at(stop_at):
    stop_at = (stop_at,) if isinstance(stop_at, str) else tuple(stop_at)
    bad = set(stop_at) - {"fold", "branch"}
    if bad:
        raise ValueError(f"stop_at kinds must be among 'fold', 'branch', got {sorted(bad)}")
    return stop_at


def _first_point(eng, problem, u0, lam0, direction, initial_tangent, backend):
    """The equilibrium the branch starts from, finished (tangent, inertia); releases the engine on failure.

    Without ``initial_tangent``: Newton at fixed λ0 (the equilibrium next to u0 whatever its
    stability), and a minimisation only if that fails; with it, the corrector on the
    hyperplane through (u0, λ0) orthogonal to it.
    """
    n = len(u0)
    try:
        if initial_tangent is None:
            try:
                A = eng.correct(u0, lam0, lam_fixed=lam0, update_scale=False)
            except _StepFailure:
                if eng.general:     # no energy to minimise
                    raise
                eng.set(lam0)
                try:
                    u_start = minimize(problem, u0, rtol=1e-10, log=None, backend=backend).u
                except NewtonError as exc:
                    raise _StepFailure(f"Newton and minimisation failed ({exc})") from None
                A = eng.correct(u_start, lam0, lam_fixed=lam0, update_scale=False)
            try:
                return eng.finish(A, None, direction)
            except _SingularTangent as exc:     # released below, as any error of the first point
                raise ContinuationError(f"the first point at parameter {lam0:.6g} is an equilibrium without a tangent "
                                        f"there: a singular point (fold or branch point); start beside it or give "
                                        f"initial_tangent ({exc})") from None
        t0u = np.asarray(initial_tangent[0], float)
        t0l = float(initial_tangent[1])
        nt = eng.norm(t0u, t0l) if t0u.shape == (n,) else math.nan
        if not (math.isfinite(nt) and nt > 0):
            eng.release()
            raise ValueError(f"initial_tangent must be (t_u of {n} unknowns, t_λ), finite and not zero")
        t0 = (t0u / nt, t0l / nt)
        A = eng.correct(u0, lam0, t=t0, update_scale=False)
        return eng.finish(A, t0)
    except _StepFailure as exc:
        eng.release()
        raise ContinuationError(f"the first point at parameter {lam0:.6g} did not converge ({exc})") from None
    except BaseException:
        eng.release()
        raise


def _check_lam_stop(eng, A, lam_stop, label, log):
    """An error when lam_stop is the start's parameter; a note when it lies behind the start."""
    if abs(lam_stop - A.lam) <= 1e-12 * max(abs(lam_stop), eng.lam_scale):
        eng.release()
        raise ValueError(f"lam_stop = {lam_stop:.9g} is the start's parameter: nothing to follow")
    if (lam_stop - A.lam) * A.t_lam < 0 and log:
        log(f"  continuation '{label}': lam_stop = {lam_stop:.9g} lies behind the start ({A.lam:.9g}) in the "
            "branch's direction: reached only after a fold (direction=-1 goes there directly)")


@dataclass
class _StepControl:
    """The checked step-control and stopping settings of one run."""

    ds_min: float
    ds_max: float
    grow: float
    fast_iterations: int
    cos_max: float            # cosine of the largest tangent turn per step
    max_steps: int
    lam_stop: float | None
    stop_at: tuple
    detect: bool
    callback: object
    log: object


def _follow(eng, ctx, problem, branch, A, ds, c):
    """Accept steps from A until a stop: (last accepted point, steps, (status, message))."""
    history = [(A, 0.0)]  # (point, s) of the accepted points (last three)
    s = 0.0
    step = 0
    cuts = 0              # steps cut since the last special point
    pending = None        # the last step cut for a special point: taken after all if no shorter step converges
    while True:
        if step >= c.max_steps:
            return A, step, ("max_steps", f"{c.max_steps} steps done")
        forced = False
        try:
            B = _trial_step(eng, A, ds, c.cos_max)
        except _StepFailure as exc:
            reason = str(exc)
            ds *= 0.5
            if c.log:
                c.log(f"    step from parameter {A.lam:.8g} failed ({reason}); ds -> {ds:.3g}")
            if ds >= c.ds_min:
                continue
            if pending is None:
                why = eng.diagnose(A)
                return A, step, ("ds_min", f"step size fell below ds_min = {c.ds_min:.3g} at parameter {A.lam:.8g} "
                                           f"(last failure: {reason})" + (f". At the last accepted point {why}" if why
                                                                          else ""))
            B, forced, pending = pending, True, None
            if c.log:
                c.log(f"    no shorter step converges: the cut step to parameter {B.lam:.8g} is taken after all")
        B, sigma_B, landed = _landing(eng, A, B, c.lam_stop, ds)
        if forced:
            ds = sigma_B
        found = []
        if c.detect:
            found, cut = _detect_or_cut(ctx, branch, A, B, s, sigma_B, step, history,
                                        not forced and cuts < MAX_CUTS and 0.5 * ds >= c.ds_min)
            if cut:
                cuts += 1
                ds *= 0.5
                pending = B
                if c.log:
                    c.log(f"    step from parameter {A.lam:.8g} to {B.lam:.8g} cut ({cut}); ds -> {ds:.3g}")
                continue
        step += 1
        if found:
            cuts, pending = 0, None
        eng.set(B.lam)     # the location's trial points moved the problem's parameter
        s += sigma_B
        ctx.add_row(B, s, step, ds=sigma_B, special=next((p.row_label for p in found if p.info.get("at_step_end")), ""))
        if hasattr(problem, "accept"):
            problem.accept(B.u)
        if c.log:
            ev = "" if B.eigenvalues is None else f"  eig {np.array2string(B.eigenvalues[:3], precision=3)}"
            c.log(f"  step {step:3d}  parameter {B.lam:.8g}  ds {sigma_B:.3g}  it {B.iterations}  "
                  f"dλ/ds {B.t_lam:+.3g}  n_neg {B.n_negative}{ev}")
        history = (history + [(B, s)])[-3:]
        A = B
        branch._last = (A.u, A.lam)
        # only accepted steps: a diverged trial's residual must not loosen the later tests
        eng.rscale = max(eng.rscale, B.predictor_residual, B.parameter_residual)
        stop = _stop(branch, c, B, landed, found)
        if stop is not None:
            return A, step, stop
        if B.iterations <= c.fast_iterations:
            ds = min(ds * c.grow, c.ds_max)


def _detect_or_cut(ctx, branch, A, B, s, sigma_B, step, history, may_cut):
    """(special points found in the step A → B, why to cut the step, or "").

    With ``may_cut``, a step that crosses more eigenvalues than one step can locate is cut
    unsearched, and one with a point that was not located is cut after the search, whose rows and
    points are taken back (and the earlier point a crossing was merged into is restored). A
    multiple crossing that is located (the cos/sin modes of a disk cross together) is kept: no cut
    would separate it.
    """
    if may_cut and None not in (A.n_negative, B.n_negative) \
            and abs(B.n_negative - A.n_negative) > ctx.max_crossings:
        return [], f"the inertia jumps from {A.n_negative} to {B.n_negative}"
    n_rows, n_points = len(branch.rows), len(branch.special_points)
    last = branch.special_points[-1] if branch.special_points else None
    saved = None if last is None else dict(last.info)
    found = ctx.detect(A, B, s, sigma_B, step, history)
    failed = next((p for p in found if not p.located), None)
    if failed is None or not may_cut:
        return found, ""
    del branch.rows[n_rows:], branch.states[n_rows:], branch.special_points[n_points:]
    if last is not None:
        last.info = saved
    return [], f"{failed.label} not located: {failed.info.get('reason', '')}"


def _trial_step(eng, A, ds, cos_max):
    """Predictor A + ds·t, corrector, tangent; a _StepFailure when the tangent turned too far."""
    u_p = A.u + ds * A.t_u
    lam_p = A.lam + ds * A.t_lam
    B = eng.correct(u_p, lam_p, t=(A.t_u, A.t_lam), max_dist=ds)
    B = eng.finish(B, (A.t_u, A.t_lam))
    turn = eng.dot(A.t_u, A.t_lam, B.t_u, B.t_lam)
    if turn < cos_max:
        raise _StepFailure(f"tangent turned by {math.degrees(math.acos(max(-1, min(1, turn)))):.0f} degrees")
    return B


def _landing(eng, A, B, lam_stop, ds):
    """(B, arclength A → B, landed): B moved exactly onto lam_stop when the step crossed it.

    ``landed`` is "exactly" at lam_stop, "missed" when the step crossed it but the corrector at
    fixed λ failed, else None.
    """
    sigma_B = eng.dot(A.t_u, A.t_lam, B.u - A.u, B.lam - A.lam)
    if lam_stop is None:
        return B, sigma_B, None
    if abs(B.lam - lam_stop) <= 1e-9 * max(abs(lam_stop), eng.lam_scale):
        return B, sigma_B, "exactly"
    if A.lam != lam_stop and (A.lam - lam_stop) * (B.lam - lam_stop) <= 0:
        L = _land(eng, A, B, lam_stop, ds)
        if L is None:
            return B, sigma_B, "missed"
        return L, eng.dot(A.t_u, A.t_lam, L.u - A.u, L.lam - A.lam), "exactly"
    return B, sigma_B, None


def _stop(branch, c, B, landed, found):
    """(status, message) when the run stops after accepting B, else None."""
    if c.callback is not None and bool(c.callback(branch, branch.rows[-1])):   # np.True_ and 1 stop too
        return "callback", "the callback asked to stop"
    if landed == "exactly":
        return "lam_stop", f"reached parameter {B.lam:.10g}"
    if landed == "missed":
        return "lam_stop", (f"the step crossed lam_stop = {c.lam_stop:.10g} but the corrector could not land on it; "
                            f"stopped at parameter {B.lam:.10g}")
    kinds = {p.kind for p in found}
    if "fold" in c.stop_at and "fold" in kinds:
        return "fold", "stopped after a fold"
    if "branch" in c.stop_at and "branch" in kinds:
        return "branch", "stopped after a branch point"
    return None


def _land(eng, A, B, lam_stop, ds):
    """A point exactly at lam_stop: corrector at fixed λ from the tangent predictor (or from B)."""
    starts = []
    if abs(A.t_lam) > 1e-12:
        sig = (lam_stop - A.lam) / A.t_lam
        starts.append(A.u + sig * A.t_u)
    starts.append(B.u)
    for u_p in starts:
        try:
            L = eng.correct(u_p, lam_stop, lam_fixed=lam_stop, max_dist=2 * ds)
            return eng.finish(L, (A.t_u, A.t_lam))
        except _StepFailure:
            continue
    return None

