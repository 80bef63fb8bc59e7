r"""Checkpoint state of the coupled loop: everything it needs to continue bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import finite as _finite, integer as _integer
from ..solvers.linear import LinearSolverError
from .observers import LoopObservers
from .parameters import MechanochemicalModel
from .stepping import TimeStepping

__all__ = ["Checkpointing", "STATE_VERSION"]

#: 2: edge unknowns are tangents of the mid-edge normals' turning angles (1: the angles)
STATE_VERSION = 2


class Checkpointing:
    """:meth:`state_dict` and :meth:`load_state_dict` of :class:`~femshell.coupled.loop.CoupledLoop`."""

    def state_dict(self) -> dict:
        """Everything the loop needs to continue bit for bit: numbers and arrays only (no RNG).

        Keys: version, t, dt, step, c (n,), u (free unknowns), u_prev and h_prev (the
        previous accepted state and step, for the secant predictor and the extrapolated
        source; u_prev empty at step 0), extrapolate (the fraction θ of :func:`stable_extrapolation`
        the next step takes), error_ratio (the last step's local error over ``error_tol``, the
        memory of the error controller; −1: none), stationary_count, n_rejected, n_snaps, newton_total,
        last_newton_iterations, last_ds, n_vertices, n_free, held_cholesky (whether the last
        state's Hessian is held as a Cholesky factor for the quasi-Newton start and the Krylov steps of the next step:
        a resumed loop factorises it again, so that it continues exactly as the uninterrupted
        one), pattern_anchor_t, pattern_anchor_c and pattern_anchor_points (when and with which c
        and shape the pattern last changed, for ``stationary_pattern_time``; left out when it is
        not followed).
        The caller stores it (the scene runner with :func:`femshell.io.save_checkpoint`, parameters in its meta).
        """
        return {"version": STATE_VERSION, "t": float(self.t), "dt": float(self.dt), "step": int(self.step),
                "c": self.c.copy(), "u": np.asarray(self.u, float).copy(),
                "stationary_count": int(self.stationary_count), "n_rejected": int(self.n_rejected),
                "n_snaps": int(self.n_snaps),
                "newton_total": int(self.newton_total), "last_newton_iterations": int(self.last_newton_iterations),
                "last_ds": float(self._last_ds), "n_vertices": int(self.mesh.n_vertices),
                "u_prev": (np.zeros(0) if self._u_prev is None else np.asarray(self._u_prev, float).copy()),
                "h_prev": float(self._h_prev), "extrapolate": float(self._extrapolate),
                "error_ratio": -1.0 if self._error_ratio is None else float(self._error_ratio),
                "n_free": int(self.shell.n_free),
                "held_cholesky": int(self._held_cholesky()),
                **self._pattern_anchor_state()}

    def _pattern_anchor_state(self) -> dict:
        a = self._pattern_anchor
        if a is None:
            return {}
        return {"pattern_anchor_t": float(a[0]), "pattern_anchor_c": a[2].copy(), "pattern_anchor_points": a[3].copy()}

    def _held_cholesky(self) -> bool:
        held = self._factorizers[0].last
        return held is not None and held.kind == "spd"

    def _checked_state(self, state: dict):
        """c, u (as tangents), t, dt, step of ``state``, checked against the mesh and the shell."""
        need = ("t", "dt", "step", "c", "u")
        missing = [k for k in need if k not in state]
        if missing:
            raise ValueError(f"state dict lacks {', '.join(missing)}")
        version = int(state.get("version", STATE_VERSION))
        if version > STATE_VERSION:
            raise ValueError(f"state version {version} is newer than this femshell ({STATE_VERSION})")
        c = np.array(state["c"], dtype=float)
        u = np.array(state["u"], dtype=float)
        # version 1 stored edge angles: read as tangents they would be other normals
        from_angles = version < 2
        if c.shape != (self.mesh.n_vertices,):
            raise ValueError(f"state c has shape {c.shape}, the mesh has {self.mesh.n_vertices} vertices")
        if u.shape != (self.shell.n_free,):
            raise ValueError(f"state u has shape {u.shape}, the shell has {self.shell.n_free} free unknowns "
                             "(other mesh or boundary conditions?)")
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(u))):
            raise ValueError("state holds non-finite values")
        if from_angles:
            u = self.shell.from_edge_angles(u)
        if np.any(c < 0):
            raise ValueError(f"state c is negative at {int(np.count_nonzero(c < 0))} vertices (a concentration is >= 0)")
        t = _finite("state t", state["t"], 0.0)
        dt = _finite("state dt", state["dt"], 0.0, lo_open=True, text="(0, inf)")
        step = _integer("state step", state["step"], 0)
        return c, u, t, dt, step, from_angles

    def load_state_dict(self, state: dict):
        """Continue from :meth:`state_dict` output (same mesh, parameters and stepping)."""
        c, u, t, dt, step, from_angles = self._checked_state(state)
        st = self.stepping
        self.t = t
        # the stepping may differ from the run that wrote the state (a new dt_max): stay within it
        self.dt = min(st.dt_max, max(st.dt_min, dt))
        self.step = step
        self.c = c
        self.u = u
        self.stationary_count = int(state.get("stationary_count", 0))
        self.n_rejected = int(state.get("n_rejected", 0))
        self.n_snaps = int(state.get("n_snaps", 0))
        self.newton_total = int(state.get("newton_total", 0))
        self.last_newton_iterations = int(state.get("last_newton_iterations", 0))
        self._last_ds = float(state.get("last_ds", 0.0))
        u_prev = np.array(state.get("u_prev", np.zeros(0)), dtype=float)
        self._u_prev = u_prev if u_prev.shape == u.shape else None
        if from_angles and self._u_prev is not None:
            self._u_prev = self.shell.from_edge_angles(self._u_prev)
        self._h_prev = float(state.get("h_prev", 0.0)) if self._u_prev is not None else 0.0
        self._source_prev = None
        # θ as chosen for the stored dt (a dt clamped to a smaller dt_max only makes it more stable)
        self._extrapolate = (float(state.get("extrapolate", 0.0))
                             if self.stepping.source_rule == "extrapolated" else 0.0)
        if self._extrapolate > 0 and self._u_prev is not None:
            self._source_prev = self.params.source(self.growth.mean_curvature(self._u_prev)[1])
        self._last_rates = (float("nan"), float("nan"))
        self._last_gain = float("nan")
        self._last_stable = None
        self._last_error = float("nan")
        ratio = float(state.get("error_ratio", -1.0))
        self._error_ratio = ratio if math.isfinite(ratio) and ratio >= 0 else None
        self._restore_pattern_anchor(state)
        self.s = self.growth.stretch(self.c)
        self.growth.apply(self.s)
        self._update_curvature()
        for f in self._factorizers:
            f.free()
        if state.get("held_cholesky", 0) and (self.stepping.quasi_newton or self.stepping.linear_solver == "krylov"):
            try:
                self._factorizers[0](self.shell.hessian(self.u))
            except LinearSolverError:
                self._factorizers[0].free()     # the next step starts with plain Newton

    def _restore_pattern_anchor(self, state: dict):
        """The pattern's clock of ``state``, where ``stationary_pattern_time`` follows it."""
        c = self.c
        self._pattern_anchor = self._pattern_now = None
        t_a = float(state.get("pattern_anchor_t", float("nan")))
        c_a = np.array(state.get("pattern_anchor_c", np.zeros(0)), dtype=float)
        x_a = np.array(state.get("pattern_anchor_points", np.zeros((0, 3))), dtype=float)
        # restored only where it is followed: a stale clock would otherwise be checkpointed on
        if (self.stepping.stationary_pattern_time > 0 and math.isfinite(t_a) and c_a.shape == c.shape
                and x_a.shape == (len(c), 3)):
            measures = self.observers.measure_pattern(x_a, self.mesh.triangles, c_a, self.params.c_star)
            self._pattern_anchor = (t_a, measures, c_a, x_a)

    @classmethod
    def from_state_dict(cls, mesh, params: MechanochemicalModel, state: dict,
                        stepping: TimeStepping | None = None, boundary_conditions=(), log=None,
                        observers: LoopObservers | None = None) -> "CoupledLoop":
        """A loop that continues from ``state`` (no initial equilibrium is computed).

        The state holds no parameters: give the run's own ``params`` and ``stepping`` (None is
        ``TimeStepping()``, the defaults) to continue it bit for bit. Others are taken as given
        (continuing a state under new parameters is a use, not an error); the proposed dt is
        kept within the new stepping's [dt_min, dt_max]. Give the run's ``observers`` too (its pattern's
        clock is measured again from the state).
        """
        loop = cls(mesh, params, stepping, c0=None, boundary_conditions=boundary_conditions,
                   equilibrate=False, log=log, observers=observers)
        loop.load_state_dict(state)
        return loop
