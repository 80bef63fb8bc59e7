r"""What the coupled loop reports: one record per accepted step, the end of a run, its error.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

__all__ = ["StepRecord", "RunResult", "CoupledError"]


class CoupledError(RuntimeError):
    """The time loop could not make a step; the loop still holds the last accepted state."""


@dataclass
class StepRecord:
    """What happened in one accepted step (or the initial state, step 0).

    t, dt : time after the step and the step length (1/β). newton_iterations : full Newton
    iterations of the accepted solve (0 when its quasi-Newton iterations sufficed); cuts :
    rejected attempts before it. max_c : max c; max_H, min_H : extremes of the vertex H
    (1/length); max_s : largest stretch; ds : max
    |Δs| of the step; energy : elastic energy (E·length³); n_spots : N_sp (regions
    with c > c*); rate_c, rate_x : the stationarity measures (TimeStepping);
    stable : the Hessian at the equilibrium had no negative eigenvalue; wall_s :
    wall time of the step (s); snapped : the shell jumped to another equilibrium past a
    fold of the quasi-static path (``TimeStepping.snap_ds``); feedback_gain : the source's
    most negative gain over the step (:func:`feedback_gain`, 1/time), which bounds the next dt;
    non_elliptic : elements whose membrane law is not elliptic (St Venant–Kirchhoff compressed
    past its limit, :meth:`~femshell.shell.model.ShellModel.non_elliptic_elements`); over_folded :
    edges whose mid-edge normal is turned by 80° or more from its faces, a fold sharper than one
    element carries (:meth:`~femshell.shell.model.ShellModel.diagnose`); step_error : the step's
    local error estimate, the largest change of the stretch the source's change over the step would
    have made (``TimeStepping.step_control``; nan where not estimated).
    """

    step: int
    t: float
    dt: float
    newton_iterations: int
    cuts: int
    max_c: float
    max_H: float
    min_H: float
    max_s: float
    ds: float
    energy: float
    n_spots: int
    rate_c: float
    rate_x: float
    stable: bool | None
    wall_s: float
    snapped: bool = False
    feedback_gain: float = float("nan")
    non_elliptic: int = 0
    over_folded: int = 0
    step_error: float = float("nan")

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class RunResult:
    """How :meth:`CoupledLoop.run` ended.

    status : "t_final", "stationary", "max_steps", "wall_time", "interrupted" or "failed";
    message : human-readable reason; steps : accepted steps in this call; t : final
    time; wall_s : wall time of the call; last : the last :class:`StepRecord`.
    """

    status: str
    message: str
    steps: int
    t: float
    wall_s: float
    last: StepRecord | None = None
    records: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status != "failed"
