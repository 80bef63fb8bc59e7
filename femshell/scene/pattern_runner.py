"""Continuation of a scene's stationary pattern in a model parameter (``[solver] kind = "pattern-continuation"``).

The scene is a time scene (mesh, shell, growth, chemistry, initial condition, the time loop's controls)
plus the continuation's keys. The time loop runs first, one step per frame as kind = "time", until it
stops (stationary or t_final); then one last step finds the stationary state by Newton on the coupled
system (:func:`~femshell.coupled.stationary_state`, theory §2.9) and follows it in ``parameter``
(:func:`~femshell.coupled.continue_pattern`) to ``stop`` or ``continuation_steps`` points. Outputs besides
the time run's: the branch, its special points with their critical modes and the bifurcation diagrams
(:func:`~femshell.scene.pattern_output.write_pattern_branch`, in ``pattern/``). A resumed run repeats the
continuation (it is not checkpointed).
"""

from __future__ import annotations

import time

from .base_runner import StepFailure
from .build import coupled_parameters
from .pattern_output import pattern_measures, write_pattern_branch
from .time_runner import TimeRunner

PATTERN_DIR = "pattern"


class PatternContinuationRunner(TimeRunner):
    """The time loop to its end, then one step: Newton on the stationary system and its continuation."""

    kind = "pattern-continuation"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.branch = None
        self.files = {}
        self.cpu_s = 0.0

    def finished(self):
        return self.branch is not None

    def advance(self):
        if not self.loop_.done:
            return super().advance()
        from ..coupled import StationaryProblem, stationary_state     # deferred: jax
        from ..coupled.pattern_continuation import continue_pattern

        so = self.scene.solver
        lp = self.loop_
        cpu = time.process_time()
        problem = StationaryProblem.of_loop(lp)
        root = stationary_state(lp, problem=problem, tol=so.stationary_tol)
        if not root.converged:
            raise StepFailure(f"the time run's last state is not near a stationary state: {root.message}")
        params = problem.params
        try:
            self.branch = continue_pattern(
                problem, root.u, root.c, so.parameter, ds=so.continuation_ds, ds_max=so.continuation_ds_max,
                lam_stop=so.stop, max_steps=so.continuation_steps, n_modes=so.n_modes, stop_at=tuple(so.stop_at),
                direction=so.direction, label=so.parameter, record=lambda z: pattern_measures(problem, z),
                log=(lambda m: self.p.say(m)) if self.verbose else None)
        except ValueError as exc:
            raise StepFailure(f"pattern continuation in {so.parameter}: {exc}") from None
        finally:
            problem.set_params(params)          # the loop's own parameters and rest state back
            lp.growth.apply(lp.s)
        self.cpu_s = time.process_time() - cpu
        self.files = write_pattern_branch(self.branch, problem, self.rd.path / PATTERN_DIR, parameter=so.parameter,
                                          pictures=self.out.pictures)
        b = self.branch
        found = ", ".join(p.summary() for p in b.special_points) or "no special point"
        return (f"pattern continuation in {so.parameter}: {len(b.rows)} points, {b.status} ({b.message}); {found}",
                1.0)

    def final_status(self):
        if self.branch is None:
            return super().final_status()
        self.message = f"pattern continuation in {self.scene.solver.parameter}: {self.branch.status}"
        return "done"

    def final(self):
        out = super().final()
        b = self.branch
        if b is not None:
            out["pattern_continuation"] = {
                "parameter": self.scene.solver.parameter, "status": b.status, "message": b.message,
                "points": len(b.rows), "cpu_s": self.cpu_s,
                "special_points": [{"kind": p.kind, "parameter": p.parameter if p.located else None,
                                    "located": p.located, "bracket": list(p.bracket),
                                    "stability": p.info.get("stability")} for p in b.special_points]}
        return out

    def extra_files(self):
        if self.branch is None:
            return {}
        label = self.scene.solver.parameter
        return {"branch": f"{PATTERN_DIR}/{label}-branch.csv",
                "special_points": f"{PATTERN_DIR}/{label}-special-points.json"}

    def report_lines(self, fin):
        lines = super().report_lines(fin)
        pc = fin.get("pattern_continuation")
        if pc:
            lines.append(f"pattern continuation in {pc['parameter']}: {pc['points']} points, {pc['status']}"
                         f" ({pc['cpu_s']:.1f} s CPU); files in {PATTERN_DIR}/")
            for sp in pc["special_points"]:
                where = (f"at {pc['parameter']} = {sp['parameter']:.8g}" if sp["located"] else
                         f"between {sp['bracket'][0]:.8g} and {sp['bracket'][1]:.8g} (not located)")
                lines.append(f"  {sp['kind']} {where}")
        return lines
