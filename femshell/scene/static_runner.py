"""Static load stepping: the load factor μ and the growth s = 1 + μ g ramped together from 0 to 1."""

from __future__ import annotations

import numpy as np

from .._interrupts import committing
from ..solvers.linear import Refactorizer
from ..solvers.newton import NewtonError, follow_load
from .base_runner import BaseRunner, StepFailure
from .build import shell_parts, stretch_field
from .frames import frame_fields, picture_field, side_picture


# ----------------------------------------------------------------------------- static load stepping

class LoadAndGrowth:
    """The shell model seen by :func:`~femshell.solvers.newton.follow_load`: setting its load factor μ
    also grows the shell to s = 1 + μ g (``set_factor``), and ``accept`` goes to ``on_accept``."""

    def __init__(self, model, set_factor, on_accept):
        self.model, self._set_factor, self.accept = model, set_factor, on_accept

    @property
    def load_factor(self):
        return self.model.load_factor

    @load_factor.setter
    def load_factor(self, mu):
        self._set_factor(mu)

    def __getattr__(self, name):
        return getattr(self.model, name)


class StaticRunner(BaseRunner):
    """Load factor μ and growth ramped together from 0 to 1 in ``steps`` increments: the equilibria along
    μ by :func:`~femshell.solvers.newton.follow_load` (cut on failure, secant predictor across steps)."""

    kind = "static"

    def initialise(self):
        self._setup()

    def _setup(self):
        self.parts = shell_parts(self.scene, self.mesh)
        so = self.scene.solver
        self.n_steps = so.steps
        self.mu = 0.0
        self.k = 0
        self.u = self.parts.model.initial_unknowns()
        self.prev = None
        self.last = None
        self._set(0.0)
        self.problem = LoadAndGrowth(self.parts.model, self._set, self._accept)
        # one pair for every load step: the pattern's symbolic analysis is done once per run, not per step
        factorizers = (Refactorizer(so.backend), Refactorizer(so.backend))
        self.newton = dict(rtol=so.newton_rtol or 1e-8, max_iter=so.newton_max_iter or 60,
                           backend=so.backend, stable=so.stable, factorizers=factorizers)

    def settle(self):
        self._set(self.mu)

    def release(self):
        for f in self.newton["factorizers"]:
            f.free()

    def _set(self, mu):
        gr = self.scene.growth
        self.parts.model.load_factor = mu
        if gr.law not in ("none", None):
            self.parts.apply(stretch_field(gr, self.mesh, strain=mu * gr.strain))

    def _edge_moments(self):
        return [(i, ld) for i, ld in enumerate(self.parts.loads) if hasattr(ld, "update_branch")]

    def restore(self, state, meta):
        self._setup()
        self.k = int(state["k"])
        self.mu = float(state["mu"])
        self.u = np.array(state["u"], dtype=float)
        if state["has_prev"]:
            self.prev = (float(state["prev_mu"]), np.array(state["prev_u"], dtype=float))
        for i, ld in self._edge_moments():
            ld._offset = np.array(state[f"load{i}_offset"], dtype=float)
            ld._ref = np.array(state[f"load{i}_ref"], dtype=float)
        self._set(self.mu)

    def state(self):
        st = {"k": self.k, "mu": self.mu, "u": self.u, "has_prev": self.prev is not None,
              "prev_mu": self.prev[0] if self.prev else 0.0,
              "prev_u": self.prev[1] if self.prev else np.zeros(0)}
        # path-dependent loads (edge moments) carry the rotation of their reference normals
        for i, ld in self._edge_moments():
            st[f"load{i}_offset"] = np.asarray(ld._offset, dtype=float)
            st[f"load{i}_ref"] = np.asarray(ld._ref, dtype=float)
        return st

    def finished(self):
        return self.k >= self.n_steps

    def _target_of(self, k):
        """The factor at the end of increment k."""
        return (k + 1) / self.n_steps

    def advance(self):
        target = self._target_of(self.k)
        self._target, self._solves = target, []
        try:
            res, = follow_load(self.problem, self.u, [target], start=self.mu, previous=self.prev,
                               max_cuts=self.scene.solver.max_cuts,
                               on_solve=lambda iterations, converged: self._solves.append((iterations, converged)),
                               log=self.p.say if self.verbose else None, **self.newton)
        except NewtonError as exc:
            raise StepFailure(f"increment to factor {target:.6g} failed: {exc}") from None
        self.last = res
        iters = sum(it for it, _ in self._solves)
        cuts = sum(1 for _, converged in self._solves if not converged)
        disp = np.linalg.norm(self.parts.model.positions(self.u) - self.mesh.points, axis=1).max()
        text = (f"step {self.k:4d}/{self.n_steps}  factor {self.mu:.4g}  newton {iters:2d}"
                f"{f' cuts {cuts}' if cuts else ''}  energy {res.energy:.6g}  max |u| {disp:.4g}"
                + ("" if res.stable is None else ("  stable" if res.stable else f"  UNSTABLE ({res.n_negative})")))
        return text, self.k / self.n_steps

    def _accept(self, u):
        """A converged increment of follow_load (``problem.accept``): the runner's state. The increment
        reaching the step's target completes the step: committed whole (an intermediate one is a state
        of its own, (u, mu) at the same k, from which a resume goes on to the target)."""
        trial = self.parts.model.load_factor
        done = abs(trial - self._target) <= 1e-14 * max(1.0, abs(self._target))
        with committing():
            self.prev, self.u, self.mu = (self.mu, self.u), u, self._target if done else trial
            self.parts.model.accept(u)
            if done:
                self.k += 1
                self.newton_total += sum(it for it, _ in self._solves)

    def series_time(self):
        return float(self.mu)

    def resume_text(self):
        return f"load factor {self.mu:.6g}"

    def final_status(self):
        self.message = f"load factor 1 reached in {self.n_steps} increments"
        return "done"

    def frame(self):
        model = self.parts.model
        _, Hv = self.parts.mean_curvature(self.u)
        pts, pd, cd = frame_fields(self.out.fields, model=model, u=self.u, s=self.parts.s, H_vertex=Hv)
        return self.mu, pts, pd, cd

    def final_points(self):
        return self.parts.model.positions(self.u)

    def final(self):
        model = self.parts.model
        x = model.positions(self.u)
        disp = x - self.mesh.points
        out = {"load_factor": self.mu, "energy": model.energy(self.u), "strain_energy": model.strain_energy(self.u),
               "max_displacement": float(np.linalg.norm(disp, axis=1).max()),
               "max_deflection_z": float(np.abs(disp[:, 2]).max()),
               "stable": None if self.last is None else self.last.stable}
        curves = {}
        for name, verts in self.mesh.topology.boundary_vertex_groups.items():
            curves[name] = [float(v) for v in disp[verts].mean(axis=0)]
        out["mean_displacement_of_curves"] = curves
        return out

    def report_lines(self, fin):
        return [f"load factor {fin['load_factor']:.6g}: strain energy {fin['strain_energy']:.6g}, max |u| "
                f"{fin['max_displacement']:.4g}, max |w| {fin['max_deflection_z']:.4g}"
                + ("" if fin["stable"] is None else (", stable" if fin["stable"] else ", UNSTABLE"))]

    def pictures(self):
        from .. import viz      # deferred: pyvista, matplotlib

        model = self.parts.model
        x = model.positions(self.u)
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        _, Hv = self.parts.mean_curvature(self.u)
        name, values = picture_field(self.out.picture_field, x, model, self.u, H=Hv, s=self.parts.s)
        title = f"{self.scene.name}: factor {self.mu:.4g}"
        top = viz.top_view(x, self.mesh.triangles, (name, values), d / "top.png", title=title, cmap=self.out.cmap)
        side = side_picture(viz, self.mesh, x, (name, values), d / "side.png", title, self.out.cmap)
        return [top, side]
