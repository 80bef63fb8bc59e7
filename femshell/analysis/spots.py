r"""Pattern measures of the seed paper: spots, ridges, their radius and spacing (docs/theory.md).

Plain functions over arrays: ``points`` (n, 3), ``triangles`` (m, 3), vertex fields (n,).
Lengths and areas are in the units of ``points`` (cell sizes);
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
counts connected regions. On a sphere of radius 10 with edges 0.76, e is 1.00–1.05 for
disks, within 4 % of a/b for ellipses and of 4L/(πw) for bent bands. Each component also reports the aspect
ratio √(λ1/λ2) of its second moment in its mean tangent plane and its isoperimetric ratio
P²/(4π A) (1 for a disk), which describe it but do not classify it.
Two limits of r_in: it is measured in straight lines in space, so on a surface folded
back on itself another fold's level line can be nearer than the component's own; and a
mesh's free boundary does not count as boundary, so a region cut by it (a half-disk at
the edge of a plate) measures as the whole it is cut from would (e 0.5 for a half-disk, 2
expected). Every chemistry scene is a closed sphere.

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

from .._checks import finite
from ..geometry import triangle_areas
from .fields import _count, _field, _mesh


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
    """The paper's pattern measures of one field c on one surface.

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
