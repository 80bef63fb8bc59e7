"""Argument checks shared by the modules: a ValueError that names the argument and its range."""

from __future__ import annotations

import math

import numpy as np


def finite(name, v, lo=None, hi=None, lo_open=False, hi_open=False, text=None) -> float:
    """``float(v)``, finite and within the bounds (open or closed), or a ValueError naming ``name``."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {v!r}") from None
    bad = not math.isfinite(v)
    if lo is not None:
        bad |= (v <= lo) if lo_open else (v < lo)
    if hi is not None:
        bad |= (v >= hi) if hi_open else (v > hi)
    if bad:
        rng = text or (f"{'(' if lo_open else '['}{'-inf' if lo is None else lo}, "
                       f"{'inf' if hi is None else hi}{')' if hi_open or hi is None else ']'}")
        raise ValueError(f"{name} must be a finite number in {rng}, got {v!r}")
    return v


def integer(name, v, lo: int, what: str | None = None, hi: int | None = None) -> int:
    """``int(v)`` when v is a whole number in [lo, hi] (an int, a float like 3.0, or a 0-d array as
    np.load gives), or a ValueError naming ``name`` (``what``: the allowed values, for the message)."""
    if isinstance(v, np.ndarray) and v.shape == ():
        v = v.item()
    ok = (not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
          and math.isfinite(v) and int(v) == v and v >= lo and (hi is None or v <= hi))
    if not ok:
        raise ValueError(f"{name} must be {what or f'an integer >= {lo}'}, got {v!r}")
    return int(v)


def finite_vector(name, value, size: int, what: str | None = None) -> np.ndarray:
    """``value`` as a float array of shape (size,) with finite entries, or a ValueError naming ``name``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be {what or f'{size} finite numbers'}, got {value!r}")
    return v


def real_array(name, value) -> np.ndarray:
    """``value`` as a float array, or a ValueError naming ``name`` when it is complex or not numbers
    (numpy would drop an imaginary part with only a warning)."""
    a = np.asarray(value)
    if np.iscomplexobj(a):
        raise ValueError(f"{name} must be real numbers, got complex values (dtype {a.dtype})")
    try:
        return np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got dtype {a.dtype}") from None


def surface(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    """``(points, triangles)`` as float (n, 3) and integer (m, 3) arrays whose indices are vertices,
    or a ValueError naming what is wrong (numpy would read a negative index as counting from the end)."""
    pts = real_array("points", points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    tri = triangle_array(triangles)
    vertex_indices(tri, len(pts))
    return pts, tri


def flat_or_spatial_surface(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    """Like :func:`surface`, but (n, 2) points are taken too, as the plane z = 0."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    tri = triangle_array(triangles)
    vertex_indices(tri, len(pts))
    return pts, tri


def triangle_array(triangles, what: str = "triangles") -> np.ndarray:
    """``triangles`` as an (m, 3) integer array (an empty one of any dtype is taken), or a ValueError
    naming ``what``. The indices are checked against the vertices by :func:`vertex_indices`."""
    tri = np.asarray(triangles)
    if tri.ndim != 2 or tri.shape[1] != 3 or (tri.size and tri.dtype.kind not in "iu"):
        raise ValueError(f"{what} must be an (m, 3) integer array, got shape {tri.shape}, dtype {tri.dtype}")
    return tri if tri.dtype.kind in "iu" else tri.astype(np.int64)


def vertex_indices(tri, n: int, of: str = "points") -> None:
    """A ValueError unless every index of ``tri`` is in [0, n) (``of``: what the n are, for the message)."""
    if tri.size and tri.min() < 0:
        raise ValueError(f"triangles hold a negative vertex index ({tri.min()}); indices run from 0")
    if tri.size and tri.max() >= n:
        raise ValueError(f"triangles index vertex {tri.max()} but there are only {n} {of}")
