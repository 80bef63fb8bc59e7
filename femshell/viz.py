"""Pictures and movies: pyvista (off-screen) shell views, matplotlib bifurcation diagrams, GIF movies.

``import femshell.viz`` is cheap: pyvista and matplotlib are imported inside the
functions. pyvista renders off-screen through EGL (Mesa llvmpipe, no display
server); ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` is set (unless the
environment already sets it) before pyvista is imported, which skips a failed
X11 attempt. Every picture is written atomically (:func:`femshell.io.atomic_write`).

Views (the seed paper's figures):

* :func:`top_view`: camera on the +z axis looking down -z (at a sphere's north
  pole, where the initial spot sits), parallel projection, smooth shading,
  coloured by a field (the concentration c) with a scalar bar titled with the
  field's name.
* :func:`side_view`: camera on the -y axis looking along +y, z up, coloured by
  the distance from the centre (bulges stand out) unless another field is given.
* :func:`view_grid`: several fields of one shape side by side (top views).
* :func:`bifurcation_diagram`: stable branches solid, unstable dashed, folds
  as triangles and branch points as circles, with labels.
* :func:`render_movie`: GIF through Pillow (always available with matplotlib);
  MP4 only when ``imageio_ffmpeg`` is importable.
* :func:`render_run`: the pictures and the movie of a finished run directory
  (backs ``femshell render DIR``).

Timing on this machine (800 x 800, 50k triangles): the first picture of a
process about 3 s (EGL context and pyvista import), later ones 0.4-1 s.
"""

from __future__ import annotations

import itertools
import math
import os
import re
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from ._checks import triangle_array, vertex_indices
from .io import atomic_write, find_series, read_frame, read_pvd

__all__ = ["top_view", "side_view", "view_grid", "bifurcation_diagram", "render_movie", "render_run",
           "WINDOW_SIZE"]

WINDOW_SIZE = (800, 800)
#: the most frames render_run puts in a movie (frames are subsampled evenly beyond this)
MAX_MOVIE_FRAMES = 300


# ----------------------------------------------------------------------------- pyvista helpers

def _pyvista():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv        # deferred: pyvista/VTK take seconds to import
    pv.OFF_SCREEN = True
    return pv


def _polydata(points, triangles):
    pv = _pyvista()
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    tri = triangle_array(triangles).astype(np.int64)
    vertex_indices(tri, len(pts))
    if not np.all(np.isfinite(pts)):
        raise ValueError("points hold NaN or infinity; nothing sensible to draw")
    faces = np.column_stack([np.full(len(tri), 3, dtype=np.int64), tri]).ravel()
    return pv.PolyData(pts, faces)


def _scalars(values, n_points, n_cells, default_name):
    """(name, array, preference) from an array or a (name, array) pair; checks length and finiteness."""
    name = default_name
    if isinstance(values, tuple) and len(values) == 2 and isinstance(values[0], str):
        name, values = values
    a = np.asarray(values, dtype=float)
    if a.ndim == 2 and a.shape[1] == 3:
        a = np.linalg.norm(a, axis=1)   # vectors are shown by magnitude
        name = f"|{name}|"
    if a.ndim != 1 or len(a) not in (n_points, n_cells):
        raise ValueError(f"field '{name}' has shape {np.shape(values)}; expected ({n_points},) per vertex "
                         f"or ({n_cells},) per triangle")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"field '{name}' holds NaN or infinity at {int((~np.isfinite(a)).sum())} entries")
    pref = "point" if len(a) == n_points else "cell"
    return name, a, pref


def _clim(a, clim):
    if clim is not None:
        try:
            lo, hi = float(clim[0]), float(clim[1])
        except (TypeError, ValueError, IndexError):
            lo = hi = math.nan
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"clim must be two finite numbers (low, high) with low <= high, got {clim!r}")
    else:
        lo, hi = float(a.min()), float(a.max())
        if lo != 0 and abs(lo) < 1e-9 * abs(hi):   # 1e-108 on the bar means 0
            lo = 0.0
    if not hi > lo:   # a constant field: give the colour map a range so the picture is defined
        hi = lo + (abs(lo) * 1e-3 if lo != 0 else 1.0)
    return lo, hi


