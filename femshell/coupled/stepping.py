r"""Time-step control of the coupled loop (theory §2.8): the step settings, the stability bounds, the error control.

The staggered step holds the source P(H) of the step's start; a mode of source gain g = ∂P/∂c
is multiplied per step by a = 1 − q (1 − g/β), q = 1 − e^{−β dt}. The next dt keeps
a ≥ −ρ (:func:`feedback_step_limit`) with g estimated from the last step (:func:`feedback_gain`).
Its accuracy is set either by the change of the stretch per step (``step_control = "stretch"``)
or by the step's local error estimate (``"error"``: :func:`held_source_error`, :func:`error_step_factor`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .._checks import finite as _finite, integer as _integer
from ..solvers.linear import BACKENDS
from ..solvers.newton import LINEAR_SOLVERS
from .parameters import store_numbers

__all__ = ["TimeStepping", "SOURCE_RULES", "STEP_CONTROLS", "feedback_gain", "feedback_step_limit",
           "stable_extrapolation", "held_source_error", "error_step_factor"]


def feedback_gain(dc, dP, fraction: float = 0.1) -> float:
    """The source's most negative gain over a step: min ΔP_i / Δc_i over the vertices whose
    |Δc_i| ≥ ``fraction`` · max |Δc| (1/time; nan if c did not change).

    For a change along one eigenvector of G = ∂P/∂c every ratio is its eigenvalue. The
    oscillating modes of a spot are local (a ring of vertices at its edge), which a global
    average (ΔP · Δc)/(Δc · Δc) would dilute with the slowly changing rest.
    """
    dc, dP = np.asarray(dc, float), np.asarray(dP, float)
    if dc.ndim != 1 or dP.shape != dc.shape:
        raise ValueError(f"dc and dP must be vectors of the same length, got shapes {dc.shape} and {dP.shape}")
    a = np.abs(dc)
    if not len(a) or a.max() <= 0:
        return float("nan")
    sel = a >= fraction * a.max()
    return float(np.min(dP[sel] / dc[sel]))


def feedback_step_limit(g: float, beta: float, rho: float, exponential: bool) -> float:
    r"""Largest dt whose staggered step multiplies a mode of source gain g by a ≥ −rho (inf: no limit).

    With the source held over the step, a mode δ of the chemistry c = P(c)/β with
    ∂P/∂c δ = g δ is multiplied per step by

    * ``exponential`` (the degradation integrated exactly, as femshell's chemistry does; with
      D > 0 the diffusion, left out here, only damps more): a = 1 − q (1 − g/β),
      q = 1 − e^{−β dt}; a ≥ −ρ ⇔ q ≤ (1 + ρ) β / (β − g);
    * implicit Euler in the degradation too: a = (1 + g dt)/(1 + β dt);
      a ≥ −ρ ⇔ dt (−g − ρ β) ≤ 1 + ρ.

    Only a negative feedback, g < −ρ β, limits dt; a positive one (a switch turning on)
    is bounded by the step's Δs instead.

    >>> from femshell.coupled import feedback_step_limit
    >>> round(feedback_step_limit(-19.0, 1.0, 1.0, exponential=True), 4)   # a = -1 exactly here
    0.1054
    >>> feedback_step_limit(0.5, 1.0, 0.5, exponential=True)
    inf
    """
    beta, rho = _finite("beta", beta, 0.0), _finite("rho", rho, 0.0)
    if not (math.isfinite(g) and g < -rho * beta) or rho <= 0:
        return math.inf
    if exponential and beta > 0:
        return -math.log1p(-(1.0 + rho) * beta / (beta - g)) / beta
    return (1.0 + rho) / (-g - rho * beta)


def stable_extrapolation(g: float, beta: float, rho: float, dt: float, h_prev: float) -> float:
    r"""The largest fraction θ ∈ [0, 1] of the source's extrapolation that keeps a ≥ −rho on a step dt.

    With the source P_n + θ (r/2)(P_n − P_{n−1}), r = dt/h_prev (θ = 1: Adams–Bashforth 2, see
    :class:`TimeStepping` ``source_rule``), a mode of gain g (as in :func:`feedback_step_limit`)
    follows δ_{n+1} = e^{−β dt} δ_n + φ g ((1 + θr/2) δ_n − (θr/2) δ_{n−1}), φ = (1 − e^{−β dt})/β
    (φ = dt for β = 0). Its roots ζ are real, one of each sign when g < 0; the negative one is
    ≥ −ρ iff the characteristic polynomial is ≥ 0 at −ρ:

        ρ q + k (ρ + (1 + ρ) θr/2) ≤ ρ (1 + ρ),   q = 1 − e^{−β dt},  k = −g φ.

    At θ = 0 this is the held source's bound, a ≥ −ρ, so θ falls from 1 to 0 as dt approaches
    that bound; full extrapolation (θ = 1, r = 1) needs dt ≲ 0.4 of it where the feedback is
    strong (−g/β ≫ 1, ρ = 0.5). A positive or unknown (nan) g never limits: θ = 1.

    >>> from femshell.coupled import stable_extrapolation
    >>> [round(stable_extrapolation(-20.0, 1.0, 0.5, dt, 0.03), 3) for dt in (0.02, 0.03, 0.05, 0.08)]
    [1.0, 0.992, 0.195, 0.0]
    """
    if not (math.isfinite(g) and g < 0):
        return 1.0
    q = -math.expm1(-beta * dt)
    k = -g * (q / beta if beta > 0 else dt)
    r = dt / h_prev
    theta = (rho * (1.0 + rho) - rho * q - k * rho) / (k * (1.0 + rho) * 0.5 * r)
    return float(min(1.0, max(0.0, theta)))


def held_source_error(source_held, source_start, source_end, dt: float, beta: float) -> np.ndarray:
    r"""Local error of c over a step of length dt whose chemistry held ``source_held``: c_2 − c⁺ per vertex.

    c_2 is the step with the source linear in time from P_n (``source_start``) to P_{n+1}
    (``source_end``, at the step's converged shape), integrated with the degradation exactly:

        c_2 − c⁺ = φ (P_n − P_held) + ψ (P_{n+1} − P_n),
        φ = (1 − e^{−β dt})/β,  ψ = ∫_0^dt e^{−β(dt−τ)} τ/dt dτ = (dt − φ)/(β dt)

    (φ = dt, ψ = dt/2 for β = 0). With the held start source (P_held = P_n) it is the
    trapezoidal correction ψ ΔP ≈ dt ΔP/2, second order in dt against the step's first;
    the diffusion of the correction is left out (it only smooths it).

    >>> import numpy as np
    >>> from femshell.coupled import held_source_error
    >>> held_source_error(np.ones(1), np.ones(1), 3.0 * np.ones(1), 0.01, 0.0)   # ψ ΔP = 0.005 · 2
    array([0.01])
    """
    dt, beta = float(dt), float(beta)
    bdt = beta * dt
    if bdt == 0:
        phi, psi = dt, 0.5 * dt
    elif bdt < 1e-4:                    # the series, where dt − φ cancels
        phi, psi = dt * (1 - bdt / 2 + bdt * bdt / 6), dt * (0.5 - bdt / 6 + bdt * bdt / 24)
    else:
        phi = -math.expm1(-bdt) / beta
        psi = (dt - phi) / bdt
    p_n = np.asarray(source_start, float)
    return phi * (p_n - np.asarray(source_held, float)) + psi * (np.asarray(source_end, float) - p_n)


#: the PI controller's exponents for a local error of order k = 2 in dt: 1/k − 0.75 β and β = 0.08
#: (Hairer, Nørsett and Wanner's DOPRI5 setting; steady at r = safety^{1/(0.44 − 0.08)})
_PI_EXPONENTS = (0.44, 0.08)


def error_step_factor(ratio: float, ratio_prev: float | None, safety: float, grow: float,
                      shrink: float = 0.2) -> float:
    r"""dt_next / dt from the step's error ratio r = error / tolerance (a PI controller, theory §2.8).

    The local error of the staggered step is second order in dt, so the elementary rule is
    dt_next = dt · safety · r^{−1/2}; with the last accepted step's ratio r_prev (None: the
    elementary rule) the proportional-integral one, dt · safety · r^{−0.44} r_prev^{0.08},
    which damps the step sequence where the error jumps (Hairer, Nørsett and Wanner, II §IV.2). Bounded to
    [``shrink``, ``grow``]; r = 0 (no error seen) grows by ``grow``.

    >>> from femshell.coupled import error_step_factor
    >>> round(error_step_factor(0.25, None, 0.8, 1.5), 6)   # 0.8 · 0.25^(−1/2) = 1.6 > grow
    1.5
    >>> round(error_step_factor(4.0, None, 0.8, 1.5), 6)    # 0.8 / 2
    0.4
    """
    if not ratio > 0:
        return float(grow) if ratio == 0 else float(shrink)
    if ratio_prev is None or not ratio_prev > 0:
        factor = safety * ratio ** -0.5
    else:
        factor = safety * ratio ** -_PI_EXPONENTS[0] * ratio_prev ** _PI_EXPONENTS[1]
    return float(min(grow, max(shrink, factor)))


SOURCE_RULES = ("start", "extrapolated")
STEP_CONTROLS = ("stretch", "error")


@dataclass(frozen=True)
class TimeStepping:
    """Controls of the time loop (times in 1/β).

    Parameters
    ----------
    t_final : end time. dt_initial, dt_min, dt_max : first, smallest and largest step.
    ds_max : largest allowed change of the stretch s in any element per step.
    grow : largest growth factor of dt from one step to the next; safety : factor on
        the predicted dt (dt_next = dt · min(grow, safety · ds_max / Δs)).
    max_cuts : cuts of one step (Δs too large or Newton failed) before giving up.
    stationary_rate_c : stop when max|Δc| / (dt · c_scale) stays below this for
        ``stationary_steps`` steps in a row, together with
    stationary_rate_x : max|Δx| / (dt · h0) (shape change per unit time in thicknesses);
        c_scale = max(max c, 1e-2 c_max). Set either to 0 to never stop early.
    stationary_pattern_time, stationary_pattern_tol : a second, coarser stop: the pattern, the
        regions where c > c* (:func:`~femshell.analysis.find_spots`), has stayed the same within
        ``stationary_pattern_tol`` (:func:`~femshell.analysis.same_pattern`: the numbers of spots
        and ridges, the patterned area, the region centroids) for ``stationary_pattern_time``.
        For runs whose pattern settles while a few vertices at the spots' edges go on changing
        for ever (a strong source). It does not see c build up below c* (a ring before it
        nucleates): give it a time longer than such a build-up. 0 (default): only the rate test
        above. The tolerance must exceed the regions' own jitter (about 1 % of their radius on
        strong-source runs). Measured by the caller's observers
        (:class:`~femshell.coupled.observers.LoopObservers`).
    newton_rtol, newton_atol_strain : convergence |∇Π| ≤ rtol · |∇Π(u_start)| + atol, with
        atol = newton_atol_strain × (the residual of a uniform unit strain).
    newton_max_iter, newton_backend : passed to :func:`~femshell.solvers.newton.minimize`.
    linear_solver : Newton's steps, ``minimize(linear_solver=...)``: "krylov" preconditions them by
        the factorisation held from the last converged state (or a later iterate) and refactorises
        only when that does not serve; "direct" factorises every iterate's Hessian. Either way each
        accepted state's stability comes from a factorisation of its own Hessian.
    quasi_newton : each Newton solve first takes up to this many quasi-Newton iterations on
        the factorisation of the last converged state's Hessian (its stability check), which
        the loop keeps (``minimize(quasi_newton=...)``; after a cut, the factorisation the
        failed attempt left); the converged state is then checked by a fresh factorisation as
        before. 0: plain Newton (one more Hessian assembly and factorisation per step). Needs
        a Cholesky factor, so PARDISO: with SuperLU every solve is plain Newton.
    ramp_ds : largest stretch increment of the initial equilibrium (growth ramped from
        s = 1 to s(c0), with a secant predictor; cut on Newton failure, grown by 1.5 after success).
    predictor : start Newton from the secant prediction u + (h/h_prev)(u − u_prev) when
        it has lower energy than u (a grown rest state leaves the old shape compressed,
        near buckling, where Newton from the old shape needs many iterations).
    snap_ds, snap_max_iter : a fold of the quasi-static path. When Newton runs out of
        iterations (or stalls) on a step whose Δs ≤ ``snap_ds``, no equilibrium is left near the old
        shape (a tiny growth increment would otherwise converge in a few iterations): the
        minimisation goes on from Newton's last iterate (lower energy than the start) for
        up to ``snap_max_iter`` more iterations, and the shell snaps to the stable
        equilibrium it reaches. Without this the loop creeps towards the fold with ever
        smaller steps. At most one snap is tried per step (where it does not settle the
        cuts go on as usual). ``snap_max_iter = 0`` disables it.
    newton_stall : a Newton solve that has made no progress for this many iterations (the
        residual not halved, the energy down by less than 1e-7 of itself) gives up and the step
        is cut, instead of running to ``newton_max_iter`` (``minimize(stall=...)``; not in a
        snap, which may creep legitimately). 0: never.
    feedback_amplification : the next dt keeps the staggering's amplification of an
        oscillating mode, estimated from the last step, at a ≥ −this (theory §2.8,
        :func:`feedback_step_limit`; 0 < value ≤ 1: 1 is the stability limit itself, smaller
        damps an oscillation faster). 0: no bound.
    source_rule : the source P(H) the chemistry holds over a step. "start": P of the step's
        start (the staggering above, first order in dt). "extrapolated": P at the step's
        midpoint extrapolated from the last two accepted states (Adams–Bashforth 2, second
        order, no extra solve), as far as that keeps an oscillation within
        ``feedback_amplification`` (:func:`stable_extrapolation`: a strong negative feedback
        allows full extrapolation only on 0.4 of the held source's dt; the step keeps its
        length and extrapolates less, down to P_n at the held source's own bound).
    step_control : what sets the accuracy of a step. "stretch": its change of the stretch, Δs ≤
        ``ds_max`` (the next dt from ``safety · ds_max / Δs``). "error": its local error, the change
        of the stretch that the source's change over the step would have made (the step against its
        second-order counterpart, :func:`held_source_error`; max over elements of |s(c⁺ + e_c) − s(c⁺)|),
        kept ≤ ``error_tol`` by a PI controller (:func:`error_step_factor`); a step above it is
        rejected after its equilibrium, and Δs is then only bounded by ``error_ds_max`` (how far
        Newton reaches). Both keep the feedback bound, ``grow`` and ``dt_max``.
    error_tol : the local error of the stretch per step allowed under ``step_control = "error"``.
    error_ds_max : the largest change of the stretch per step under ``step_control = "error"``.
    max_steps : stop after this many accepted steps in one call of :meth:`CoupledLoop.run`.
    """

    t_final: float = 100.0
    dt_initial: float = 0.01
    dt_min: float = 1e-8
    dt_max: float = 2.0
    ds_max: float = 0.02
    grow: float = 1.5
    safety: float = 0.8
    max_cuts: int = 12
    stationary_rate_c: float = 1e-3
    stationary_rate_x: float = 1e-3
    stationary_steps: int = 3
    stationary_pattern_time: float = 0.0
    stationary_pattern_tol: float = 0.02
    newton_rtol: float = 1e-6
    newton_atol_strain: float = 1e-10
    newton_max_iter: int = 40
    newton_backend: str = "auto"
    linear_solver: str = "krylov"
    quasi_newton: int = 12
    ramp_ds: float = 0.1
    predictor: bool = True
    snap_ds: float = 1e-3
    snap_max_iter: int = 400
    newton_stall: int = 10
    feedback_amplification: float = 0.5
    source_rule: str = "start"
    step_control: str = "stretch"
    error_tol: float = 0.01
    error_ds_max: float = 0.25
    max_steps: int | None = None

    def __post_init__(self):
        _finite("t_final", self.t_final, 0.0)
        _finite("dt_min", self.dt_min, 0.0, lo_open=True, text="(0, inf)")
        _finite("dt_max", self.dt_max, self.dt_min, text=f"[dt_min = {self.dt_min}, inf)")
        _finite("dt_initial", self.dt_initial, self.dt_min, self.dt_max,
                text=f"[dt_min = {self.dt_min}, dt_max = {self.dt_max}]")
        _finite("ds_max", self.ds_max, 0.0, lo_open=True, text="(0, inf)")
        _finite("grow", self.grow, 1.0)
        _finite("safety", self.safety, 0.0, 1.0, lo_open=True, text="(0, 1]")
        _integer("max_cuts", self.max_cuts, 0)
        _finite("stationary_rate_c", self.stationary_rate_c, 0.0)
        _finite("stationary_rate_x", self.stationary_rate_x, 0.0)
        _integer("stationary_steps", self.stationary_steps, 1)
        _finite("stationary_pattern_time", self.stationary_pattern_time, 0.0)
        _finite("stationary_pattern_tol", self.stationary_pattern_tol, 0.0)
        _finite("newton_rtol", self.newton_rtol, 0.0, lo_open=True, text="(0, inf)")
        _finite("newton_atol_strain", self.newton_atol_strain, 0.0)
        _integer("newton_max_iter", self.newton_max_iter, 1)
        _integer("quasi_newton", self.quasi_newton, 0)
        _integer("newton_stall", self.newton_stall, 0)
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {self.linear_solver!r}")
        if self.newton_backend not in BACKENDS:
            raise ValueError(f"newton_backend must be one of {BACKENDS}, got {self.newton_backend!r}")
        _finite("ramp_ds", self.ramp_ds, 0.0, lo_open=True, text="(0, inf)")
        _finite("snap_ds", self.snap_ds, 0.0)
        _finite("feedback_amplification", self.feedback_amplification, 0.0, 1.0)
        _integer("snap_max_iter", self.snap_max_iter, 0)
        if self.source_rule not in SOURCE_RULES:
            raise ValueError(f"source_rule must be one of {SOURCE_RULES}, got {self.source_rule!r}")
        if self.step_control not in STEP_CONTROLS:
            raise ValueError(f"step_control must be one of {STEP_CONTROLS}, got {self.step_control!r}")
        _finite("error_tol", self.error_tol, 0.0, lo_open=True, text="(0, inf)")
        _finite("error_ds_max", self.error_ds_max, 0.0, lo_open=True, text="(0, inf)")
        if self.max_steps is not None:
            _integer("max_steps", self.max_steps, 0, "None or an integer >= 0")
        store_numbers(self)

    @property
    def stretch_limit(self) -> float:
        """The largest change of the stretch per step in force: ``ds_max`` or, under error control, ``error_ds_max``."""
        return self.ds_max if self.step_control == "stretch" else self.error_ds_max

    def as_dict(self) -> dict:
        return asdict(self)
