"""A run directory: femshell's files in it, its lock, setting aside and putting back an earlier run
(``--overwrite``), and the mesh fingerprint a resume is checked against."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import sys
from pathlib import Path

import numpy as np

from .. import io as fio
from .text import dump_toml


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
             "buckling.csv", "modes.vtu", "movie.gif", "movie.mp4")
RUN_DIRS = ("pictures", "special")
#: femshell's own files inside RUN_DIRS and its frames (a user's files there are left alone)
RUN_DIR_FILES = re.compile(r"(top|side|bifurcation)(_\d{6}|_last)?\.png|(primary|switched)-\d+-\w+\.vtu")
FRAME = re.compile(rf"{SERIES}_\d{{6}}\.vtu")


class RunDirError(ValueError):
    """The output directory cannot be used as asked (exit code 2)."""


# ----------------------------------------------------------------------------- the run directory

def pid_alive(pid: int) -> bool:
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
                if tmp and own(tmp[0]) and p.is_file() and not pid_alive(tmp[1]):
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
                if pid_alive(pid) and pid != os.getpid():
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


def checkpoint_scene(path: Path):
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


def mesh_fingerprint(mesh) -> dict:
    """What identifies a mesh across a resume: its triangles exactly, its vertices by their moments."""
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
