r"""Newton's method for equilibria of an energy, returning stable ones when asked.

The solver knows a *problem*: any object with ``energy(u)``, ``gradient(u)`` and
``hessian(u)`` (scipy sparse, symmetric), and optionally ``energy_and_gradient(u)``, both
in one pass (the line search then tries its full step with it: a full step is usually
taken, and its gradient is needed next), and ``diagnose(u)``, a sentence on what in a state
may prevent an equilibrium (or None), appended to the error of a failed solve. It minimises
:math:`\Pi(u)`:

1. factorise :math:`K = \nabla^2\Pi`: Cholesky where it is positive definite, else a
   symmetric-indefinite LDLᵀ (:class:`~femshell.solvers.linear.Refactorizer`); either gives
   the inertia (number of negative eigenvalues, Sylvester's law);
2. if :math:`K` is not positive definite, the Newton step is still taken when it is
   a descent direction that the line search accepts; otherwise K is shifted,
   :math:`K + \tau D` (:math:`D` = the positive diagonal of K), with τ growing until
   it is positive definite (a Levenberg–Marquardt step: always a descent direction);
3. backtracking line search on :math:`\Pi` (Armijo), falling back to the residual
   norm when energy differences reach round-off;
4. converged when :math:`\|\nabla\Pi\| \le` ``rtol`` × scale + ``atol``, or below
   ε √n max|K_ij| max|u|, what float64 resolves at u (so a start that is already the
   equilibrium, with nothing to scale the tolerance, converges at once), or when the
   Newton step's predicted decrease of Π falls below float64 resolution of Π (the
   residual's round-off floor: nothing can be gained by iterating);
5. with ``stable=True`` a converged point (or one at the round-off floor) whose Hessian
   has negative eigenvalues is a saddle: step along the eigenvector of the most negative
   eigenvalue (the sign that lowers Π) and continue, so the result is a local minimum.

Refactorising only when it pays (``linear_solver="krylov"``; theory §2.6; the coupled loop's
default, ``TimeStepping.linear_solver``, and the continuation corrector's): a
step's system K d = −∇Π is solved by CG or GMRES preconditioned by the last factorisation held
(of an earlier iterate's Hessian, or of the previous solve's converged state), and K is
factorised afresh only when that does not serve: the Krylov solve does not converge within its
iteration budget, is no descent direction, the line search refuses its step, or the
step reduced the residual by less than half (:class:`~femshell.solvers.krylov.HeldFactor`).
The convergence test, and with it the stability check, always factorises the point's own
Hessian, so its inertia, and every ``stable`` result, is exact; a solve of k iterations started
from a held factorisation costs one factorisation instead of k + 1. ``linear_solver="direct"``
factorises every iterate's Hessian.

In a sequence of solves (time or load stepping) the caller keeps the factorisations
(``factorizers``): the held one then preconditions the next solve's first steps, and it can
also start each solve with quasi-Newton iterations on it (``quasi_newton``,
:func:`lagged_quasi_newton`), which do not even assemble a Hessian.

This module is the driver (:func:`minimize`) and the load stepping on it (:func:`follow_load`); the
parts are modules of their own, their public names importable from here too: the line search
(:mod:`~femshell.solvers.line_search`), the shift and the step off a saddle
(:mod:`~femshell.solvers.negative_curvature`), the quasi-Newton start
(:mod:`~femshell.solvers.quasi_newton`), the result and the error (:mod:`~femshell.solvers.newton_result`).

Example
-------
>>> import numpy as np, scipy.sparse as sp
>>> class Quartic:  # a double well in 2D: minima at (+-1, 0), saddle at 0
...     def energy(self, u): return (u[0]**2 - 1)**2 / 4 + u[1]**2 / 2
...     def gradient(self, u): return np.array([u[0]**3 - u[0], u[1]])
...     def hessian(self, u): return sp.csr_matrix(np.diag([3*u[0]**2 - 1, 1.0]))
>>> r = minimize(Quartic(), np.array([0.0, 0.3]), stable=True, log=None)
>>> bool(r.converged), bool(r.stable), float(abs(round(r.u[0], 6)))
(True, True, 1.0)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .._checks import finite, integer
from .krylov import HeldFactor
from .line_search import line_search
from .linear import LinearSolverError, Refactorizer
from .negative_curvature import ESCAPE_AMPLITUDES, escape_saddle, is_saddle, shift_to_positive
from .newton_result import NewtonError, NewtonResult, newton_result
from .quasi_newton import lagged_quasi_newton

__all__ = ["minimize", "follow_load", "secant_start", "check_unknowns", "NewtonError", "NewtonResult",
           "LINEAR_SOLVERS", "lagged_quasi_newton", "line_search", "shift_to_positive", "escape_saddle",
           "ESCAPE_AMPLITUDES"]


def minimize(problem, u0, *, rtol=1e-9, atol=0.0, max_iter=60, stable=False, residual_scale=None,
             backend="auto", max_step=None, factorizers=None, quasi_newton=0, stall=None,
             linear_solver="direct", log=print) -> NewtonResult:
    """Find an equilibrium (a local minimum if ``stable``) of ``problem`` from ``u0``.

    Parameters
    ----------
    rtol, atol : convergence when |grad| <= rtol * scale + atol, with scale =
        ``residual_scale`` or, by default, the norm of the applied load λ ∂W/∂u where
        the problem has loads, else |grad(u0)|.
    stable : escape saddle points along negative-curvature directions.
    max_step : largest allowed max-norm of a step (None: unlimited).
    factorizers : (Refactorizer, Refactorizer), optional
        For the Hessian and for its shifted versions. A caller that solves many times on
        one mesh (a time or load stepping) passes the same pair to every call, so the
        symbolic analysis of the sparsity pattern is done once; by default each call makes
        its own (with ``backend``) and frees them at the end.
    quasi_newton : int
        With ``factorizers`` whose last factorisation (of an earlier, positive definite
        Hessian K₀, a Cholesky: the previous solve's stability check) is still held, first up to this many
        quasi-Newton iterations on it (:func:`lagged_quasi_newton`): no Hessian is assembled
        or factorised until they converge or stall; then Newton goes on as usual, so a
        converged point is still checked (and, if ``stable``, made stable) by a fresh
        factorisation of its own Hessian. 0: plain Newton.
    stall : int, optional
        Give up (:class:`NewtonError`, "stalled") when over the last ``stall`` iterations the
        residual has not halved and the energy has fallen by less than 1e-7 of its size: Newton
        is then creeping with shifted steps about a near-singular Hessian and would use all of
        ``max_iter``. A caller that can cut its step (a time stepping) gains from stopping
        early; None: never.
    linear_solver : "krylov" | "direct"
        "krylov": solve each step's system by CG or GMRES preconditioned by the last factorisation
        held, refactorising only when that does not serve (module docstring); "direct": factorise
        every iterate's Hessian (the default here: in an isolated solve there is no factorisation to
        hold, and on the post-buckling paths of the ``extremes`` validation case the Krylov steps' other
        round-off led to other states). Both test convergence, and stability, on a fresh factorisation.
    """
    u = check_unknowns(problem, u0)
    max_iter, quasi_newton = integer("max_iter", max_iter, 0), integer("quasi_newton", quasi_newton, 0)
    if stall not in (None, False):
        stall = integer("stall", stall, 1, "an integer >= 1 (or None/False: never)")
    if factorizers is not None and not (isinstance(factorizers, (tuple, list)) and len(factorizers) == 2
                                        and all(isinstance(f, Refactorizer) for f in factorizers)):
        raise ValueError(f"factorizers must be a pair of Refactorizer (or None), got {factorizers!r}")
    rtol, atol = finite("rtol", rtol, 0), finite("atol", atol, 0)
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {linear_solver!r}")
    if residual_scale is not None:
        residual_scale = finite("residual_scale", residual_scale, 0)
    if max_step is not None and not (isinstance(max_step, (int, float, np.integer, np.floating))
                                     and not isinstance(max_step, bool) and max_step > 0):
        raise ValueError(f"max_step must be a number > 0 (or None), got {max_step!r}")
    times = {"assembly": 0.0, "factorize": 0.0, "solve": 0.0, "line_search": 0.0}
    t0 = time.perf_counter()
    e = problem.energy(u)
    g = problem.gradient(u)
    times["assembly"] += time.perf_counter() - t0
    if not (np.isfinite(e) and np.all(np.isfinite(g))):
        raise NewtonError("energy or gradient is not finite at the starting point")
    residual_scale, scale_from_start = _residual_scale(problem, u, g, residual_scale)
    own = factorizers is None
    if own:
        factorizers = (Refactorizer(backend), Refactorizer(backend))
    counted = sum(sum(f.counts.values()) for f in factorizers)
    try:
        qn_iterations = 0
        held = factorizers[0].last
        for f in factorizers:
            f.restart()
        krylov = HeldFactor(held if held is not None and held._valid else None) if linear_solver == "krylov" else None
        if quasi_newton and held is not None and held.kind == "spd" and held.n == len(u):
            u, e, g, qn_iterations = lagged_quasi_newton(problem, u, e, g, held, rtol * residual_scale + atol,
                                                         quasi_newton, times, max_step=max_step)
            if log:
                log(f"    quasi-Newton on the held factorisation: {qn_iterations} iterations, |r| {np.linalg.norm(g):.3e}")
        try:
            out = _minimize(problem, u, e, g, times, residual_scale, rtol, atol, max_iter, stable, max_step,
                            factorizers, log, stall, scale_from_start, krylov)
        except NewtonError as exc:
            _explain(problem, exc)
            if exc.result is not None:
                _count(exc.result, factorizers, counted, krylov)
            raise
        out.quasi_newton_iterations = qn_iterations
        return _count(out, factorizers, counted, krylov)
    finally:
        if own:
            for f in factorizers:
                f.free()


#: values of ``minimize(linear_solver=...)``
LINEAR_SOLVERS = ("krylov", "direct")


def _count(result, factorizers, before, krylov):
    """Put the solve's numbers of factorisations and Krylov solves into ``result``."""
    result.factorizations = sum(sum(f.counts.values()) for f in factorizers) - before
    if krylov is not None:
        result.krylov_solves, result.krylov_iterations = krylov.solves, krylov.iterations
    return result


