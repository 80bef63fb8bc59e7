"""Mesh validation, orientation repair and element-quality statistics.

Every check here is vectorised numpy over all triangles / vertices / edges at
once; the only Python loops run over the (few) defect *kinds* and, in
:func:`orient_consistently`, over the O(log depth) pointer-jumping rounds.

* :func:`check_mesh` raises :class:`~femshell.mesh.topology.MeshError` naming
  every defect it finds (which vertex, triangle or edge, where, and how many),
  or returns a :class:`MeshReport` summary of a good mesh.
* :func:`orient_consistently` flips triangles so that neighbours agree and the
  normals follow design.md section 3: outward on closed surfaces, +z on flat
  ones, away from the centroid on other open surfaces.
* :func:`quality_report`, :func:`format_quality` and :func:`warn_poor_quality`
  measure angles, aspect ratios, edge lengths and areas.

Lengths are in the mesh's length unit (the cell size, design.md section 3),
areas in that unit squared, angles in degrees.

Example
-------
>>> import numpy as np
>>> from femshell.mesh import SurfaceMesh, check_mesh
>>> m = SurfaceMesh(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
>>> check_mesh(m).n_triangles
1
>>> check_mesh(m.with_points([[0., 0, 0], [1, 0, 0], [2, 0, 0]]))
Traceback (most recent call last):
    ...
femshell.mesh.topology.MeshError: mesh is invalid (1 defect kind):
  - degenerate triangles: triangle 0 has area 0 < 1e-12 * (mean edge length)^2 = 1.78e-12; vertices [0, 1, 2] (1 such triangle)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..geometry import fold_angles, triangle_area_vectors, triangle_areas
from .surface import SurfaceMesh
from .topology import MeshError

#: The largest extent of a mesh's vertices must lie in this range (the generators make sizes in [1e-6, 1e5]).
EXTENT_RANGE = (1e-9, 1e8)
#: A triangle is degenerate when its area is below this times the squared mean edge length.
DEGENERATE_AREA_FACTOR = 1e-12
#: Across an interior edge, normals more than this many degrees apart mark a fold
#: (a triangle turned over onto its neighbour). A regular tetrahedron has 109.5 degrees.
FOLD_ANGLE_DEG = 150.0
#: How many examples a message lists before "...".
_N_EXAMPLES = 5


# --------------------------------------------------------------------------- report

@dataclass(frozen=True)
class MeshReport:
    """Summary of a mesh that passed :func:`check_mesh`.

    Lengths in the mesh unit, ``area`` in length², ``min_angle_deg`` in degrees.
    ``boundary_curves`` maps curve name -> number of boundary edges.
    ``warnings`` holds non-fatal remarks (poor element quality) for the caller to log.
    """

    n_vertices: int
    n_triangles: int
    n_edges: int
    n_boundary_edges: int
    n_components: int
    euler_characteristic: int
    is_closed: bool
    is_flat: bool
    boundary_curves: dict = field(default_factory=dict)
    area: float = 0.0
    mean_edge_length: float = 0.0
    min_angle_deg: float = 0.0
    warnings: tuple = ()

    def __str__(self):
        kind = "closed" if self.is_closed else "open"
        kind += ", flat" if self.is_flat else ""
        curves = ", ".join(f"{k}: {v} edges" for k, v in self.boundary_curves.items()) or "none"
        lines = [f"mesh OK: {self.n_vertices} vertices, {self.n_triangles} triangles, {self.n_edges} edges, "
                 f"{self.n_components} component(s), Euler characteristic {self.euler_characteristic}, {kind}",
                 f"  area {self.area:.6g}, mean edge length {self.mean_edge_length:.4g}, "
                 f"min angle {self.min_angle_deg:.3g} deg; boundary curves: {curves}"]
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


# --------------------------------------------------------------------------- small helpers

def _examples(values, fmt=str, k=_N_EXAMPLES) -> str:
    """'a, b, c, ...' listing the first k items."""
    values = list(values)
    text = ", ".join(fmt(v) for v in values[:k])
    return text + (", ..." if len(values) > k else "")


def _plural(n: int, word: str, words: str | None = None) -> str:
    """'1 such triangle', '3 such triangles' ('vertex' / 'vertices' via ``words``)."""
    return f"{n} such {word if n == 1 else (words or word + 's')}"


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


def _face_components(topo):
    """(n_components, label per face) of the graph of faces joined across interior edges."""
    m = topo.n_faces
    inner = topo.edge_faces[topo.edge_faces[:, 1] >= 0]
    g = coo_matrix((np.ones(len(inner)), (inner[:, 0], inner[:, 1])), shape=(m, m))
    return connected_components(g, directed=False)


def _component_orientation_scores(points, triangles, topo, label, n_comp, flat_tol=1e-9):
    """Per component: is it closed, is it flat, and a signed score that is > 0 when
    the normals already follow the convention (outward / +z / away from centroid).

    The score is the signed enclosed volume (length³) for closed components, the
    projected area on the xy plane (length²) for flat ones, and the flux of the
    area vectors away from the area centroid (length³) for other open ones; an open
    curved component whose flux is negligible falls back to the projected area.
    """
    p = points[triangles]
    av = triangle_area_vectors(points, triangles)
    area = np.linalg.norm(av, axis=1)
    closed = np.ones(n_comp, bool)
    closed[label[topo.edge_faces[topo.boundary_edges, 0]]] = False

    # signed volume: sum of tetrahedra (origin, p0, p1, p2); translation invariant when closed
    vol = np.bincount(label, np.einsum("mi,mi->m", p[:, 0], np.cross(p[:, 1], p[:, 2])), n_comp) / 6.0
    nz = np.bincount(label, av[:, 2], n_comp)

    lo = np.full((n_comp, 3), np.inf)
    hi = np.full((n_comp, 3), -np.inf)
    np.minimum.at(lo, label, p.min(axis=1))
    np.maximum.at(hi, label, p.max(axis=1))
    size = np.maximum((hi - lo).max(axis=1), 1e-300)
    flat = (hi[:, 2] - lo[:, 2]) <= flat_tol * size

    comp_area = np.maximum(np.bincount(label, area, n_comp), 1e-300)
    cf = p.mean(axis=1)
    centre = np.column_stack([np.bincount(label, area * cf[:, i], n_comp) for i in range(3)]) / comp_area[:, None]
    away = np.bincount(label, np.einsum("mi,mi->m", av, cf - centre[label]), n_comp)
    away = np.where(np.abs(away) <= 1e-9 * comp_area * size, nz, away)

    score = np.where(closed, vol, np.where(flat, nz, away))
    return closed, flat, score


def _coincident_vertices(points, named_curves) -> np.ndarray:
    """Pairs (i, j) of vertices at the same point (within 1e-10 of the mesh's extent), except pairs
    whose two vertices both lie on named boundary curves (a deliberate cut, like a slit)."""
    extent = max(float(np.ptp(points, axis=0).max()), 1e-300)
    key = np.round((points - points.min(axis=0)) / (1e-10 * extent)).astype(np.int64)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    shared = np.flatnonzero(counts[inverse] > 1)
    if not len(shared):
        return np.zeros((0, 2), np.int64)
    order = shared[np.argsort(inverse[shared], kind="stable")]
    first = np.r_[True, inverse[order][1:] != inverse[order][:-1]]
    lead = np.maximum.accumulate(np.where(first, np.arange(len(order)), 0))
    pairs = np.column_stack([order[lead], order])[~first]           # each later copy with the first
    on_curve = np.zeros(len(points), bool)
    for seg in named_curves.values():
        on_curve[np.asarray(seg, np.int64).ravel()] = True
    return pairs[~(on_curve[pairs[:, 0]] & on_curve[pairs[:, 1]])]


# --------------------------------------------------------------------------- check_mesh

def check_mesh(mesh: SurfaceMesh, *, require_closed: bool | None = None,
               require_flat: bool | None = None) -> MeshReport:
    """Validate a mesh for shell computations; raise :class:`MeshError` naming every defect.

    Checks, in three stages (a later stage needs the earlier ones to pass):

    1. coordinates are finite; vertex indices are in range; no triangle repeats a vertex;
    2. every edge has at most two triangles (from :func:`build_topology`);
    3. consistent orientation (names an edge and its two triangles); degenerate
       triangles (area < 1e-12 * mean edge length², in length²); inverted triangles on a
       flat mesh (normal z of the wrong sign compared with the majority); folded
       triangles on a curved mesh (normals more than 150 degrees apart across an
       edge); unreferenced vertices (they leave singular rows in the stiffness);
       coincident vertices (an unmerged mesh, cut along them) unless both lie on
       named boundary curves (a deliberate cut such as the annulus' slit);
       non-manifold (bow-tie) vertices; normals against the convention of design.md
       section 3 (inward on a closed component, -z on a flat mesh: fix with
       :func:`orient_consistently`); and the optional requirements.

    Parameters
    ----------
    mesh : SurfaceMesh
    require_closed : bool or None
        True: the mesh must have no boundary edges; False: it must have some; None: either.
    require_flat : bool or None
        True: all vertices in one plane z = const (``mesh.is_flat()``); False: not flat; None: either.

    Returns
    -------
    MeshReport
        Summary numbers; ``warnings`` lists non-fatal quality remarks (angles < 5 degrees).

    Example
    -------
    >>> import numpy as np
    >>> from femshell.mesh import SurfaceMesh
    >>> sq = SurfaceMesh(np.array([[0., 0], [1, 0], [1, 1], [0, 1]]), np.array([[0, 1, 2], [0, 2, 3]]))
    >>> r = check_mesh(sq, require_flat=True)
    >>> r.is_closed, r.n_boundary_edges, r.area
    (False, 4, 1.0)
    """
    if not isinstance(mesh, SurfaceMesh):
        raise TypeError(f"check_mesh takes a SurfaceMesh, got {type(mesh).__name__} (build one with "
                        "SurfaceMesh(points, triangles), or read a file with femshell.mesh.read_mesh)")
    pts, tri = mesh.points, mesh.triangles
    n, m = len(pts), len(tri)
    label = f"mesh '{mesh.name}'" if mesh.name else "mesh"

    def fail(problems):
        if problems:
            head = f"{label} is invalid ({len(problems)} defect kind{'' if len(problems) == 1 else 's'}):"
            raise MeshError("\n  - ".join([head] + problems))

    # ---- stage 1: raw arrays
    if m == 0:
        raise MeshError(f"{label} has no triangles")
    problems = []
    bad_v = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if len(bad_v):
        problems.append("non-finite coordinates: " + _examples(
            bad_v, lambda v: f"vertex {v} at {pts[v].tolist()}") + f" ({_plural(len(bad_v), 'vertex', 'vertices')})")
    if not len(bad_v):
        extent = float(np.ptp(pts, axis=0).max()) if n else 0.0
        if not EXTENT_RANGE[0] <= extent <= EXTENT_RANGE[1]:
            # areas (length²) and curvatures (1/length) of such a mesh underflow or overflow float64
            problems.append(f"size out of range: the mesh spans {extent:.3g} (largest extent of its vertices), "
                            f"outside [{EXTENT_RANGE[0]:g}, {EXTENT_RANGE[1]:g}]; rescale its coordinates")
    out = (tri < 0) | (tri >= n)
    bad_t = np.flatnonzero(out.any(axis=1))
    if len(bad_t):
        problems.append(f"vertex index out of range 0..{n - 1}: " + _examples(
            bad_t, lambda t: f"triangle {t} refers to vertex {tri[t][out[t]][0]} ({tri[t].tolist()})")
            + f" ({_plural(len(bad_t), 'triangle')})")
    rep = np.flatnonzero((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2]))
    if len(rep):
        problems.append("degenerate triangles: " + _examples(
            rep, lambda t: f"triangle {t} repeats a vertex {tri[t].tolist()}") + f" ({_plural(len(rep), 'triangle')})")
    fail(problems)

    # ---- stage 2: topology (raises for non-manifold edges, naming edge and triangles)
    try:
        topo = mesh.topology
    except MeshError as err:
        raise MeshError(f"{label} is invalid (1 defect kind):\n  - {err}") from err

    # ---- stage 3: everything that needs topology and geometry
    problems = []
    av = triangle_area_vectors(pts, tri)
    area = np.linalg.norm(av, axis=1)
    lengths = triangle_edge_lengths(pts, tri)
    mean_len = float(lengths.mean())
    tiny = DEGENERATE_AREA_FACTOR * mean_len ** 2
    degenerate = area < tiny

    inc = topo.inconsistent_edges
    if len(inc):
        problems.append("inconsistent orientation: " + _examples(
            inc, lambda e: f"edge {tuple(topo.edges[e].tolist())} runs the same way in triangles "
                           f"{topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]}")
            + f" ({_plural(len(inc), 'edge')}); " + (
                "fix with orient_consistently(mesh)" if not len(_relative_flips(topo, len(tri))[3]) else
                "the surface is non-orientable (like a Möbius strip): no flips make it consistent, and a "
                "shell needs a two-sided surface"))

    deg = np.flatnonzero(degenerate)
    if len(deg):
        problems.append("degenerate triangles: " + _examples(
            deg, lambda t: f"triangle {t} has area {area[t]:.3g} < 1e-12 * (mean edge length)^2 = {tiny:.3g}; "
                           f"vertices {tri[t].tolist()}") + f" ({_plural(len(deg), 'triangle')})")

    flat = mesh.is_flat()
    if flat:
        # On a flat mesh the sign of the normal's z component is the orientation;
        # triangles disagreeing with the majority are turned over (a tangled mesh),
        # even when the index order looks consistent.
        ok = ~degenerate
        pos = ok & (av[:, 2] > 0)
        neg = ok & (av[:, 2] < 0)
        if pos.any() and neg.any():
            minority = neg if neg.sum() <= pos.sum() else pos
            inv = np.flatnonzero(minority)
            problems.append("inverted triangles: " + _examples(
                inv, lambda t: f"triangle {t} has normal z {'<' if neg[t] else '>'} 0 "
                               f"(signed area {av[t, 2]:.3g}), vertices {tri[t].tolist()}")
                + f" ({_plural(len(inv), 'triangle')}, against {int((~minority & ok).sum())} of the other sign)")
    else:
        # A triangle turned over onto its neighbour: normals (almost) opposite across
        # an edge whose index order is consistent (inconsistent edges are reported above).
        inner = np.flatnonzero(topo.edge_faces[:, 1] >= 0)
        f0, f1 = topo.edge_faces[inner, 0], topo.edge_faces[inner, 1]
        angle = np.zeros(topo.n_edges)
        angle[inner] = fold_angles(pts, tri, topo.edge_faces)
        consistent = np.ones(topo.n_edges, bool)
        consistent[inc] = False
        fold = inner[(angle[inner] > FOLD_ANGLE_DEG) & consistent[inner] & ~degenerate[f0] & ~degenerate[f1]]
        if len(fold):
            problems.append("folded triangles: " + _examples(
                fold, lambda e: f"at edge {tuple(topo.edges[e].tolist())} the normals of triangles "
                                f"{topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]} are "
                                f"{angle[e]:.1f} deg apart")
                + f" ({_plural(len(fold), 'edge')})")

    used = np.bincount(tri.ravel(), minlength=n) > 0
    unused = np.flatnonzero(~used)
    if len(unused):
        problems.append("unreferenced vertices (they leave singular rows in the stiffness): " + _examples(
            unused, lambda v: f"vertex {v} at {pts[v].tolist()}")
            + f" ({_plural(len(unused), 'vertex', 'vertices')}); remove them")

    twins = _coincident_vertices(pts, mesh.boundary)
    if len(twins):
        problems.append("coincident vertices (separate copies of one point, so the surface is cut there, as in "
                        "an unmerged STL file): " + _examples(
                            twins, lambda pr: f"vertices {pr[0]} and {pr[1]} at {pts[pr[0]].tolist()}")
                        + f" ({_plural(len(twins), 'pair')}); merge them, or name the cut as boundary curves "
                        "on both sides (like the annulus' slit)")

    bowtie = _nonmanifold_vertices(tri, topo)
    if len(bowtie):
        nfan = bowtie[:, 1]
        problems.append("non-manifold vertices: " + _examples(
            range(len(bowtie)), lambda i: f"vertex {bowtie[i, 0]} at {pts[bowtie[i, 0]].tolist()} "
                                          f"has {nfan[i]} separate triangle fans")
            + f" ({_plural(len(bowtie), 'vertex', 'vertices')}); a shell surface needs one fan per vertex")

    # Normal convention of design.md section 3, per connected component; only
    # meaningful once the orientation is consistent (otherwise reported above).
    n_comp, comp = _face_components(topo)
    if not len(inc):
        closed_c, flat_c, score = _component_orientation_scores(pts, tri, topo, comp, n_comp)
        first_face = np.unique(comp, return_index=True)[1]
        inward = np.flatnonzero(closed_c & (score < 0))
        if len(inward):
            problems.append("inward normals on a closed surface: " + _examples(
                inward, lambda c: f"component {c} (containing triangle {first_face[c]}) has signed volume "
                                  f"{score[c]:.4g} < 0") + f" ({_plural(len(inward), 'component')}); "
                "design.md section 3 wants outward normals: fix with orient_consistently(mesh)")
        down = np.flatnonzero(~closed_c & flat_c & (score < 0))
        if len(down):
            problems.append("flat surface with -z normals: " + _examples(
                down, lambda c: f"component {c} (containing triangle {first_face[c]}) has projected area "
                                f"{score[c]:.4g} < 0") + f" ({_plural(len(down), 'component')}); "
                "design.md section 3 wants +z normals on flat meshes: fix with orient_consistently(mesh)")

    if require_closed is True and not topo.is_closed:
        b = topo.boundary_edges
        problems.append(f"mesh is not closed: {len(b)} boundary edges in {len(topo.boundary_edge_groups)} curve(s), "
                        "e.g. " + _examples(b, lambda e: f"edge {tuple(topo.edges[e].tolist())} of triangle "
                                                          f"{topo.edge_faces[e, 0]}", k=3))
    if require_closed is False and topo.is_closed:
        problems.append("mesh is closed (no boundary edges) but an open surface was required")
    if require_flat is True and not flat:
        z = pts[:, 2]
        dev = np.abs(z - np.median(z))
        size = max(np.ptp(pts, axis=0).max(), 1e-300)
        off = np.flatnonzero(dev > 1e-9 * size)
        if not len(off):
            off = np.array([int(np.argmax(dev))])
        off = off[np.argsort(-dev[off], kind="stable")]
        problems.append(f"mesh is not flat: z spans {np.ptp(z):.4g}; furthest from z = {np.median(z):.4g}: "
                        + _examples(off, lambda v: f"vertex {v} at {pts[v].tolist()}", k=3)
                        + f" ({len(off)} vertices off that plane)")
    if require_flat is False and flat:
        problems.append("mesh is flat (all z equal) but a curved surface was required")
    fail(problems)

    angles = triangle_angles(pts, tri)
    warn = warn_poor_quality(mesh, _angles=angles)
    return MeshReport(
        n_vertices=n, n_triangles=m, n_edges=topo.n_edges, n_boundary_edges=len(topo.boundary_edges),
        n_components=int(n_comp), euler_characteristic=topo.euler_characteristic,
        is_closed=topo.is_closed, is_flat=flat,
        boundary_curves={k: len(v) for k, v in topo.boundary_edge_groups.items()},
        area=float(area.sum()), mean_edge_length=mean_len, min_angle_deg=float(angles.min()),
        warnings=(warn,) if warn else ())


def _nonmanifold_vertices(tri: np.ndarray, topo) -> np.ndarray:
    """Vertices whose triangles form more than one edge-connected fan, as rows (vertex, n_fans).

    Graph on the 3m triangle corners: across every interior edge, join the two
    corners of each end vertex. The connected components of this graph are the
    fans; a manifold vertex has exactly one.
    """
    m = len(tri)
    inner = np.flatnonzero(topo.edge_faces[:, 1] >= 0)
    f0, f1 = topo.edge_faces[inner, 0], topo.edge_faces[inner, 1]
    k0, k1 = topo.edge_local[inner, 0], topo.edge_local[inner, 1]
    a0, b0 = (k0 + 1) % 3, (k0 + 2) % 3          # local positions of the edge's ends in f0
    a1, b1 = (k1 + 1) % 3, (k1 + 2) % 3
    same = tri[f0, a0] == tri[f1, a1]             # ends appear in the same or swapped order
    c1a = np.where(same, a1, b1)
    c1b = np.where(same, b1, a1)
    rows = np.concatenate([3 * f0 + a0, 3 * f0 + b0])
    cols = np.concatenate([3 * f1 + c1a, 3 * f1 + c1b])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * m, 3 * m))
    _, fan = connected_components(g, directed=False)
    # distinct (vertex, fan) pairs; integer keys are much faster than np.unique(axis=0)
    pairs = np.unique(tri.ravel() * np.int64(3 * m) + fan)
    nfan = np.bincount(pairs // (3 * m), minlength=topo.n_vertices)
    bad = np.flatnonzero(nfan > 1)
    return np.column_stack([bad, nfan[bad]])


# --------------------------------------------------------------------------- orientation

def orient_consistently(mesh: SurfaceMesh) -> SurfaceMesh:
    """Flip triangles so that neighbours agree and normals follow design.md section 3.

    Per connected component (triangles joined across edges), the relative flips
    come from the parity of a breadth-first spanning tree of the face graph whose
    edges are marked "same" (the two triangles run along the shared edge in the
    same direction, so one of them must flip) or "consistent"; the parity to the
    root is accumulated by pointer jumping, so there is no Python loop over faces.
    The global sign of each component is then chosen: outward (positive signed
    volume) when closed, +z (positive projected area) when flat, away from the
    area centroid for other open surfaces.

    Returns ``mesh`` itself when nothing needs flipping, else a new mesh with the
    same points, boundary curves and name. Raises :class:`MeshError` when a
    component is non-orientable (a Möbius strip), naming an edge that cannot be
    made consistent, or when an edge has more than two triangles.

    Example
    -------
    >>> import numpy as np
    >>> sq = SurfaceMesh(np.array([[0., 0], [1, 0], [1, 1], [0, 1]]), np.array([[0, 2, 1], [0, 2, 3]]))
    >>> orient_consistently(sq).triangles.tolist()
    [[0, 1, 2], [0, 2, 3]]
    """
    topo = mesh.topology
    tri = mesh.triangles
    flip, inner, f0, still, n_comp, comp = _relative_flips(topo, len(tri))
    if len(still):
        e = inner[still[0]]
        bad_comps = np.unique(comp[f0[still]])
        raise MeshError(
            f"{'mesh ' + repr(mesh.name) if mesh.name else 'mesh'} is non-orientable (like a Möbius strip): "
            f"component(s) {_examples(bad_comps)} cannot be oriented consistently; e.g. edge "
            f"{tuple(topo.edges[e].tolist())} between triangles {topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]} "
            f"stays inconsistent ({_plural(len(still), 'edge')} after propagation); a shell needs a two-sided surface")

    oriented = np.where(flip[:, None], tri[:, [0, 2, 1]], tri)
    _, _, score = _component_orientation_scores(mesh.points, oriented, topo, comp, n_comp)
    flip ^= (score < 0)[comp]
    if not flip.any():
        return mesh
    new_tri = np.where(flip[:, None], tri[:, [0, 2, 1]], tri)
    return SurfaceMesh(mesh.points, new_tri, mesh.boundary, mesh.name)


def _relative_flips(topo, m):
    """(flip per face to agree with its component's root, the interior edges, their first faces, the
    interior edges still inconsistent after the flips (non-orientable where any), n_comp, comp)."""
    inner = np.flatnonzero(topo.edge_faces[:, 1] >= 0)
    f0, f1 = topo.edge_faces[inner, 0], topo.edge_faces[inner, 1]
    k0, k1 = topo.edge_local[inner, 0], topo.edge_local[inner, 1]
    same = topo.face_edge_sign[f0, k0] == topo.face_edge_sign[f1, k1]
    n_comp, comp = _face_components(topo)
    flip = _flip_parity(m, f0, f1, same, comp)
    return flip, inner, f0, np.flatnonzero(same ^ flip[f0] ^ flip[f1]), n_comp, comp


def _flip_parity(m, f0, f1, same, comp):
    """Whether to flip each face so that it agrees with the root face of its component.

    A virtual node ``m`` joins the first face of every component, so one
    breadth-first search spans all components. ``par[f]`` starts as the mark of
    the tree edge from f to its parent and, by pointer jumping
    (par[f] ^= par[parent[f]]; parent[f] = parent[parent[f]]), becomes the parity
    of the whole path to the root in O(log depth) vectorised rounds.
    """
    _, reps = np.unique(comp, return_index=True)
    rows = np.concatenate([f0, f1, reps, np.full(len(reps), m)])
    cols = np.concatenate([f1, f0, np.full(len(reps), m), reps])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(m + 1, m + 1)).tocsr()
    _, pred = breadth_first_order(g, m, directed=False, return_predecessors=True)
    parent = pred.astype(np.int64)
    parent[m] = m

    # Mark of the tree edge (f, parent f): look the pair up among the face-graph edges.
    # If two triangles share two edges with different marks, the one found here may be
    # wrong; the consistency check after propagation then reports the surface.
    key = np.concatenate([f0 * (m + 1) + f1, f1 * (m + 1) + f0])
    mark = np.concatenate([same, same])
    order = np.argsort(key, kind="stable")
    key, mark = key[order], mark[order]
    faces = np.arange(m)
    want = faces * (m + 1) + parent[:m]
    pos = np.minimum(np.searchsorted(key, want), max(len(key) - 1, 0))
    par = np.zeros(m + 1, bool)
    if len(key):
        par[:m] = np.where(parent[:m] == m, False, mark[pos] & (key[pos] == want))

    for _ in range(64):                      # 2^64 > any tree depth
        if (parent == m).all():
            break
        par = par ^ par[parent]
        parent = parent[parent]
    return par[:m]


# --------------------------------------------------------------------------- quality

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
