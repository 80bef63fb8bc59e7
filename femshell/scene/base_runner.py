"""The loop shared by the three solver kinds: frames, checkpoints, progress, the summary and pictures.

A runner implements ``initialise``/``restore`` (the first state), ``advance`` (one accepted
step), ``finished``, ``frame``, ``state`` (what the checkpoint holds) and ``final`` (the measures
of the summary); :meth:`BaseRunner.run` owns the order in which they are written."""

from __future__ import annotations

import math
import traceback
from pathlib import Path

import numpy as np

from .. import io as fio
from .._interrupts import committing, interruptible, raise_if_interrupted, step_scope
from ..geometry import fold_angles, triangle_areas
from .progress import Progress, hms
from .rundir import CHECKPOINT, SCENE_FILE, SERIES, RunDir, mesh_fingerprint
from .schema import Scene
from .text import dump_toml


#: a fold between neighbouring faces beyond this (degrees) is reported as under-resolved
FOLD_WARNING_DEG = 30.0
FINAL = ("t_final", "stationary", "done", "lam_stop", "max_steps_branch", "fold", "branch", "callback")


class StepFailure(RuntimeError):
    """A step could not be made; the runner keeps the last accepted state."""


# ----------------------------------------------------------------------------- runners

class BaseRunner:
    """The loop shared by the three solver kinds: frames, checkpoints, progress, summary, pictures."""

    kind = "?"

    def __init__(self, scene: Scene, mesh, rd: RunDir, *, progress: Progress, max_steps=None, verbose=False):
        self.scene = scene
        self.mesh = mesh
        self.rd = rd
        self.p = progress
        self.max_steps = max_steps
        self.max_steps_from = "--max-steps"
        self.verbose = verbose
        self.out = scene.output
        self.step = 0                 # accepted steps in total (all invocations)
        self.steps_this_run = 0
        self.status = "running"
        self.message = ""
        self.newton_total = 0
        self.wall_before = 0.0
        self.resumes = 0
        self.setting_changes = []       # all invocations': [{"step", "changes"}], kept in the checkpoint
        self.last_frame_step = -1
        self.last_ckpt_step = -1
        self._identity = None          # the checkpoint's mesh fingerprint and scene, made at the first one

    # --- to implement
    def initialise(self):
        raise NotImplementedError

    def restore(self, state, meta):
        raise NotImplementedError

    def advance(self):
        """One accepted step; returns the progress text and the fraction done (or None)."""
        raise NotImplementedError

    def finished(self) -> bool:
        raise NotImplementedError

    def series_time(self) -> float:
        raise NotImplementedError

    def frame(self):
        raise NotImplementedError

    def state(self) -> dict:
        raise NotImplementedError

    def final(self) -> dict:
        return {}

    def final_points(self):
        """The deformed vertex positions of the current state (None: no shape)."""
        return None

    def resolution(self) -> dict:
        """How far the final shape folds between neighbouring faces beyond the rest shape (degrees).

        A Kirchhoff element resolves a bend that turns the surface by a few degrees per edge; beyond
        FOLD_WARNING_DEG per edge the shape depends on the mesh, and the report says so.
        """
        x = self.final_points()
        if x is None:
            return {}
        tri, ef = self.mesh.triangles, self.mesh.topology.edge_faces
        turn = np.abs(fold_angles(np.asarray(x, float), tri, ef) - fold_angles(np.asarray(self.mesh.points, float),
                                                                               tri, ef))
        if not (len(turn) and np.all(np.isfinite(turn))):
            return {}
        return {"max_fold_change_deg": float(turn.max()),
                "edges_folded_over_limit": int(np.count_nonzero(turn > FOLD_WARNING_DEG))}

    def pictures(self) -> list:
        return []

    def loop(self):
        """Step until finished (subclasses whose solver drives the loop override this)."""
        while not self.finished():
            if self.step_limit_reached():
                return
            raise_if_interrupted()
            with step_scope():              # a Ctrl-C once the step commits waits for its frame and checkpoint
                text, frac = self.advance()
                with committing():
                    self.accepted(text, frac)

    # --- shared
    def step_limit_reached(self) -> bool:
        """True (and the run paused) once this invocation has taken its --max-steps / solver.max_steps."""
        if self.max_steps is None or self.steps_this_run < self.max_steps:
            return False
        self.status, self.message = "paused", (f"stopped after {self.steps_this_run} steps ({self.max_steps_from}); "
                                               "continue with --resume")
        return True

    def settle(self):
        """Back to the last accepted state's parameter after a step was abandoned midway (an error,
        Ctrl-C), so that the summary's measures are of that state (subclasses with a parameter)."""

    def release(self):
        """Free what the steps held (factorisations) once no step follows, before the results are
        written (subclasses that hold some)."""

    def accepted(self, text, fraction):
        self.step += 1
        self.steps_this_run += 1
        if self.step % self.out.every == 0:
            self.write_frame()
        if self.step % self.out.checkpoint_every == 0:
            self.checkpoint()
        self.p.step(text, fraction)

    def write_frame(self):
        """The state's frame; a step that left the state where the series ends (the same series time: a
        linear-buckling or pattern-continuation step after its ramp or loop) adds none."""
        if self.writer.entries and self.writer.entries[-1][0] == self.series_time():
            self.last_frame_step = self.step
            return
        t, pts, pd, cd = self.frame()
        self.writer.write(t, points=pts, point_data=pd, cell_data=cd)
        self.last_frame_step = self.step

    def checkpoint(self):
        from ..shell.element import EDGE_UNKNOWN      # deferred: jax

        meta = {"kind": self.kind, "edge_unknown": EDGE_UNKNOWN, "step": self.step, "series_time": self.series_time(),
                "wall_s": self.wall_before + self.p.elapsed, "newton_total": self.newton_total,
                "resumes": self.resumes, "setting_changes": self.setting_changes, "scene": self.scene.name,
                "n_vertices": self.mesh.n_vertices}
        if self._identity is None:          # what the run is made of does not change: computed once
            self._identity = {"mesh": mesh_fingerprint(self.mesh), "scene_toml": dump_toml(self.scene.data)}
        meta.update(self._identity)
        meta.update(self.extra_meta())
        fio.save_checkpoint(self.rd.path / CHECKPOINT, self.state(), meta)
        self.last_ckpt_step = self.step

    def extra_meta(self) -> dict:
        return {}

    def run(self, resume_from=None, changes=(), finished=None) -> int:
        """Run (or resume from ``resume_from``, with the resumable scene keys ``changes`` changed) to the end.

        ``finished``: the summary of a finished run whose final pictures are missing; only they are drawn.
        """
        rdp = self.rd.path
        self.writer = fio.TimeSeriesWriter(rdp, self.mesh, SERIES, resume=resume_from is not None)
        if resume_from is not None:
            state, meta = resume_from
            self.step = int(meta["step"])
            self.wall_before = float(meta.get("wall_s", 0.0))
            self.p.wall_before = self.wall_before
            self.newton_total = int(meta.get("newton_total", 0))
            self.resumes = int(meta.get("resumes", 0)) + 1
            self.setting_changes = list(meta.get("setting_changes", []))
            if changes:
                self.setting_changes.append({"step": self.step, "changes": list(changes)})
            self.restore(state, meta)
            raise_if_interrupted()
            self.writer.truncate_after(float(meta["series_time"]))
            self.last_frame_step = self.last_ckpt_step = self.step
            self.rd.start(self.scene)
            self.p.say(f"resumed from the checkpoint at step {self.step} ({self.resume_text()})")
        else:
            self._thickness_warning()
            self.initialise()
            raise_if_interrupted()          # a stop that arrived in a finalizer: as if on time, nothing written
            self.write_frame()
            self.checkpoint()
            self.rd.start(self.scene)
        with interruptible():
            code = self._steps() if finished is None else self._as_finished(finished)
            self.release()
            code = self._final_pictures(code, late=not self._write_results())
        self.report(code)
        return code

    def _steps(self) -> int:
        """The steps to the end (or a failure, a stop): the exit code so far, the status set."""
        try:
            self.loop()
            raise_if_interrupted()      # a stop dropped in the last step (the loop ended without a check)
            if self.status == "running":
                self.status = self.final_status()
        except StepFailure as exc:
            self.status, self.message = "failed", str(exc)
            return 1
        except Exception as exc:        # a bug, not bad input: keep the last accepted state and say so
            traceback.print_exc()
            self.settle()
            self.status, self.message = "failed", (f"internal error after step {self.step} ({type(exc).__name__}: "
                                                   f"{exc}); please report it with the traceback above")
            return 1
        except KeyboardInterrupt:
            self.settle()
            self.status = "interrupted"
            # the scene stored in --out already holds any --set overrides of this run
            self.message = (f"interrupted after step {self.step}; continue with: femshell run --out {self.rd.path} "
                            "--resume")
            return 130
        return 0

    def _as_finished(self, summary) -> int:
        """A finished run restored to draw its missing final pictures: its status and message as they were."""
        self.status, self.message = summary["status"], summary.get("message", "")
        return 0

    def _write_results(self) -> bool:
        """The last accepted state's frame, checkpoint and summary, whatever happened; they must agree, so a
        Ctrl-C waits for them. The summary comes before the pictures (a renderer that dies natively must not
        leave a finished run without one) and says that they are still to be drawn. False: a Ctrl-C arrived."""
        try:
            with committing():
                if self.status not in ("interrupted", "failed", "paused") and self.last_frame_step != self.step:
                    self.write_frame()
                if self.last_ckpt_step != self.step:
                    self.checkpoint()
                self.write_summary([])
        except KeyboardInterrupt:
            return False
        return True

    def _final_pictures(self, code, late) -> int:
        """Draw a finished run's final pictures and list them in the summary; the exit code.

        A stop (Ctrl-C, SIGTERM) while they are drawn, or before (``late``), has one outcome: the
        run stays finished, the summary says its pictures are still to be drawn
        (``files.pictures_pending``; ``--resume`` or ``femshell render`` draws them), exit code 130.
        A signal that the renderer swallows or turns into another error (an ImportError from VTK)
        counts as the stop it is. A renderer's error is a warning: the run stays finished.
        """
        if not (self.status in FINAL and self.out.pictures):
            return code if not late else (code or 130)
        pics, drawn = [], False
        if not late:
            try:
                raise_if_interrupted()
                pics = self.pictures()
                if self.out.movie:
                    pics += self._movie()
                raise_if_interrupted()
                drawn = True
            except KeyboardInterrupt:
                late = True
            except Exception as exc:
                try:
                    raise_if_interrupted()
                    self.p.say(f"warning: pictures failed: {type(exc).__name__}: {exc} (femshell run --out "
                               f"{self.rd.path} --resume tries again)")
                except KeyboardInterrupt:
                    late = True
        if drawn:
            try:
                with committing():
                    self.write_summary(pics)
            except KeyboardInterrupt:
                self.p.failure("interrupted as the run ended; its results and pictures are complete")
                return code or 130
        if late:
            self.p.failure(f"interrupted while drawing the final pictures: the run is finished ({self.status}, "
                           f"{self.step} steps) but its pictures are not drawn; femshell run --out {self.rd.path} "
                           f"--resume (or femshell render {self.rd.path}) draws them")
            return code or 130
        return code

    def resume_text(self):
        return f"series time {self.series_time():.6g}"

    def _movie(self) -> list:
        """The run's movie (output.movie), coloured by output.picture_field where the frames hold it,
        from at most MAX_MOVIE_FRAMES frames (a top view is drawn for each frame it uses)."""
        from ..viz import MAX_MOVIE_FRAMES, render_run      # deferred: pyvista, matplotlib

        pf = self.out.picture_field
        field = pf if pf in self.out.fields else None
        every = max(1, math.ceil(len(self.writer) / MAX_MOVIE_FRAMES))
        paths = render_run(self.rd.path, field=field, every=every, cmap=self.out.cmap)
        return [p for p in paths if p.suffix in (".gif", ".mp4")]

    def _thickness_warning(self):
        """Kirchhoff–Love theory needs h ≪ the surface's size: say so where h is a quarter of it or more."""
        h = self.scene.shell.thickness
        area = float(triangle_areas(np.asarray(self.mesh.points, float), self.mesh.triangles).sum())
        size = math.sqrt(area / math.pi)        # a disk's radius; twice a sphere's
        if isinstance(h, (int, float)) and size > 0 and h > 0.25 * size:
            self.p.failure(f"warning: the shell is thick for thin-shell (Kirchhoff–Love) theory: thickness {h:g} "
                           f"against a surface of size sqrt(area/pi) = {size:.3g} (a sphere's diameter, a disk's "
                           "radius); the model assumes thickness ≪ size, so read the results as qualitative")

    def final_status(self):
        return "done"

    def write_summary(self, pics):
        m = self.mesh
        fin, res = self._final_measures()
        summary = {
            "scene": self.scene.name, "description": self.scene.description,
            "source": str(self.scene.source) if self.scene.source else None,
            "solver": self.kind, "status": self.status, "message": self.message,
            "steps": self.step, "steps_this_run": self.steps_this_run, "resumes": self.resumes,
            "setting_changes": self.setting_changes,
            "newton_iterations": self.newton_total,
            "wall_s": self.wall_before + self.p.elapsed, "wall_s_this_run": self.p.elapsed,
            "mesh": {"n_vertices": m.n_vertices, "n_triangles": m.n_triangles, "n_edges": m.topology.n_edges,
                     "name": m.name},
            "parameters": self.scene.data,
            "final": clean({**fin, **res}),
            "files": {"series": f"{SERIES}.pvd", "frames": len(self.writer), "checkpoint": CHECKPOINT,
                      "scene": SCENE_FILE,
                      "pictures": [str(Path(p).relative_to(self.rd.path)) for p in pics],
                      "pictures_pending": bool(self.status in FINAL and self.out.pictures and not pics)},
            "femshell_version": _version(),
        }
        summary["files"].update(self.extra_files())
        fio.write_summary(self.rd.path, summary)

    def extra_files(self) -> dict:
        return {}

    def _final_measures(self) -> tuple:
        """(final(), resolution()) of the current state, computed once: the summary and the report both
        need them, and each is a pass over the whole mesh (pattern measures, fold angles)."""
        key = (self.step, self.status)
        cached = getattr(self, "_final_cache", None)
        if cached is None or cached[0] != key:
            self._final_cache = cached = (key, (self.final(), self.resolution()))
        return cached[1]

    def report(self, code):
        fin, res = self._final_measures()
        lines = [f"{self.status}: {self.message}" if self.message else f"{self.status}",
                 f"  {self.step} steps ({self.steps_this_run} in this run), {self.newton_total} Newton iterations, "
                 f"wall time {hms(self.wall_before + self.p.elapsed)} ({self.p.elapsed:.1f} s in this run)"]
        lines += [f"  {line}" for line in self.report_lines(fin)]
        lines.append(f"  outputs in {self.rd.path}/: {SERIES}.pvd ({len(self.writer)} frames), summary.json, "
                     f"{CHECKPOINT}" + (", pictures/" if (self.rd.path / "pictures").is_dir() else ""))
        if code == 1:
            self.p.failure(lines[0])
            lines = lines[1:]
        for line in lines:
            self.p.say(line)
        if res.get("edges_folded_over_limit"):      # said even when quiet, as the other warnings
            self.p.failure(f"  warning: neighbouring faces turn by up to {res['max_fold_change_deg']:.0f}° against "
                           f"the rest shape ({res['edges_folded_over_limit']} edges over {FOLD_WARNING_DEG:g}°): the "
                           "shape bends on the scale of one edge there, finer than the mesh resolves (a strip rolled "
                           "at 43° per edge ends 6 % of its length off); refine the mesh (mesh.n_vertices or "
                           "mesh.edge_length) where the shape matters")

    def report_lines(self, fin) -> list:
        return []


def clean(obj):
    if isinstance(obj, dict):
        return {k: clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return clean(obj.tolist())
    return fio.finite_or_none(obj)


def _version():
    try:
        from importlib.metadata import version
        return version("femshell")
    except Exception:  # pragma: no cover
        return None