def _picture_path(path, suffixes=(".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")) -> Path:
    """``path`` as a Path, checked before any drawing: a known picture suffix, not a directory."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"picture path {path} must end in one of {', '.join(suffixes)}")
    if path.is_dir():
        raise ValueError(f"picture path {path} is a directory")
    return path


def _check_cmap(cmap):
    import matplotlib           # deferred: matplotlib is slow to import

    if isinstance(cmap, str) and cmap not in matplotlib.colormaps:
        raise ValueError(f"unknown colour map {cmap!r}; e.g. viridis, plasma, magma, inferno, cividis, coolwarm "
                         "(any name in matplotlib.colormaps)")


def _render(points, triangles, scalars, path, *, view, title, cmap, clim, scalar_name,
            window_size=WINDOW_SIZE, show_edges=False):
    pv = _pyvista()
    path = _picture_path(path)
    _check_cmap(cmap)
    mesh = _polydata(points, triangles)
    name, a, pref = _scalars(scalars, mesh.n_points, mesh.n_cells, scalar_name)
    lo, hi = _clim(a, clim)
    pl = pv.Plotter(off_screen=True, window_size=tuple(window_size))
    try:
        pl.set_background("white")
        pl.add_mesh(mesh, scalars=a, preference=pref, cmap=cmap, clim=(lo, hi), smooth_shading=True,
                    show_edges=show_edges, show_scalar_bar=True,
                    scalar_bar_args=dict(title=name, vertical=True, color="black", position_x=0.86,
                                         position_y=0.1, height=0.8, width=0.08, fmt="%.3g",
                                         title_font_size=20, label_font_size=16))
        if title:
            pl.add_text(str(title), position="upper_edge", font_size=12, color="black")
        _set_camera(pl, points, view)
        atomic_write(path, lambda tmp: pl.screenshot(str(tmp)))
    finally:
        pl.close()
    return Path(path)


#: fraction of the picture width left of the scalar bar, where the shape is centred
_FREE_WIDTH = 0.84


def _set_camera(pl, points, view, free_width=_FREE_WIDTH, margin=1.06, aspect=None):
    """Parallel projection that fills the picture left of the scalar bar with the shape."""
    p = np.asarray(points, dtype=float)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = np.maximum(0.5 * (hi - lo), 1e-12 * max(float(np.abs(p).max()), 1.0))
    d = 4.0 * float(np.linalg.norm(half)) + 1.0
    if view == "top":       # look down -z; x to the right, y up on the picture
        normal, up, right = np.array([0, 0, 1.0]), np.array([0, 1.0, 0]), np.array([1.0, 0, 0])
    elif view == "bottom":  # look up +z; x to the left
        normal, up, right = np.array([0, 0, -1.0]), np.array([0, 1.0, 0]), np.array([-1.0, 0, 0])
    elif view == "side":    # look along +y; x to the right, z up
        normal, up, right = np.array([0, -1.0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0])
    else:
        raise ValueError(f"unknown view {view!r}")
    if aspect is None:
        w, h = pl.window_size
        aspect = w / h
    half_h = float(np.abs(up) @ half)
    half_w = float(np.abs(right) @ half)
    scale = margin * max(half_h, half_w / (aspect * free_width))    # world half-height of the picture
    # shift the focal point so the shape's centre sits at free_width / 2 of the picture width
    focal = centre + right * (0.5 - free_width / 2) * 2 * scale * aspect
    pl.camera_position = [tuple(focal + d * normal), tuple(focal), tuple(up)]
    pl.enable_parallel_projection()
    pl.camera.parallel_scale = scale
    pl.reset_camera_clipping_range()


def _surface_centroid(points, triangles):
    """Area-weighted centroid of a triangulated surface (the centre of a sphere, bulges barely move it)."""
    p = np.asarray(points, dtype=float)
    t = np.asarray(triangles, dtype=np.int64)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if not area.sum() > 0:
        return p.mean(axis=0)
    return (area[:, None] * (a + b + c) / 3).sum(axis=0) / area.sum()


# ----------------------------------------------------------------------------- views

def top_view(points, triangles, scalars, path, title=None, cmap="viridis", clim=None, *,
             scalar_name: str = "value", window_size=WINDOW_SIZE, show_edges=False) -> Path:
    """Top view PNG: camera on +z looking down -z, parallel projection, smooth shading.

    ``scalars``: (n,) per vertex or (m,) per triangle, or a pair ``(name, array)``
    (the name titles the scalar bar; otherwise ``scalar_name``); (n, 3) vectors are
    shown by magnitude. ``clim``: (min, max) of the colour map (default: the field's
    range; give it explicitly to compare pictures). Writes ``path`` atomically and returns it.
    """
    return _render(points, triangles, scalars, path, view="top", title=title, cmap=cmap, clim=clim,
                   scalar_name=scalar_name, window_size=window_size, show_edges=show_edges)


def side_view(points, triangles, path, scalars=None, title=None, cmap="viridis", clim=None, *,
              centre=None, scalar_name: str = "value", window_size=WINDOW_SIZE, show_edges=False) -> Path:
    """Side view PNG: camera on -y looking along +y, z up, parallel projection.

    Coloured by ``scalars`` if given (as in :func:`top_view`), else by the distance
    from ``centre`` (default: the area-weighted centroid of the surface), the field
    "radius", which shows bulges of a sphere.
    """
    if scalars is None:
        pts = np.asarray(points, dtype=float)
        c = _surface_centroid(pts, triangles) if centre is None else np.asarray(centre, dtype=float)
        scalars = ("radius", np.linalg.norm(pts - c, axis=1))
    return _render(points, triangles, scalars, path, view="side", title=title, cmap=cmap, clim=clim,
                   scalar_name=scalar_name, window_size=window_size, show_edges=show_edges)


def view_grid(points, triangles, fields: dict, path, view: str = "top", ncols: int | None = None,
              cmap="viridis", panel_size=(400, 400), title=None) -> Path:
    """Several fields of one shape side by side: ``fields`` maps name -> (n,) or (m,) array."""
    pv = _pyvista()
    path = _picture_path(path)
    _check_cmap(cmap)
    if not fields:
        raise ValueError("view_grid needs at least one field")
    mesh = _polydata(points, triangles)
    k = len(fields)
    ncols = ncols or min(k, 3)
    nrows = math.ceil(k / ncols)
    pl = pv.Plotter(off_screen=True, shape=(nrows, ncols),
                    window_size=(panel_size[0] * ncols, panel_size[1] * nrows))
    try:
        pl.set_background("white")
        for i, (name, values) in enumerate(fields.items()):
            pl.subplot(i // ncols, i % ncols)
            name, a, pref = _scalars((name, values), mesh.n_points, mesh.n_cells, name)
            m = mesh.copy()
            pl.add_mesh(m, scalars=a, preference=pref, cmap=cmap, clim=_clim(a, None), smooth_shading=True,
                        scalar_bar_args=dict(title=name, vertical=True, color="black", fmt="%.3g",
                                             position_x=0.86, position_y=0.1, height=0.8, width=0.08,
                                             title_font_size=16, label_font_size=12))
            if title and i == 0:
                pl.add_text(str(title), position="upper_left", font_size=10, color="black")
            _set_camera(pl, points, view, aspect=panel_size[0] / panel_size[1])
        atomic_write(path, lambda tmp: pl.screenshot(str(tmp)))
    finally:
        pl.close()
    return Path(path)


# ----------------------------------------------------------------------------- bifurcation diagrams

_FOLD = {"fold", "lp", "limit", "limit point", "turning point"}
_BRANCH = {"branch", "bp", "branch point", "bifurcation", "pitchfork", "bifurcation point"}


def _columns(table) -> dict:
    if table is None or isinstance(table, (str, bytes)) or not hasattr(table, "__iter__"):
        raise TypeError(f"table must be a dict of columns or a list of row dicts, got {type(table).__name__}")
    if isinstance(table, dict):
        cols = {k: list(np.asarray(v).tolist()) if isinstance(v, np.ndarray) else list(v)
                for k, v in table.items()}
        lengths = {k: len(v) for k, v in cols.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"table columns have different lengths: {lengths}")
        return cols
    rows = list(table)
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    return {k: [r.get(k) for r in rows] for k in keys}


def _stable_flags(values, n):
    if values is None:
        return [True] * n
    out = []
    for v in values:
        if isinstance(v, str):   # a column read from CSV: bool("False") would be True
            word = v.strip().lower()
            if word in ("", "none", "nan"):
                v = None
            elif word in ("true", "1", "yes", "stable"):
                v = True
            elif word in ("false", "0", "no", "unstable"):
                v = False
            else:
                raise ValueError(f"stable flag {v!r} is not true/false/1/0 (or empty for unknown)")
        if v is None or (isinstance(v, float) and math.isnan(v)):
            out.append(None)
        else:
            out.append(bool(v))
    return out


def bifurcation_diagram(table, x: str = "parameter", y: str = "amplitude", stable_key: str = "stable",
                        special_points=None, path="bifurcation.png", *, branch_key: str = "branch",
                        special_key: str = "special", title=None, xlabel=None, ylabel=None,
                        figsize=(6.4, 4.8), dpi=125) -> Path:
    """Bifurcation diagram PNG (matplotlib, Agg), written atomically; returns the path.

    ``table``: dict of columns or a list of row dicts with at least ``x`` and ``y``.
    Optional columns: ``stable_key`` (bool; missing or None = unknown, dotted),
    ``branch_key`` (rows of one branch are joined in table order, each branch its own
    colour), ``special_key`` (a label string such as "fold", "LP", "BP" marks a row as a
    special point). Stable pieces solid, unstable dashed; a piece ends where the
    stability changes, sharing that point with the next piece.

    ``special_points``: extra points, a list of dicts with ``x``, ``y`` (or the keys
    named by ``x`` and ``y``), ``kind`` ("fold"/"LP": triangle, "branch"/"BP": circle,
    anything else: square) and optional ``label``.
    """
    import matplotlib           # deferred: matplotlib is slow to import
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    path = _picture_path(path, (".png",))
    cols = _columns(table)
    for k in (x, y):
        if k not in cols:
            raise ValueError(f"bifurcation table has no column '{k}' (columns: {', '.join(cols)})")
    xs = np.asarray(cols[x], dtype=float)
    ys = np.asarray(cols[y], dtype=float)
    n = len(xs)
    stable = _stable_flags(cols.get(stable_key), n)
    branches = list(cols[branch_key]) if branch_key in cols else [0] * n

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    colours = matplotlib.colormaps["tab10"]
    order = list(dict.fromkeys(branches))
    style = {True: "-", False: "--", None: ":"}
    for bi, b in enumerate(order):
        idx = [i for i in range(n) if branches[i] == b]
        colour = colours(bi % 10)
        start = 0
        for j in range(1, len(idx) + 1):
            if j == len(idx) or stable[idx[j]] != stable[idx[start]]:
                seg = idx[start:j + 1] if j < len(idx) else idx[start:j]
                ok = np.isfinite(xs[seg]) & np.isfinite(ys[seg])
                s = stable[idx[start]]
                ax.plot(xs[seg][ok], ys[seg][ok], style[s], color=colour, lw=1.8 if s else 1.4,
                        marker="." if len(seg) == 1 else None)
                start = j
        if len(order) > 1:
            ax.plot([], [], "-", color=colour, label=f"branch {b}")

    points = []
    if special_key in cols:
        for i, s in enumerate(cols[special_key]):
            if isinstance(s, str) and s.strip():
                points.append({"x": xs[i], "y": ys[i], "kind": s, "label": s})
    for p in special_points or []:
        px = p.get("x", p.get(x))
        py = p.get("y", p.get(y))
        if px is None or py is None:
            raise ValueError(f"special point {p!r} needs 'x' and 'y' (or '{x}' and '{y}')")
        points.append({"x": float(px), "y": float(py), "kind": str(p.get("kind", "")),
                       "label": p.get("label", p.get("kind", ""))})
    kinds_seen = set()
    for p in points:
        kind = p["kind"].strip().lower()
        if kind in _FOLD:
            marker, key = "^", "fold"
        elif kind in _BRANCH:
            marker, key = "o", "branch point"
        else:
            marker, key = "s", kind or "special point"
        ax.plot([p["x"]], [p["y"]], marker, ms=8, mfc="white" if key == "branch point" else "black",
                mec="black", mew=1.5, zorder=5)
        kinds_seen.add((key, marker))
        if p["label"]:
            ax.annotate(str(p["label"]), (p["x"], p["y"]), textcoords="offset points", xytext=(6, 6),
                        fontsize=9)
    handles = [Line2D([], [], ls="-", color="0.3", label="stable")]
    if any(s is False for s in stable):
        handles.append(Line2D([], [], ls="--", color="0.3", label="unstable"))
    if any(s is None for s in stable):
        handles.append(Line2D([], [], ls=":", color="0.3", label="stability unknown"))
    for key, marker in sorted(kinds_seen):
        handles.append(Line2D([], [], ls="", marker=marker, color="black",
                              mfc="white" if key == "branch point" else "black", label=key))
    branch_handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + branch_handles, fontsize=8, loc="best")
    ax.set_xlabel(xlabel or x)
    ax.set_ylabel(ylabel or y)
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))


# ----------------------------------------------------------------------------- movies

def _frame_image(item):
    from PIL import Image       # deferred: only the movie writers need it
    if isinstance(item, (str, os.PathLike)):
        with Image.open(item) as im:
            return im.convert("RGB")
    if isinstance(item, Image.Image):
        return item.convert("RGB")
    a = np.asarray(item)
    if a.dtype != np.uint8:
        raise ValueError(f"movie frames given as arrays must be uint8 images, got dtype {a.dtype}")
    return Image.fromarray(a[..., :3] if a.ndim == 3 else a).convert("RGB")


def _iter_frames(frames, n_frames):
    if callable(frames):
        if n_frames is None:
            raise ValueError("render_movie with a callback needs n_frames")
        for i in range(n_frames):
            yield _frame_image(frames(i))
    else:
        for item in frames:
            yield _frame_image(item)


def _check_fps(fps, ext=".gif"):
    # a GIF stores each frame's duration in 1/100 s in 16 bits: 0.002 fps (500 s a frame) is near that
    # limit, and viewers play frames shorter than 2/100 s at 1/10 s, so a GIF's rate is at most 50 fps
    hi = 50 if ext == ".gif" else 1000
    if not (isinstance(fps, (int, float, np.integer, np.floating)) and 0.002 <= fps <= hi):
        raise ValueError(f"fps must be a number in [0.002, {hi}] frames per second{' for a GIF' if hi == 50 else ''}, "
                         f"got {fps!r}")


def render_movie(frames: Sequence | Iterable | Callable, path, fps: float = 5.0, *, n_frames: int | None = None,
                 loop: int = 0) -> Path:
    """A movie from PNG paths, PIL images or uint8 arrays, or ``frames(i)`` for i < ``n_frames``.

    ``.gif`` (Pillow; frames of other sizes are resized to the first frame's size,
    each frame gets its own adaptive palette, dithered) or ``.mp4`` (only when ``imageio_ffmpeg``
    is importable; RuntimeError otherwise). Written atomically; returns the path.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".gif", ".mp4"):     # before any frame is computed
        raise ValueError(f"movie format {ext or '(none)'} not supported; use .gif (or .mp4 with imageio-ffmpeg)")
    _check_fps(fps, ext)
    it = _iter_frames(frames, n_frames)
    try:
        first = next(it)
    except StopIteration:
        raise ValueError("render_movie: no frames") from None
    size = first.size

    def fit(im):
        return im if im.size == size else im.resize(size)

    if ext == ".gif":
        from PIL import Image

        def to_palette(im):
            # adaptive 256-colour palette per frame, then Floyd-Steinberg dithering against it:
            # smooth colour maps without the banding of plain median-cut quantisation
            pal = im.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
            return im.quantize(palette=pal, dither=Image.Dither.FLOYDSTEINBERG)

        def write(tmp):
            to_palette(first).save(tmp, format="GIF", save_all=True,
                                   append_images=(to_palette(fit(im)) for im in it),
                                   duration=int(round(1000 / fps)), loop=loop, optimize=False, disposal=1)
        return atomic_write(path, write)
    try:
        import imageio_ffmpeg   # deferred: optional, only for MP4
    except ImportError:
        raise RuntimeError("mp4 movies need the imageio-ffmpeg package (pip install imageio-ffmpeg); "
                           "write a .gif instead") from None
    w, h = size[0] + size[0] % 2, size[1] + size[1] % 2   # yuv420p needs even sizes

    def write(tmp):
        gen = imageio_ffmpeg.write_frames(str(tmp), (w, h), fps=fps, pix_fmt_in="rgb24", macro_block_size=1)
        gen.send(None)
        try:
            for im in itertools.chain([first], it):
                a = np.zeros((h, w, 3), np.uint8)
                a[:size[1], :size[0]] = np.asarray(fit(im))
                gen.send(a.tobytes())
        finally:
            gen.close()
    return atomic_write(path, write)


