r"""The staggered mechanochemical time loop (theory §1.4, §2.8): growth -> stable equilibrium -> H -> chemistry.

One step of length dt from an accepted state (t, c, u), u a stable equilibrium of the shell
grown by s(c):

1. chemistry on the current surface x(u): c⁺ = step(c, dt, P(H(u))) (or P extrapolated to the
   step's midpoint, ``TimeStepping.source_rule``), :class:`~femshell.chemistry.ReactionDiffusion`;
2. Δs = max over elements |s(c⁺) − s(c)|; Δs > ``ds_max`` (``error_ds_max`` under error control)
   cuts the step (before any mechanics);
3. growth: the rest state ā = s² ā0, b̄ = s² b̄0, h̄(s) of s(c⁺)
   (:class:`~femshell.growth.GrowthRestState`);
4. mechanics: the stable equilibrium from u or its secant prediction
   (:class:`~femshell.coupled.equilibrium.Equilibria`); a Newton failure cuts dt, a fold snaps;
5. the step's local error, the stretch's change from the source's change over it
   (:func:`~femshell.coupled.stepping.held_source_error`); above ``error_tol`` it is cut
   (``TimeStepping.step_control = "error"`` only);
6. accept: t += dt, (c, u) ← (c⁺, u⁺), H of the new shape; dt_next = dt · min(grow,
   safety · ds_max/Δs) (``step_control = "stretch"``) or from the error (a PI controller,
   :func:`~femshell.coupled.stepping.error_step_factor`), bounded by the staggering's
   stability (:mod:`femshell.coupled.stepping`).

H = ½ tr(a⁻¹ b) − k_ref per element, averaged to the vertices (theory §2.7). After ``max_cuts``
cuts (or dt < ``dt_min``) a :class:`~femshell.coupled.records.CoupledError` says why, and the
loop keeps the last accepted state. Nothing is accepted with a non-finite value. The loop
writes nothing: it reports through :class:`~femshell.coupled.observers.LoopObservers` and
``run``'s callbacks. Units: lengths in cell sizes, time in 1/β, E = 1.

Example
-------
>>> from femshell.mesh.generators import sphere                                  # doctest: +SKIP
>>> from femshell.coupled import MechanochemicalModel, TimeStepping, InitialSpot, CoupledLoop
>>> mesh = sphere(30.0, n_vertices=2500)                                          # doctest: +SKIP
>>> params = MechanochemicalModel(h0=2.0, radius=30.0, c_star=0.1, D=0.0)
>>> loop = CoupledLoop(mesh, params, TimeStepping(t_final=20.0), c0=InitialSpot())  # doctest: +SKIP
>>> result = loop.run(callback=lambda rec, lp: print(rec.t, rec.max_c))             # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import partial

import numpy as np

from .._checks import finite as _finite, integer as _integer
from ..chemistry import ReactionDiffusion
from ..growth import GrowthRestState
from ..shell import ShellModel
from ..shell.model import FOLD_LIMIT_DEG
from ..solvers.linear import LinearSolverError, Refactorizer, factorize
from ..solvers.newton import NewtonError
from .equilibrium import Equilibria, rejected
from .initial import InitialSpot
from .observers import LoopObservers
from .parameters import MechanochemicalModel
from .records import CoupledError, RunResult, StepRecord
from .state import Checkpointing
from .stepping import (TimeStepping, error_step_factor, feedback_gain, feedback_step_limit, held_source_error,
                       stable_extrapolation)

__all__ = ["CoupledLoop"]


@dataclass
class _Attempt:
    """One try at a step: accepted (``ok``) or why not, with what it computed."""

    ok: bool
    reason: str = ""
    ds: float = 0.0
    snap_tried: bool = False
    c: np.ndarray | None = None
    s: np.ndarray | None = None
    result: object = None
    snapped: bool = False
    held: np.ndarray | None = None
    curvature: tuple | None = None
    error: float = float("nan")


class CoupledLoop(Equilibria, Checkpointing):
    """The staggered quasi-static mechanochemical loop (module docstring).

    Parameters
    ----------
    mesh : SurfaceMesh
        The rest shape (a sphere of radius R for the paper's cases).
    params : MechanochemicalModel
    stepping : TimeStepping, optional
    c0 : InitialSpot, (n,) array or None
        Initial concentration (None: zero everywhere).
    boundary_conditions : sequence
        Shell boundary conditions (none for a closed sphere: the six rigid-body
        components are pinned by ShellModel's default).
    equilibrate : bool
        Find the stable equilibrium of the initial growth s(c0) now (ramped in steps of
        ``stepping.ramp_ds``). :meth:`from_state_dict` skips it.
    log : callable or None
        ``log(str)`` for one line per step and every cut (default ``observers.log``).
    observers : LoopObservers, optional
        The caller's callbacks: region counts, the pattern's clock, the commit's interrupt guard.

    Attributes
    ----------
    t, dt, step, c, u : the current state (dt is the proposal for the next step).
    s : (m,) element stretches of c; H, H_vertex : H per element / vertex (1/length).
    shell : ShellModel; growth : GrowthRestState; chemistry : ReactionDiffusion.
    """

    def __init__(self, mesh, params: MechanochemicalModel, stepping: TimeStepping | None = None, c0=None,
                 boundary_conditions=(), equilibrate: bool = True, log=None, observers: LoopObservers | None = None):
        if not isinstance(params, MechanochemicalModel):
            raise TypeError(f"params must be a MechanochemicalModel, got {type(params).__name__}")
        if stepping is not None and not isinstance(stepping, TimeStepping):
            raise TypeError(f"stepping must be a TimeStepping, got {type(stepping).__name__}")
        if not all(hasattr(mesh, k) for k in ("points", "triangles", "topology")):
            raise TypeError(f"mesh must be a SurfaceMesh (see femshell.mesh), got {type(mesh).__name__}")
        self.mesh = mesh
        self.params = params
        self.stepping = stepping or TimeStepping()
        self.observers = observers or LoopObservers()
        if self.stepping.stationary_pattern_time > 0 and not self.observers.follows_patterns:
            raise ValueError("stationary_pattern_time > 0 needs the observers measure_pattern and same_pattern "
                             "(e.g. femshell.analysis.find_spots and same_pattern)")
        self.log = log if log is not None else self.observers.log
        n = mesh.n_vertices
        # the rest state at s = 1 (the drawn shape) is replaced by GrowthRestState right away
        self.shell = ShellModel(mesh, params.material, params.h0, boundary_conditions)
        self.growth = GrowthRestState(self.shell, params.h0, params.thickness_mode, params.rest_curvature,
                                      params.natural_curvature, params.stretch)
        self.chemistry = ReactionDiffusion(mesh.triangles, n, D=params.D, beta=params.beta, points=mesh.points,
                                           factorize=partial(factorize, kind="spd"))
        self._length = float(params.h0)
        self._atol = self._residual_floor()
        # one pair for the whole run: the Hessian's sparsity pattern is analysed once
        self._factorizers = (Refactorizer(self.stepping.newton_backend), Refactorizer(self.stepping.newton_backend))

        if c0 is None:
            c = np.zeros(n)
        elif isinstance(c0, InitialSpot):
            c = c0.field(np.asarray(mesh.points, float), params)
        else:
            c = np.array(c0, dtype=float)
            if c.shape != (n,):
                raise ValueError(f"c0 must have one value per vertex, shape ({n},), got {c.shape}")
        if not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ValueError("initial concentration c0 must be finite and >= 0")
        self.t = 0.0
        self.dt = float(self.stepping.dt_initial)
        self.step = 0
        self.c = c
        self.u = self.shell.initial_unknowns()
        self.stationary_count = 0
        self._pattern_anchor = None       # (t, PatternMeasures, c, points) since which the pattern is the same
        self._pattern_now = None          # (step, PatternMeasures) of the last step followed
        self.n_rejected = 0
        self.n_snaps = 0
        self.newton_total = 0
        self.last_newton_iterations = 0
        self._last_ds = 0.0
        self._u_prev, self._h_prev = None, 0.0
        self._source_prev = None        # P at the previous accepted state (source_rule = "extrapolated")
        self._extrapolate = 0.0         # the fraction of its source's extrapolation the next step takes
        self._last_rates = (float("nan"), float("nan"))
        self._last_gain = float("nan")
        self._last_stable = None
        self._last_error = float("nan")     # the last accepted step's stretch error (StepRecord.step_error)
        self._error_ratio = None            # ... over error_tol, for the PI controller (step_control = "error")
        self.s = self.growth.stretch(self.c)
        if equilibrate:
            self._equilibrate_initial()
        else:
            self.growth.apply(self.s)
        self._update_curvature()
        if equilibrate:
            self._say_non_elliptic()
            self._say_over_folded()

    # ---- helpers ------------------------------------------------------------------------------
    def _say(self, msg):
        if self.log:
            self.log(msg)

    def _say_non_elliptic(self):
        """Log the elements of the current state that are compressed past SVK's limit, if any."""
        if self.non_elliptic:
            limit = self.shell.material.svk_ellipticity_stretch
            self._say(f"  step {self.step} t = {self.t:.6g}: {self.non_elliptic} elements are compressed past the "
                      f"St Venant–Kirchhoff membrane's ellipticity limit (equibiaxial stretch {limit:.3g}): "
                      "a triangle there can collapse on the mesh scale, and Newton then stalls; "
                      "the neo-Hookean membrane (scene: material.law = \"neo-hookean\"; API: membrane_law) "
                      "stays elliptic")

    def _say_over_folded(self):
        """Log the edges of the current state folded more sharply than one element carries, if any."""
        if self.over_folded:
            self._say(f"  step {self.step} t = {self.t:.6g}: {self.over_folded} mid-edge normals are turned by "
                      f"{FOLD_LIMIT_DEG:g}° or more from their faces: the shell folds there more sharply than one "
                      "element carries, and the shape there is the mesh's; a finer mesh resolves it")

    def _steep_switch_hint(self, ds) -> str:
        """Why no dt meets ds_max: s(c) jumps where c crosses c* (a large b makes Λ(c) a step)."""
        p = self.params
        return (f"; the stretch still jumps by {ds:.3g} in a step of dt_min: where c crosses c* = {p.c_star:g}, "
                f"s(c) rises by {p.s_max - 1:.3g} over a change of c of about 8/b = {8 / p.b:.3g} (b = {p.b:g}), "
                "less than any step resolves; a smaller b (scene: growth.b) or a larger ds_max (solver.ds_max) "
                "lets the loop step across the switch")

    def _non_elliptic_hint(self) -> str:
        """Why a step may fail that the user can act on: St Venant–Kirchhoff past its limit."""
        if not self.non_elliptic:
            return ""
        return (f"; {self.non_elliptic} elements of the last accepted state are compressed past the St Venant–"
                "Kirchhoff ellipticity limit, where triangles can collapse: the neo-Hookean membrane "
                "(scene: material.law = \"neo-hookean\"; API: membrane_law) stays elliptic")

    def _update_curvature(self, curvature=None):
        """H, energy and the diagnostics of the current state (``curvature``: its (H, H_vertex) if known)."""
        self.H, self.H_vertex = self.growth.mean_curvature(self.u) if curvature is None else curvature
        self.energy = float(self.shell.strain_energy(self.u))
        self.non_elliptic = len(self.shell.non_elliptic_elements(self.u))
        self.over_folded = len(self.shell.over_folded_edges(self.u))

    @property
    def points(self) -> np.ndarray:
        """Current vertex positions (n, 3)."""
        return self.shell.positions(self.u)

    @property
    def source(self) -> np.ndarray:
        """P(H) at the vertices for the current shape (concentration/time)."""
        return self.params.source(self.H_vertex)

    # ---- one step -----------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """t reached t_final or the pattern is stationary."""
        return self._at_end() or self.is_stationary

    def _at_end(self) -> bool:
        tf = self.stepping.t_final
        return self.t >= tf - 1e-12 * max(1.0, abs(tf))

    @property
    def is_stationary(self) -> bool:
        """c and the shape stopped changing (the rate test), or the pattern did (``stationary_pattern_time``)."""
        return self.stationary_reason != ""

    @property
    def stationary_reason(self) -> str:
        """Why the run is stationary: a sentence, or "" while it is not."""
        st = self.stepping
        if st.stationary_rate_c > 0 and st.stationary_rate_x > 0 and self.stationary_count >= st.stationary_steps:
            return (f"rates of c and shape {self._last_rates[0]:.2g}, {self._last_rates[1]:.2g} per unit "
                    f"time for {self.stationary_count} steps")
        held = self.pattern_unchanged_for
        if st.stationary_pattern_time > 0 and held >= st.stationary_pattern_time * (1 - 1e-12):
            m = self._pattern_anchor[1]
            return (f"the pattern ({m.n_spots} region(s), {100 * m.fraction_patterned:.3g} % of the area) has stayed "
                    f"the same within {st.stationary_pattern_tol:g} since t = {self._pattern_anchor[0]:.6g}")
        return ""

    @property
    def pattern_unchanged_for(self) -> float:
        """Time over which the pattern has stayed the same (0 unless ``stationary_pattern_time`` > 0)."""
        return 0.0 if self._pattern_anchor is None else self.t - self._pattern_anchor[0]

    def _follow_pattern(self):
        """Restart the pattern's clock where it is no longer the one it was (``stationary_pattern_time``)."""
        obs = self.observers
        pts = self.points
        now = obs.measure_pattern(pts, self.mesh.triangles, self.c, self.params.c_star)
        self._pattern_now = (self.step, now)
        anchor = self._pattern_anchor
        if anchor is None or not obs.same_pattern(anchor[1], now, self.stepping.stationary_pattern_tol):
            self._pattern_anchor = (self.t, now, self.c.copy(), pts)

    def advance(self) -> StepRecord:
        """Make one accepted step (cutting dt as needed); returns its record.

        Raises :class:`CoupledError` (the state is unchanged) when the step cannot be
        made within ``max_cuts`` cuts or dt would fall below ``dt_min``.
        """
        st = self.stepping
        wall0 = time.perf_counter()
        if self._at_end():
            raise CoupledError(f"t = {self.t:.6g} has reached t_final = {st.t_final:.6g}")
        points = self.points
        source = self.params.source(self.H_vertex)
        dt = float(self.dt)
        cuts = 0
        attempt = _Attempt(ok=False)
        try:
            while True:
                remaining = st.t_final - self.t
                last = dt >= remaining * (1 - 1e-12)
                h = remaining if last else dt
                if h < st.dt_min * (1 - 1e-12) and not last:
                    raise CoupledError(self._too_short(h, attempt))
                attempt = self._attempt(h, source, points, attempt.snap_tried)
                if attempt.ok:
                    break
                cuts += 1
                self.n_rejected += 1
                if cuts > st.max_cuts:
                    raise CoupledError(f"step {self.step + 1} at t = {self.t:.6g} failed after {st.max_cuts} cuts "
                                       f"(last dt = {h:.3g}: {attempt.reason}); the last accepted state is kept"
                                       + self._non_elliptic_hint())
                factor = 0.5
                if math.isfinite(attempt.ds) and attempt.ds > st.stretch_limit:
                    factor = min(0.5, max(0.1, st.safety * st.stretch_limit / attempt.ds))
                elif attempt.error > st.error_tol:
                    factor = min(0.5, error_step_factor(attempt.error / st.error_tol, None, st.safety, 1.0))
                dt = h * factor
                self._say(f"  step {self.step + 1} t = {self.t:.6g}: cut to dt = {dt:.3g} ({attempt.reason})")
        except BaseException:
            self.growth.apply(self.s)       # an error or Ctrl-C mid-attempt: back to the accepted rest state
            raise

        # accept: all at once (an interrupt here would leave half a step: c new, rest state old)
        with self.observers.commit():
            before = self.state_dict()
            try:
                return self._accept(attempt, h, last, cuts, points, source, wall0)
            except BaseException:
                self.load_state_dict(before)      # an error while committing: not half a step
                raise

    def _too_short(self, h: float, attempt: _Attempt) -> str:
        """The message of a step cut below dt_min (``attempt``: the last rejected one)."""
        reason = attempt.reason
        return (f"step {self.step + 1} at t = {self.t:.6g}: dt = {h:.3g} fell below dt_min = "
                f"{self.stepping.dt_min:.3g} ({reason}); the last accepted state is kept"
                + (self._steep_switch_hint(attempt.ds) if reason.startswith("max |Δs|") else "")
                + self._non_elliptic_hint())

    def _attempt(self, h: float, source, points, snap_tried: bool) -> _Attempt:
        """Try a step of length h: chemistry, the Δs test, growth and the equilibrium.

        A rejected attempt leaves the accepted rest state in place; at most one snap per step
        (``snap_tried``): where it does not settle, the cuts that follow are plain.
        """
        st = self.stepping
        held = self._held_source(source, h)
        try:
            c_new = self.chemistry.step(self.c, h, source=held, points=points)
        except (ValueError, FloatingPointError, ArithmeticError, LinearSolverError) as exc:
            raise CoupledError(f"step {self.step + 1} at t = {self.t:.6g}: the chemistry step failed: "
                               f"{exc}") from exc
        if not np.all(np.isfinite(c_new)):
            return _Attempt(False, "non-finite concentration", float("inf"), snap_tried)
        s_new = self.growth.stretch(c_new)
        ds = float(np.max(np.abs(s_new - self.s))) if len(s_new) else 0.0
        if not ds <= st.stretch_limit * (1 + 1e-12):
            name = "ds_max" if st.step_control == "stretch" else "error_ds_max"
            return _Attempt(False, f"max |Δs| = {ds:.3g} > {name} = {st.stretch_limit:.3g}", ds, snap_tried)
        self.growth.apply(s_new)
        start = self.u
        if st.predictor and self._u_prev is not None and self._h_prev > 0:
            start = self._predict(self.u, self._u_prev, h / self._h_prev)
        res, snapped, reason = None, False, ""
        try:
            res = self._newton(start)
        except NewtonError as exc:
            if not snap_tried and self._snap_applies(exc, ds):
                snap_tried = True
                res = self._snap(exc.result, ds)
            snapped = res is not None
            if not snapped:
                reason = f"Newton failed: {exc}"
        reason = reason or rejected(res) or ""
        curvature, error = None, float("nan")
        if not reason and not snapped and st.step_control == "error":   # a snap is no time error: dt cannot avoid it
            curvature = self.growth.mean_curvature(res.u)
            error = self._stretch_error(c_new, s_new, held, source, curvature[1], h)
            if not error <= st.error_tol:
                reason = f"local error of the stretch {error:.3g} > error_tol = {st.error_tol:.3g}"
        if reason:
            self.growth.apply(self.s)           # back to the accepted rest state
            return _Attempt(False, reason, ds, snap_tried, error=error)
        return _Attempt(True, "", ds, snap_tried, c_new, s_new, res, snapped, held, curvature, error)

    def _stretch_error(self, c_new, s_new, held, source, H_vertex_new, h: float) -> float:
        """The step's local error in the stretch: max over elements |s(c⁺ + e_c) − s(c⁺)|, e_c the
        change of c that the source's change over the step would have made (:func:`held_source_error`)."""
        e_c = held_source_error(held, source, self.params.source(H_vertex_new), h, self.params.beta)
        s_2 = self.growth.stretch(np.maximum(c_new + e_c, 0.0))
        return float(np.max(np.abs(s_2 - s_new))) if len(s_new) else 0.0

    def _held_source(self, source, h: float):
        """The source the chemistry holds over a step of length h from the current state.

        ``source_rule = "extrapolated"``: P at the step's midpoint extrapolated from the last two
        accepted states (Adams–Bashforth 2), P_n + θ (h / 2h_prev)(P_n − P_{n−1}) with θ the
        fraction of the extrapolation that is stable (:func:`stable_extrapolation`, decided with
        the next dt), kept within P's range [0, w Hs]. Otherwise, and where there is no
        previous state (the first step, after a snap), P_n itself.
        """
        if not (self._extrapolate > 0 and self._source_prev is not None and self._h_prev > 0):
            return source
        mid = source + (0.5 * self._extrapolate * h / self._h_prev) * (source - self._source_prev)
        return np.clip(mid, 0.0, self.params.w * self.params.Hs)

    def _accept(self, attempt: _Attempt, h, last, cuts, points, source, wall0) -> StepRecord:
        """Commit the step of length h to the attempt's c, stretch and equilibrium; returns its record."""
        st = self.stepping
        c_new, s_new, res, ds, snapped = attempt.c, attempt.s, attempt.result, attempt.ds, attempt.snapped
        x_old = points
        c_old = self.c
        self.c = c_new
        # a snap is no trend: the secant through it would predict a second jump
        self._u_prev, self._h_prev = (None, 0.0) if snapped else (self.u, h)
        self._source_prev = None if snapped else source
        self.n_snaps += int(snapped)
        self.u = res.u
        self.s = s_new
        self.t = st.t_final if last else self.t + h
        self.step += 1
        self.last_newton_iterations = res.iterations
        self.newton_total += res.iterations
        self._last_stable = res.stable
        self._last_ds = ds
        was_elliptic, was_resolved = self.non_elliptic == 0, self.over_folded == 0
        if attempt.curvature is None:
            self._update_curvature()
        else:                                   # measured for the error control: not twice
            self._update_curvature(attempt.curvature)
        self._last_error = (float("nan") if snapped else attempt.error if attempt.curvature is not None
                            else self._stretch_error(c_new, s_new, attempt.held, source, self.H_vertex, h))
        if was_elliptic:
            self._say_non_elliptic()
        if was_resolved:
            self._say_over_folded()
        self._follow_stationarity(c_old, x_old, h)
        self.dt = self._next_dt(h, ds, cuts, c_old, source)
        rec = self.record(dt=h, cuts=cuts, wall_s=time.perf_counter() - wall0, snapped=snapped)
        self._say(f"step {rec.step:5d} t {rec.t:10.5g} dt {rec.dt:9.3g} newton {rec.newton_iterations:2d} "
                  f"(+{res.quasi_newton_iterations} quasi) "
                  f"cuts {cuts} max c {rec.max_c:.4g} max H {rec.max_H:.4g} ds {ds:.3g} "
                  f"spots {rec.n_spots} {rec.wall_s:.2f}s{' snapped' if snapped else ''}")
        return rec

    def _follow_stationarity(self, c_old, x_old, h: float):
        """Rates of change of c and of the shape over the accepted step of length h, and the stationarity counters.

        rate_c = max|c − c_old| / (h c_scale), rate_x = max|x − x_old| / (h h0) with c_scale the
        largest |c| (at least 1 % of c_max) and h0 the shell's thickness (the length of the model).
        """
        st, p = self.stepping, self.params
        c_scale = max(float(np.max(np.abs(self.c))) if len(self.c) else 0.0,
                      1e-2 * p.c_max if math.isfinite(p.c_max) else 0.0, 1e-300)
        rate_c = float(np.max(np.abs(self.c - c_old))) / (h * c_scale) if len(self.c) else 0.0
        rate_x = float(np.max(np.abs(self.points - x_old))) / (h * self._length)
        self._last_rates = (rate_c, rate_x)
        if rate_c < st.stationary_rate_c and rate_x < st.stationary_rate_x:
            self.stationary_count += 1
        else:
            self.stationary_count = 0
        if st.stationary_pattern_time > 0:
            self._follow_pattern()

    def _next_dt(self, h: float, ds: float, cuts: int, c_old, source_old) -> float:
        """dt of the next step after an accepted one of length h that changed the stretch by ds.

        Grows while Δs (``step_control = "stretch"``) or the local error (``"error"``, which keeps
        Δs within ``error_ds_max``) stays small, never beyond a step that had to be cut, and stays
        within the stability limit of the staggering (module docstring).
        """
        st, p = self.stepping, self.params
        limit = st.stretch_limit
        grow = st.grow if ds <= 0 else min(st.grow, st.safety * limit / ds)
        if st.step_control == "error":
            ratio = self._last_error / st.error_tol
            if math.isfinite(ratio):
                grow = min(grow, error_step_factor(ratio, self._error_ratio, st.safety, st.grow))
            self._error_ratio = ratio if math.isfinite(ratio) else None
        nxt = h * max(grow, 0.1)
        if cuts:
            nxt = min(nxt, h)
        self._last_gain = feedback_gain(self.c - c_old, p.source(self.H_vertex) - source_old)
        if st.feedback_amplification > 0:
            nxt = min(nxt, feedback_step_limit(self._last_gain, p.beta, st.feedback_amplification,
                                               exponential=True))
        nxt = float(min(st.dt_max, max(st.dt_min, nxt)))
        self._extrapolate = (stable_extrapolation(self._last_gain, p.beta, st.feedback_amplification or 1.0, nxt, h)
                             if st.source_rule == "extrapolated" else 0.0)
        return nxt

    def record(self, dt: float = 0.0, cuts: int = 0, wall_s: float = 0.0, snapped: bool = False) -> StepRecord:
        """The :class:`StepRecord` of the current state."""
        pts = self.points
        if self._pattern_now is not None and self._pattern_now[0] == self.step:
            n_spots = self._pattern_now[1].n_spots          # found by _follow_pattern for this step
        elif self.observers.count_regions is not None:
            n_spots = self.observers.count_regions(pts, self.mesh.triangles, self.c, self.params.c_star)
        else:
            n_spots = -1                                    # not counted
        return StepRecord(step=self.step, t=float(self.t), dt=float(dt),
                          newton_iterations=int(self.last_newton_iterations),
                          cuts=int(cuts), max_c=float(self.c.max()) if len(self.c) else 0.0,
                          max_H=float(self.H_vertex.max()), min_H=float(self.H_vertex.min()),
                          max_s=float(self.s.max()), ds=float(self._last_ds), energy=float(self.energy),
                          n_spots=int(n_spots), rate_c=float(self._last_rates[0]),
                          rate_x=float(self._last_rates[1]), stable=self._last_stable, wall_s=float(wall_s),
                          snapped=bool(snapped), feedback_gain=float(self._last_gain),
                          non_elliptic=int(self.non_elliptic), over_folded=int(self.over_folded),
                          step_error=float(self._last_error))

    # ---- loops --------------------------------------------------------------------------------
    def iterate(self, max_steps: int | None = None):
        """Generator: one :class:`StepRecord` per accepted step until t_final or stationarity.

        Raises :class:`CoupledError` when a step fails (the loop keeps the last accepted state).
        """
        k = 0
        while not self.done and (max_steps is None or k < max_steps):
            rec = self.advance()
            k += 1
            yield rec

    def run(self, callback=None, *, checkpoint=None, checkpoint_every: int = 10, max_steps: int | None = None,
            wall_time: float | None = None, keep_records: bool = False) -> RunResult:
        """Step until t_final, stationarity, ``max_steps`` (default ``stepping.max_steps``) or ``wall_time`` (s).

        ``callback(record, loop)`` after each accepted step (write frames there);
        ``checkpoint(state_dict, record)`` every ``checkpoint_every`` accepted steps and
        once at the end, whatever the reason, including a failed step (then with the
        last accepted state). A failure does not raise: the result has status "failed"
        and the message. Neither does Ctrl-C (KeyboardInterrupt): the run ends with status
        "interrupted" on the last accepted state, checkpointed. Any other exception (from the
        callback, or an unexpected solver error) is raised after that checkpoint.
        ``keep_records`` keeps all step records in the result.
        """
        checkpoint_every = _integer("checkpoint_every", checkpoint_every, 1)
        if wall_time is not None:
            _finite("wall_time", wall_time, 0.0)
        max_steps = self.stepping.max_steps if max_steps is None else _integer("max_steps", max_steps, 0)
        t0 = time.perf_counter()
        k = 0
        last = None
        records = []
        status, message = None, ""
        dirty = False
        try:
            while True:
                stop = self._stop_reason(k, max_steps, wall_time, t0)
                if stop is not None:
                    status, message = stop
                    break
                with self.observers.step_scope():   # an interrupt held by the commit waits for callback and checkpoint
                    last = self.advance()
                    k += 1
                    dirty = True
                    if keep_records:
                        records.append(last)
                    if callback is not None:
                        callback(last, self)
                    if checkpoint is not None and k % int(checkpoint_every) == 0:
                        checkpoint(self.state_dict(), last)
                        dirty = False
        except CoupledError as exc:
            status, message = "failed", str(exc)
            self._say(f"coupled loop stopped: {exc}")
        except KeyboardInterrupt:
            # Ctrl-C (or SIGTERM, where the caller maps it to KeyboardInterrupt) mid-step: the
            # accepted state is intact, but a trial step may have changed the rest state
            self.growth.apply(self.s)
            status, message = "interrupted", f"interrupted at t = {self.t:.6g} after {k} step(s) of this run"
            self._say(f"coupled loop {message}")
        except BaseException as exc:
            # not a failed step but an error (a callback's, a solver's): raised, after the
            # accepted steps are checkpointed (unless the checkpoint is what failed)
            if checkpoint is not None and dirty:
                self._checkpoint_after_error(checkpoint, last, k, exc)
            raise
        if checkpoint is not None and dirty:
            checkpoint(self.state_dict(), last if last is not None else self.record())
        return RunResult(status, message, k, float(self.t), time.perf_counter() - t0, last, records)

    def _stop_reason(self, k: int, max_steps, wall_time, t0: float):
        """(status, message) where ``run`` stops before another step, else None."""
        if self._at_end():
            return "t_final", f"reached t_final = {self.stepping.t_final:g}"
        if self.is_stationary:
            return "stationary", f"stationary at t = {self.t:.6g}: {self.stationary_reason}"
        if max_steps is not None and k >= max_steps:
            return "max_steps", f"stopped after {k} steps (max_steps)"
        if wall_time is not None and time.perf_counter() - t0 >= wall_time:
            return "wall_time", f"stopped after {time.perf_counter() - t0:.1f} s (wall_time)"
        return None

    def _checkpoint_after_error(self, checkpoint, last, k: int, exc: BaseException):
        """Checkpoint the accepted steps before ``exc`` is raised; a failing checkpoint is noted on it."""
        try:
            checkpoint(self.state_dict(), last)
        except Exception as ck:
            self._say(f"coupled loop: the checkpoint after the error failed too: {ck}")
            if hasattr(exc, "add_note"):                # Python >= 3.11
                exc.add_note(f"the checkpoint of the last {k} step(s) was not written: {ck}")

