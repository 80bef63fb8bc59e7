"""Linear buckling of a scene's state (``[solver] kind = "linear-buckling"``; docs/guide/continuation.md).

The factor μ of the loads and the growth strain (ramped together as by kind = "static") is taken to
``at`` in ``steps`` increments (none when at = 0: the rest shape), then
:func:`~femshell.linear_buckling.shell_buckling_loads` gives the critical factors above it and their
modes. Outputs besides the static ones: ``buckling.csv`` (mode, critical factor, increment),
``modes.vtu`` (the state with each mode as a vertex vector field ``mode_i``), the factors in
summary.json, and a picture of the first mode (``pictures/mode_1.png``) when pictures are on.
"""

from __future__ import annotations

import numpy as np

from ..io.modes import write_buckling_csv, write_modes_vtu
from ..linear_buckling import ShellBuckling, shell_buckling_loads
from .base_runner import StepFailure
from .static_runner import StaticRunner

CSV, VTU = "buckling.csv", "modes.vtu"


class _Factor:
    """The runner's factor μ (loads and growth together) as a parametrized problem of its model."""

    parameter_scale = 1.0

    def __init__(self, runner):
        self.runner, self.model, self.parameter = runner, runner.parts.model, runner.mu

    def set_parameter(self, mu):
        self.parameter = float(mu)
        self.runner._set(self.parameter)


class LinearBucklingRunner(StaticRunner):
    """Static increments to the factor ``at``, then one step: the linear buckling of that state."""

    kind = "linear-buckling"

    def _setup(self):
        super()._setup()
        self.at = float(self.scene.solver.at)
        self.n_steps = self.scene.solver.steps if self.at > 0 else 0
        self.result = None

    def _target_of(self, k):
        return self.at * (k + 1) / self.n_steps

    def finished(self):
        return self.result is not None

    def advance(self):
        if self.k < self.n_steps:
            text, _ = super().advance()
            return text, self.k / (self.n_steps + 1)
        so = self.scene.solver
        try:
            self.result = shell_buckling_loads(_Factor(self), self.u, k=so.modes, target=so.target,
                                               backend=so.backend)
        except ValueError as exc:
            raise StepFailure(f"linear buckling at factor {self.mu:.6g}: {exc}") from None
        finally:
            self._set(self.mu)
        self._write_modes()
        res = self.result
        shown = ", ".join(f"{p:.6g}" for p in res.parameters[:4]) + (" ..." if len(res.parameters) > 4 else "")
        return f"linear buckling at factor {self.mu:.4g}: critical factors {shown or 'none'}", 1.0

    def _write_modes(self):
        res = self.result
        x = self.parts.model.positions(self.u)
        modes = [res.displacements(i) for i in range(len(res.parameters))]
        write_modes_vtu(self.rd.path / VTU, x, self.mesh.triangles, modes)
        write_buckling_csv(self.rd.path / CSV, res.parameters, res.increments)

    def state(self):
        st = super().state()
        res = self.result
        st["buckled"] = res is not None
        st["buckling_parameters"] = np.zeros(0) if res is None else res.parameters
        st["buckling_increments"] = np.zeros(0) if res is None else res.increments
        st["buckling_modes"] = np.zeros((0, 0)) if res is None else res.modes
        return st

    def restore(self, state, meta):
        super().restore(state, meta)
        if bool(state.get("buckled", False)):
            self.result = ShellBuckling(parameters=np.array(state["buckling_parameters"], dtype=float),
                                        increments=np.array(state["buckling_increments"], dtype=float),
                                        modes=np.array(state["buckling_modes"], dtype=float),
                                        model=self.parts.model, p0=self.mu)

    def final_status(self):
        n = len(self.result.parameters)
        self.message = (f"linear buckling at factor {self.mu:.6g}: " +
                        (f"first critical factor {self.result.parameters[0]:.6g} ({n} modes)" if n else
                         "no critical factor (the state does not buckle under more of its loads and growth)"))
        return "done"

    def final(self):
        out = super().final()
        if self.result is not None:
            res = self.result
            out.update(state_factor=self.mu, critical_factors=res.parameters.tolist(),
                       increments=res.increments.tolist(), modes_between_state_and_target=res.n_between)
        return out

    def extra_files(self):
        return {"buckling": CSV, "modes": VTU} if self.result is not None else {}

    def report_lines(self, fin):
        lines = super().report_lines(fin)
        if "critical_factors" in fin:
            lines.append("critical factors: " + (", ".join(f"{p:.6g}" for p in fin["critical_factors"]) or "none")
                         + f" ({CSV}, modes in {VTU})")
        return lines

    def pictures(self):
        from .. import viz      # deferred: pyvista, matplotlib

        pics = super().pictures()
        res = self.result
        if res is None or not len(res.parameters):
            return pics
        x = self.parts.model.positions(self.u)
        d = res.displacements(0)
        size = float(np.ptp(x, axis=0).max())
        title = f"{self.scene.name}: mode 1, critical factor {res.parameters[0]:.4g}"
        pics.append(viz.top_view(x + 0.05 * size * d, self.mesh.triangles, ("|mode 1|", np.linalg.norm(d, axis=1)),
                                 self.rd.path / "pictures" / "mode_1.png", title=title, cmap=self.out.cmap))
        return pics