def _residual_scale(problem, u, g, residual_scale):
    """(scale of the convergence test, whether it is the start's imbalance).

    The given ``residual_scale``; else the applied load |λ ∂W/∂u| (at λ = 0 the unit load: the
    start may already be the equilibrium, to round-off); without loads (growth), |∇Π(u0)|.
    """
    scale_from_start = False
    if residual_scale is None:
        if hasattr(problem, "load_gradient") and getattr(problem, "loads", None):
            with np.errstate(over="ignore"):     # an overflowing load is named below
                residual_scale = (abs(problem.load_factor) or 1.0) * np.linalg.norm(problem.load_gradient(u))
        else:
            residual_scale = np.linalg.norm(g)
            scale_from_start = True
    if not np.isfinite(residual_scale):
        raise NewtonError(f"the residual scale is not finite ({residual_scale}): the applied load overflows float64")
    return max(residual_scale, 1e-300), scale_from_start


def _explain(problem, exc: NewtonError):
    """Append the problem's own reading of the last iterate to the error, where it has one: an optional
    ``problem.diagnose(u)`` returning a sentence or None (a shell names over-folded edges, say). The
    solver knows energies, not physics, so only the problem can say why its state has no equilibrium."""
    diagnose = getattr(problem, "diagnose", None)
    if callable(diagnose) and exc.result is not None:
        why = diagnose(exc.result.u)
        if why:
            exc.args = (f"{exc.args[0]}. At the last iterate {why}",) + exc.args[1:]


