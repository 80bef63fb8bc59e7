"""Vertex fields on a triangulated surface: argument checks and lumped vertex areas."""

from __future__ import annotations

import numpy as np

from .._checks import integer, triangle_array, vertex_indices
from ..geometry import triangle_areas


def _mesh(points, triangles):
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    tri = triangle_array(triangles)
    vertex_indices(tri, len(pts))
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"points hold NaN or infinity at {int((~np.isfinite(pts)).any(axis=1).sum())} vertices")
    return pts, tri.astype(np.int64)


def _count(name, v, lo, hi):
    """An integer argument in [lo, hi] (a whole float such as 18.0 is accepted)."""
    return integer(name, v, lo, f"an integer in [{lo}, {hi}]", hi)


def _field(values, n, name="values"):
    v = np.asarray(values, dtype=float)
    if v.shape != (n,):
        raise ValueError(f"{name} must have one value per vertex, shape ({n},), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} holds {int((~np.isfinite(v)).sum())} non-finite value(s)")
    return v


def vertex_areas(points, triangles) -> np.ndarray:
    """Lumped vertex areas, one third of the adjacent triangle areas (length²), shape (n,)."""
    pts, tri = _mesh(points, triangles)
    return np.bincount(tri.ravel(), weights=np.repeat(triangle_areas(pts, tri) / 3.0, 3), minlength=len(pts))
