r"""Running a scene: the output directory, progress, checkpoints, resume, summary and pictures.

Output directory ``DIR`` (``--out``, default ``./<scene name>-out``)::

    scene.toml          the complete scene as run (every default filled in)
    series.pvd          ParaView time series; one series_NNNNNN.vtu per frame
    checkpoint.npz      the last accepted state (+ checkpoint.npz.prev, the one before)
    summary.json        scene, parameters, status, steps, wall time, final measures
    pictures/           top.png (coloured by c or |displacement|), side.png (by radius; for a
                        shell that was flat an oblique view coloured like top.png),
                        bifurcation.png (continuation)
    branch.csv          continuation only: one row per accepted and special point
    special/            continuation only: the special points with their critical modes

Policy (every file is written atomically by :mod:`femshell.io`):

* A new run refuses a ``DIR`` that already holds a run (finished or not), unless
  ``--resume`` (continue it) or ``--overwrite`` (replace femshell's files there; other
  files are left alone) is given. A scene error never touches ``DIR``. With ``--overwrite``
  the earlier run waits in ``DIR/.femshell-replaced`` until the new run has its first
  checkpoint, and is put back if the new run stops before that (bad input found while
  building the model, an initial state that cannot be made, Ctrl-C); after a ``kill -9``
  there, the next command on ``DIR`` (``run``, also ``--resume`` without a scene, or
  ``render``) puts it back. ``scene.toml`` is written once the run has its first accepted
  state (or has been restored from a checkpoint); a resume without a scene reads the
  checkpoint's own scene when ``scene.toml`` is missing.
* A checkpoint is written after every ``output.checkpoint_every`` accepted steps (1 by
  default): ``kill -9`` loses at most the step in progress. Ctrl-C (SIGINT) and SIGTERM
  stop after writing a checkpoint of the last accepted state and a summary with status
  "interrupted" (exit code 130). One that arrives once a step has begun to commit waits
  until that step, its frame and its checkpoint are written (:mod:`femshell._interrupts`;
  a few seconds at most at 25 000 vertices; ``kill -9`` does not wait). One whose exception
  Python drops (raised in a garbage-collector callback) stops the run before its next step.
* The final pictures are part of a finished run: ``summary.json`` says finished first, with
  ``files.pictures_pending``, and lists the pictures once drawn. A run stopped before they
  are (Ctrl-C or SIGTERM: exit code 130; ``kill -9``; a renderer that died) gets them from
  ``--resume`` or ``femshell render DIR``, which draw only them.
* ``--resume`` continues from the checkpoint; frames written after it are dropped and
  written again. The scene must be the one in ``DIR/scene.toml`` except for
  ``[output]``, ``solver.t_final``, ``solver.max_steps``, ``solver.stop``,
  ``solver.switch_stop``, ``solver.stationary_pattern_time``,
  ``solver.stationary_pattern_tol`` (so a finished run can be extended), and the time step's
  cap and source rule, ``solver.dt_max`` (with ``solver.dt_initial``, which a resumed run does not
  use but which must not exceed dt_max) and ``solver.source_rule``: they change the path's steps,
  not the model. The resume says which of these keys changed, and ``summary.json`` keeps every
  such change with the step it came at (``setting_changes``). With the run's own scene the
  time loop and the static solver resume bit for bit as the uninterrupted run; a continuation
  restarts its branch from the last accepted point along the secant (same branch, not the
  same steps).
  The mesh file may move (its content is checked by a fingerprint instead of its path).
* ``--max-steps N`` (and, for the time loop, ``solver.max_steps``) pauses an invocation after
  N accepted steps (status "paused"); ``--resume`` continues.
* A step that fails (Newton diverges, dt below dt_min, the continuation's step below
  ds_min) ends the run with status "failed", the message, a checkpoint of the last
  accepted state and exit code 1; so does an unexpected error (a bug: its traceback is
  printed for the report). Nothing non-finite is ever written.

Exit codes: 0 finished (or paused by ``--max-steps``), 1 failed, 2 bad input, 130 interrupted (also
a stop after the last step, while the results or pictures were written). A run started in the
background by a shell script (``femshell run ... &``) inherits SIGINT ignored: Ctrl-C in the
terminal leaves it running, SIGTERM (``kill PID``) stops it as Ctrl-C would.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
import sys
import threading
import time
import traceback
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .. import io as fio
from ..solvers.linear import Refactorizer
from ..solvers.newton import NewtonError, follow_load
from .._interrupts import committing, interruptible, raise_if_interrupted, step_scope
from .build import load_scene, make_mesh, plan, shell_parts, stretch_field, time_loop
from .estimate import LARGE_MESH, MEM_BASE, MEM_PER_VERTEX, Estimate, expected_vertices, machine_memory
from .schema import Scene, SceneError, continuation_start, validate
from .text import apply_overrides, dump_toml, parse_scene

__all__ = ["run_scene", "RunDirError", "RUN_FILES", "recover_run_dir", "pictures_pending"]

CHECKPOINT = "checkpoint.npz"
SCENE_FILE = "scene.toml"
SERIES = "series"
LOCK = ".femshell.lock"
#: where --overwrite keeps the earlier run until the new one has started
REPLACED = ".femshell-replaced"
#: marks a complete set-aside in REPLACED; DROPPED: a replaced run being deleted
SET_ASIDE = ".complete"
DROPPED = ".femshell-replaced.drop"
#: femshell's files in a run directory (what --overwrite replaces)
RUN_FILES = (SCENE_FILE, CHECKPOINT, CHECKPOINT + ".prev", fio.SUMMARY_NAME, f"{SERIES}.pvd", "branch.csv",
             "movie.gif", "movie.mp4")
RUN_DIRS = ("pictures", "special")
#: femshell's own files inside RUN_DIRS and its frames (a user's files there are left alone)
RUN_DIR_FILES = re.compile(r"(top|side|bifurcation)(_\d{6}|_last)?\.png|(primary|switched)-\d+-\w+\.vtu")
FRAME = re.compile(rf"{SERIES}_\d{{6}}\.vtu")
#: keys that may change between a run and its --resume
RESUMABLE_CHANGES = {("solver", "t_final"), ("solver", "max_steps"), ("solver", "stop"), ("solver", "switch_stop"),
                     ("solver", "stationary_pattern_time"), ("solver", "stationary_pattern_tol"),
                     ("solver", "dt_max"), ("solver", "dt_initial"), ("solver", "source_rule")}
#: a fold between neighbouring faces beyond this (degrees) is reported as under-resolved
FOLD_WARNING_DEG = 30.0
FINAL = ("t_final", "stationary", "done", "lam_stop", "max_steps_branch", "fold", "branch", "callback")


class RunDirError(ValueError):
    """The output directory cannot be used as asked (exit code 2)."""


class StepFailure(RuntimeError):
    """A step could not be made; the runner keeps the last accepted state."""


def _hms(sec):
    if not math.isfinite(sec):
        return "?"
    sec = int(round(sec))
    h, r = divmod(sec, 3600)
    m, s = divmod(r, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


# ----------------------------------------------------------------------------- the run directory

def _alive(pid: int) -> bool:
    """Whether a process with this pid runs (another user's counts)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class RunDir:
    def __init__(self, path: Path):
        self.path = Path(path)

    def has_run(self) -> bool:
        return self.path.is_dir() and (any((self.path / f).exists() for f in RUN_FILES) or bool(self.frames()))

    def frames(self, root=None) -> list:
        """The series' frame files (series_NNNNNN.vtu; not a user's series_*.vtu), sorted."""
        root = self.path if root is None else root
        return sorted(p for p in root.glob(f"{SERIES}_*.vtu") if FRAME.fullmatch(p.name))

    def describe(self) -> str:
        s = self.summary()
        if s:
            return f"a run of scene '{s.get('scene')}' with status '{s.get('status')}' ({s.get('steps')} steps)"
        if (self.path / CHECKPOINT).exists():
            return "an unfinished run (a checkpoint)"
        return "femshell output"

    def summary(self):
        import json
        p = self.path / fio.SUMMARY_NAME
        if not p.exists():
            return None
        try:
            return json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    def _run_paths(self, root=None):
        """femshell's files of a run in the directory, relative to it (never a user's files, also not
        inside pictures/ and special/)."""
        root = self.path if root is None else root
        out = [Path(f) for f in RUN_FILES if (root / f).exists()]
        out += [Path(p.name) for p in self.frames(root)]
        for d in RUN_DIRS:
            if (root / d).is_dir():
                out += sorted(Path(d) / p.name for p in (root / d).iterdir() if RUN_DIR_FILES.fullmatch(p.name))
        return out

    def set_aside(self):
        """Move an earlier run's files into ``DIR/.femshell-replaced`` (``--overwrite``).

        They are deleted by :meth:`start` once the new run has its first checkpoint, and put
        back by :meth:`put_back` when the new run stops before that (bad input found while
        building it, or an initial state that cannot be made): no output is lost to a run
        that never started. A marker file says the move is complete (before it, every file in
        ``DIR`` is still the earlier run's).
        """
        aside = self.path / REPLACED
        aside.mkdir()
        for p in self._run_paths():
            (aside / p).parent.mkdir(exist_ok=True)
            (self.path / p).rename(aside / p)
        fio.atomic_write_text(aside / SET_ASIDE, "")

    def put_back(self):
        """Undo :meth:`set_aside`: delete what the new run wrote, restore the earlier run."""
        aside = self.path / REPLACED
        if not aside.is_dir():
            return
        if (aside / SET_ASIDE).exists():        # else the set-aside was cut short: DIR holds only the earlier run
            for p in self._run_paths():
                (self.path / p).unlink()
        for p in self._run_paths(aside):
            (self.path / p).parent.mkdir(exist_ok=True)
            (aside / p).rename(self.path / p)
        shutil.rmtree(aside)

    def recover(self):
        """Finish what a process killed while it started an ``--overwrite`` left: an earlier run in
        ``.femshell-replaced`` is put back (the new run never reached :meth:`start`), a replaced run
        whose deletion was cut short is deleted. Called with the lock held; returns what was done
        (None: nothing)."""
        if (self.path / DROPPED).is_dir():
            shutil.rmtree(self.path / DROPPED)
        if not (self.path / REPLACED).is_dir():
            return None
        self.put_back()
        return (f"{self.path}: put back the run that an interrupted --overwrite had set aside in "
                f"{REPLACED}/")

    def start(self, scene):
        """The new run has its first accepted state: store its scene, drop a replaced run (renamed
        first, so that a kill during the deletion leaves nothing to put back)."""
        fio.atomic_write_text(self.path / SCENE_FILE, "# the scene as run by femshell (every default filled in)\n"
                                                      + dump_toml(scene.data))
        if (self.path / REPLACED).is_dir():
            if (self.path / DROPPED).is_dir():
                shutil.rmtree(self.path / DROPPED)
            os.replace(self.path / REPLACED, self.path / DROPPED)
            shutil.rmtree(self.path / DROPPED)

    def remove_temporaries(self):
        """Delete the temporary files that a writer killed mid-write left next to femshell's files
        (a checkpoint's are megabytes on large meshes); called with the lock held. A file whose
        writer still runs (``femshell render`` takes no lock) is kept."""
        for root, own in [(self.path, lambda n: n in RUN_FILES or FRAME.fullmatch(n))] + [
                (self.path / d, RUN_DIR_FILES.fullmatch) for d in RUN_DIRS]:
            if not root.is_dir():
                continue
            for p in root.iterdir():
                tmp = fio.temporary_of(p.name)
                if tmp and own(tmp[0]) and p.is_file() and not _alive(tmp[1]):
                    with contextlib.suppress(OSError):
                        p.unlink()

    @contextlib.contextmanager
    def lock(self):
        """One run per directory: ``DIR/.femshell.lock`` holds the pid; stale locks (dead pid) are taken over."""
        self.path.mkdir(parents=True, exist_ok=True)
        p = self.path / LOCK
        for _ in range(2):
            try:
                fd = os.open(p, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
                break
            except FileExistsError:
                try:
                    pid = int(p.read_text().strip() or "0")
                except (OSError, ValueError):
                    pid = 0
                if _alive(pid) and pid != os.getpid():
                    raise RunDirError(f"{self.path} is in use by a running femshell (pid {pid}, in {p}); wait for "
                                      "it or stop it, or choose another --out (if no femshell runs there, the "
                                      "lock is stale: delete that file)") from None
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
        else:  # pragma: no cover
            raise RunDirError(f"{self.path}: cannot take the lock {p}")
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        try:
            self.remove_temporaries()
            yield
        finally:
            with contextlib.suppress(FileNotFoundError):
                p.unlink()


# ----------------------------------------------------------------------------- progress

class Progress:
    """Progress lines with elapsed time and an estimate of what remains."""

    def __init__(self, out, interval=0.0, quiet=False, wall_before=0.0):
        self.out = out
        self.interval = interval
        self.quiet = quiet
        self.t0 = time.perf_counter()
        self.wall_before = wall_before
        self.history = []     # (wall, fraction)
        self.last_print = -math.inf

    @property
    def elapsed(self):
        return time.perf_counter() - self.t0

    def say(self, text):
        if not self.quiet:
            print(text, file=self.out, flush=True)

    def failure(self, text):
        """A failed run is said even when quiet (then on stderr): its exit code alone does not say why."""
        print(text, file=sys.stderr if self.quiet else self.out, flush=True)

    def step(self, text, fraction=None, force=False):
        now = self.elapsed
        if fraction is not None and math.isfinite(fraction):
            self.history.append((now, float(fraction)))
            self.history = self.history[-12:]
        if not force and now - self.last_print < self.interval:
            return
        self.last_print = now
        eta = self.remaining()
        tail = f"{_hms(self.wall_before + now)} elapsed" + (f", ~{_hms(eta)} left" if eta is not None else "")
        self.say(f"{text}  [{tail}]")

    def remaining(self):
        """Wall seconds left, extrapolated from the last steps; None where that means nothing: the steps
        seen moved the run by less than MIN_FRACTION of its length (tiny steps, a huge t_final: their rate
        says little about the steps to come), or the figure exceeds MAX_ESTIMATE_S."""
        if len(self.history) < 2:
            return None
        (w0, f0), (w1, f1) = self.history[0], self.history[-1]
        if f1 >= 1.0:
            return 0.0
        if not f1 - f0 >= self.MIN_FRACTION or w1 <= w0:
            return None
        left = (1.0 - f1) * (w1 - w0) / (f1 - f0)
        return left if left <= self.MAX_ESTIMATE_S else None

    MIN_FRACTION = 1e-3
    MAX_ESTIMATE_S = 10 * 86400.0


# ----------------------------------------------------------------------------- output fields

def energy_fields(model, u):
    mem, bend = model.energy_parts(u)
    area = np.asarray(model.rest.area, dtype=float)
    return mem / area, bend / area


def frame_fields(wanted, *, model, u, s, H_vertex, c=None, contractility=None):
    """(point_data, cell_data) of one frame, restricted to ``wanted``."""
    pts = model.positions(u)
    pd, cd = {}, {}
    if "c" in wanted and c is not None:
        pd["c"] = c
    if "H" in wanted:
        pd["H"] = H_vertex
    if "Lambda" in wanted and c is not None:
        pd["Lambda"] = contractility(c)
    if "displacement" in wanted:
        pd["displacement"] = pts - model.mesh.points
    if "stretch" in wanted:
        cd["stretch"] = s
    if "thickness" in wanted:
        cd["thickness"] = np.asarray(model.rest.thickness, dtype=float)
    if any(f in wanted for f in ("energy_density", "membrane_energy_density", "bending_energy_density")):
        mem, bend = energy_fields(model, u)
        if "energy_density" in wanted:
            cd["energy_density"] = mem + bend
        if "membrane_energy_density" in wanted:
            cd["membrane_energy_density"] = mem
        if "bending_energy_density" in wanted:
            cd["bending_energy_density"] = bend
    return pts, pd, cd


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

        A Kirchhoff element resolves a bend that turns the surface by a few degrees per edge;
        measured on the rolled cantilever (embedded scene, 16 steps per turn): the tip is off by
        0.3 / 1.4 / 3.2 / 5.7 % of the length at fold angles of 7.5 / 15 / 23 / 43 degrees.
        """
        from ..geometry import fold_angles

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
        t, pts, pd, cd = self.frame()
        self.writer.write(t, points=pts, point_data=pd, cell_data=cd)
        self.last_frame_step = self.step

    def checkpoint(self):
        from ..shell.element import EDGE_UNKNOWN

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
        from ..viz import MAX_MOVIE_FRAMES, render_run

        pf = self.out.picture_field
        field = pf if pf in self.out.fields else None
        every = max(1, math.ceil(len(self.writer) / MAX_MOVIE_FRAMES))
        paths = render_run(self.rd.path, field=field, every=every, cmap=self.out.cmap)
        return [p for p in paths if p.suffix in (".gif", ".mp4")]

    def _thickness_warning(self):
        """Kirchhoff–Love theory needs h ≪ the surface's size: say so where h is a quarter of it or more."""
        from ..geometry import triangle_areas

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
            "final": _clean({**fin, **res}),
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
                 f"wall time {_hms(self.wall_before + self.p.elapsed)} ({self.p.elapsed:.1f} s in this run)"]
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


def _clean(obj):
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    return fio.finite_or_none(obj)


def _version():
    try:
        from importlib.metadata import version
        return version("femshell")
    except Exception:  # pragma: no cover
        return None


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
        from .build import coupled_parameters, initial_concentration

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
        from ..coupled import CoupledError
        try:
            self.loop_ = time_loop(self.scene, self.mesh, log=self._log)
        except CoupledError as exc:
            raise StepFailure(f"the initial equilibrium failed: {exc}") from None
        self.newton_total = self.loop_.newton_total
        self.p.say(f"  done in {time.perf_counter() - t:.1f} s")

    def restore(self, state, meta):
        self.loop_ = time_loop(self.scene, self.mesh, state=state, log=self._log)

    def advance(self):
        from ..coupled import CoupledError
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
        from ..analysis import find_spots

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
            from ..shell.model import FOLD_LIMIT_DEG

            lines.append(f"{fin['over_folded_edges']} mid-edge normals are turned by {FOLD_LIMIT_DEG:g}° or more from "
                         "their faces: the shell folds there more sharply than one element carries (a finer mesh "
                         "resolves it)")
        return lines

    def pictures(self):
        from .. import viz

        lp = self.loop_
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        name, values = _picture_field(self.out.picture_field, lp.points, lp.shell, lp.u, c=lp.c,
                                      H=lp.H_vertex, s=lp.s, contractility=lp.params.contractility)
        title = f"{self.scene.name}: t = {lp.t:.4g}"
        clim = (0.0, max(float(values.max()), 1e-12)) if name == "c" else None
        top = viz.top_view(lp.points, self.mesh.triangles, (name, values), d / "top.png", title=title,
                           cmap=self.out.cmap, clim=clim)
        side = viz.side_view(lp.points, self.mesh.triangles, d / "side.png", title=title, cmap=self.out.cmap)
        return [top, side]


def rigid_align(X, x):
    """``x`` moved rigidly (rotation + translation, Kabsch) onto the reference ``X`` (for pictures)."""
    X = np.asarray(X, float)
    x = np.asarray(x, float)
    cX, cx = X.mean(axis=0), x.mean(axis=0)
    U, _, Vt = np.linalg.svd((x - cx).T @ (X - cX))
    dd = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1.0, 1.0, dd]) @ Vt
    return (x - cx) @ R + cX