def check_unknowns(problem, u0) -> np.ndarray:
    """``u0`` as a float vector (a copy), or a ValueError when it is not one of the problem's
    ``n_free`` unknowns (where the problem says how many)."""
    u = np.array(u0, dtype=float)
    n_free = getattr(problem, "n_free", None)
    if u.ndim != 1 or (n_free is not None and len(u) != n_free):
        raise ValueError(f"u0 must be a vector of the problem's {n_free if n_free is not None else ''} free unknowns, "
                         f"got shape {u.shape}")
    return u


def _stalled(history, window) -> bool:
    """Over the last ``window`` iterations the residual has not halved and the energy hardly fell."""
    if not window or len(history) <= window:
        return False
    _, e_old, r_old = history[-1 - window]
    _, e_new, r_new = history[-1]
    return r_new > 0.5 * r_old and e_old - e_new < 1e-7 * max(abs(e_old), abs(e_new), 1e-300)


def _minimize(problem, u, e, g, times, residual_scale, rtol, atol, max_iter, stable, max_step, factorizers, log,
              stall=None, scale_from_start=False, krylov=None):
    hessian_factors, shifted_factors = factorizers
    history = []
    n_neg = None
    res = np.linalg.norm(g)
    escapes = 0
    e_start = e

    def leave_saddle(it, res):
        """Step off the saddle at u along its most negative mode (at most 20 times per solve)."""
        nonlocal u, e, g, escapes, residual_scale
        if escapes >= 20:
            raise NewtonError("could not leave the saddle after 20 escapes", newton_result(
                u, False, it, e, res, residual_scale, n_neg, history, times))
        escapes += 1
        t = time.perf_counter()
        u, e, g = escape_saddle(problem, u, e, K, log)
        times["line_search"] += time.perf_counter() - t
        if scale_from_start:    # a start at an exact equilibrium (a saddle) had an imbalance of round-off
            residual_scale = max(residual_scale, float(np.linalg.norm(g)))

    roundoff_floor = False
    escaped = False          # the last thing done was a step off a saddle: its residual is not yet tested
    tau = None
    it = 0
    try:
        for it in range(max_iter + 1):
            escaped = False
            res = np.linalg.norm(g)
            history.append((it, e, res))
            if log:
                log(f"    newton {it:3d}  energy {e:.12g}  |r| {res:.3e}")
            t = time.perf_counter()
            K = problem.hessian(u)
            times["assembly"] += time.perf_counter() - t
            floor = _roundoff_residual(K, u)
            done = res <= max(rtol * residual_scale + atol, floor)
            # the held factorisation preconditions the step; the converged point's own one checks it
            d = _krylov_direction(krylov, K, g, times) if krylov is not None and not done and it < max_iter else None
            fac, n_neg = (None, None) if d is not None else _fresh_factorization(K, hessian_factors, times, krylov)
            if done:
                if not stable or n_neg == 0:
                    break
                if not is_saddle(K, n_neg):        # the inertia unknown: the smallest eigenvalue is >= 0
                    n_neg = 0
                    break
                leave_saddle(it, res)
                escaped = True
                continue
            if it == max_iter:
                break
            if _stalled(history, stall):
                raise NewtonError(f"Newton stalled at iteration {it}: |r| = {res:.3e} did not halve and the energy "
                                  f"fell by less than 1e-7 of it over the last {stall} iterations", newton_result(
                                      u, False, it, e, res, residual_scale, n_neg, history, times), stalled=True)
            if d is not None:
                un, en, gn, ok = _step(problem, u, e, g, d, max_step, times)
                if ok:
                    krylov.judge(res, np.linalg.norm(gn))
                    u, e, g = un, en, gn
                    continue
                # the line search refused the Krylov step: Newton's own step on a fresh factorisation
                fac, n_neg = _fresh_factorization(K, hessian_factors, times, krylov)
            u, e, g, ok, d, tau = _descend(problem, u, e, g, K, fac, n_neg, tau, shifted_factors, max_step, times,
                                           log)
            if not ok:
                # no step lowers Π when the predicted decrease is below what float64 can resolve
                # in Π: the residual has reached its round-off floor, which is as converged as it gets
                if abs(g @ d) <= 1e-13 * max(abs(e), abs(e_start), 1e-300):
                    if stable and is_saddle(K, n_neg):
                        # a saddle at the round-off floor (an equilibrium by symmetry, as a flat plate
                        # grown past buckling): leave it as a converged saddle is left
                        leave_saddle(it, res)
                        escaped = True
                        continue
                    if stable and n_neg is None:
                        n_neg = 0                 # the smallest eigenvalue is >= 0
                    roundoff_floor = True
                    if log:
                        log(f"    newton: stopped at the round-off floor, |r| = {res:.3e}")
                    break
                raise NewtonError(f"line search failed at iteration {it} (|r| = {res:.3e})", newton_result(
                    u, False, it, e, res, residual_scale, n_neg, history, times))
    except NewtonError as exc:
        if exc.result is None:         # the factorisation, the shift or the escape failed: still say where
            exc.result = newton_result(u, False, it, e, float(np.linalg.norm(g)), residual_scale, n_neg, history, times)
        raise
    if escaped:
        # the last iteration stepped off a saddle: the new point is no equilibrium yet
        res = float(np.linalg.norm(g))
        out = newton_result(u, False, it, e, res, residual_scale, None, history, times)
        raise NewtonError(f"Newton left a saddle on its last iteration (max_iter = {max_iter}): |r| = {res:.3e} "
                          "at the new point; allow more iterations", out)
    converged = roundoff_floor or res <= max(rtol * residual_scale + atol, floor)
    out = newton_result(u, converged, it, e, res, residual_scale, n_neg, history, times)
    if not converged:
        raise NewtonError(f"Newton did not converge in {max_iter} iterations: |r| = {res:.3e} > "
                          f"{rtol * residual_scale + atol:.3e}", out)
    return out


