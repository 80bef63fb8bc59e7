r"""Linear (P1) interpolation of vertex fields from one flat triangulation to points of another.

What a refinement study needs to carry a state to a finer mesh of the same flat reference: each query
point q is located in a triangle (a, b, c) of the source mesh and gets

.. math:: f(q) = \lambda_a f_a + \lambda_b f_b + \lambda_c f_c, \qquad q = \lambda_a a + \lambda_b b + \lambda_c c,

the barycentric coordinates λ. Two meshes of a curved boundary do not cover the same region (each polygon
is inscribed in the curve), so a query point a hair outside the source mesh takes the linear extension of
the nearest triangle (λ slightly negative) instead of failing.

>>> import numpy as np
>>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
>>> t = np.array([[0, 1, 2], [1, 3, 2]])
>>> interpolate_p1(p, t, p[:, 0] + 2 * p[:, 1], np.array([[0.25, 0.5], [0.9, 0.8]]))
array([1.25, 2.5 ])
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: triangles (by nearest centroid) tried per query point, and for a point found in none of them
CANDIDATES, WIDER = 12, 96


def _flat(points, what):
    x = np.asarray(points, dtype=float)
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"{what} must have shape (n, 2) or (n, 3), got {x.shape}")
    if x.shape[1] == 3:
        extent = float(np.ptp(x[:, :2], axis=0).max()) if len(x) else 0.0
        if len(x) and np.ptp(x[:, 2]) > 1e-9 * max(extent, 1e-300):
            raise ValueError(f"{what} must be flat, in the xy plane (reference positions), got z from "
                             f"{x[:, 2].min():.6g} to {x[:, 2].max():.6g}")
        x = x[:, :2]
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{what} hold NaN or infinity")
    return x


def _barycentric(xy, tri, cand, q):
    """λ (k, c, 3) of the points q (k, 2) in the candidate triangles cand (k, c)."""
    a, b, c = (xy[tri[cand, j]] for j in range(3))
    d = q[:, None, :] - a
    e1, e2 = b - a, c - a
    det = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    l1 = (d[..., 0] * e2[..., 1] - d[..., 1] * e2[..., 0]) / det
    l2 = (e1[..., 0] * d[..., 1] - e1[..., 1] * d[..., 0]) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


def locate(points, triangles, query):
    """The triangle of the flat mesh (points, triangles) holding each query point, and its barycentric
    coordinates: (index (k,), λ (k, 3)). A point outside the mesh gets the triangle it is least outside of
    (among the ``WIDER`` nearest by centroid), with some λ < 0."""
    xy, q = _flat(points, "points"), _flat(query, "query points")
    tri = np.asarray(triangles)
    if tri.ndim != 2 or tri.shape[1] != 3 or not len(tri):
        raise ValueError(f"triangles must have shape (m, 3) with m >= 1, got {tri.shape}")
    if tri.min() < 0 or tri.max() >= len(xy):
        raise ValueError(f"triangles index vertices 0..{len(xy) - 1}, got {tri.min()}..{tri.max()}")
    tree = cKDTree(xy[tri].mean(axis=1))

    def best_of(q, k):
        """Per point: the triangle among the k of nearest centroid that it is least outside of, and its λ."""
        cand = tree.query(q, k=k)[1].reshape(len(q), k)
        lam = _barycentric(xy, tri, cand, q)
        best = np.argmax(lam.min(axis=-1), axis=1)
        rows = np.arange(len(q))
        return cand[rows, best], lam[rows, best]

    found, lam_found = best_of(q, min(CANDIDATES, len(tri)))
    # a point near a long sliver may have its triangle beyond the nearest centroids: look wider (the wider set
    # holds the first; a point a hair outside the mesh keeps the triangle it is least outside of)
    miss = np.flatnonzero(lam_found.min(axis=1) < -1e-12)
    if len(miss) and len(tri) > CANDIDATES:
        found[miss], lam_found[miss] = best_of(q[miss], min(WIDER, len(tri)))
    return found, lam_found


def interpolate_p1(points, triangles, values, query):
    """Values (n,) or (n, d) at the vertices of the flat mesh (points, triangles), linearly interpolated at the
    query points (k, 2 or 3): (k,) or (k, d) (module docstring; outside the mesh the nearest triangle's linear
    extension)."""
    v = np.asarray(values, dtype=float)
    if v.shape[:1] != (len(np.asarray(points)),):
        raise ValueError(f"values must have one row per mesh vertex ({len(np.asarray(points))}), got shape {v.shape}")
    index, lam = locate(points, triangles, query)
    corners = np.asarray(triangles)[index]
    return np.einsum("kj,kj...->k...", lam, v[corners])