def _side_picture(viz, mesh, x, scalars, path, title, cmap):
    """side.png: the side view (coloured by radius) of a curved shell; for a shell that was flat, an
    oblique view (the shape turned 35° about x, then 25° about z) coloured like the top view:
    a strip rolled about y is edge-on in the side view."""
    if not mesh.is_flat():
        return viz.side_view(x, mesh.triangles, path, title=title, cmap=cmap)
    a, b = math.radians(35.0), math.radians(25.0)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    c = x.mean(axis=0)
    xo = (x - c) @ (rz @ rx).T + c
    return viz.side_view(xo, mesh.triangles, path, scalars=scalars, title=f"{title} (oblique view)", cmap=cmap)


def _picture_field(name, points, model, u, *, c=None, H=None, s=None, contractility=None):
    if name == "c":
        return "c", c
    if name == "Lambda":
        return "Lambda", contractility(c)
    if name == "H":
        return "H", H
    if name == "displacement":
        return "|displacement|", np.linalg.norm(points - model.mesh.points, axis=1)
    if name == "z":
        return "z", points[:, 2]
    if name == "radius":
        return "radius", np.linalg.norm(points - points.mean(axis=0), axis=1)
    if name == "stretch":
        return "stretch", s
    if name == "thickness":
        return "thickness", np.asarray(model.rest.thickness, float)
    mem, bend = energy_fields(model, u)
    return name, {"energy_density": mem + bend, "membrane_energy_density": mem, "bending_energy_density": bend}[name]


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

    def advance(self):
        target = (self.k + 1) / self.n_steps
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
        from .. import viz

        model = self.parts.model
        x = model.positions(self.u)
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        _, Hv = self.parts.mean_curvature(self.u)
        name, values = _picture_field(self.out.picture_field, x, model, self.u, H=Hv, s=self.parts.s)
        title = f"{self.scene.name}: factor {self.mu:.4g}"
        top = viz.top_view(x, self.mesh.triangles, (name, values), d / "top.png", title=title, cmap=self.out.cmap)
        side = _side_picture(viz, self.mesh, x, (name, values), d / "side.png", title, self.out.cmap)
        return [top, side]