def _descend(problem, u, e, g, K, fac, n_neg, tau, shifted_factors, max_step, times, log):
    """One step from u: Newton's d = −K⁻¹g with a line search, or the shifted (K + τD)⁻¹ step.

    With negative curvature the plain Newton step is still taken when it lowers Π (a compressed
    flat sheet relaxes in plane this way); otherwise K is shifted, τ starting near the last
    shift that worked. Returns (u, e, g, ok, d, tau); ``ok`` False: no step lowered Π.
    """
    t = time.perf_counter()
    d = -fac.solve(g)
    times["solve"] += time.perf_counter() - t
    ok = False
    if not n_neg or g @ d < -1e-8 * np.linalg.norm(g) * np.linalg.norm(d):
        u, e, g, ok = _step(problem, u, e, g, d, max_step, times)
    if not ok and n_neg:
        shifted, tau = shift_to_positive(K, shifted_factors, times, max(1e-8, tau / 16) if tau else 1e-6)
        if log:
            log(f"    newton: Hessian has {n_neg} negative eigenvalues; shifted by {tau:.2e}")
        d = -shifted.solve(g)
        u, e, g, ok = _step(problem, u, e, g, d, max_step, times)
    return u, e, g, ok, d, tau


def _roundoff_residual(K, u) -> float:
    """|r| that float64 cannot resolve at u: ε √n max|K_ij| max|u|.

    A start that is already the equilibrium (no load, no growth) has a residual of
    round-off only; with no load to scale the tolerance, rtol |r(u0)| is below what
    any iterate can reach, and without this floor Newton failed there.
    """
    data = K.data if sp.issparse(K) else np.asarray(K)
    return float(np.finfo(float).eps * math.sqrt(len(u)) * np.abs(data).max(initial=0.0) * np.abs(u).max()) \
        if len(u) else 0.0


