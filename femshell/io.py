"""Results on disk: atomic files, ParaView time series, checkpoints, summary.json.

No physics and no plotting here: data flows one way, from the solvers into io and viz.

Every file is written **atomically**: the content goes to a temporary file in
the same directory (same file system), is flushed to disk, and then replaces
the target with :func:`os.replace`. A run killed at any moment leaves either
the old complete file or the new complete file, never a truncated one.
Temporary files are named ``.<name>.tmp-<pid>-<random><suffix>`` (hidden, same
extension so that format detection by extension still works) and are removed
when the writer fails.

**No NaN or infinity in a result file**: :func:`atomic_write_json`,
:func:`write_summary`, :class:`TimeSeriesWriter` and :func:`save_checkpoint`
refuse non-finite numbers with a ValueError that names the offending key or
field, e.g. ``summary.json: rows[3].value is NaN``.

Time series readable by ParaView: one
VTU file per frame, ``<name>_000042.vtu`` (meshio, binary, zlib), and a PVD
collection ``<name>.pvd`` listing ``(time, file)``; open the .pvd in ParaView.
Times are written with Python's shortest round-trip ``repr``, so the time read
back is bit-identical to the time written. A resumed run calls
:meth:`TimeSeriesWriter.truncate_after` with the checkpoint time and then
produces the same series as an uninterrupted run.

Checkpoints: one ``.npz`` file (no pickle) holding the state arrays and a JSON
header with the metadata; the previous checkpoint is kept as ``<path>.prev``.
:func:`load_checkpoint` falls back to ``.prev`` with a warning when the main
file is corrupt.

Units: whatever the caller stores (design units: lengths in cell sizes, time in 1/beta).

Example
-------
>>> import tempfile, numpy as np
>>> from femshell.mesh import SurfaceMesh
>>> from femshell.io import TimeSeriesWriter, read_pvd
>>> d = tempfile.mkdtemp()
>>> m = SurfaceMesh(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
>>> w = TimeSeriesWriter(d, m)
>>> _ = w.write(0.0, point_data={"c": np.zeros(3)})
>>> _ = w.write(0.5, point_data={"c": np.ones(3)})
>>> [t for t, _ in read_pvd(w.pvd_path)]
[0.0, 0.5]
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import re
import secrets
import shutil
import warnings
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from io import StringIO
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ._checks import triangle_array, vertex_indices

__all__ = [
    "atomic_path", "atomic_write", "atomic_write_text", "atomic_write_json", "check_generated", "replace_generated",
    "to_json_safe", "finite_or_none", "temporary_of",
    "TimeSeriesWriter", "Frame", "read_pvd", "read_frame", "find_series",
    "save_checkpoint", "load_checkpoint", "CheckpointError",
    "write_summary", "SUMMARY_NAME",
    "write_branch_csv", "write_special_points",
]

SUMMARY_NAME = "summary.json"
CHECKPOINT_FORMAT = "femshell-checkpoint"
CHECKPOINT_VERSION = 1
_HEADER_KEY = "__femshell_header__"


# ----------------------------------------------------------------------------- atomic files

def _tmp_name(path: Path) -> Path:
    suffix = "".join(path.suffixes[-1:])
    return path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}{suffix}")


_TEMPORARY = re.compile(r"\.(?P<target>.+)\.tmp-(?P<pid>\d+)-[0-9a-f]{8}(\.\w+)?")


def temporary_of(name: str):
    """(target file name, writer's pid) of a temporary file named as :func:`atomic_path` names
    them, or None for any other name: what a writer killed mid-write leaves behind.

    >>> temporary_of(".summary.json.tmp-123-0a1b2c3d.json"), temporary_of("summary.json")
    (('summary.json', 123), None)
    """
    m = _TEMPORARY.fullmatch(name)
    return (m["target"], int(m["pid"])) if m else None


def finite_or_none(v):
    """``v`` for a JSON file: numpy scalars as Python numbers, NaN and infinity as None (null);
    other values unchanged.

    >>> finite_or_none(float("nan")), finite_or_none(np.float64(2.5)), finite_or_none(np.int64(3))
    (None, 2.5, 3)
    """
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _fsync_dir(directory: Path) -> None:
    """Make a rename durable (best effort; not every file system allows opening a directory)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _fsync_file(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _raise_for_target(exc: BaseException, tmp: Path, path: Path) -> None:
    """An OSError about the temporary file is raised again naming ``path``, the file the user asked for."""
    if isinstance(exc, OSError) and exc.filename is not None and Path(exc.filename) == tmp:
        raise type(exc)(exc.errno, f"{exc.strerror} (a new {path.name} is written next to it first)",
                        str(path)) from exc


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Context manager: yields a temporary path next to ``path``; on normal exit it replaces ``path``.

    Write the complete file to the yielded path inside the ``with`` block. If the
    block raises, the temporary file is deleted and ``path`` is left untouched.
    The temporary path keeps the extension of ``path`` (``x.png`` -> ``.x.png.tmp-..-...png``)
    so libraries that pick the format from the extension work.

    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "a.txt")
    >>> with atomic_path(p) as tmp:
    ...     _ = open(tmp, "w").write("hello")
    >>> open(p).read()
    'hello'
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a directory; cannot write a file there")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise OSError(f"{path}: the writer did not create the temporary file {tmp.name}")
        _fsync_file(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        _raise_for_target(exc, tmp, path)
        raise
    _fsync_dir(path.parent)


def atomic_write(path, writer: Callable[[Path], Any]) -> Path:
    """Write ``path`` atomically: ``writer(tmp_path)`` writes the whole file, then it replaces ``path``.

    If ``writer`` raises (or the process dies), ``path`` keeps its old content and the
    temporary file is removed (when the process survives). Returns ``Path(path)``.
    """
    with atomic_path(path) as tmp:
        writer(tmp)
    return Path(path)


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write a text file atomically (see :func:`atomic_write`)."""
    def w(tmp):
        with open(tmp, "w", encoding=encoding) as f:
            f.write(text)
    return atomic_write(path, w)


def check_writable_dir(path, what: str) -> Path:
    """Make ``path`` a directory (with parents) and check that files can be created in it, or a
    ValueError naming ``what`` (a command-line option): before hours of computing, not after."""
    import tempfile

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} is a file, not a directory: choose a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot write there ({exc.strerror or exc})") from None
    return path


def check_generated(path, begin: str, end: str) -> str:
    """The text of a page whose generated part lies between the marker lines ``begin`` and
    ``end``; ValueError naming the file when it cannot be read or a marker is missing. Scripts
    call it before computing, so that a wrong page is reported at once, not after the run."""
    path = Path(path)
    try:
        doc = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the page whose table is to be rewritten ({exc.strerror})") from None
    if begin not in doc or end not in doc:
        raise ValueError(f"{path}: no generated-part markers ({begin} ... {end})")
    return doc


def replace_generated(path, begin: str, end: str, text: str) -> Path:
    """Replace what lies between the marker lines ``begin`` and ``end`` of a text file (a page
    whose tables a script generates) by ``text``, atomically; the markers stay. ValueError
    naming the file when it cannot be read or a marker is missing (:func:`check_generated`)."""
    path = Path(path)
    doc = check_generated(path, begin, end)
    head, rest = doc.split(begin, 1)
    tail = rest.split(end, 1)[1]
    return atomic_write_text(path, f"{head}{begin}\n{text}\n{end}{tail}")


def _key_path(parent: str, key) -> str:
    if isinstance(key, int):
        return f"{parent}[{key}]"
    return f"{parent}.{key}" if parent else str(key)


def to_json_safe(obj, where: str = "", _path: str = ""):
    """``obj`` converted to plain JSON types, refusing NaN and infinity.

    numpy scalars and arrays become Python numbers and lists, ``Path`` becomes
    ``str``, tuples become lists, dict keys must be ``str`` (int/float/bool keys
    are converted as ``json`` would). Raises ValueError ``"<where>: <key path> is NaN"``
    (or ``inf``/``-inf``) and TypeError for objects JSON cannot hold, naming the key path
    (``rows[3].value``; ``where`` is usually the file name).
    """
    label = (lambda p: f"{where}: {p or '(top level)'}") if where else (lambda p: p or "(top level)")
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        if not math.isfinite(v):
            raise ValueError(f"{label(_path)} is {_nonfinite_name(v)}; result files never hold NaN or "
                             "infinity (store null, or leave the entry out)")
        return v
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            if isinstance(k, (bool, np.bool_)):
                k = "true" if k else "false"
            elif isinstance(k, (int, np.integer)):
                k = str(int(k))
            elif isinstance(k, (float, np.floating)):
                k = repr(float(k))
            elif not isinstance(k, str):
                raise TypeError(f"{label(_path)} has a key {k!r} of type {type(k).__name__}; "
                                "JSON keys must be strings")
            if k in out:        # {1: .., "1": ..}: json.dumps would write the key twice, a reader keeps one
                raise ValueError(f"{label(_path)} has two keys that are both {k!r} in JSON")
            out[k] = to_json_safe(v, where, _key_path(_path, k))
        return out
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fiubUS":
            return to_json_safe(obj.tolist(), where, _path)
        raise TypeError(f"{label(_path)} is an array of dtype {obj.dtype}, not JSON-serialisable")
    if isinstance(obj, (list, tuple)):
        return [to_json_safe(v, where, _key_path(_path, i)) for i, v in enumerate(obj)]
    if isinstance(obj, complex):
        raise TypeError(f"{label(_path)} is a complex number, not JSON-serialisable")
    raise TypeError(f"{label(_path)} is a {type(obj).__name__}, not JSON-serialisable")


def _nonfinite_name(v) -> str:
    v = complex(v)
    if math.isnan(v.real) or math.isnan(v.imag):
        return "NaN"
    x = v.real if math.isinf(v.real) else v.imag
    return "inf" if x > 0 else "-inf"


def atomic_write_json(path, obj, indent: int | None = 1) -> Path:
    """Write ``obj`` as JSON atomically; refuses NaN/inf naming the key path.

    Example of the error: ``ValueError: summary.json: rows[3].value is NaN; ...``.
    The file is validated completely before anything is written.
    """
    path = Path(path)
    safe = to_json_safe(obj, where=path.name)
    text = json.dumps(safe, indent=indent, allow_nan=False, ensure_ascii=False) + "\n"
    return atomic_write_text(path, text)


def write_summary(out_dir, summary: dict) -> Path:
    """Write ``out_dir/summary.json`` atomically (no NaN/inf; see :func:`atomic_write_json`)."""
    if not isinstance(summary, dict):
        raise TypeError(f"summary must be a dict, got {type(summary).__name__}")
    return atomic_write_json(Path(out_dir) / SUMMARY_NAME, summary)


# ----------------------------------------------------------------------------- time series

_PLURAL = {"vertex": "vertices", "triangle": "triangles"}


def _check_field(kind: str, name, values, n: int, what: str) -> np.ndarray:
    if not isinstance(name, str) or not name:
        raise ValueError(f"{kind} field names must be non-empty strings, got {name!r}")
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{kind} field '{name}' is not a float array: {e}") from None
    if a.ndim not in (1, 2) or a.shape[0] != n or (a.ndim == 2 and a.shape[1] == 0):
        raise ValueError(f"{kind} field '{name}' has shape {a.shape}; expected ({n},) or ({n}, k), k >= 1 "
                         f"(one value per {what})")
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad)[0]
        v = a[tuple(idx)]
        rows = int(np.any(bad.reshape(n, -1), axis=1).sum())
        raise ValueError(f"{kind} field '{name}' holds non-finite values ({_nonfinite_name(v)} at {what} "
                         f"{int(idx[0])}, {rows} {what if rows == 1 else _PLURAL[what]} affected); "
                         "refusing to write a result with NaN/inf")
    return a


def _pvd_text(entries) -> str:
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             '  <Collection>']
    for t, fname in entries:
        lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" file="{fname}"/>')
    lines += ['  </Collection>', '</VTKFile>', '']
    return "\n".join(lines)


def read_pvd(path) -> list[tuple[float, Path]]:
    """The ``(time, vtu path)`` entries of a PVD collection, in file order (paths absolute).

    Raises FileNotFoundError if ``path`` does not exist and ValueError if it is not a
    valid PVD file.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such PVD file")
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a PVD file (find_series(DIR) finds a run's series)")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ValueError(f"{path}: not a valid PVD (XML) file: {e}") from None
    except OSError as e:
        raise ValueError(f"{path}: cannot read the PVD file ({e.strerror or e})") from None
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        raise ValueError(f"{path}: not a PVD collection (root <{root.tag} type={root.get('type')!r}>)")
    out = []
    for ds in root.iter("DataSet"):
        try:
            t = float(ds.get("timestep"))
        except (TypeError, ValueError):
            t = math.nan
        if not math.isfinite(t):
            raise ValueError(f"{path}: DataSet without a finite numeric timestep: {ET.tostring(ds)!r}")
        f = ds.get("file")
        if not f:
            raise ValueError(f"{path}: DataSet at time {t!r} has no file attribute")
        # the directory resolved, not the file: a frame that is a symlink keeps its name in the run
        out.append((t, Path(os.path.normpath(path.parent.resolve() / f))))
    return out


def find_series(out_dir, name: str | None = None) -> Path:
    """The PVD file of a run directory: ``<name>.pvd`` if given (``name`` with or without ".pvd"), else
    ``series.pvd``, else the only .pvd."""
    out_dir = Path(out_dir)
    if out_dir.is_file():
        raise ValueError(f"{out_dir} is a file; give the run directory that holds the series")
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: no such directory")
    if name is not None:
        p = out_dir / (name if name.endswith(".pvd") else f"{name}.pvd")
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such time series")
        return p
    if (out_dir / "series.pvd").exists():
        return out_dir / "series.pvd"
    found = sorted(out_dir.glob("*.pvd"))
    if not found:
        raise FileNotFoundError(f"{out_dir}: no time series (.pvd file) in this directory")
    if len(found) > 1:
        raise ValueError(f"{out_dir}: several time series ({', '.join(p.name for p in found)}) and no "
                         "series.pvd; pass the name of one (femshell render --series NAME)")
    return found[0]


@dataclass
class Frame:
    """One frame of a time series: the deformed surface and its fields."""
    time: float
    points: np.ndarray            # (n, 3)
    triangles: np.ndarray         # (m, 3) int
    point_data: dict = field(default_factory=dict)   # name -> (n,) or (n, k)
    cell_data: dict = field(default_factory=dict)    # name -> (m,) or (m, k)
    path: Path | None = None


def read_frame(path, time: float = float("nan")) -> Frame:
    """Read one VTU frame written by :class:`TimeSeriesWriter` (triangles only)."""
    from .mesh.io import meshio_read
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such frame file")
    m = meshio_read(path)
    blocks = [i for i, c in enumerate(m.cells) if c.type == "triangle"]
    if not blocks:
        raise ValueError(f"{path}: no triangle cells")
    i = blocks[0]
    cell_data = {k: np.asarray(v[i]) for k, v in m.cell_data.items()}
    return Frame(time, np.asarray(m.points, dtype=float), np.asarray(m.cells[i].data, dtype=np.int64),
                 {k: np.asarray(v) for k, v in m.point_data.items()}, cell_data, path)


class TimeSeriesWriter:
    """A ParaView time series: ``<out_dir>/<name>_NNNNNN.vtu`` frames plus the ``<name>.pvd`` index.

    Parameters
    ----------
    out_dir : path
        Created if missing.
    mesh : SurfaceMesh (or anything with ``points`` (n, 3) and ``triangles`` (m, 3))
        The triangulation, fixed for the whole series; each frame gives new points.
    name : str
        Base name of the files.
    resume : bool
        False (a new run): frames of an earlier series with this name in ``out_dir``
        are deleted when the first frame is written (its arguments checked first, so a
        refused frame leaves the earlier series in place). True: the existing ``.pvd`` is
        read and appended to; entries whose file is missing are dropped with a warning (frames
        without their ``.pvd`` cannot be resumed: ValueError, nothing deleted). Call
        :meth:`truncate_after` with the checkpoint time so frames written after the checkpoint disappear.

    Notes
    -----
    Each :meth:`write` writes its VTU atomically, then rewrites the .pvd atomically,
    so a killed run leaves a valid series (at worst an orphan VTU that the next
    write with that index replaces). Times must increase strictly (use a step
    counter as "time" for continuation runs).
    """

    def __init__(self, out_dir, mesh, name: str = "series", resume: bool = False):
        if not re.fullmatch(r"[A-Za-z0-9_.\-]+", name or ""):
            raise ValueError(f"series name must be letters, digits, '_', '-' or '.', got {name!r}")
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.name = name
        self.points = np.asarray(mesh.points, dtype=float)
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ValueError(f"mesh points must have shape (n, 3), got {self.points.shape}")
        tri = triangle_array(mesh.triangles, "mesh triangles")
        vertex_indices(tri, len(self.points), of="mesh points")
        self.triangles = tri.astype(np.int64)
        self.n_points, self.n_cells = len(self.points), len(self.triangles)
        self.pvd_path = self.out_dir / f"{name}.pvd"
        self._pattern = re.compile(re.escape(name) + r"_(\d{6,})\.vtu")
        self.entries: list[tuple[float, str]] = []
        if resume and not self.pvd_path.exists() and any(self._pattern.fullmatch(p.name)
                                                         for p in self.out_dir.iterdir()):
            raise ValueError(f"{self.pvd_path} is missing: the frames of {self.out_dir} cannot be resumed without "
                             "their index (put it back, or start a new series)")
        if resume and self.pvd_path.exists():
            kept = []
            for t, p in read_pvd(self.pvd_path):
                if p.exists() and p.parent == self.out_dir.resolve():
                    kept.append((t, p.name))
                else:
                    warnings.warn(f"{self.pvd_path}: frame {p.name} at time {t!r} is missing or outside "
                                  f"{self.out_dir}; dropped from the series", RuntimeWarning, stacklevel=2)
            self.entries = kept
            self._write_index()
            self._remove_orphans()
            self._earlier_series = False
        else:
            self._earlier_series = True   # deleted by the first write that passes its checks

    # -- bookkeeping
    @property
    def times(self) -> list[float]:
        return [t for t, _ in self.entries]

    def __len__(self):
        return len(self.entries)

    def _index_of(self, fname: str) -> int:
        m = self._pattern.fullmatch(fname)
        return int(m.group(1)) if m else -1

    def _remove_orphans(self, all_frames: bool = False):
        listed = {f for _, f in self.entries}
        for p in self.out_dir.iterdir():
            if self._pattern.fullmatch(p.name) and (all_frames or p.name not in listed):
                with contextlib.suppress(OSError):
                    p.unlink()
            elif (tmp := temporary_of(p.name)) and (self._pattern.fullmatch(tmp[0]) or tmp[0] == self.pvd_path.name):
                with contextlib.suppress(OSError):
                    p.unlink()   # temporary file of a killed writer

    def _write_index(self):
        atomic_write_text(self.pvd_path, _pvd_text(self.entries))

    # -- public
    def truncate_after(self, t: float) -> list[Path]:
        """Drop the frames with time > ``t`` (index first, then files); returns the deleted paths."""
        t = float(t)
        drop = [(tt, f) for tt, f in self.entries if tt > t]
        if not drop:
            return []
        self.entries = [(tt, f) for tt, f in self.entries if tt <= t]
        self._write_index()
        removed = []
        for _, f in drop:
            p = self.out_dir / f
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
                removed.append(p)
        return removed

    def write(self, time: float, points=None, point_data: dict | None = None,
              cell_data: dict | None = None) -> Path:
        """Write one frame at ``time`` and update the .pvd; returns the VTU path.

        ``points``: (n, 3) deformed positions (default: the mesh points). ``point_data``:
        name -> (n,) scalars or (n, k) vectors (k = 3 for ParaView vectors);
        ``cell_data``: name -> (m,) or (m, k), one row per triangle. Values are
        stored as float64. Non-finite values are refused with a ValueError naming the field.
        """
        import meshio
        try:
            time = float(time)
        except (TypeError, ValueError):
            raise ValueError(f"time must be a number, got {time!r}") from None
        if not math.isfinite(time):
            raise ValueError(f"time is {_nonfinite_name(time)}; refusing to write a frame")
        if self.entries and not time > self.entries[-1][0]:
            raise ValueError(f"{self.pvd_path.name}: time {time!r} does not follow the last frame's time "
                             f"{self.entries[-1][0]!r} (times must increase; after a resume call "
                             "truncate_after(checkpoint_time) first)")
        pts = self.points if points is None else np.asarray(points, dtype=float)
        if pts.shape != (self.n_points, 3):
            raise ValueError(f"points have shape {pts.shape}, the mesh has ({self.n_points}, 3)")
        if not np.all(np.isfinite(pts)):
            raise ValueError(f"points hold non-finite values at {int((~np.isfinite(pts)).any(axis=1).sum())} "
                             "vertices; refusing to write a frame of a broken state")
        pdata = {k: _check_field("point", k, v, self.n_points, "vertex") for k, v in (point_data or {}).items()}
        cdata = {k: [_check_field("cell", k, v, self.n_cells, "triangle")]
                 for k, v in (cell_data or {}).items()}
        if self._earlier_series:
            self._remove_orphans(all_frames=True)
            if self.pvd_path.exists():
                self.pvd_path.unlink()
            self._earlier_series = False
        index = max((self._index_of(f) for _, f in self.entries), default=-1) + 1
        fname = f"{self.name}_{index:06d}.vtu"
        mesh = meshio.Mesh(pts, [("triangle", self.triangles)], point_data=pdata, cell_data=cdata)
        path = atomic_write(self.out_dir / fname, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))
        self.entries.append((time, fname))
        self._write_index()
        return path

    def frames(self) -> Iterator[Frame]:
        """Read the written frames back, in order."""
        for t, f in self.entries:
            yield read_frame(self.out_dir / f, t)


# ----------------------------------------------------------------------------- checkpoints

class CheckpointError(ValueError):
    """A checkpoint file is missing, unreadable or not a femshell checkpoint."""


def _prev_path(path: Path) -> Path:
    return path.with_name(path.name + ".prev")


#: checkpoints this process wrote (and verified), by resolved path -> their (inode, size, mtime):
#: rotating one into ``.prev`` needs no second read
_VERIFIED: dict = {}


def _signature(path: Path) -> tuple:
    st = path.stat()
    return st.st_ino, st.st_size, st.st_mtime_ns


def _readable(path: Path) -> bool:
    """Whether ``path`` is a readable checkpoint (one this process wrote and nobody changed since, or
    one that reads back)."""
    if _VERIFIED.get(str(path.resolve())) == _signature(path):
        return True
    try:
        _read_checkpoint(path)
    except (CheckpointError, OSError):
        return False
    return True


def save_checkpoint(path, state: dict, meta: dict | None = None) -> Path:
    """Save a checkpoint atomically; the checkpoint it replaces is kept as ``<path>.prev``.

    ``state``: name -> numpy array, float, int, bool or str (names must not start
    with "__"). Float values must be finite (ValueError naming the key otherwise).
    ``meta``: JSON-serialisable dict (time, step, scene, parameters ...; no NaN).
    The file is an uncompressed ``.npz`` (readable without pickle) with the meta as
    JSON inside. Sequence: new file complete in a temporary file -> the current
    checkpoint is linked (or copied) to ``.prev`` atomically -> the new file replaces
    the current one. At every instant ``path`` is a complete checkpoint. A current file
    that does not read (the one a resume fell back from) is replaced without becoming
    ``.prev``: the readable ``.prev`` stays the fallback.
    """
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"checkpoint path must end in .npz, got {path.name}")
    if not isinstance(state, dict):
        raise TypeError(f"state must be a dict, got {type(state).__name__}")
    if meta is not None and not isinstance(meta, dict):
        raise TypeError(f"meta must be a dict, got {type(meta).__name__}")
    kinds, arrays = {}, {}
    for k, v in state.items():
        if not isinstance(k, str) or not k or k.startswith("__"):
            raise ValueError(f"checkpoint state keys must be non-empty strings not starting with '__', got {k!r}")
        if isinstance(v, (bool, np.bool_)):
            kinds[k], a = "bool", np.asarray(bool(v))
        elif isinstance(v, (int, np.integer)):
            if not -2**63 <= int(v) < 2**63:
                raise ValueError(f"checkpoint state '{k}' = {v} does not fit in 64 bits")
            kinds[k], a = "int", np.asarray(int(v), dtype=np.int64)
        elif isinstance(v, (float, np.floating)):
            kinds[k], a = "float", np.asarray(float(v))
        elif isinstance(v, str):
            kinds[k], a = "str", np.asarray(v)
        elif isinstance(v, np.ndarray):
            kinds[k], a = "array", v
            if a.dtype.kind not in "biufcUS":
                raise TypeError(f"checkpoint state '{k}' has dtype {a.dtype}; only numeric, bool and "
                                "string arrays are stored (no pickle)")
        else:
            raise TypeError(f"checkpoint state '{k}' is a {type(v).__name__}; store numpy arrays, "
                            "numbers or strings")
        if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
            bad = a[~np.isfinite(a)].flat[0]
            raise ValueError(f"{path.name}: state '{k}' holds non-finite values ({_nonfinite_name(bad)}); "
                             "refusing to checkpoint a broken state")
        arrays[k] = a
    header = {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "kinds": kinds,
              "meta": to_json_safe(meta or {}, where=f"{path.name} meta")}
    arrays[_HEADER_KEY] = np.frombuffer(json.dumps(header, allow_nan=False).encode("utf-8"), dtype=np.uint8)

    if path.is_dir():
        raise ValueError(f"checkpoint path {path} is a directory")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        _read_checkpoint(tmp)   # verify what was written before it replaces anything
        if path.exists() and _readable(path):
            prev, prev_tmp = _prev_path(path), _tmp_name(_prev_path(path))
            try:
                os.link(path, prev_tmp)
            except OSError:
                shutil.copy2(path, prev_tmp)
            os.replace(prev_tmp, prev)
        os.replace(tmp, path)
        _VERIFIED[str(path.resolve())] = _signature(path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        _raise_for_target(exc, tmp, path)
        raise
    _fsync_dir(path.parent)
    return path


def _read_checkpoint(path: Path):
    try:
        # our own handle: np.load leaks the one it opens when the file is not an archive
        with open(path, "rb") as fh:
            # anything but a zip archive would reach np.load's pickle branch and its advice to unpickle
            if fh.read(4) != b"PK\x03\x04":
                raise CheckpointError(f"{path}: not a femshell checkpoint (not an .npz archive)")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as z:
                if _HEADER_KEY not in z.files:
                    raise CheckpointError(f"{path}: not a femshell checkpoint (no header)")
                header = json.loads(bytes(z[_HEADER_KEY]).decode("utf-8"))
                if not isinstance(header, dict) or not isinstance(header.get("kinds"), dict):
                    raise CheckpointError(f"{path}: not a femshell checkpoint (malformed header)")
                if header.get("format") != CHECKPOINT_FORMAT:
                    raise CheckpointError(f"{path}: not a femshell checkpoint (format {header.get('format')!r})")
                if header.get("version", 0) > CHECKPOINT_VERSION:
                    raise CheckpointError(f"{path}: checkpoint version {header.get('version')} is newer than "
                                          f"this femshell reads ({CHECKPOINT_VERSION})")
                kinds = header["kinds"]
                missing = sorted(set(kinds) - set(z.files))
                if missing:
                    raise CheckpointError(f"{path}: state entries missing: {', '.join(missing)}")
                state = {}
                for k, kind in kinds.items():
                    a = z[k]   # reading each member checks its CRC
                    if kind == "array":
                        state[k] = a
                    elif kind == "float":
                        state[k] = float(a)
                    elif kind == "int":
                        state[k] = int(a)
                    elif kind == "bool":
                        state[k] = bool(a)
                    elif kind == "str":
                        state[k] = str(a)
                    else:
                        raise CheckpointError(f"{path}: unknown kind {kind!r} of state '{k}'")
                return state, header.get("meta", {})
    except CheckpointError:
        raise
    except FileNotFoundError:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, KeyError, EOFError, json.JSONDecodeError,
            UnicodeDecodeError, TypeError) as e:
        raise CheckpointError(f"{path}: corrupt or unreadable checkpoint ({type(e).__name__}: {e})") from None


def load_checkpoint(path) -> tuple[dict, dict]:
    """Load ``(state, meta)`` saved by :func:`save_checkpoint`.

    If ``path`` is corrupt (truncated, bad CRC, not a checkpoint) or missing while
    ``<path>.prev`` exists, the previous checkpoint is loaded instead with a
    RuntimeWarning (the resumed run then repeats the steps after that checkpoint).
    Raises FileNotFoundError when neither exists and CheckpointError (a ValueError)
    when no readable checkpoint is left.
    """
    path = Path(path)
    prev = _prev_path(path)
    if not path.exists() and not prev.exists():
        raise FileNotFoundError(f"{path}: no checkpoint (and no {prev.name}) to resume from")
    try:
        return _read_checkpoint(path)
    except (CheckpointError, FileNotFoundError) as e:
        first = e if path.exists() else FileNotFoundError(f"{path}: missing")
        if not prev.exists():
            raise
    try:
        state, meta = _read_checkpoint(prev)
    except CheckpointError as e2:
        raise CheckpointError(f"no readable checkpoint: {first}; and {e2}") from None
    warnings.warn(f"{first}; loaded the previous checkpoint {prev.name} instead", RuntimeWarning, stacklevel=2)
    return state, meta


# ----------------------------------------------------------------------------- continuation branches

def _csv_cell(v):
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return v


def write_branch_csv(branch, path) -> Path:
    """Write a :class:`~femshell.solvers.continuation.Branch`'s table as CSV, atomically.

    One column per key of any row (first-seen order), one line per row; floats in shortest
    round-trip form, booleans as 0/1, missing values empty. Returns the path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = StringIO()
    cols = branch.columns
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in branch.rows:
        w.writerow([_csv_cell(r.get(k)) for k in cols])
    return atomic_write_text(path, buf.getvalue())


def _slug(s):
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in str(s)) or "branch"


def write_special_points(branch, directory, mesh_writer=None, prefix=None) -> list:
    """Write every special point of ``branch``: ``mesh_writer(stem, u, modes)`` and a JSON summary.

    ``mesh_writer(stem: Path, u: ndarray, modes: dict[str, ndarray])`` gets the file stem
    ``directory/<prefix>-special-<k>-<kind>`` (it adds its own extension), the state and the
    critical modes (``"mode_0"``, ...) as vectors of the problem's unknowns, and may return the
    path it wrote. ``directory/<prefix>-special-points.json`` lists kind, parameter,
    multiplicity, eigenvalues, inertia and the file of each point (``prefix`` defaults to the
    branch's label). Returns what the writer returned (the stems when it returned None).
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    prefix = prefix or _slug(branch.label)
    out, meta = [], []
    for k, p in enumerate(branch.special_points):
        stem = directory / f"{prefix}-special-{k:02d}-{p.kind}"
        written = None
        if mesh_writer is not None:
            modes = {f"mode_{j}": p.modes[:, j] for j in range(p.modes.shape[1])}
            written = mesh_writer(stem, p.u, modes)
        out.append(written if written is not None else stem)
        meta.append({"kind": p.kind, "label": p.label, "parameter": p.parameter, "s": p.s,
                     "multiplicity": p.multiplicity, "n_negative_before": p.n_negative_before,
                     "n_negative_after": p.n_negative_after, "located": p.located,
                     "bracket": [finite_or_none(float(x)) for x in p.bracket],
                     "eigenvalues": [finite_or_none(float(x)) for x in np.asarray(p.eigenvalues)],
                     "step": p.step, "file": str(out[-1])})
    atomic_write_text(directory / f"{prefix}-special-points.json", json.dumps(
        {"branch": branch.label, "status": branch.status, "special_points": meta}, indent=1))
    return out
