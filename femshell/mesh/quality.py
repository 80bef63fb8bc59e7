"""Element quality of a triangle mesh: angles, aspect ratios, edge lengths and areas (angles in
degrees, lengths in the mesh's unit), as statistics, a short table and a warning."""

from __future__ import annotations

import numpy as np

from ..geometry import triangle_areas
from .surface import SurfaceMesh


def triangle_edge_lengths(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Length of local edge k (opposite local vertex k, topology.py convention), shape (m, 3).

    >>> triangle_edge_lengths(np.array([[0., 0, 0], [3, 0, 0], [0, 4, 0]]), np.array([[0, 1, 2]]))
    array([[5., 4., 3.]])
    """
    p = points[triangles]
    return np.linalg.norm(p[:, [2, 0, 1]] - p[:, [1, 2, 0]], axis=2)


def triangle_angles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Interior angle at local vertex k in degrees, shape (m, 3).

    atan2(|e1 x e2|, e1 . e2) rather than arccos keeps full accuracy for angles
    near 0 and 180 degrees, which are exactly the ones quality checks care about.

    >>> triangle_angles(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])).round(6)
    array([[90., 45., 45.]])
    """
    p = points[triangles]
    e1 = p[:, [1, 2, 0]] - p       # to the next vertex
    e2 = p[:, [2, 0, 1]] - p       # to the previous vertex
    s = np.linalg.norm(np.cross(e1, e2), axis=2)
    c = np.einsum("mki,mki->mk", e1, e2)
    return np.degrees(np.arctan2(s, c))



def quality_report(mesh: SurfaceMesh) -> dict:
    """Element-quality statistics of a triangle mesh.

    Works on any mesh whose coordinates and indices are valid (no topology needed).
    Keys (angles in degrees, lengths in the mesh unit, areas in length²;
    ``*_triangle`` keys give the index of the triangle where the extreme occurs):

    ``n_vertices, n_triangles, min_angle_deg, min_angle_triangle, max_angle_deg,
    max_angle_triangle, aspect_min, aspect_mean, aspect_max, aspect_max_triangle,
    edge_min, edge_mean, edge_max, edge_spread, area_min, area_min_triangle,
    area_max, area_max_triangle, area_total, n_min_angle_below_10,
    n_min_angle_below_5``

    The aspect ratio is longest edge / (2 sqrt(3) inradius): 1 for an equilateral
    triangle, (1 + sqrt 2)/sqrt 3 = 1.394 for a right isosceles one, inf for a
    degenerate one. Edge statistics run over unique edges; ``edge_spread`` is
    max/min.

    Example
    -------
    >>> import numpy as np
    >>> tri = SurfaceMesh(np.array([[0., 0], [1, 0], [0.5, np.sqrt(3) / 2]]), np.array([[0, 1, 2]]))
    >>> r = quality_report(tri)
    >>> round(r["min_angle_deg"], 9), round(r["aspect_max"], 12)
    (60.0, 1.0)
    """
    pts, tri = mesh.points, mesh.triangles
    angles = triangle_angles(pts, tri)
    lengths = triangle_edge_lengths(pts, tri)
    area = triangle_areas(pts, tri)
    semi = 0.5 * lengths.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inradius = area / semi
        aspect = lengths.max(axis=1) / (2.0 * np.sqrt(3.0) * inradius)
    aspect = np.where(np.isnan(aspect), np.inf, aspect)

    # unique undirected edges, so interior edges are not counted twice
    a, b = tri[:, [1, 2, 0]].ravel(), tri[:, [2, 0, 1]].ravel()
    key = np.unique(np.minimum(a, b) * np.int64(len(pts)) + np.maximum(a, b))
    i, j = np.divmod(key, len(pts))
    elen = np.linalg.norm(pts[j] - pts[i], axis=1)

    tmin = angles.min(axis=1)
    tmax = angles.max(axis=1)
    i_min, i_max = int(np.argmin(tmin)), int(np.argmax(tmax))
    with np.errstate(divide="ignore"):
        spread = float(elen.max() / elen.min()) if elen.min() > 0 else np.inf
    return {
        "n_vertices": int(len(pts)),
        "n_triangles": int(len(tri)),
        "min_angle_deg": float(tmin[i_min]),
        "min_angle_triangle": i_min,
        "max_angle_deg": float(tmax[i_max]),
        "max_angle_triangle": i_max,
        "aspect_min": float(aspect.min()),
        "aspect_mean": float(aspect.mean()),
        "aspect_max": float(aspect.max()),
        "aspect_max_triangle": int(np.argmax(aspect)),
        "edge_min": float(elen.min()),
        "edge_mean": float(elen.mean()),
        "edge_max": float(elen.max()),
        "edge_spread": spread,
        "area_min": float(area.min()),
        "area_min_triangle": int(np.argmin(area)),
        "area_max": float(area.max()),
        "area_max_triangle": int(np.argmax(area)),
        "area_total": float(area.sum()),
        "n_min_angle_below_10": int((tmin < 10).sum()),
        "n_min_angle_below_5": int((tmin < 5).sum()),
    }


def format_quality(report: dict) -> str:
    """A short human-readable table of a :func:`quality_report` dict.

    Example
    -------
    >>> import numpy as np
    >>> sq = SurfaceMesh(np.array([[0., 0], [1, 0], [1, 1], [0, 1]]), np.array([[0, 1, 2], [0, 2, 3]]))
    >>> print(format_quality(quality_report(sq)))  # doctest: +NORMALIZE_WHITESPACE
    mesh quality: 4 vertices, 2 triangles
      quantity                min        mean         max  where (min / max)
      angle [deg]              45           -          90  triangle 0 / triangle 0
      aspect ratio          1.394       1.394       1.394  - / triangle 0
      edge length               1       1.083       1.414  spread max/min 1.41
      area                    0.5           -         0.5  triangle 0 / triangle 0
      triangles with min angle < 10 deg: 0, < 5 deg: 0
    """
    r = report
    g = "{:>11.4g}".format
    lines = [
        f"mesh quality: {r['n_vertices']} vertices, {r['n_triangles']} triangles",
        f"  {'quantity':<16}{'min':>11} {'mean':>11} {'max':>11}  where (min / max)",
        f"  {'angle [deg]':<16}{g(r['min_angle_deg'])} {'-':>11} {g(r['max_angle_deg'])}  "
        f"triangle {r['min_angle_triangle']} / triangle {r['max_angle_triangle']}",
        f"  {'aspect ratio':<16}{g(r['aspect_min'])} {g(r['aspect_mean'])} {g(r['aspect_max'])}  "
        f"- / triangle {r['aspect_max_triangle']}",
        f"  {'edge length':<16}{g(r['edge_min'])} {g(r['edge_mean'])} {g(r['edge_max'])}  "
        f"spread max/min {r['edge_spread']:.3g}",
        f"  {'area':<16}{g(r['area_min'])} {'-':>11} {g(r['area_max'])}  "
        f"triangle {r['area_min_triangle']} / triangle {r['area_max_triangle']}",
        f"  triangles with min angle < 10 deg: {r['n_min_angle_below_10']}, < 5 deg: {r['n_min_angle_below_5']}",
    ]
    return "\n".join(lines)


def warn_poor_quality(mesh: SurfaceMesh, min_angle_deg: float = 5.0, *, _angles=None) -> str | None:
    """A warning for the caller to log when triangles have an angle under ``min_angle_deg`` (degrees), else None.

    Example
    -------
    >>> import numpy as np
    >>> sliver = SurfaceMesh(np.array([[0., 0], [1, 0], [0.5, 0.01]]), np.array([[0, 1, 2]]))
    >>> warn_poor_quality(sliver)
    'mesh has 1 triangles with angles under 5 degrees (worst 1.1 at triangle 0); expect poor accuracy'
    """
    angles = triangle_angles(mesh.points, mesh.triangles) if _angles is None else _angles
    tmin = angles.min(axis=1)
    bad = tmin < min_angle_deg
    if not bad.any():
        return None
    worst = int(np.argmin(tmin))
    return (f"mesh has {int(bad.sum())} triangles with angles under {min_angle_deg:g} degrees "
            f"(worst {tmin[worst]:.1f} at triangle {worst}); expect poor accuracy")