def _krylov_direction(krylov, K, g, times):
    """The Krylov solution d of K d = −g on the held factorisation if it is a descent direction, else None."""
    t = time.perf_counter()
    d = krylov.solve(K, -g)
    times["krylov"] = times.get("krylov", 0.0) + time.perf_counter() - t
    if d is None or not g @ d < -1e-8 * np.linalg.norm(g) * np.linalg.norm(d):
        return None
    return d


def _fresh_factorization(K, factorizer, times, krylov):
    """(factorisation of K, its number of negative eigenvalues or None); held for the Krylov steps."""
    t = time.perf_counter()
    fac = _factorize(K, factorizer)
    times["factorize"] += time.perf_counter() - t
    if krylov is not None:
        krylov.hold(fac)
    return fac, (fac.inertia[1] if fac.inertia is not None else None)


def _factorize(K, factorizer):
    """Factorisation of K with its inertia (Cholesky if positive definite, else LDLᵀ: Refactorizer)."""
    try:
        return factorizer(K)
    except LinearSolverError as exc:
        raise NewtonError(f"the Hessian could not be factorised: {exc}") from exc


def _step(problem, u, e, g, d, max_step, times):
    t = time.perf_counter()
    out = line_search(problem, u, e, g, d, max_step=max_step)
    times["line_search"] += time.perf_counter() - t
    return out


def secant_start(problem, u, current, trial, previous):
    """The start of the solve at parameter ``trial``: u extrapolated along the secant from the converged
    state before, ``previous = (parameter, state)``, to the last one, u at ``current``; u itself without a
    previous state at another parameter, or where the energy is not finite at the extrapolation. Along a
    smooth path this lands near the next equilibrium, sparing the damped iterations a large-rotation
    step needs from the last state."""
    if previous is None or previous[0] == current:
        return u
    start = u + (trial - current) / (current - previous[0]) * (u - previous[1])
    return start if np.isfinite(problem.energy(start)) else u


