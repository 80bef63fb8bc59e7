r"""Pattern measures of the seed paper (design.md 1.5) and wrinkle counts (design.md 1.6).

Plain functions over arrays: ``points`` (n, 3), ``triangles`` (m, 3), vertex fields (n,).
Lengths and areas are in the units of ``points`` (cell sizes, design.md section 3);
angles in radians. Nothing here knows the shell or the time loop.

**Spots.** The tissue is "patterned" where the contractility is low, Λ(c) below the
midpoint (Λmax + Λmin)/2, i.e. where c > c*. With c interpolated linearly on each
triangle (P1), the region {c > c*} is cut exactly out of every triangle (marching
triangles), so its area ``A_l`` and its perimeter do not depend on a lumping rule.
Its connected components (vertices with c > c*, joined by mesh edges; a triangle
with any such vertex belongs to their component) are the paper's spots; components
smaller than ``min_area`` are ignored. With ``N_sp`` the number of components and
``A_tot`` the surface area (paper, section 3):

.. math::  r_{spot} = \sqrt{A_l / (\pi N_{sp})}, \qquad
           d_{spacing} = 2 \left(\sqrt{A_{tot} / (\pi N_{sp})} - \sqrt{A_l / (\pi N_{sp})}\right)

**Ridges.** A component is labelled ``"ridge"`` when it is elongated, measured by

.. math::  e = A / (\pi r_{in}^2),

its area over that of its largest inscribed disk, r_in being the largest distance from a
point of the component to its boundary (the P1 level line c = c*). e = a/b for an
ellipse of semi-axes a ≥ b (1 for a disk), 4L/(πw) for a band of length L and width w,
straight, bent or closed, and it grows with the number of round spots fused into a line
(the paper's "lines of bulges"). It does not use the component's mean tangent plane,
which a bent or closed band does not have. Components with e > ``ridge_elongation``
(default 2.5) are ridges, the others spots; N_sp counts both kinds, as the paper's N_sp
counts connected regions. Measured on a sphere of radius 10 with edges 0.76: e = 1.00–1.05
for disks of radius 1.5–5, 1.99 and 3.88 for ellipses of axis ratio 2 and 4, within 4 %
of 4L/(πw) for bands bent through 90° and 240°. Each component also reports the aspect
ratio √(λ1/λ2) of its second moment in its mean tangent plane and its isoperimetric ratio
P²/(4π A) (1 for a disk), which describe it but do not classify it.
Two limits of r_in: it is measured in straight lines in space, so on a surface folded
back on itself another fold's level line can be nearer than the component's own; and a
mesh's free boundary does not count as boundary, so a region cut by it (a half-disk at
the edge of a plate) measures as the whole it is cut from would (r_in 0.59 and e 0.5 for a
half-disk of radius 0.6, measured; 2 expected). Every chemistry scene is a closed sphere.

Example
-------
>>> import numpy as np
>>> from femshell.mesh.generators import sphere                         # doctest: +SKIP
>>> m = sphere(10.0, n_vertices=2000)                                     # doctest: +SKIP
>>> c = np.exp(-np.sum((m.points - [0, 0, 10]) ** 2, axis=1) / 4)         # doctest: +SKIP
>>> find_spots(m.points, m.triangles, c, c_star=0.1).n_spots              # doctest: +SKIP
1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ._checks import finite, finite_vector, integer, triangle_array, vertex_indices
from .geometry import triangle_areas

__all__ = ["vertex_areas", "spot_radius", "spot_spacing", "Region", "PatternMeasures", "find_spots",
           "count_spots", "same_pattern", "polar_profile", "PolarProfile", "azimuthal_spectrum", "azimuthal_power",
           "count_wrinkles"]


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


def spot_radius(area_low: float, n_spots: int) -> float:
    r"""Mean spot radius √(A_l / (π N_sp)) (length); NaN when there is no spot.

    >>> round(spot_radius(3 * math.pi * 4.0, 3), 12)      # three disks of radius 2
    2.0
    """
    n_spots = _count("n_spots", n_spots, 0, 2**62)
    area_low = finite("area_low", area_low, 0.0)
    if n_spots == 0:
        return float("nan")
    return math.sqrt(area_low / (math.pi * n_spots))


def spot_spacing(area_total: float, area_low: float, n_spots: int) -> float:
    r"""Mean spacing between spot edges 2 (√(A_tot/(π N_sp)) − √(A_l/(π N_sp))) (length); NaN without spots.

    Each spot is given an equal share A_tot/N_sp of the surface as a disk; the spacing
    is twice the width of the unpatterned ring around the spot.

    >>> round(spot_spacing(4 * math.pi * 9.0, 4 * math.pi * 4.0, 4), 12)   # shares of radius 3, spots of 2
    2.0
    """
    n_spots = _count("n_spots", n_spots, 0, 2**62)
    area_total, area_low = finite("area_total", area_total, 0.0), finite("area_low", area_low, 0.0)
    if n_spots == 0:
        return float("nan")
    if not (0 <= area_low <= area_total * (1 + 1e-12)):
        raise ValueError(f"need 0 <= area_low <= area_total, got {area_low} and {area_total}")
    return 2.0 * (math.sqrt(area_total / (math.pi * n_spots)) - math.sqrt(area_low / (math.pi * n_spots)))


# ----------------------------------------------------------------------------- marching triangles

def _cut_triangles(pts, tri, f):
    """Area of {f > 0} in each triangle for the P1 interpolant of f, and its level line f = 0.

    Returns (area_in (m,), contour_length (m,), segments (k, 2, 3)): the level line's
    segment in each of the k cut triangles.
    """
    v = f[tri]                                   # (m, 3)
    x = pts[tri]                                 # (m, 3, 3)
    area = triangle_areas(pts, tri)
    pos = v > 0
    npos = pos.sum(axis=1)
    frac = np.where(npos == 3, 1.0, 0.0)
    length = np.zeros(len(tri))
    segments = [np.zeros((0, 2, 3))]
    for k_pos in (1, 2):
        rows = np.flatnonzero(npos == k_pos)
        if rows.size == 0:
            continue
        # the odd vertex out: the positive one when one is positive, the negative one when two are
        odd = np.argmax(pos[rows] if k_pos == 1 else ~pos[rows], axis=1)
        i = odd
        j = (odd + 1) % 3
        k = (odd + 2) % 3
        vi, vj, vk = v[rows, i], v[rows, j], v[rows, k]
        # crossing points on edges i-j and i-k: t = vi / (vi - vj) from vertex i
        tij = vi / (vi - vj)
        tik = vi / (vi - vk)
        corner = tij * tik                        # area fraction of the small triangle at i
        frac[rows] = corner if k_pos == 1 else 1.0 - corner
        xi, xj, xk = x[rows, i], x[rows, j], x[rows, k]
        pij = xi + tij[:, None] * (xj - xi)
        pik = xi + tik[:, None] * (xk - xi)
        length[rows] = np.linalg.norm(pij - pik, axis=1)
        segments.append(np.stack([pij, pik], axis=1))
    return frac * area, length, np.concatenate(segments)


def _vertex_graph(tri, n, keep):
    """Adjacency (CSR) of the mesh edges whose both ends are kept."""
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    e = e[keep[e[:, 0]] & keep[e[:, 1]]]
    data = np.ones(len(e))
    return sp.coo_matrix((data, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()


def _inscribed_radii(pts, tri, above, label, n_comp, segments):
    """Radius of the largest disk inside each component of {f > 0}: max distance to the level line.

    The distance of a point to the level line f = 0 is the straight (chord) distance to the
    nearest point of its P1 segments (sampled at their ends and midpoints: the sampling adds
    at most (ℓ/4)²/(2 d) for segments of length ℓ). The nearest boundary point of an inside
    point lies on its own component's boundary, so one search serves all components. The
    largest distance is usually between vertices (the centre of a round spot): it is taken
    over the vertices and over 15 points of each triangle near the vertex maximum. On a
    surface curved with radius R the chord is shorter than the geodesic by r³/(24 R²).
    Returns (n_comp,); inf for a component with no boundary (f > 0 on a whole closed surface).
    """
    if len(segments) == 0:
        return np.full(n_comp, np.inf)
    tree = cKDTree(np.concatenate([segments[:, 0], segments[:, 1], segments.mean(axis=1)]))
    av = np.flatnonzero(above)
    dist = np.zeros(len(pts))
    dist[av] = tree.query(pts[av])[0]
    r_in = np.zeros(n_comp)
    np.maximum.at(r_in, label[av], dist[av])
    # between the vertices: inside triangles within one edge of their component's vertex maximum
    t_in = tri[np.all(above[tri], axis=1)]
    if len(t_in):
        x = pts[t_in]
        longest = np.max(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2), axis=1)
        comp = label[t_in[:, 0]]
        near = dist[t_in].max(axis=1) >= r_in[comp] - longest
        lattice = np.array([(i, j, 4 - i - j) for i in range(5) for j in range(5 - i)], float) / 4.0  # (15, 3)
        q = np.einsum("qk,tkd->tqd", lattice, x[near])
        d = tree.query(q.reshape(-1, 3))[0].reshape(len(q), len(lattice))
        np.maximum.at(r_in, comp[near], d.max(axis=1))
    return r_in


@dataclass
class Region:
    """One connected region where c > c* (a spot or a ridge).

    ``area`` and ``perimeter`` are exact for the P1 interpolant (length², length);
    ``centroid`` (3,) is the area-weighted centre of its (partial) triangles;
    ``aspect`` = √(λ1/λ2) of the second moment in its mean tangent plane (1 for a disk);
    ``isoperimetric`` = perimeter² / (4π area) (1 for a flat disk, 1 − A/(4πR²) for a cap of a sphere of radius R); ``inscribed_radius`` r_in
    (length) and ``elongation`` A/(π r_in²) (1 for a disk, a/b for an ellipse); ``kind``
    "spot" or "ridge" (elongation above the threshold).
    """

    vertices: np.ndarray
    area: float
    perimeter: float
    centroid: np.ndarray
    aspect: float
    isoperimetric: float
    inscribed_radius: float
    elongation: float
    kind: str
    c_max: float


@dataclass
class PatternMeasures:
    """The paper's pattern measures (design.md 1.5) of one field c on one surface.

    ``n_spots`` is N_sp, the number of connected low-Λ regions of both kinds;
    ``n_ridges`` how many of them are elongated ("ridge"); ``spot_radius`` and
    ``spacing`` follow the paper's formulas with N_sp (NaN when N_sp = 0);
    ``fraction_patterned`` = A_l / A_tot. Areas in length², lengths in length.
    """

    n_spots: int
    n_ridges: int
    area_low: float
    area_total: float
    fraction_patterned: float
    spot_radius: float
    spacing: float
    regions: list = field(default_factory=list)
    ignored_regions: int = 0

    @property
    def kind(self) -> str:
        """"none", "spots", "ridges" or "mixed" (both kinds present)."""
        if self.n_spots == 0:
            return "none"
        if self.n_ridges == 0:
            return "spots"
        return "ridges" if self.n_ridges == self.n_spots else "mixed"

    def as_dict(self) -> dict:
        """JSON-friendly summary (no arrays; NaN radius/spacing become None)."""
        def num(x):
            return None if not math.isfinite(x) else float(x)
        return {"n_spots": self.n_spots, "n_ridges": self.n_ridges, "kind": self.kind,
                "area_low": float(self.area_low), "area_total": float(self.area_total),
                "fraction_patterned": float(self.fraction_patterned), "spot_radius": num(self.spot_radius),
                "spacing": num(self.spacing), "ignored_regions": self.ignored_regions,
                "regions": [{"area": r.area, "perimeter": r.perimeter, "aspect": num(r.aspect),
                             "isoperimetric": r.isoperimetric, "inscribed_radius": num(r.inscribed_radius),
                             "elongation": num(r.elongation), "kind": r.kind, "c_max": r.c_max,
                             "centroid": [float(v) for v in r.centroid], "n_vertices": int(len(r.vertices))}
                            for r in self.regions]}


def find_spots(points, triangles, c, c_star: float, *, min_area: float | None = None,
               ridge_elongation: float = 2.5) -> PatternMeasures:
    """Connected regions of {c > c*} and the paper's measures (see module docstring).

    Parameters
    ----------
    points : (n, 3) array
        The surface on which areas are measured (the current, deformed one for a run).
    triangles : (m, 3) int array
    c : (n,) array
        Concentration at the vertices.
    c_star : float
        Threshold: low contractility where c > c*.
    min_area : float, optional
        Regions smaller than this (length²) are ignored and counted in
        ``ignored_regions``; their area is left out of A_l too. Default: twice the
        median triangle area (one vertex barely over the threshold is not a spot).
    ridge_elongation : float
        Components with A/(π r_in²) above this are ridges (see the module docstring).

    Examples
    --------
    Two caps of height 1 at the poles of a sphere of radius 10 (c > c* where z > 9 or z < −9):
    each has the area 2πRh = 62.8, so the spot radius √(A_l/(π N)) is √20 = 4.47.

    >>> import numpy as np
    >>> from femshell.mesh.generators import sphere
    >>> from femshell.analysis import find_spots
    >>> m = sphere(10.0, n_vertices=2000)
    >>> c = np.exp(-(10 - np.abs(m.points[:, 2])) ** 2)          # c* = e^-1 where |z| = 9
    >>> s = find_spots(m.points, m.triangles, c, c_star=np.exp(-1.0))
    >>> s.n_spots, [r.kind for r in s.regions], bool(abs(s.spot_radius - 20 ** 0.5) < 0.02)
    (2, ['spot', 'spot'], True)
    """
    ridge_elongation = finite("ridge_elongation", ridge_elongation, 1.0)
    cs = _components(points, triangles, c, c_star, min_area)
    pts, tri, cv, tri_area = cs.pts, cs.tri, cs.c, cs.tri_area
    area_total = float(tri_area.sum())
    if cs.n_comp == 0:
        return PatternMeasures(0, 0, 0.0, area_total, 0.0, float("nan"), float("nan"), [], 0)
    n_comp, label, vt, area_in = cs.n_comp, cs.label, cs.vt, cs.area_in
    above = label >= 0
    has = vt >= 0
    r_in = _inscribed_radii(pts, tri, above, label, n_comp, cs.segments)
    comp_perim = np.bincount(vt[has], weights=cs.contour[has], minlength=n_comp)
    # area-weighted centroid and second moment of the triangle centroids (weights: area inside)
    xc = pts[tri].mean(axis=1)
    nrm = np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]) * 0.5  # area vectors
    x = pts[tri]
    sq_edges = sum(np.sum((x[:, a] - x[:, b]) ** 2, axis=1) for a, b in ((0, 1), (1, 2), (2, 0)))
    # vertices and triangles of each component, grouped once (no pass over the mesh per component)
    av = np.flatnonzero(above)
    ov = av[np.argsort(label[av], kind="stable")]
    v_start = np.searchsorted(label[ov], np.arange(n_comp + 1))
    ht = np.flatnonzero(has)
    ot = ht[np.argsort(vt[ht], kind="stable")]
    t_start = np.searchsorted(vt[ot], np.arange(n_comp + 1))
    regions = []
    ignored = 0
    area_low = 0.0
    kept = cs.kept()
    for k in range(n_comp):
        verts = ov[v_start[k]:v_start[k + 1]]
        A = float(cs.comp_area[k])
        if not kept[k]:
            ignored += 1
            continue
        sel = ot[t_start[k]:t_start[k + 1]]
        wgt = area_in[sel]
        cen = (wgt[:, None] * xc[sel]).sum(axis=0) / A
        nmean = (wgt[:, None] * nrm[sel] / np.maximum(tri_area[sel], 1e-300)[:, None]).sum(axis=0)
        aspect = float("inf")
        if np.linalg.norm(nmean) > 1e-12 * A:
            nhat = nmean / np.linalg.norm(nmean)
            e1 = np.cross(nhat, [1.0, 0.0, 0.0])
            if np.linalg.norm(e1) < 0.5:
                e1 = np.cross(nhat, [0.0, 1.0, 0.0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(nhat, e1)
            d = xc[sel] - cen
            q = np.column_stack([d @ e1, d @ e2])
            # each triangle also carries its own (isotropic part of the) second moment, trace
            # Σ ℓ² / 36 per unit area: matters for regions one or two triangles wide
            Mm = (wgt[:, None, None] * q[:, :, None] * q[:, None, :]).sum(axis=0) / A
            Mm += np.eye(2) * float(np.sum(wgt * sq_edges[sel])) / (72.0 * A)
            lam = np.linalg.eigvalsh(Mm)
            aspect = math.sqrt(lam[1] / lam[0]) if lam[0] > 0 else float("inf")
        P = float(comp_perim[k])
        iso = P * P / (4.0 * math.pi * A)
        elong = A / (math.pi * r_in[k] ** 2) if r_in[k] > 0 else float("inf")
        kind = "ridge" if elong > ridge_elongation else "spot"
        regions.append(Region(verts, A, P, cen, aspect, iso, float(r_in[k]), elong, kind, float(cv[verts].max())))
        area_low += A
    N = len(regions)
    n_ridges = sum(r.kind == "ridge" for r in regions)
    return PatternMeasures(N, n_ridges, area_low, area_total, min(area_low / area_total, 1.0) if area_total > 0 else 0.0,
                           spot_radius(area_low, N), spot_spacing(area_total, min(area_low, area_total), N),
                           regions, ignored)


def count_spots(points, triangles, c, c_star: float, min_area: float | None = None) -> int:
    """N_sp: the number of connected regions with c > c* (see :func:`find_spots`), without the
    measures of each region (a run counts them at every step)."""
    cs = _components(points, triangles, c, c_star, min_area)
    return int(np.count_nonzero(cs.kept()))


@dataclass
class _Components:
    pts: np.ndarray
    tri: np.ndarray
    c: np.ndarray
    tri_area: np.ndarray
    min_area: float
    area_in: np.ndarray         # (m,) area of {c > c*} in each triangle
    contour: np.ndarray         # (m,) length of the level line c = c* in each triangle
    segments: np.ndarray        # (k, 2, 3) its segments
    n_comp: int
    label: np.ndarray           # (n,) component of each vertex above c*, -1 elsewhere
    vt: np.ndarray              # (m,) component of each triangle (of any vertex above c*), -1: none
    comp_area: np.ndarray       # (n_comp,) area of each component

    def kept(self) -> np.ndarray:
        """(n_comp,) bool: the components counted as regions (area at least min_area, and positive)."""
        return (self.comp_area >= self.min_area) & (self.comp_area > 0)


def _components(points, triangles, c, c_star, min_area) -> _Components:
    """The connected components of {c > c*} over the mesh edges and their areas (P1 interpolant)."""
    pts, tri = _mesh(points, triangles)
    if len(pts) and not len(tri):
        raise ValueError(f"no triangles for the {len(pts)} points: the measures need a surface")
    n = len(pts)
    cv = _field(c, n, "c")
    c_star = finite("c_star", c_star)
    if min_area is not None:
        min_area = finite("min_area", min_area, 0.0)
    tri_area = triangle_areas(pts, tri)
    if min_area is None:
        min_area = 2.0 * float(np.median(tri_area)) if len(tri) else 0.0
    f = cv - c_star
    above = f > 0
    area_in, contour, segments = _cut_triangles(pts, tri, f)
    label = np.full(n, -1)
    n_comp = 0
    if above.any():
        _, comp = connected_components(_vertex_graph(tri, n, above), directed=False)
        # number the components with a vertex above the threshold 0 … n_comp - 1
        av = np.flatnonzero(above)
        _, lv = np.unique(comp[av], return_inverse=True)
        n_comp = int(lv.max()) + 1
        label[av] = lv
    vt = label[tri].max(axis=1) if len(tri) else np.zeros(0, int)
    has = vt >= 0
    comp_area = np.bincount(vt[has], weights=area_in[has], minlength=n_comp)
    return _Components(pts, tri, cv, tri_area, min_area, area_in, contour, segments, n_comp, label, vt, comp_area)


def same_pattern(a: PatternMeasures, b: PatternMeasures, tol: float = 0.02) -> bool:
    r"""Whether two patterns are the same regions within ``tol``.

    Same: equal numbers of spots and of ridges, patterned areas within ``tol`` of each other
    (|A_l(b) − A_l(a)| ≤ tol A_l(a)), and every region centroid of each within tol · r̄ of a
    centroid of the other, r̄ = √(A_l(a) / (π N)) the mean region radius. Two empty patterns
    are the same. It compares the regions, not the field: c may still change inside them or
    below c* (a ring that has not yet nucleated is invisible).

    >>> import numpy as np
    >>> from femshell.mesh.generators import sphere
    >>> m = sphere(10.0, n_vertices=800)
    >>> spot = lambda x0, amp: amp * np.exp(-np.sum((m.points - x0) ** 2, axis=1) / 8)
    >>> a = find_spots(m.points, m.triangles, spot([0, 0, 10], 1.0), 0.1)
    >>> b = find_spots(m.points, m.triangles, spot([0, 0, 10], 1.002), 0.1)   # 0.2 % stronger
    >>> c = find_spots(m.points, m.triangles, spot([0, 0, 10], 1.3), 0.1)     # larger
    >>> same_pattern(a, b), same_pattern(a, c)
    (True, False)
    """
    tol = finite("tol", tol, 0.0)
    if (a.n_spots, a.n_ridges, len(a.regions)) != (b.n_spots, b.n_ridges, len(b.regions)):
        return False
    if not a.regions:
        return True
    if abs(b.area_low - a.area_low) > tol * a.area_low:
        return False
    xa = np.array([r.centroid for r in a.regions])
    xb = np.array([r.centroid for r in b.regions])
    d = np.linalg.norm(xa[:, None, :] - xb[None, :, :], axis=2)
    reach = tol * math.sqrt(a.area_low / (math.pi * len(a.regions)))
    return bool(d.min(axis=1).max() <= reach and d.min(axis=0).max() <= reach)


# ----------------------------------------------------------------------------- profiles

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


# ----------------------------------------------------------------------------- wrinkles (disk test)

def _sample_on_mesh(xy, tri, v, q):
    """Linear interpolation of a vertex field at points q (k, 2) of a flat triangulation; NaN outside.

    The points are taken in runs of 16 (neighbours on a circle), each tested only against the triangles
    whose bounding box meets the run's: the search over all triangles cost 1.25 s per call at 50 000."""
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    box_lo, box_hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    margin = 1e-9 * float(np.ptp(xy, axis=0).max())    # the inside test below admits points 1e-12 outside
    out = np.full(len(q), np.nan)
    tol = -1e-12
    for start in range(0, len(q), 16):
        run = q[start:start + 16]
        lo, hi = run.min(axis=0) - margin, run.max(axis=0) + margin
        near = np.flatnonzero(np.all(box_hi >= lo, axis=1) & np.all(box_lo <= hi, axis=1))
        if not len(near):
            continue
        an, bn, cn, dn = a[near], b[near], c[near], det[near]
        p = run[:, None, :]                                     # (k, 1, 2)
        l1 = ((p[..., 0] - an[:, 0]) * (cn[:, 1] - an[:, 1]) - (cn[:, 0] - an[:, 0]) * (p[..., 1] - an[:, 1])) / dn
        l2 = ((bn[:, 0] - an[:, 0]) * (p[..., 1] - an[:, 1]) - (p[..., 0] - an[:, 0]) * (bn[:, 1] - an[:, 1])) / dn
        l0 = 1.0 - l1 - l2
        inside = (l0 >= tol) & (l1 >= tol) & (l2 >= tol)      # (k, candidates)
        has = inside.any(axis=1)
        j = np.argmax(inside, axis=1)
        r = np.arange(len(j))
        t = tri[near[j]]
        val = l0[r, j] * v[t[:, 0]] + l1[r, j] * v[t[:, 1]] + l2[r, j] * v[t[:, 2]]
        out[start:start + 16] = np.where(has, val, np.nan)
    return out


