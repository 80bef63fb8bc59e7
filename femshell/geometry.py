r"""Differential geometry of a triangulated surface: areas, normals, fundamental forms, curvature.

Plain functions over arrays: ``points`` (n, 3), ``triangles`` (m, 3). Lengths in the
units of ``points``; curvatures in 1/length.

The mean curvature used by the chemistry (docs/theory.md §5) comes from the shell's own
second fundamental form :math:`b` (see :mod:`femshell.shell.bending`), per element

.. math:: H = \tfrac12 \operatorname{tr}(a^{-1} b) - k_0,

and is averaged to vertices with area weights (:func:`element_to_vertex`).

Example
-------
>>> import numpy as np
>>> a = np.array([[[1.0, 0.0], [0.0, 1.0]]]); b = a / 2.0
>>> float(mean_curvature(a, b)[0])   # a sphere of radius 2
0.5
"""

from __future__ import annotations

import numpy as np

from ._checks import surface


def _area_vectors(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    x = points[triangles]
    return 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])


def triangle_area_vectors(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """½ (x1 − x0) × (x2 − x0): area times unit normal, (m, 3)."""
    return _area_vectors(*surface(points, triangles))


def triangle_areas(points, triangles) -> np.ndarray:
    """Areas (m,), length²."""
    return np.linalg.norm(triangle_area_vectors(points, triangles), axis=1)


def face_normals(points, triangles) -> np.ndarray:
    """Unit normals (m, 3), oriented by the vertex order (counter-clockwise seen from the normal);
    zero for a triangle of zero area, which has none."""
    av = triangle_area_vectors(points, triangles)
    return av / np.maximum(np.linalg.norm(av, axis=1), 1e-300)[:, None]


def vertex_normals(points, triangles) -> np.ndarray:
    """Area-weighted unit vertex normals (n, 3); zero at a vertex in no triangle of non-zero area."""
    points, triangles = surface(points, triangles)
    av = _area_vectors(points, triangles)
    n = np.column_stack([np.bincount(triangles.ravel(), np.repeat(av[:, i], 3), minlength=len(points))
                         for i in range(3)])
    return n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]


def fold_angles(points, triangles, edge_faces) -> np.ndarray:
    """Angle (degrees) between the unit normals of the two faces of every interior edge.

    ``edge_faces`` (ne, 2) from :class:`femshell.mesh.topology.Topology` (−1 where missing; those
    edges are left out, the rest keep their order). A smooth surface resolved by the mesh has small
    angles; one near 90° or beyond is a fold on the scale of a single edge, finer than the mesh can
    represent. A face of zero area has no normal and counts as 90° from its neighbours.

    >>> pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]])
    >>> round(float(fold_angles(pts, np.array([[0, 1, 2], [2, 1, 3]]), np.array([[0, 1]]))[0]), 1)
    54.7
    """
    av = triangle_area_vectors(points, triangles)
    n = av / np.maximum(np.linalg.norm(av, axis=1), 1e-300)[:, None]
    ef = np.asarray(edge_faces)
    ef = ef[ef[:, 1] >= 0]
    cos = np.einsum("ij,ij->i", n[ef[:, 0]], n[ef[:, 1]])
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def element_to_vertex(values: np.ndarray, points, triangles) -> np.ndarray:
    """Area-weighted average of per-triangle values at each vertex: Σ A_f v_f / Σ A_f (n,);
    0 at a vertex in no triangle of non-zero area.

    >>> pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> element_to_vertex(np.array([1.0, 3.0]), pts, np.array([[0, 1, 2], [1, 3, 2]]))
    array([1., 2., 2., 3.])
    """
    points, triangles = surface(points, triangles)
    values = np.asarray(values, dtype=float)
    if values.shape != (len(triangles),):
        raise ValueError(f"values must be one number per triangle, shape ({len(triangles)},), got {values.shape}")
    area = np.linalg.norm(_area_vectors(points, triangles), axis=1)
    n = len(points)
    num = np.zeros(n)
    den = np.zeros(n)
    for k in range(3):
        num += np.bincount(triangles[:, k], area * values, minlength=n)
        den += np.bincount(triangles[:, k], area, minlength=n)
    return num / np.maximum(den, 1e-300)


def _metric_determinant(a, b):
    """det(a) of first fundamental forms (m, 2, 2) that pair with b (m, 2, 2); a must be positive definite."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim != 3 or a.shape[1:] != (2, 2) or b.shape != a.shape:
        raise ValueError(f"fundamental forms a and b must both have shape (m, 2, 2), got {a.shape} and {b.shape}")
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    bad = ~((det > 0) & (a[:, 0, 0] > 0))      # with det > 0, a11 > 0 makes both eigenvalues positive
    if bad.any():
        raise ValueError(f"{bad.sum()} of {len(det)} first fundamental forms a are not positive definite "
                         f"(det(a) <= 0, a11 <= 0 or not finite, first at element {np.flatnonzero(bad)[0]}): "
                         "degenerate (collapsed) triangles")
    return a, b, det


def mean_curvature(a: np.ndarray, b: np.ndarray, k0: float = 0.0) -> np.ndarray:
    """H = ½ tr(a⁻¹ b) − k0 per element from the fundamental forms (m, 2, 2)."""
    a, b, det = _metric_determinant(a, b)
    tr = (a[:, 1, 1] * b[:, 0, 0] - a[:, 0, 1] * b[:, 1, 0] - a[:, 1, 0] * b[:, 0, 1] + a[:, 0, 0] * b[:, 1, 1]) / det
    return 0.5 * tr - k0


def gaussian_curvature(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """K = det(b) / det(a) per element."""
    a, b, det = _metric_determinant(a, b)
    return (b[:, 0, 0] * b[:, 1, 1] - b[:, 0, 1] * b[:, 1, 0]) / det
