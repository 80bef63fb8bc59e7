"""The mechanochemical time loop of a scene (:class:`~femshell.coupled.CoupledLoop`), one frame per step."""

from __future__ import annotations

import math
import time

import numpy as np

from ..analysis import find_spots
from .base_runner import BaseRunner, StepFailure
from .build import coupled_parameters, initial_concentration, time_loop
from .frames import frame_fields, picture_field


# ----------------------------------------------------------------------------- time loop

class TimeRunner(BaseRunner):
    kind = "time"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        cap = self.scene.solver.max_steps      # steps of one invocation, like --max-steps
        if cap is not None and (self.max_steps is None or cap < self.max_steps):
            self.max_steps, self.max_steps_from = cap, "solver.max_steps"

    def _log(self, msg):
        if msg.startswith("initial equilibrium") or (self.verbose and not msg.startswith("step ")):
            self.p.say(f"  {msg.strip()}")

    def _seed_warning(self):
        """A seed narrower than the mesh resolves leaves c ≈ 0 at every vertex: say so (the run would
        report a 'decayed' pattern that is only the mesh's)."""
        params, _, _ = coupled_parameters(self.scene)
        try:
            c0 = initial_concentration(self.scene, self.mesh, params)
        except ValueError:
            return                      # the loop names it
        if c0 is None:
            return
        field = c0.field(np.asarray(self.mesh.points, float), params) if hasattr(c0, "field") else np.asarray(c0)
        ini = self.scene.initial
        amp = params.c_max if ini.amplitude is None else ini.amplitude
        width = params.h0 if ini.width is None else ini.width
        if math.isfinite(amp) and amp > 0 and field.max() < 0.5 * amp:
            pts, e = np.asarray(self.mesh.points, float), self.mesh.topology.edges
            edge = float(np.linalg.norm(pts[e[:, 1]] - pts[e[:, 0]], axis=1).mean())
            self.p.failure(f"warning: the initial spot (width {width:.3g}) is narrower than the mesh resolves "
                           f"(mean edge {edge:.3g}): its largest vertex value is {field.max() / amp:.2%} of its "
                           "amplitude; widen it (initial.width) or refine the mesh")

    def initialise(self):
        self._seed_warning()
        self.p.say("initial equilibrium of the grown spot (Newton, growth ramped) ...")
        t = time.perf_counter()
        from ..coupled import CoupledError      # deferred: jax
        try:
            self.loop_ = time_loop(self.scene, self.mesh, log=self._log)
        except CoupledError as exc:
            raise StepFailure(f"the initial equilibrium failed: {exc}") from None
        self.newton_total = self.loop_.newton_total
        self.p.say(f"  done in {time.perf_counter() - t:.1f} s")

    def restore(self, state, meta):
        self.loop_ = time_loop(self.scene, self.mesh, state=state, log=self._log)

    def advance(self):
        from ..coupled import CoupledError      # deferred: jax
        try:
            rec = self.loop_.advance()
        except CoupledError as exc:
            raise StepFailure(str(exc)) from None
        self.newton_total = self.loop_.newton_total
        tf = self.loop_.stepping.t_final
        text = (f"step {rec.step:5d}  t {rec.t:9.4g}/{tf:g}  dt {rec.dt:8.3g}  newton {rec.newton_iterations:2d}"
                f"{f' cuts {rec.cuts}' if rec.cuts else ''}  max c {rec.max_c:.3g}  max H {rec.max_H:.3g}  "
                f"spots {rec.n_spots}")
        return text, (rec.t / tf if tf > 0 else 1.0)

    def finished(self):
        return self.loop_.done

    def final_status(self):
        lp = self.loop_
        if lp.is_stationary and lp.t < lp.stepping.t_final:
            self.message = f"stationary at t = {lp.t:.6g} ({lp.stationary_reason})"
            return "stationary"
        self.message = f"reached t_final = {lp.stepping.t_final:g}"
        return "t_final"

    def series_time(self):
        return float(self.loop_.t)

    def resume_text(self):
        return f"t = {self.loop_.t:.6g}"

    def frame(self):
        lp = self.loop_
        pts, pd, cd = frame_fields(self.out.fields, model=lp.shell, u=lp.u, s=lp.s, H_vertex=lp.H_vertex,
                                   c=lp.c, contractility=lp.params.contractility)
        return lp.t, pts, pd, cd

    def state(self):
        return self.loop_.state_dict()

    def final_points(self):
        return self.loop_.points

    def final(self):
        lp = self.loop_
        pm = find_spots(lp.points, self.mesh.triangles, lp.c, lp.params.c_star)
        pattern = pm.as_dict()
        pattern["regions"] = pattern["regions"][:100]
        r = np.linalg.norm(lp.points - lp.points.mean(axis=0), axis=1)
        return {"t": lp.t, "max_c": float(lp.c.max()), "min_c": float(lp.c.min()), "max_H": float(lp.H_vertex.max()),
                "min_H": float(lp.H_vertex.min()), "energy": lp.energy, "max_stretch": float(lp.s.max()),
                "radius_min": float(r.min()), "radius_max": float(r.max()), "rejected_steps": lp.n_rejected,
                "snaps": lp.n_snaps, "non_elliptic_elements": int(lp.non_elliptic),
                "over_folded_edges": int(lp.over_folded),
                "stationary": bool(lp.is_stationary), "stationary_reason": lp.stationary_reason,
                "c_max_theory": lp.params.c_max, "pattern": pattern}

    def report_lines(self, fin):
        pat = fin["pattern"]
        extra = ""
        if pat["n_spots"]:
            # a spacing between spots needs two (one spot's is round-off of its share minus itself)
            spacing = f"{pat['spacing']:.3g}" if pat["n_spots"] > 1 and pat["spacing"] is not None else "–"
            extra = f", spot radius {pat['spot_radius']:.3g}, spacing {spacing}" if pat["spot_radius"] else ""
        lines = [f"t = {fin['t']:.6g}: max c {fin['max_c']:.3g}, max H {fin['max_H']:.3g}; pattern: {pat['n_spots']} "
                 f"region(s) with c > c* ({pat['kind']}, {pat['n_ridges']} ridges), {100 * pat['fraction_patterned']:.1f} % "
                 f"of the area{extra}"]
        if fin["non_elliptic_elements"]:
            lines.append(f"{fin['non_elliptic_elements']} elements are compressed past the St Venant–Kirchhoff "
                         "ellipticity limit: the shape there depends on the mesh (material.law = \"neo-hookean\" "
                         "stays elliptic)")
        if fin.get("over_folded_edges"):
            from ..shell.model import FOLD_LIMIT_DEG      # deferred: jax

            lines.append(f"{fin['over_folded_edges']} mid-edge normals are turned by {FOLD_LIMIT_DEG:g}° or more from "
                         "their faces: the shell folds there more sharply than one element carries (a finer mesh "
                         "resolves it)")
        return lines

    def pictures(self):
        from .. import viz      # deferred: pyvista, matplotlib

        lp = self.loop_
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        name, values = picture_field(self.out.picture_field, lp.points, lp.shell, lp.u, c=lp.c,
                                      H=lp.H_vertex, s=lp.s, contractility=lp.params.contractility)
        title = f"{self.scene.name}: t = {lp.t:.4g}"
        clim = (0.0, max(float(values.max()), 1e-12)) if name == "c" else None
        top = viz.top_view(lp.points, self.mesh.triangles, (name, values), d / "top.png", title=title,
                           cmap=self.out.cmap, clim=clim)
        side = viz.side_view(lp.points, self.mesh.triangles, d / "side.png", title=title, cmap=self.out.cmap)
        return [top, side]