def _circle_samples(points, values, radius, center, n_samples, triangles):
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (n, 2) or (n, 3), got {pts.shape}")
    v = _field(values, len(pts), "values")
    if pts.shape[1] == 3:   # a circle in the xy plane: a curved mesh would be silently projected onto it
        extent = max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]))
        if np.ptp(pts[:, 2]) > 1e-9 * extent:
            raise ValueError(f"points must be a flat mesh in the xy plane (the reference positions), got z from "
                             f"{pts[:, 2].min():.6g} to {pts[:, 2].max():.6g}")
    radius = finite("radius", radius, 0.0, lo_open=True)
    ns = _count("n_samples", n_samples, 8, 1_000_000)
    phi = 2 * math.pi * np.arange(ns) / ns
    cx, cy = finite_vector("center", center, 2)
    q = np.column_stack([cx + radius * np.cos(phi), cy + radius * np.sin(phi)])
    if triangles is not None:
        tri = _mesh(pts, triangles)[1]
        if not len(tri):
            raise ValueError("triangles is empty: no mesh to sample the circle on")
        w = _sample_on_mesh(pts[:, :2], tri, v, q)
    else:
        from scipy.interpolate import LinearNDInterpolator
        from scipy.spatial import QhullError

        if not np.all(np.isfinite(pts)):
            raise ValueError("points hold NaN or infinity")
        try:
            w = LinearNDInterpolator(pts[:, :2], v)(q)
        except (QhullError, ValueError) as exc:   # fewer than 3 points, or all on a line
            raise ValueError(f"cannot triangulate the points in the xy plane ({str(exc).splitlines()[0]}); "
                             "pass the mesh's triangles") from None
    if not np.all(np.isfinite(w)):
        raise ValueError(f"the circle of radius {radius} about {center} leaves the mesh")
    return w


