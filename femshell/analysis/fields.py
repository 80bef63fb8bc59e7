"""Vertex fields on a triangulated surface: argument checks and lumped vertex areas."""

from __future__ import annotations

import numpy as np

from .._checks import flat_or_spatial_surface, integer
from ..geometry import triangle_areas


def _mesh(points, triangles):
    pts, tri = flat_or_spatial_surface(points, triangles)
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
