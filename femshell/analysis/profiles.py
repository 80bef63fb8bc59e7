"""Binned means of a vertex field against the polar angle from a pole."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import finite_vector
from .fields import _count, _field, vertex_areas


@dataclass
class PolarProfile:
    """Binned means against the polar angle θ from the pole (radians, 0 at the pole).

    ``theta`` bin centres (k,), ``mean`` area-weighted means (k,) (NaN in empty bins),
    ``count`` vertices per bin (k,), ``edges`` bin edges (k+1,).
    """

    theta: np.ndarray
    mean: np.ndarray
    count: np.ndarray
    edges: np.ndarray


def polar_profile(points, values, n_bins: int = 18, *, triangles=None, pole=(0.0, 0.0, 1.0),
                  center=None) -> PolarProfile:
    """Means of a vertex field in bins of the polar angle (the paper's Fig. 6d: c and H against θ).

    The angle is measured at ``center`` (default: the centroid of the points) from the
    direction ``pole``. With ``triangles`` the mean is weighted by the lumped vertex
    areas, otherwise every vertex counts the same.

    >>> import numpy as np
    >>> from femshell.mesh.generators import sphere
    >>> from femshell.analysis import polar_profile
    >>> m = sphere(10.0, n_vertices=2000)
    >>> p = polar_profile(m.points, m.points[:, 2] / 10, n_bins=6, triangles=m.triangles)   # cos θ
    >>> np.round(p.theta, 2)                # bin centres: 30° bands
    array([0.26, 0.79, 1.31, 1.83, 2.36, 2.88])
    >>> exact = [0.933, 0.683, 0.25, -0.25, -0.683, -0.933]    # the area means of cos θ over the bands
    >>> bool(np.allclose(p.mean, exact, atol=0.01))
    True
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"points hold NaN or infinity at {int((~np.isfinite(pts)).any(axis=1).sum())} vertices")
    v = _field(values, len(pts), "values")
    n_bins = _count("n_bins", n_bins, 1, 100_000)
    p = finite_vector("pole", pole, 3)
    if not np.linalg.norm(p) > 0:
        raise ValueError(f"pole must be a non-zero 3-vector, got {pole!r}")
    p = p / np.linalg.norm(p)
    ctr = pts.mean(axis=0) if center is None else finite_vector("center", center, 3)
    d = pts - ctr
    r = np.linalg.norm(d, axis=1)
    theta = np.arccos(np.clip((d @ p) / np.maximum(r, 1e-300), -1.0, 1.0))
    w = np.ones(len(pts)) if triangles is None else vertex_areas(pts, triangles)
    edges = np.linspace(0.0, math.pi, int(n_bins) + 1)
    idx = np.clip(np.searchsorted(edges, theta, side="right") - 1, 0, int(n_bins) - 1)
    num = np.bincount(idx, weights=w * v, minlength=n_bins)
    den = np.bincount(idx, weights=w, minlength=n_bins)
    cnt = np.bincount(idx, minlength=n_bins)
    mean = np.divide(num, den, out=np.full(n_bins, np.nan), where=den > 0)
    return PolarProfile(0.5 * (edges[1:] + edges[:-1]), mean, cnt, edges)