def _spectrum(w):
    ns = len(w)
    amp = np.abs(np.fft.rfft(w)) / ns
    amp[1:] *= 2.0
    if ns % 2 == 0:
        amp[-1] /= 2.0
    return amp


def azimuthal_spectrum(points, values, radius: float, *, center=(0.0, 0.0), n_samples: int = 512,
                       triangles=None):
    """Fourier amplitudes |ŵ_k| (k = 0 .. n_samples/2) of a field sampled on a circle.

    ``points`` are the (reference) positions (n, 2) or (n, 3) of a flat mesh in the xy
    plane, ``values`` (n,) a vertex field (e.g. the deflection w), sampled by linear
    interpolation at ``n_samples`` angles on the circle of ``radius`` about ``center``:
    on the mesh's own ``triangles`` when given, else on a Delaunay triangulation of the
    points (slower). Amplitudes are in the unit of ``values``:
    w(φ) = ŵ_0 + Σ_k ŵ_k cos(k φ − φ_k). Raises ValueError when the circle leaves the mesh.
    """
    return _spectrum(_circle_samples(points, values, radius, center, n_samples, triangles))


def azimuthal_power(points, values, radii, *, triangles=None, skip_outside: bool = False):
    """|ŵ_k|² (k = 0 .. 256) summed over the circles of the given ``radii`` about the origin.

    One circle can pass where a mode's part of some wavenumber vanishes; the sum over several
    does not. See :func:`azimuthal_spectrum` (512 samples per circle). A circle that leaves
    the mesh raises ValueError, or with ``skip_outside`` is left out; None if none is left.
    """
    power = None
    for r in radii:
        try:
            amp = azimuthal_spectrum(points, values, r, triangles=triangles)
        except ValueError:
            if not skip_outside:
                raise
            continue
        power = amp ** 2 if power is None else power + amp ** 2
    return power


