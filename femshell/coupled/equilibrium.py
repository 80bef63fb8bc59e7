r"""The mechanics of the coupled loop: the stable equilibrium of the grown shell (theory §2.6, §2.8).

Newton with ``stable=True`` (a local minimum, never a saddle) warm started from the last shape or
its secant prediction; past a fold of the quasi-static path (Newton out of iterations on a tiny
growth increment) the minimisation goes on and the shell snaps; the initial growth s(c0) is
ramped up from s = 1. A mixin of :class:`~femshell.coupled.loop.CoupledLoop`, which owns the state.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..solvers.newton import NewtonError, minimize
from .records import CoupledError

__all__ = ["Equilibria", "rejected", "strain_force_unit"]


def strain_force_unit(shell, growth, params) -> float:
    """|∇Π| of a uniform unit strain of the rest shape (by a 1e-3 difference), the scale of the shell's
    forces; E h0 √(area) if that is not a positive number. Leaves the rest state at s = 1."""
    u0 = shell.initial_unknowns()
    m = len(growth.a0)
    growth.apply(np.ones(m))
    g1 = shell.gradient(u0)
    growth.apply(np.full(m, 1.001))
    g2 = shell.gradient(u0)
    growth.apply(np.ones(m))
    unit = float(np.linalg.norm(g2 - g1)) / 1e-3
    if not (math.isfinite(unit) and unit > 0):
        unit = params.E * params.h0 * math.sqrt(float(np.sum(shell.rest.area)))
    return unit


def rejected(res) -> str | None:
    """Why an equilibrium from Newton cannot be accepted (non-finite, or a saddle), or None."""
    if not (np.all(np.isfinite(res.u)) and math.isfinite(res.energy)):
        return "Newton returned a non-finite state"
    if res.stable is False:     # minimize reports a saddle it could not leave; never accept one
        return f"the equilibrium is a saddle ({res.n_negative} negative eigenvalues)"
    return None


class Equilibria:
    """Stable equilibria of the loop's shell (``self.shell``, ``self.growth``, ``self.stepping``)."""

    def _residual_floor(self) -> float:
        """atol of Newton: newton_atol_strain × :func:`strain_force_unit`."""
        return self.stepping.newton_atol_strain * strain_force_unit(self.shell, self.growth, self.params)

    def _newton(self, u_start, max_iter=None, residual_scale=None, stall=True):
        st = self.stepping
        return minimize(self.shell, u_start, stable=True, rtol=st.newton_rtol, atol=self._atol,
                        max_iter=int(max_iter or st.newton_max_iter), residual_scale=residual_scale,
                        factorizers=self._factorizers, quasi_newton=st.quasi_newton, linear_solver=st.linear_solver,
                        stall=(st.newton_stall or None) if stall else None, log=None)

    def _snap_applies(self, failed: NewtonError, ds: float) -> bool:
        """Newton ran out of iterations or stalled (not a failed line search) at Δs ≤ snap_ds, snaps enabled."""
        st = self.stepping
        last = failed.result
        return not (st.snap_max_iter == 0 or ds > st.snap_ds or last is None
                    or (last.iterations < st.newton_max_iter and not failed.stalled)
                    or not np.all(np.isfinite(last.u)))

    def _snap(self, last, ds: float):
        """The stable equilibrium past a fold (``TimeStepping.snap_ds``), or None if it does not settle.

        ``last`` is the failed Newton's last iterate (:class:`NewtonResult`), of lower energy than
        the old shape; the minimisation goes on from there with the residual scale of the original
        start, so the tolerance is the one the step would have had.
        """
        st = self.stepping
        self._say(f"  step {self.step + 1} t = {self.t:.6g}: no equilibrium near the old shape at Δs = {ds:.3g} "
                  f"(a fold): minimising on for up to {st.snap_max_iter} iterations")
        try:
            res = self._newton(last.u, max_iter=st.snap_max_iter, residual_scale=last.residual_scale, stall=False)
        except NewtonError as exc:
            self._say(f"  step {self.step + 1}: the snap did not settle: {exc}")
            return None
        return replace(res, iterations=last.iterations + res.iterations)

    def _predict(self, u, u_prev, ratio):
        """Secant predictor u + ratio (u − u_prev) for the current rest state, if it lowers the energy.

        A grown rest state leaves the previous shape compressed; a compressed shell is
        near (or past) buckling, where Newton from the old shape struggles. The secant
        step moves most of the way along the growth path first.
        """
        if u_prev is None or not (ratio > 0 and math.isfinite(ratio)):
            return u
        guess = u + min(ratio, 2.0) * (u - u_prev)
        try:
            e_guess = self.shell.energy(guess)
        except (ValueError, FloatingPointError):
            return u
        return guess if (math.isfinite(e_guess) and e_guess < self.shell.energy(u)) else u

    def _equilibrate_initial(self):
        """Stable equilibrium for s(c0), the growth ramped up from s = 1 in increments ≤ ramp_ds."""
        st = self.stepping
        target = self.s
        ones = np.ones_like(target)
        span = float(np.max(np.abs(target - 1.0))) if len(target) else 0.0
        lam, dlam = 0.0, 1.0 if span <= st.ramp_ds else st.ramp_ds / span
        u = self.u
        u_prev, lam_prev = None, None
        iters = 0
        cuts = cuts_in_row = 0
        t_start = t_said = time.perf_counter()
        while True:
            trial = min(1.0, lam + dlam)
            s = ones + trial * (target - ones)
            self.growth.apply(s)
            start = u if u_prev is None else self._predict(u, u_prev, (trial - lam) / (lam - lam_prev))
            try:
                res = self._newton(start)
                why = rejected(res)
            except NewtonError as exc:
                why = exc
            if why is not None:
                cuts += 1
                cuts_in_row += 1
                if cuts_in_row > st.max_cuts or dlam < 1e-6:
                    self.growth.apply(ones + lam * (target - ones))
                    raise CoupledError(f"initial equilibrium: Newton failed at growth fraction {trial:.4g} "
                                       f"after {cuts_in_row} cuts of one ramp step ({why}); a smaller ramp_ds (now "
                                       f"{st.ramp_ds:g}) and a larger newton_max_iter (now {st.newton_max_iter}) "
                                       "help thin or strongly grown shells")
                dlam *= 0.5
                self._say(f"  initial equilibrium: Newton failed at fraction {trial:.4g}; ramp step cut to {dlam:.3g}")
                continue
            u_prev, lam_prev = u, lam
            u, lam = res.u, trial
            cuts_in_row = 0
            iters += res.iterations
            self._last_stable = res.stable
            if lam >= 1.0:
                break
            now = time.perf_counter()
            if now - t_said >= 10.0:       # a thin or strongly grown shell can take minutes here
                t_said = now
                self._say(f"initial equilibrium: growth fraction {lam:.3g} after {now - t_start:.0f} s "
                          f"({iters} Newton iterations, {cuts} cuts)")
            dlam = min(1.0 - lam, 1.5 * dlam)
        self.u = u
        self.last_newton_iterations = iters
        self.newton_total += iters
        self._say(f"initial equilibrium: {iters} Newton iterations, {cuts} cuts, max s {float(target.max()):.4g}")