# ----------------------------------------------------------------------------- continuation

class ContinuationRunner(BaseRunner):
    """Pseudo-arclength continuation (femshell.solvers.continuation), one frame per accepted point."""

    kind = "continuation"

    def settle(self):
        self.problem.set_parameter(self.lam)

    def _setup(self):
        from ..solvers.continuation import GrowthParameter, LoadParameter

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
            self.problem = LoadParameter(model, length_scale=length, parameter_scale=scale)
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
            self.problem = GrowthParameter(model, rest_of, length_scale=length, parameter_scale=scale)
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
            from ..analysis import count_wrinkles
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
                "rows": _clean(self.segments + self.cur_rows), "specials": _clean(self.specials),
                "branch_status": self.branch_status,
                "switch_point": None if sp is None else _clean({
                    "kind": sp.kind, "parameter": sp.parameter, "s": sp.s, "multiplicity": sp.multiplicity,
                    "n_negative_before": sp.n_negative_before, "n_negative_after": sp.n_negative_after,
                    "step": sp.step, "parameter_scale": sp.parameter_scale})}

    def _switch_point(self):
        for p in self.sp_objects:
            if p.kind == "branch" and p.located:       # an unlocated one has no mode to switch along
                return p
        return None

    def restore(self, state, meta):
        from ..solvers.continuation import SpecialPoint

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
            self.sp_objects = [SpecialPoint(
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
        from ..solvers.continuation import Branch, ContinuationError, continuation, switch_branch

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
            if resumed and stop is not None and math.isclose(self.lam, stop, rel_tol=1e-12, abs_tol=1e-300):
                # paused exactly at the stop value: the branch is finished, nothing left to follow
                self.resume_tangent = None
                branch = Branch(label)
                branch.status, branch.message = "lam_stop", f"reached parameter {stop:.6g}"
            elif primary and not resumed:
                self._seg_start = self.start
                # toward the stop value, which may lie below the start
                direction = -1 if stop is not None and stop < self.start else 1
                branch = continuation(self.problem, self.u, self.start, ds=so.ds, lam_stop=stop, label=label,
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
                branch = switch_branch(self.problem, sp, amplitude=amp, ds=so.ds, lam_stop=stop, label=label,
                                       callback=callback, max_steps=so.max_steps, **opts)
            else:
                self._seg_start = self.lam
                tu, tl = self.resume_tangent
                self.resume_tangent = None
                self.problem.set_parameter(self.lam)
                branch = continuation(self.problem, self.u, self.lam, ds=so.ds, lam_stop=stop, label=label,
                                      callback=callback, initial_tangent=(tu, tl), **opts)
        except ContinuationError as exc:
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
        import meshio

        m = meshio.Mesh(x, [("triangle", self.mesh.triangles)], point_data=pdata)
        fio.atomic_write(path, lambda tmp: meshio.write(tmp, m, file_format="vtu"))
        info = {"branch": label, "kind": sp.kind, "label": sp.label, "parameter": sp.parameter,
                "multiplicity": sp.multiplicity, "n_negative_before": sp.n_negative_before,
                "n_negative_after": sp.n_negative_after, "eigenvalues": list(np.asarray(sp.eigenvalues)[:6]),
                "located": sp.located, "file": str(path.relative_to(self.rd.path))}
        if not sp.located:
            info["bracket"] = list(sp.bracket)
        if self.flat and self.r2 is not None and sp.modes.shape[1]:
            from ..analysis import azimuthal_power
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
        import csv
        import io as _io

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
            lines.append(f"{s['branch']}: {s['label']} at {self.param} = {s['parameter']:.8g}, multiplicity "
                         f"{s['multiplicity']}" + (f", mode n = {s['mode_n']}" if "mode_n" in s else ""))
        return lines

    def pictures(self):
        from .. import viz

        model = self.parts.model
        x = model.positions(self.u)
        if self.free_body:
            x = rigid_align(self.mesh.points, x)     # undo the tilt the rigid-body pins allow
        d = self.rd.path / "pictures"
        d.mkdir(exist_ok=True)
        _, Hv = self.parts.mean_curvature(self.u)
        name, values = _picture_field(self.out.picture_field, x, model, self.u, H=Hv, s=self.parts.s)
        title = f"{self.scene.name}: {self.param} = {self.lam:.4g}"
        out = [viz.top_view(x, self.mesh.triangles, (name, values), d / "top.png", title=title, cmap=self.out.cmap),
               _side_picture(viz, self.mesh, x, (name, values), d / "side.png", title, self.out.cmap)]
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


RUNNERS = {"time": TimeRunner, "static": StaticRunner, "continuation": ContinuationRunner}


# ----------------------------------------------------------------------------- entry point

def _differences_from(text, label, sc, base_dir) -> tuple[list, list]:
    """:func:`_scene_differences` of the scene TOML ``text`` (None: none) against ``sc``.

    A stored scene that no longer validates cannot be compared: refused, rather than taken as equal.
    """
    if not text:
        return [], []
    try:
        old = validate(parse_scene(text, str(label)), name=sc.name, label=str(label), base_dir=base_dir,
                       check_files=False).data
    except SceneError as exc:
        raise RunDirError(f"{label}: the scene the run was made with does not validate any more, so the scene "
                          f"given now cannot be checked against it and the run is not resumed:\n{exc}\n(start a "
                          "new run with --overwrite or another --out)") from None
    return _scene_differences(old, sc.data)


def _scene_differences(old: dict, new: dict) -> tuple[list, list]:
    """(differences that forbid a resume, changes of RESUMABLE_CHANGES keys as {"key", "from", "to"})."""
    diffs, changes = [], []
    for sec in sorted(set(old) | set(new)):
        if sec in ("description", "name", "output"):
            continue
        a, b = old.get(sec), new.get(sec)
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b)):
                # a mesh file may move: the checkpoint's fingerprint checks its content
                if (sec, k) == ("mesh", "file") or a.get(k) == b.get(k):
                    continue
                if (sec, k) in RESUMABLE_CHANGES:
                    changes.append({"key": f"{sec}.{k}", "from": a.get(k), "to": b.get(k)})
                else:
                    diffs.append(f"[{sec}] {k}: {a.get(k)!r} in the run, {b.get(k)!r} now")
        elif a != b:
            diffs.append(f"[{sec}] differs")
    return diffs, changes


def run_scene(scene=None, out=None, resume=False, dry_run=False, *, overwrite=False, overrides=(), max_steps=None,
              quiet=False, verbose=False, stream=None) -> int:
    """Run a scene (a .toml path, an embedded name or a loaded :class:`Scene`); see the module docstring.

    Returns the exit code.

    Raises :class:`SceneError` / :class:`RunDirError` (ValueErrors, exit code 2) for bad input,
    before anything is computed or any file in ``out`` is touched.
    """
    stream = stream or sys.stdout
    if out is not None and not str(out).strip():
        raise RunDirError("--out is empty: give the run's directory (or leave --out out for ./<scene name>-out)")
    if resume and overwrite:
        raise RunDirError("--resume and --overwrite contradict each other: choose one")
    if out and not dry_run:                 # before the scene is read from it (a resume without a scene)
        recover_run_dir(out, stream=sys.stderr if quiet else stream)
    if scene is None:
        if not (resume and out):
            raise RunDirError("give a SCENE (a .toml file or an embedded scene name; see `femshell scenes`)")
        p = Path(out) / SCENE_FILE
        text = p.read_text(encoding="utf-8") if p.is_file() else _checkpoint_scene(Path(out))
        if text is None and not RunDir(Path(out)).has_run():
            raise RunDirError(f"{out}: nothing to resume (no femshell run there: a run stopped before its first "
                              "accepted state leaves none); start it with femshell run SCENE --out "
                              f"{out}, without --resume")
        if text is None:
            raise RunDirError(f"{out}: no {SCENE_FILE} to resume from; give the SCENE too")
        raw = parse_scene(text, str(p))
        raw = apply_overrides(raw, overrides, str(p), note=False)   # changes on resume go to setting_changes
        sc = validate(raw, name=raw.get("name") or Path(out).name, label=str(p), source=None, base_dir=Path(out))
    else:
        sc = load_scene(scene, overrides)
    if max_steps is not None and max_steps < 0:
        raise RunDirError(f"--max-steps must be >= 0, got {max_steps}")
    dest = Path(out) if out else Path(f"{sc.name}-out")
    if dest.exists() and not dest.is_dir():
        raise RunDirError(f"--out {dest} is a file, not a directory: choose a directory")
    if dry_run:
        lines, _ = plan(sc, sized_mesh(sc, stream))
        lines = with_estimate(lines)
        lines.append(f"  out        {dest}/ (nothing computed, nothing written: --dry-run)")
        print("\n".join(lines), file=stream)
        return 0

    rd = RunDir(dest)
    recover_run_dir(dest, stream=sys.stderr if quiet else stream)
    resume_from, changes, finished = None, [], None
    if rd.has_run() and not resume and not overwrite:
        raise RunDirError(f"{rd.path} already holds {rd.describe()}; use --resume to continue it, --overwrite to "
                          "replace it (femshell's files there are replaced), or choose another --out")
    if resume:
        if not rd.path.is_dir() or not rd.has_run():
            raise RunDirError(f"{rd.path}: nothing to resume (no femshell run there); run without --resume")
        frames = rd.frames()
        if frames and not (rd.path / f"{SERIES}.pvd").exists():
            # the writer would start a new series over them
            raise RunDirError(f"{rd.path}: {SERIES}.pvd is missing but {len(frames)} frames {SERIES}_*.vtu are "
                              f"there; a resume would start a new series and replace them: put {SERIES}.pvd back, "
                              "or move the frames elsewhere to resume with a new series")
        ck = rd.path / CHECKPOINT
        if not (ck.exists() or (rd.path / (CHECKPOINT + ".prev")).exists()):
            raise RunDirError(f"{rd.path}: no {CHECKPOINT} to resume from (the run there has no accepted state, "
                              "or its checkpoints were deleted); start it again with --overwrite")
        try:
            resume_from = fio.load_checkpoint(ck)
        except (fio.CheckpointError, FileNotFoundError) as exc:
            raise RunDirError(f"cannot resume: {exc}") from None
        if resume_from[1].get("kind") != sc.kind:
            raise RunDirError(f"{ck}: a checkpoint of a {resume_from[1].get('kind')} run, but the scene runs "
                              f"{sc.kind}")
        # the checkpoint's own scene (scene.toml in the directory may have been edited or deleted since),
        # then scene.toml; the changes reported are against the first that exists, the scene the
        # checkpoint's steps were made with (a resume killed before its first checkpoint leaves a newer scene.toml)
        old_p = rd.path / SCENE_FILE
        compared = False
        for label, text in ((ck, resume_from[1].get("scene_toml")),
                            (old_p, old_p.read_text(encoding="utf-8") if old_p.is_file() else None)):
            diffs, new_settings = _differences_from(text, label, sc, rd.path)
            if text and not compared:
                changes, compared = new_settings, True
            if len(diffs) > 8:              # another scene altogether: the first keys say enough
                diffs = diffs[:8] + [f"... and {len(diffs) - 8} more"]
            if diffs:
                raise RunDirError(f"{label}: the run there was made with another scene than the one given now, so it "
                                  "cannot be resumed:\n  " + "\n  ".join(diffs) + "\n(resume with the run's own "
                                  f"scene: femshell run --out {rd.path} --resume, without a scene or --set, after "
                                  "putting back its scene.toml if that was edited; or start a new run with "
                                  "--overwrite or another --out)")
        summ = rd.summary()
        done = (summ and summ.get("status") in FINAL and summ.get("steps") == resume_from[1].get("step")
                and not _extends(summ, sc))
        if done and pictures_pending(rd.path) and sc.output.pictures:
            finished = summ                 # stopped before its final pictures: only they are drawn now
        elif done:
            if sc.kind != "time":
                how = ("a finished continuation or load stepping is not extended: start a new run with --overwrite "
                       "or another --out")
            elif summ["status"] == "stationary":
                how = ("it stopped because the pattern became stationary, which a resume does not undo: to run past "
                       "that, start a new run with --overwrite or another --out and stricter or zero "
                       "solver.stationary_* values")
            else:
                how = "extend it with --set solver.t_final=... --resume"
            print(f"{rd.path}: the run is already finished (status {summ['status']}, {summ['steps']} steps); "
                  f"nothing to do ({how})", file=stream)
            return 0

    # scene errors of mesh files come before the directory is touched
    mesh = sized_mesh(sc, None if quiet else stream)
    if resume_from is not None:
        n_ck = resume_from[1].get("n_vertices")
        fp = resume_from[1].get("mesh")
        changed = None
        if n_ck is not None and n_ck != mesh.n_vertices:
            changed = f"a mesh of {n_ck} vertices, the scene's mesh has {mesh.n_vertices}"
        elif fp is not None and not same_mesh(fp, mesh_fingerprint(mesh)):
            changed = "another mesh: the scene's mesh has as many vertices, but other triangles or vertex positions"
        if changed:
            raise RunDirError(f"{rd.path / CHECKPOINT} was made on {changed} (was its mesh file changed?): put the "
                              "run's mesh back, or start a new run with --overwrite or another --out")
        # the shell's edge unknowns were once angles: a time run's state says so itself (its version) and is
        # converted; a static or continuation state holds bare unknowns and is refused
        from ..shell.element import EDGE_UNKNOWN

        if resume_from[1].get("edge_unknown") != EDGE_UNKNOWN and resume_from[1].get("kind") != "time":
            raise RunDirError(f"{rd.path / CHECKPOINT} was written before femshell's shell took the tangent of the "
                              "mid-edge normal's angle as its edge unknown (2026-11-28), and its state cannot be read "
                              "as one: start a new run with --overwrite or another --out")
    if sc.mesh_kind == "file":
        from ..mesh import check_mesh

        for w in check_mesh(mesh).warnings:     # a sliver or a poor triangle the run may stumble on
            print(f"warning: mesh {mesh.name}: {w}", file=sys.stderr if quiet else stream)
    progress = Progress(stream, interval=sc.output.progress_interval, quiet=quiet)
    # SIGTERM as Ctrl-C from here on: a run stopped while it starts still puts an earlier run back
    with interruptible():
        return _run_locked(sc, mesh, rd, progress, resume, resume_from, overwrite, max_steps, verbose, changes,
                           finished)


def sized_mesh(sc, stream=None):
    """The scene's mesh, after its estimated cost (:mod:`.estimate`) was checked against the machine's
    memory: a run that cannot fit is refused (SceneError, with the numbers) before gmsh starts, a large
    mesh is announced on ``stream`` with its estimate and said to progress while gmsh works."""
    n = expected_vertices({"kind": sc.mesh_kind, **asdict(sc.mesh)})
    if n is not None:
        _refuse_beyond_memory(sc, n)
    if n is None or n < LARGE_MESH or stream is None:
        mesh = make_mesh(sc)
    else:
        est = Estimate(n)
        print(f"meshing about {n} vertices with gmsh (~{est.text()}) ...", file=stream, flush=True)
        t0 = time.perf_counter()
        with _heartbeat(stream, "  still meshing", t0):
            mesh = make_mesh(sc)
        print(f"  meshed: {mesh.n_vertices} vertices in {time.perf_counter() - t0:.0f} s", file=stream, flush=True)
    if n is None:
        _refuse_beyond_memory(sc, mesh.n_vertices)
    return mesh


def _refuse_beyond_memory(sc, n):
    est = Estimate(n)
    total, avail = machine_memory()
    if total is not None and est.memory > total:
        raise SceneError(f"{sc.label}: [mesh] a mesh of about {n} vertices needs about {est.memory / 1e9:.3g} GB of "
                         f"memory (estimate: {MEM_BASE / 1e9:.2g} GB + {MEM_PER_VERTEX / 1e3:.0f} kB per vertex), more "
                         f"than this machine's {total / 1e9:.3g} GB ({(avail or 0) / 1e9:.3g} GB available): at most "
                         f"about {int((total - MEM_BASE) / MEM_PER_VERTEX)} vertices fit; choose a coarser mesh")


def with_estimate(lines: list) -> list:
    """The plan's lines with the run's estimated cost after the mesh line."""
    i = next((k for k, line in enumerate(lines) if line.startswith("  mesh ")), None)
    m = re.search(r": (\d+) vertices", lines[i]) if i is not None else None
    if m is None:
        return lines
    return lines[:i + 1] + [f"  estimate   {Estimate(int(m.group(1))).text()}"] + lines[i + 1:]


@contextlib.contextmanager
def _heartbeat(stream, text, t0, every=15.0):
    """Print ``text`` with the seconds since ``t0`` every ``every`` seconds while the block runs (gmsh
    releases the GIL while it meshes)."""
    done = threading.Event()

    def beat():
        while not done.wait(every):
            print(f"{text} ({time.perf_counter() - t0:.0f} s)", file=stream, flush=True)

    th = threading.Thread(target=beat, daemon=True)
    th.start()
    try:
        yield
    finally:
        done.set()
        th.join()


def _checkpoint_scene(path: Path):
    """The scene TOML kept in ``path``'s checkpoint (a run killed before it wrote scene.toml), or None."""
    try:
        return fio.load_checkpoint(path / CHECKPOINT)[1].get("scene_toml")
    except (fio.CheckpointError, FileNotFoundError):
        return None


def recover_run_dir(path, stream=None, *, busy_ok=False):
    """Put back (or finish replacing) what an ``--overwrite`` killed while it started left in ``path``
    (:meth:`RunDir.recover`), saying so on ``stream``. Every command on a run directory calls it first.
    A directory in use by a live run is refused (:class:`RunDirError`), or left alone with ``busy_ok``."""
    rd = RunDir(path)
    if not ((rd.path / REPLACED).is_dir() or (rd.path / DROPPED).is_dir()):
        return
    try:
        with rd.lock():
            msg = rd.recover()
    except RunDirError:
        if busy_ok:
            return
        raise
    if msg:
        print(msg, file=stream or sys.stderr)


def pictures_pending(path) -> bool:
    """Whether the run in ``path`` is finished but its final pictures are not drawn (a stop while they were)."""
    summ = RunDir(path).summary() or {}
    return bool(summ.get("status") in FINAL and (summ.get("files") or {}).get("pictures_pending"))


def _run_locked(sc, mesh, rd, progress, resume, resume_from, overwrite, max_steps, verbose, changes=(),
                finished=None):
    quiet = progress.quiet
    with rd.lock():
        if overwrite:
            rd.set_aside()                  # put back below if the new run does not start
        try:
            if resume_from is None:
                head = with_estimate(plan(sc, mesh)[0])
                for line in head:
                    progress.say(line)
                progress.say(f"  out        {rd.path}/")
            elif finished is not None:
                progress.say(f"scene '{sc.name}': the run in {rd.path}/ is finished; drawing its final pictures")
            elif resume and not quiet:
                progress.say(f"scene '{sc.name}': resuming the run in {rd.path}/")
            if resume_from is not None and changes:
                progress.say("  changed since the run's last invocation: "
                             + ", ".join(f"{c['key']} {c['from']!r} -> {c['to']!r}" for c in changes))
            runner = RUNNERS[sc.kind](sc, mesh, rd, progress=progress, max_steps=max_steps, verbose=verbose)
            return runner.run(resume_from, changes, finished)
        except StepFailure as exc:          # the initial state could not be made: nothing to checkpoint
            progress.failure(f"failed: {exc}")
            aside = rd.path / REPLACED
            earlier = overwrite and aside.is_dir() and bool(rd._run_paths(aside))
            if overwrite:
                rd.put_back()
            if earlier:
                progress.say(f"the earlier run in {rd.path}/ is kept")
            else:
                fio.write_summary(rd.path, {"scene": sc.name, "solver": sc.kind, "status": "failed",
                                            "message": str(exc), "steps": 0, "parameters": sc.data,
                                            "wall_s": progress.elapsed})
            return 1
        except BaseException:               # bad input found while building, or a stop before the start
            if overwrite:
                rd.put_back()
            raise


def mesh_fingerprint(mesh) -> dict:
    """What identifies a mesh across a resume: its triangles exactly, its vertices by their moments."""
    import hashlib

    pts = np.asarray(mesh.points, float)
    tri = np.ascontiguousarray(mesh.triangles, dtype=np.int64)
    return {"triangles_sha1": hashlib.sha1(tri.tobytes()).hexdigest(),
            "moments": [float(v) for v in np.concatenate([pts.sum(axis=0), (pts ** 2).sum(axis=0)])]}


def same_mesh(a, b) -> bool:
    """The same triangles and vertex moments within 1e-9 of their size (a regenerated mesh may differ by
    round-off)."""
    ma, mb = np.asarray(a["moments"], float), np.asarray(b["moments"], float)
    return (a["triangles_sha1"] == b["triangles_sha1"] and ma.shape == mb.shape
            and bool(np.all(np.abs(ma - mb) <= 1e-9 * np.maximum(np.abs(ma).max(), 1e-300))))


def _extends(summary, sc):
    """True when a finished time run's t_final was raised (the resume continues it)."""
    if sc.kind != "time":
        return False
    try:
        old_tf = summary["parameters"]["solver"]["t_final"]
        t = summary["final"]["t"]
    except (KeyError, TypeError):
        return False
    return sc.solver.t_final > old_tf and summary.get("status") == "t_final" and t < sc.solver.t_final