def count_wrinkles(points, values, radius: float, *, center=(0.0, 0.0), n_samples: int = 512,
                   triangles=None, min_mode: int = 1, rel_tol: float = 1e-3, method: str = "fourier") -> int:
    """Number of azimuthal wrinkles of a field (the deflection w) on a circle of ``radius``.

    ``method="fourier"``: the dominant azimuthal mode k ≥ ``min_mode`` of w(φ) (w ∝ cos kφ
    has k wrinkles). ``method="zeros"``: half the number of sign changes of w(φ) − mean.
    Returns 0 when the non-axisymmetric part is below ``rel_tol`` of the total amplitude
    on the circle (an axisymmetric or flat state). ``min_mode=2`` ignores a tilt (k = 1).
    See :func:`azimuthal_spectrum` for the sampling (pass ``triangles`` for speed).

    >>> import numpy as np
    >>> from femshell.mesh.generators import disk
    >>> from femshell.analysis import count_wrinkles
    >>> d = disk(radius=5.0, edge_length=0.25)
    >>> x, y = d.points[:, 0], d.points[:, 1]
    >>> count_wrinkles(d.points, np.hypot(x, y) ** 2 * np.cos(5 * np.arctan2(y, x)), 3.0, triangles=d.triangles)
    5
    """
    if method not in ("fourier", "zeros"):
        raise ValueError(f"method must be 'fourier' or 'zeros', got {method!r}")
    w = _circle_samples(points, values, radius, center, n_samples, triangles)
    min_mode = _count("min_mode", min_mode, 1, len(w) // 2)
    rel_tol = finite("rel_tol", rel_tol, 0.0, 1.0)
    amp = _spectrum(w)
    scale = amp[0] + amp[1:].sum()
    modes = amp[int(min_mode):]
    if scale == 0 or modes.max() <= rel_tol * scale:
        return 0
    if method == "fourier":
        return int(min_mode + int(np.argmax(modes)))
    d = w - w.mean()
    s = np.sign(d)
    s[s == 0] = 1
    return int(np.count_nonzero(s != np.roll(s, 1)) // 2)
