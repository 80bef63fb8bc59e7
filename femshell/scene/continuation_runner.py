"""Pseudo-arclength continuation of a scene in its parameter (``solver.parameter``), folds and branch
points located and written, the branch of the first branch point followed on request."""

from __future__ import annotations

import csv
import io as _io
import math

import numpy as np

from .. import io as fio
from .._interrupts import committing, raise_if_interrupted
from ..analysis import azimuthal_power, count_wrinkles
from ..solvers import continuation as cont
from .base_runner import BaseRunner, StepFailure, clean
from .build import shell_parts, stretch_field
from .frames import frame_fields, picture_field, rigid_align, side_picture
from .schema import continuation_start


# ----------------------------------------------------------------------------- continuation

class ContinuationRunner(BaseRunner):
    """Pseudo-arclength continuation (femshell.solvers.continuation), one frame per accepted point."""

    kind = "continuation"

    def settle(self):
        self.problem.set_parameter(self.lam)

    def _setup(self):
        sc = self.scene
        so, gr = sc.solver, sc.growth
        self.parts = parts = shell_parts(sc, self.mesh)
        model = parts.model
        self.param = so.parameter
        h0 = sc.shell.thickness
        self.start = continuation_start(so.parameter, so.start, gr.strain, gr.inner_radius)
        if self.param == "loads.factor":
            if gr.law not in ("none", None):
                parts.apply(stretch_field(gr, self.mesh))
            model.load_factor = self.start
        else:
            model.load_factor = 1.0
        stop = so.stop
        scale = so.parameter_scale or (abs(stop - self.start) if stop is not None else 1.0) or 1.0
        length = so.length_scale or h0
        if self.param == "loads.factor":
            self.problem = cont.LoadParameter(model, length_scale=length, parameter_scale=scale)
        else:
            key = "strain" if self.param == "growth.strain" else "inner_radius"

            def rest_of(lam):
                try:
                    s = stretch_field(gr, self.mesh, **{key: lam})
                    rest = parts.rest_for(s)
                except ValueError as exc:   # the branch (or a difference step) left the parameter's range
                    raise ValueError(f"the continuation in {self.param} reached {lam:.9g}, outside its range: "
                                     f"{exc}; start and stop further inside") from None
                parts.s = s
                return rest
            self.problem = cont.GrowthParameter(model, rest_of, length_scale=length, parameter_scale=scale)
        self.problem.set_parameter(self.start)
        flat = self.mesh.is_flat()
        self.flat = flat
        self.free_body = not sc.boundary
        self.r2 = gr.inner_radius if gr.law == "inner_region" else None
        # the flat mesh's largest distance from the axis: the circles about R2 must stay inside it
        self.r_mesh = float(np.hypot(self.mesh.points[:, 0], self.mesh.points[:, 1]).max())
        self.segments = []        # finished segments' rows (all branches)
        self.cur_rows = []
        self.cur_label = "primary"
        self.phase = "primary"
        self.specials = []        # dicts written to summary
        self.sp_objects = []      # SpecialPoint objects of the primary branch (for switching)
        self.u = model.initial_unknowns()
        self.lam = self.start
        self.prev = None
        self.branch_status = {}
        self.resume_tangent = None
        self.seg_offset = 0

    def initialise(self):
        self._setup()

    def deflection(self, z):
        """Out-of-plane displacement of a flat shell; for a free shell with its best-fit plane
        a + b X + c Y removed (the rigid-body pins let a buckled free disk tilt)."""
        if not self.free_body:
            return z
        X = self.mesh.points
        A = np.column_stack([np.ones(len(X)), X[:, 0], X[:, 1]])
        coef, *_ = np.linalg.lstsq(A, z, rcond=None)
        return z - A @ coef

    def _count_radius(self):
        """The circle of the wrinkle count: r = 1.15 R2, just outside the grown region (inside the mesh)."""
        return min(1.15 * self.r2, 0.98 * self.r_mesh)

    def record(self, u):
        x = self.parts.model.positions(u)
        disp = x - self.mesh.points
        if self.flat:
            # a free shell: measured in its best rigid fit onto the reference (large tilts included)
            w = rigid_align(self.mesh.points, x)[:, 2] - self.mesh.points[:, 2] if self.free_body else disp[:, 2]
            amp = float(np.abs(w).max())
        else:
            amp = float(np.linalg.norm(disp, axis=1).max())
        out = {"amplitude": amp}
        if self.flat and self.r2 is not None:
            # counted as the disk-wrinkles validation case counts them: w with its best-fit plane removed, just
            # outside the grown region, and a shifted or tilted dome (k = 1) is no wrinkle
            try:
                out["wrinkles"] = count_wrinkles(self.mesh.points, self.deflection(disp[:, 2]), self._count_radius(),
                                                triangles=self.mesh.triangles, min_mode=2, rel_tol=0.05)
            except ValueError:
                out["wrinkles"] = -1
        return out

    # --- state
    def state(self):
        st = {"u": self.u, "lam": float(self.lam), "has_prev": self.prev is not None,
              "prev_u": self.prev[0] if self.prev else np.zeros(0),
              "prev_lam": float(self.prev[1]) if self.prev else 0.0}
        sp = self._switch_point()
        if sp is not None:
            st.update({"sp_u": sp.u, "sp_tu": sp.tangent[0], "sp_tl": float(sp.tangent[1]), "sp_modes": sp.modes,
                       "sp_eigs": np.asarray(sp.eigenvalues, float),
                       "sp_weights": np.asarray(sp.weights if sp.weights is not None else np.zeros(0), float)})
        return st

    def extra_meta(self):
        sp = self._switch_point()
        return {"phase": self.phase, "label": self.cur_label,
                "rows": clean(self.segments + self.cur_rows), "specials": clean(self.specials),
                "branch_status": self.branch_status,
                "switch_point": None if sp is None else clean({
                    "kind": sp.kind, "parameter": sp.parameter, "s": sp.s, "multiplicity": sp.multiplicity,
                    "n_negative_before": sp.n_negative_before, "n_negative_after": sp.n_negative_after,
                    "step": sp.step, "parameter_scale": sp.parameter_scale})}

    def _switch_point(self):
        for p in self.sp_objects:
            if p.kind == "branch" and p.located:       # an unlocated one has no mode to switch along
                return p
        return None

    def restore(self, state, meta):
        self._setup()
        self.phase = meta["phase"]
        self.cur_label = meta["label"]
        self.branch_status = dict(meta.get("branch_status", {}))
        self.specials = list(meta.get("specials", []))
        self.segments = list(meta.get("rows", []))
        self.cur_rows = []
        self.u = np.array(state["u"], dtype=float)
        self.lam = float(state["lam"])
        self.problem.set_parameter(self.lam)
        if state["has_prev"]:
            self.prev = (np.array(state["prev_u"], float), float(state["prev_lam"]))
        spm = meta.get("switch_point")
        if spm is not None and "sp_u" in state:
            w = np.array(state["sp_weights"], float)
            self.sp_objects = [cont.SpecialPoint(
                kind=spm["kind"], parameter=spm["parameter"], s=spm["s"], u=np.array(state["sp_u"], float),
                tangent=(np.array(state["sp_tu"], float), float(state["sp_tl"])),
                eigenvalues=np.array(state["sp_eigs"], float), modes=np.array(state["sp_modes"], float),
                multiplicity=int(spm["multiplicity"]), n_negative_before=spm["n_negative_before"],
                n_negative_after=spm["n_negative_after"], step=int(spm["step"]),
                weights=w if len(w) else None, parameter_scale=float(spm["parameter_scale"]))]
        if self.prev is not None and self.phase != "done":
            du, dl = self.u - self.prev[0], self.lam - self.prev[1]
            if np.any(du) or dl:
                self.resume_tangent = (du, dl)

    def series_time(self):
        return float(self.step)

    def resume_text(self):
        return f"{self.cur_label} branch at {self.param} = {self.lam:.8g}"

    def finished(self):
        return self.phase == "done"

    def final_status(self):
        so = self.scene.solver
        # a branch that ran out of steps before the stop value it was given is not a finished study
        short = [k for k, v in self.branch_status.items() if v["status"] == "max_steps" and self._stop(k) is not None]
        text = "; ".join(f"{k} branch: {v['message']}" for k, v in self.branch_status.items() if k not in short)
        if short:
            self.message = "; ".join(
                f"{k} branch: stopped at solver.max_steps = {so.max_steps} before its stop value {self._stop(k):g}"
                for k in short) + (": run again with a larger solver.max_steps (or a larger solver.ds) and "
                                   "--overwrite") + (f"; {text}" if text else "")
            return "max_steps_branch"
        if not self.message:
            self.message = text
        return "done"

    def frame(self):
        model = self.parts.model
        _, Hv = self.parts.mean_curvature(self.u)
        pts, pd, cd = frame_fields(self.out.fields, model=model, u=self.u, s=self.parts.s, H_vertex=Hv)
        return float(self.step), pts, pd, cd

    # --- the loop: continuation() drives, the callback reports
    def loop(self):
        while self.phase != "done":
            if self.step_limit_reached():
                return
            if self.phase == "primary":
                self._segment(primary=True)
            elif self.phase == "switched":
                self._segment(primary=False)
            if self.status == "paused":
                return

    def _options(self, steps_done):
        so = self.scene.solver
        ds = so.ds
        return dict(ds_min=so.ds_min, ds_max=so.ds_max or 2 * ds, max_steps=max(so.max_steps - steps_done, 1),
                    n_eigs=so.n_eigs, record=self.record, detect=so.detect, stop_at=tuple(so.stop_at),
                    rtol=so.newton_rtol or 1e-8, backend=so.backend,
                    **({} if so.newton_max_iter is None else {"max_corrector_iterations": so.newton_max_iter}),
                    log=(lambda s: self.p.say(s)) if self.verbose else None)

    def _stop(self, label):
        """The stop value of a branch ("primary" or "switched"; None: no stop value, max_steps only)."""
        so = self.scene.solver
        return so.switch_stop if label == "switched" and so.switch_stop is not None else so.stop

    def _segment(self, primary):
        so = self.scene.solver
        label = self.cur_label
        steps_done = sum(1 for r in self.segments if r.get("branch") == label and not r.get("special")
                         and r.get("step", 0) > 0)
        resumed = self.resume_tangent is not None
        stop = self._stop(label)
        opts = self._options(steps_done)
        self.seg_offset = 1 if resumed else 0
        self._sp_seen = 0

        def callback(branch, row):
            raise_if_interrupted()
            with committing():              # the branch's point, its row, frame and checkpoint together
                return _accept_point(branch, row)

        def numbered(rows):
            # a resumed branch's solver counts its steps from 0 again: the table goes on from the steps before
            return [dict(r, branch=label, **({"step": r["step"] + steps_done} if "step" in r else {})) for r in rows]

        def _accept_point(branch, row):
            self.cur_rows = numbered(list(branch.rows)[self.seg_offset:])
            self.prev = (self.u, self.lam)
            self.u, self.lam = branch.states[-1] if branch.states[-1] is not None else branch.last
            self.u = np.asarray(self.u, float)
            self.lam = float(self.lam)
            new_sp = branch.special_points[self._sp_seen:]
            for sp in new_sp:
                self._special(sp, label)
            self._sp_seen = len(branch.special_points)
            self.newton_total += int(row.get("iterations") or 0)
            text = (f"{label} step {row['step'] + steps_done:3d}  {self.param} {row['parameter']:.6g}  ds {row['ds']:.3g}  "
                    f"it {row['iterations']}  n_neg {row['n_negative']}  amplitude {row.get('amplitude', 0):.4g}"
                    + (f"  wrinkles {int(row['wrinkles'])}" if "wrinkles" in row else "")
                    + (f"  passed {', '.join(sp.label for sp in new_sp)}" if new_sp else ""))
            # the branch ends at its stop value or at max_steps, whichever comes first
            frac = (row["step"] + steps_done) / so.max_steps
            if stop is not None and stop != self._seg_start:
                frac = max(frac, (row["parameter"] - self._seg_start) / (stop - self._seg_start))
            frac = min(max(frac, 0.0), 1.0)
            self.accepted(text, frac)
            if self.max_steps is not None and self.steps_this_run >= self.max_steps:
                return True
            return None

        try:
            branch = self._follow(primary, resumed, stop, label, callback, opts)
        except cont.ContinuationError as exc:
            raise StepFailure(str(exc)) from None
        for sp in branch.special_points[self._sp_seen:]:
            self._special(sp, label)
        self._sp_seen = len(branch.special_points)
        self.cur_rows = numbered(list(branch.rows)[self.seg_offset:])
        self.segments += self.cur_rows
        self.cur_rows = []
        if branch.status == "callback":       # --max-steps
            self.step_limit_reached()
            self.resume_tangent = None if self.prev is None else (self.u - self.prev[0], self.lam - self.prev[1])
            return
        self.branch_status[label] = {"status": branch.status, "message": branch.message}
        if branch.status == "ds_min":
            raise StepFailure(f"{label} branch: {branch.message}")
        if primary and so.switch_branch and self._switch_point() is not None:
            self.phase, self.cur_label = "switched", "switched"
            self.prev = None
        else:
            if primary and so.switch_branch:
                self.message = "no branch point on the primary branch: nothing to switch to"
            self.phase = "done"
        self.checkpoint()

    def _follow(self, primary, resumed, stop, label, callback, opts):
        """The branch of this segment: a new primary branch, the switched one from its branch point,
        a resumed one along its secant, or an empty one (paused exactly at its stop value)."""
        so = self.scene.solver
        if resumed and stop is not None and math.isclose(self.lam, stop, rel_tol=1e-12, abs_tol=1e-300):
            # paused exactly at the stop value: the branch is finished, nothing left to follow
            self.resume_tangent = None
            branch = cont.Branch(label)
            branch.status, branch.message = "lam_stop", f"reached parameter {stop:.6g}"
            return branch
        elif primary and not resumed:
            self._seg_start = self.start
            # toward the stop value, which may lie below the start
            direction = -1 if stop is not None and stop < self.start else 1
            return cont.continuation(self.problem, self.u, self.start, ds=so.ds, lam_stop=stop, label=label,
                                     direction=direction, callback=callback, **opts)
        elif not resumed:
            sp = self._switch_point()
            # the switched branch's first step is measured from its branch point, not from where the
            # primary branch ended (a resume takes its direction from that difference)
            self.u, self.lam = np.asarray(sp.u, float), float(sp.parameter)
            self._seg_start = sp.parameter
            self.p.say(f"branch switching at {sp.label} {self.param} = {sp.parameter:.8g} "
                       f"(multiplicity {sp.multiplicity})")
            amp = so.switch_amplitude or so.ds
            opts.pop("max_steps")
            return cont.switch_branch(self.problem, sp, amplitude=amp, ds=so.ds, lam_stop=stop, label=label,
                                      callback=callback, max_steps=so.max_steps, **opts)
        else:
            self._seg_start = self.lam
            tu, tl = self.resume_tangent
            self.resume_tangent = None
            self.problem.set_parameter(self.lam)
            return cont.continuation(self.problem, self.u, self.lam, ds=so.ds, lam_stop=stop, label=label,
                                     callback=callback, initial_tangent=(tu, tl), **opts)

    def _special(self, sp, label):
        if label == "primary":
            self.sp_objects.append(sp)
        k = len(self.specials)
        d = self.rd.path / "special"
        d.mkdir(exist_ok=True)
        model = self.parts.model
        x = model.positions(sp.u)
        pdata = {"displacement": x - self.mesh.points}
        for j in range(sp.modes.shape[1]):
            pdata[f"mode_{j}"] = model.mode_displacements(sp.modes[:, j])
        path = d / f"{label}-{k:02d}-{sp.kind}.vtu"
        import meshio      # deferred: meshio

        m = meshio.Mesh(x, [("triangle", self.mesh.triangles)], point_data=pdata)
        fio.atomic_write(path, lambda tmp: meshio.write(tmp, m, file_format="vtu"))
        info = {"branch": label, "kind": sp.kind, "label": sp.label,
                "parameter": sp.parameter if sp.located else None,     # a bracket has no parameter
                "multiplicity": sp.multiplicity, "n_negative_before": sp.n_negative_before,
                "n_negative_after": sp.n_negative_after, "eigenvalues": list(np.asarray(sp.eigenvalues)[:6]),
                "located": sp.located, "file": str(path.relative_to(self.rd.path))}
        if not sp.located:
            info["bracket"] = list(sp.bracket)
        if self.flat and self.r2 is not None and sp.modes.shape[1]:
            # the dominant azimuthal wavenumber of the critical mode, 0 for a dome (counting wrinkles from k = 1 up
            # called a dome with a trace of tilt "1 wave"), from the power on four circles about R2 as the
            # disk-wrinkles validation case finds it; a circle outside a non-circular flat mesh is skipped
            z = self.deflection(model.mode_displacements(sp.modes[:, 0])[:, 2])
            radii = [f * self.r2 for f in (0.5, 0.85, 1.15, 1.5) if f * self.r2 < 0.98 * self.r_mesh]
            power = azimuthal_power(self.mesh.points, z, radii, triangles=self.mesh.triangles, skip_outside=True)
            if power is not None:
                info["mode_n"] = int(np.argmax(power))
        self.specials.append(info)
        if not sp.located:
            self.p.say(f"  found {sp.label} between {self.param} = {sp.bracket[0]:.8g} and {sp.bracket[1]:.8g}, not "
                       f"located ({sp.info.get('reason', '')})")
            return
        self.p.say(f"  found {sp.label} at {self.param} = {sp.parameter:.8g} (multiplicity {sp.multiplicity}"
                   + (f", mode n = {info['mode_n']}" if "mode_n" in info else "") + ")")

    def rows(self):
        return self.segments + self.cur_rows

    def write_table(self):
        rows = self.rows()
        cols = []
        for r in rows:
            cols += [k for k in r if k not in cols]
        buf = _io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            # an empty cell for a missing or non-finite value: never 'nan' in a result file
            w.writerow(["" if r.get(k) is None or (isinstance(r[k], float) and not math.isfinite(r[k])) else
                        (repr(float(r[k])) if isinstance(r[k], float) else r[k]) for k in cols])
        fio.atomic_write_text(self.rd.path / "branch.csv", buf.getvalue())

    def checkpoint(self):
        super().checkpoint()
        self.write_table()

    def extra_files(self):
        return {"table": "branch.csv", "special_points": [s["file"] for s in self.specials]}

    def final_points(self):
        return self.parts.model.positions(self.u)

    def final(self):
        model = self.parts.model
        disp = model.positions(self.u) - self.mesh.points
        rec = self.record(self.u)
        return {"parameter": self.param, "final_value": self.lam, "energy": model.strain_energy(self.u),
                "max_displacement": float(np.linalg.norm(disp, axis=1).max()), **rec,
                "branches": self.branch_status, "special_points": self.specials,
                "rows": len(self.rows())}

    def report_lines(self, fin):
        lines = [f"{self.param} = {fin['final_value']:.8g} at the end: amplitude {fin['amplitude']:.4g}"
                 + (f", {fin['wrinkles']} wrinkles" if "wrinkles" in fin else "")]
        for s in self.specials:
            if not s.get("located", True):
                lines.append(f"{s['branch']}: {s['label']} between {self.param} = {s['bracket'][0]:.8g} and "
                             f"{s['bracket'][1]:.8g}, not located")
                continue
            lines.append(f"{s['branch']}: {s['label']} at {self.param} = {s['parameter']:.8g}, multiplicity "
                         f"{s['multiplicity']}" + (f", mode n = {s['mode_n']}" if "mode_n" in s else ""))
        return lines

    def pictures(self):
        from .. import viz      # deferred: pyvista, matplotlib

        model = self.parts.model
        x = model.positions(self.u)
        if self.free_body:
            x = rigid_align(self.mesh.points, x)     # undo the tilt the rigid-body pins allow
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        _, Hv = self.parts.mean_curvature(self.u)
        name, values = picture_field(self.out.picture_field, x, model, self.u, H=Hv, s=self.parts.s)
        title = f"{self.scene.name}: {self.param} = {self.lam:.4g}"
        out = [viz.top_view(x, self.mesh.triangles, (name, values), d / "top.png", title=title, cmap=self.out.cmap),
               side_picture(viz, self.mesh, x, (name, values), d / "side.png", title, self.out.cmap)]
        rows = [r for r in self.rows() if r.get("amplitude") is not None]
        sp = self._switch_point()
        if sp is not None and any(r.get("branch") == "switched" for r in rows):
            # the new branch starts at its branch point
            i = next(i for i, r in enumerate(rows) if r.get("branch") == "switched")
            rows.insert(i, dict(self.record(sp.u), parameter=sp.parameter, stable=None, branch="switched",
                                special=""))
        if rows:
            scale = self.scene.solver.parameter_scale
            x = [r["parameter"] / (scale or 1.0) for r in rows]
            table = {"parameter": x, "amplitude": [r["amplitude"] for r in rows],
                     "stable": [r.get("stable") for r in rows], "branch": [r.get("branch") for r in rows],
                     "special": [r.get("special") or "" for r in rows]}
            ylabel = "max |w| (out-of-plane displacement)" if self.flat else "max |displacement|"
            xlabel = self.param if not scale else f"{self.param} / {scale:g}"
            out.append(viz.bifurcation_diagram(table, x="parameter", y="amplitude", path=d / "bifurcation.png",
                                               xlabel=xlabel, ylabel=ylabel, title=self.scene.name))
        return out