# ----------------------------------------------------------------------------- a whole run

def _pick_field(frame, field):
    pdata, cdata = frame.point_data, frame.cell_data
    if field is not None:
        if field in pdata:
            return field, pdata[field]
        if field in cdata:
            return field, cdata[field]
        raise ValueError(f"{frame.path}: no field '{field}' (point fields: {', '.join(pdata) or 'none'}; "
                       f"cell fields: {', '.join(cdata) or 'none'})")
    if "c" in pdata:
        return "c", pdata["c"]
    if "c" in cdata:
        return "c", cdata["c"]
    for d in (pdata, cdata):
        for k, v in d.items():
            if np.ndim(v) == 1:
                return k, v
    return "z", frame.points[:, 2]


def render_run(out_dir, field: str | None = None, *, series: str | None = None, every: int = 1,
               movie: bool = True, fps: float = 5.0, cmap: str = "viridis",
               pictures_dir: str = "pictures") -> list[Path]:
    """Pictures and a movie of a finished run directory (``femshell render DIR``).

    Reads ``out_dir``'s PVD/VTU time series (:func:`femshell.io.find_series`), writes
    a top view per frame (every ``every``-th frame, always including the last) coloured
    by ``field`` (default "c" when present, else the first scalar field, else z)
    with one colour range over all frames, into ``out_dir/pictures/top_NNNNNN.png``
    (replacing the ``top_NNNNNN.png`` of an earlier rendering; other files there are kept);
    a side view of the last frame ``pictures/side_last.png`` (coloured by radius);
    and ``out_dir/movie.gif`` of the top views (at most 300 frames, subsampled evenly).
    Returns the written paths.
    """
    out_dir = Path(out_dir)
    pvd = find_series(out_dir, series)
    entries = read_pvd(pvd)
    if not entries:
        raise ValueError(f"{pvd}: the time series has no frames")
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    if movie:
        _check_fps(fps)
    _check_cmap(cmap)
    chosen = list(range(0, len(entries), every))
    if chosen[-1] != len(entries) - 1:
        chosen.append(len(entries) - 1)

    def field_of(i, field):
        f = read_frame(entries[i][1], entries[i][0])
        name, v = _pick_field(f, field)
        v = np.asarray(v, dtype=float)
        return f, name, (np.linalg.norm(v, axis=1) if v.ndim == 2 else v)

    if field is None:   # chosen once, from the first frame: every frame is coloured by the same field
        field = field_of(chosen[0], None)[1]
        if field == "z":
            field = None

    # pass 1: one colour range over all frames, and every frame checked before any picture is
    # replaced (frames are read one at a time: long runs fit in memory)
    lo, hi = math.inf, -math.inf
    for i in chosen:
        f, _, v = field_of(i, field)
        try:
            _polydata(f.points, f.triangles)
        except ValueError as exc:
            raise ValueError(f"{entries[i][1]}: {exc}") from None
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{entries[i][1]}: the field to draw holds NaN or infinity")
        lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
    lo, hi = _clim(np.array([lo, hi]), None)     # the snap of a single picture's range (1e-108 -> 0)
    pic_dir = out_dir / pictures_dir
    pic_dir.mkdir(parents=True, exist_ok=True)
    written, tops = [], []
    for i in chosen:
        f, name, v = field_of(i, field)
        p = pic_dir / f"top_{i:06d}.png"
        top_view(f.points, f.triangles, (name, v), p, title=f"t = {f.time:.4g}", cmap=cmap, clim=(lo, hi))
        tops.append(p)
        written.append(p)
    for old in pic_dir.glob("top_*.png"):   # pictures of an earlier rendering of a longer series
        if old not in tops and re.fullmatch(r"top_\d{6}\.png", old.name):    # not a user's top_mine.png
            old.unlink()
    written.append(side_view(f.points, f.triangles, pic_dir / "side_last.png",
                             title=f"t = {f.time:.4g}", cmap=cmap))
    if movie:
        sel = tops
        if len(sel) > MAX_MOVIE_FRAMES:
            sel = [tops[j] for j in np.linspace(0, len(tops) - 1, MAX_MOVIE_FRAMES).round().astype(int)]
        written.append(render_movie(sel, out_dir / "movie.gif", fps=fps))
    return written