def follow_load(problem, u0, factors, *, start=0.0, max_cuts=8, callback=None, log=print, previous=None,
                on_solve=None, **newton_options):
    """Equilibria along increasing load factors, each warm-started from the previous one.

    ``u0`` is the equilibrium at load factor ``start`` (0: the unloaded state).
    ``problem.load_factor`` is set to each value of ``factors`` in turn. A step
    whose Newton solve fails is cut in half and retried from the last converged
    state; a converged step doubles the step again (never beyond the requested
    factor), so a stretch of the path that needs small steps is crossed in small
    steps, and larger ones follow it. The step is never cut below ``2**-max_cuts``
    of the interval to the requested factor: a failure at that size raises a
    :class:`NewtonError` that carries the last converged state. The work is bounded:
    per requested factor at most ``2**max_cuts`` converged and
    ``2**max_cuts + max_cuts + 1`` failed Newton solves.
    ``problem.accept(u)`` (if present) is called after each converged step;
    ``callback(factor, result)`` after each requested factor.
    ``previous`` = (load factor, state): the converged state before ``u0``, for the secant
    predictor of the first step (a path followed in several calls). ``on_solve(iterations,
    converged)`` after every Newton solve, failed ones included.
    Returns the list of :class:`NewtonResult` at the requested factors.
    """
    u = np.array(u0, float)
    current = float(start)
    factors = [float(f) for f in factors]
    if not all(np.isfinite(factors + [current])):
        raise ValueError(f"load factors and start must be finite, got start {start} and factors {factors}")
    # 2**-50 of an interval is about float resolution: more cuts would only repeat the same factor
    max_cuts = integer("max_cuts", max_cuts, 0, "an integer in [0, 50]", hi=50)
    # (load factor, state) of the converged step before, for the secant predictor
    path = _LoadPath(u, current, None if previous is None else (float(previous[0]), np.asarray(previous[1], float)))
    own = newton_options.get("factorizers") is None
    if own:     # one pair for all the steps: the pattern's symbolic analysis is done once, not per solve
        backend = newton_options.get("backend", "auto")
        newton_options = {**newton_options, "factorizers": (Refactorizer(backend), Refactorizer(backend))}
    try:
        out = []
        for target in factors:
            res = _advance_load(problem, path, target, max_cuts, newton_options, log, on_solve)
            if log:
                log(f"  load factor {target:.6g}: {res.summary()}")
            if callback:
                callback(target, res)
            out.append(res)
        return out
    finally:
        if own:
            for f in newton_options["factorizers"]:
                f.free()


@dataclass
class _LoadPath:
    """Where :func:`follow_load` is: the last converged state u at load factor ``current``."""

    u: np.ndarray
    current: float
    previous: tuple | None = None      # (load factor, state) of the converged step before, for the secant
    last: NewtonResult | None = None   # the last converged result, handed back with a failure

    def last_converged(self, problem):
        """The last converged result; before any, u0 described as it is."""
        if self.last is not None:
            return self.last
        g = problem.gradient(self.u)
        return newton_result(self.u, False, 0, problem.energy(self.u), float(np.linalg.norm(g)), 1.0, None, [], {})


def _advance_load(problem, path, target, max_cuts, newton_options, log, on_solve):
    """Converged steps from ``path.current`` to ``target``, halving a failed step, doubling after success."""
    interval = target - path.current
    min_step = abs(interval) * 0.5 ** max_cuts * (1 - 1e-12)
    step = interval
    while True:
        current = path.current
        trial = current + step
        if step != 0 and trial == current:
            problem.load_factor = current
            raise NewtonError(f"load step from {current:.17g} towards {target:.6g} is below the float resolution "
                              f"there (step {step:.3g}): it cannot be cut further", path.last_converged(problem))
        problem.load_factor = trial
        start = secant_start(problem, path.u, current, trial, path.previous)
        try:
            res = minimize(problem, start, log=None, **newton_options)
        except BaseException as exc:
            if not isinstance(exc, NewtonError):
                problem.load_factor = current     # an error of another kind: leave the last converged factor
                raise
            if on_solve:
                on_solve(getattr(exc.result, "iterations", 0) or 0, False)
            if abs(step) * 0.5 <= min_step:    # (<=: a step of 0, to a factor equal to the start, ends too)
                problem.load_factor = current
                raise NewtonError(f"load step from {current:.6g} to {trial:.6g} failed, and the step cannot be "
                                  f"cut further (max_cuts = {max_cuts}: not below 2**-{max_cuts} of the interval "
                                  f"to {target:.6g}; last converged load factor {current:.6g}): {exc}",
                                  path.last_converged(problem))
            step *= 0.5
            if log:
                log(f"  load factor {trial:.6g}: Newton failed, step cut to {step:.3g}")
            continue
        if on_solve:
            on_solve(res.iterations, True)
        path.previous = (current, path.u)
        path.u, path.current, path.last = res.u, trial, res
        if hasattr(problem, "accept"):
            problem.accept(path.u)
        if abs(path.current - target) <= 1e-14 * max(1.0, abs(target)):
            return res
        # a converged step earns one doubling back, not the whole remaining interval at once: a
        # stretch that needs many small steps would otherwise pay a failed solve for every one
        remaining = target - path.current
        step = remaining if abs(2.0 * step) >= abs(remaining) else 2.0 * step
