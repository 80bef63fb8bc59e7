"""ParaView time series: one VTU file per frame and a PVD collection listing ``(time, file)``;
times round-trip bit for bit, and a resumed run truncates the series at its checkpoint time."""

from __future__ import annotations

import contextlib
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from .._checks import triangle_array, vertex_indices
from ..mesh.io import meshio_read
from .files import _nonfinite_name, atomic_write, atomic_write_text, temporary_of

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
