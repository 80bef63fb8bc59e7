"""The flat plate of the linear reference: its scikit-fem mesh, per-triangle fields, bending stiffness.

Shared input checks of :mod:`.prestress` and :mod:`.eigenproblem`: points in a plane, triangles
made counter-clockwise (element order kept, so per-triangle arrays stay aligned), scalars or
one value per triangle, Poisson's ratio in (-1, 0.5].
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["bending_stiffness"]


def bending_stiffness(E, nu, thickness):
    """Plate bending stiffness D = E t^3 / (12 (1 - nu^2)) (units of E times length^3)."""
    return np.asarray(E, float) * np.asarray(thickness, float) ** 3 / (12.0 * (1.0 - nu ** 2))


def _mesh2d(points2d, triangles):
    """A scikit-fem MeshTri from (n, 2|3) points and (m, 3) triangles, triangles made counter-clockwise.

    Element order is preserved, so per-triangle arrays stay aligned with ``triangles``.
    """
    # deferred: scikit-fem takes over a second to import
    from skfem import MeshTri

    p = np.asarray(points2d, float)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ValueError(f"points2d must have shape (n, 2) or (n, 3), got {p.shape}")
    if p.shape[1] == 3:
        if np.ptp(p[:, 2]) > 1e-9 * max(np.ptp(p[:, :2], axis=0).max(), 1e-300):
            raise ValueError("points are not in a plane z = const; this module treats flat plates only")
        p = p[:, :2]
    t = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    e1 = p[t[:, 1]] - p[t[:, 0]]
    e2 = p[t[:, 2]] - p[t[:, 0]]
    area2 = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    if np.any(area2 == 0):
        raise ValueError(f"triangle {int(np.flatnonzero(area2 == 0)[0])} has zero area")
    cw = area2 < 0
    t[cw] = t[cw][:, [0, 2, 1]]
    return MeshTri(np.ascontiguousarray(p.T), np.ascontiguousarray(t.T))


def _per_triangle(value, m, name, positive=False):
    """Broadcast a scalar or a per-triangle array to shape (m,); finite (and > 0 if ``positive``)."""
    try:
        a = np.asarray(value, float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or one number per triangle, got {value!r}") from None
    a = np.full(m, float(a)) if a.ndim == 0 else a.reshape(-1)
    if a.shape != (m,):
        raise ValueError(f"{name} must be a scalar or have one value per triangle ({m}), got shape {a.shape}")
    bad = ~np.isfinite(a) | ((a <= 0) if positive else False)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} must be finite{' and > 0' if positive else ''}, got {a[i]:g} at triangle {i}")
    return a


def _poisson(nu) -> float:
    """Poisson's ratio of a plate, in (-1, 0.5]."""
    try:
        v = float(nu)
    except (TypeError, ValueError):
        v = math.nan
    if not -1.0 < v <= 0.5:
        raise ValueError(f"nu must be in (-1, 0.5], got {nu!r}")
    return v


def _at_quadrature(values, basis):
    """Per-element values (m,) as a field on the quadrature points of ``basis``, shape (m, nqp)."""
    return np.repeat(values[:, None], basis.X.shape[1], axis=1)


def _boundary_facets(mesh, vertices):
    """Boundary facets of a skfem mesh; with ``vertices`` only those with both ends in that set."""
    bf = mesh.boundary_facets()
    if vertices is None:
        return bf
    vs = np.zeros(mesh.p.shape[1], bool)
    vs[np.asarray(vertices, np.int64).ravel()] = True
    return bf[vs[mesh.facets[0, bf]] & vs[mesh.facets[1, bf]]]
