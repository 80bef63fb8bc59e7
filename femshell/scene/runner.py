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
  ``kill -9`` does not wait). One whose exception
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
  cap, source rule and step control, ``solver.dt_max`` (with ``solver.dt_initial``, which a resumed run
  does not use but which must not exceed dt_max), ``solver.source_rule``, ``solver.step_control``,
  ``solver.error_tol`` and ``solver.error_ds_max``: they change the path's steps,
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

import re
import sys
import time
from dataclasses import asdict
from pathlib import Path

from .. import _periodic as periodic, io as fio
from .._interrupts import interruptible
from ..mesh import check_mesh
from .base_runner import FINAL, FOLD_WARNING_DEG, BaseRunner, StepFailure
from .build import load_scene, make_mesh, plan
from .estimate import LARGE_MESH, MEM_BASE, MEM_PER_VERTEX, Estimate, expected_vertices, machine_memory
from .progress import Progress
from .rundir import (CHECKPOINT, DROPPED, REPLACED, RUN_FILES, SCENE_FILE, SERIES, RunDir, RunDirError,
                     checkpoint_scene, mesh_fingerprint, recover_run_dir, same_mesh)
from .schema import SceneError, validate
from .static_runner import StaticRunner
from .text import apply_overrides, parse_scene
from .time_runner import TimeRunner

__all__ = ["run_scene", "RunDirError", "RUN_FILES", "recover_run_dir", "pictures_pending", "RunDir", "StepFailure",
           "TimeRunner", "REPLACED", "DROPPED", "FOLD_WARNING_DEG", "BaseRunner", "Progress"]


#: keys that may change between a run and its --resume
RESUMABLE_CHANGES = {("solver", "t_final"), ("solver", "max_steps"), ("solver", "stop"), ("solver", "switch_stop"),
                     ("solver", "stationary_pattern_time"), ("solver", "stationary_pattern_tol"),
                     ("solver", "dt_max"), ("solver", "dt_initial"), ("solver", "source_rule"),
                     ("solver", "step_control"), ("solver", "error_tol"), ("solver", "error_ds_max")}
def runner_class(kind: str):
    """The runner of a solver kind."""
    if kind == "continuation":
        # deferred: only a continuation run loads the continuation machinery (a --dry-run imports none of it)
        from .continuation_runner import ContinuationRunner

        return ContinuationRunner
    if kind == "linear-buckling":
        from .buckling_runner import LinearBucklingRunner      # deferred: as the continuation runner

        return LinearBucklingRunner
    if kind == "pattern-continuation":
        from .pattern_runner import PatternContinuationRunner  # deferred: as the continuation runner

        return PatternContinuationRunner
    return {"time": TimeRunner, "static": StaticRunner}[kind]


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


def _scene_of_run(scene, out, resume, overrides):
    """The scene to run: ``scene`` with its overrides, or (``--resume`` without one) the scene kept in ``out``."""
    if scene is None:
        if not (resume and out):
            raise RunDirError("give a SCENE (a .toml file or an embedded scene name; see `femshell scenes`)")
        p = Path(out) / SCENE_FILE
        text = p.read_text(encoding="utf-8") if p.is_file() else checkpoint_scene(Path(out))
        if text is None and not RunDir(Path(out)).has_run():
            raise RunDirError(f"{out}: nothing to resume (no femshell run there: a run stopped before its first "
                              "accepted state leaves none); start it with femshell run SCENE --out "
                              f"{out}, without --resume")
        if text is None:
            raise RunDirError(f"{out}: no {SCENE_FILE} to resume from; give the SCENE too")
        raw = parse_scene(text, str(p))
        raw = apply_overrides(raw, overrides, str(p), note=False)   # changes on resume go to setting_changes
        return validate(raw, name=raw.get("name") or Path(out).name, label=str(p), source=None, base_dir=Path(out))
    return load_scene(scene, overrides)


def _resume_point(rd, sc, stream):
    """(checkpoint, changed settings, the summary of a run that lacks only its pictures) of a ``--resume``
    in ``rd``, after checking that the run there can be resumed with ``sc``; None when it is finished
    and there is nothing to do."""
    changes, finished = [], None
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
        return None
    return resume_from, changes, finished


def _check_resumed_mesh(rd, meta, mesh):
    """A checkpoint (its ``meta``) is resumed on the mesh it was made on, with the edge unknown it was made with."""
    n_ck = meta.get("n_vertices")
    fp = meta.get("mesh")
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
    from ..shell.element import EDGE_UNKNOWN      # deferred: jax

    if meta.get("edge_unknown") != EDGE_UNKNOWN and meta.get("kind") != "time":
        raise RunDirError(f"{rd.path / CHECKPOINT} was written before femshell's shell took the tangent of the "
                          "mid-edge normal's angle as its edge unknown (2026-11-28), and its state cannot be read "
                          "as one: start a new run with --overwrite or another --out")


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
    sc = _scene_of_run(scene, out, resume, overrides)
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
        point = _resume_point(rd, sc, stream)
        if point is None:
            return 0
        resume_from, changes, finished = point
    # scene errors of mesh files come before the directory is touched
    mesh = sized_mesh(sc, None if quiet else stream)
    if resume_from is not None:
        _check_resumed_mesh(rd, resume_from[1], mesh)
    if sc.mesh_kind == "file":
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


def _heartbeat(stream, text, t0, every=15.0):
    """Print ``text`` with the seconds since ``t0`` every ``every`` seconds while the block runs (gmsh
    releases the GIL while it meshes)."""
    return periodic.every(every, lambda: print(f"{text} ({time.perf_counter() - t0:.0f} s)", file=stream, flush=True),
                          name="femshell-heartbeat")


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
            runner = runner_class(sc.kind)(sc, mesh, rd, progress=progress, max_steps=max_steps, verbose=verbose)
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
