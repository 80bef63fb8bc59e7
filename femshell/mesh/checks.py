"""Mesh validation, orientation repair and element-quality statistics.

Every check here is vectorised numpy over all triangles / vertices / edges at
once; the only Python loops run over the (few) defect *kinds* and, in
:func:`orient_consistently`, over the O(log depth) pointer-jumping rounds.

* :func:`check_mesh` raises :class:`~femshell.mesh.topology.MeshError` naming
  every defect it finds (which vertex, triangle or edge, where, and how many),
  or returns a :class:`MeshReport` summary of a good mesh.
* :func:`orient_consistently` (:mod:`~femshell.mesh.orientation`) flips triangles so that neighbours agree and the
  normals follow femshell's convention: outward on closed surfaces, +z on flat
  ones, away from the centroid on other open surfaces.
* :func:`quality_report`, :func:`format_quality` and :func:`warn_poor_quality`
  (:mod:`~femshell.mesh.quality`) measure angles, aspect ratios, edge lengths and areas.

Lengths are in the mesh's length unit (the cell size),
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
from scipy.sparse.csgraph import connected_components

from ..geometry import fold_angles, triangle_area_vectors
from .orientation import _component_orientation_scores, _face_components, _relative_flips, orient_consistently
from .quality import format_quality, quality_report, triangle_angles, triangle_edge_lengths, warn_poor_quality
from .surface import SurfaceMesh
from .topology import MeshError, examples, plural

__all__ = ["MeshReport", "check_mesh", "orient_consistently", "quality_report", "format_quality",
           "warn_poor_quality", "triangle_angles", "triangle_edge_lengths", "EXTENT_RANGE",
           "DEGENERATE_AREA_FACTOR", "FOLD_ANGLE_DEG"]


#: The largest extent of a mesh's vertices must lie in this range (the generators make sizes in [1e-6, 1e5]).
EXTENT_RANGE = (1e-9, 1e8)
#: A triangle is degenerate when its area is below this times the squared mean edge length.
DEGENERATE_AREA_FACTOR = 1e-12
#: Across an interior edge, normals more than this many degrees apart mark a fold
#: (a triangle turned over onto its neighbour). A regular tetrahedron has 109.5 degrees.
FOLD_ANGLE_DEG = 150.0


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
       non-manifold (bow-tie) vertices; normals against femshell's convention
       (inward on a closed component, -z on a flat mesh: fix with
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
    fail(_array_problems(pts, tri))

    # ---- stage 2: topology (raises for non-manifold edges, naming edge and triangles)
    try:
        topo = mesh.topology
    except MeshError as err:
        raise MeshError(f"{label} is invalid (1 defect kind):\n  - {err}") from err

    # ---- stage 3: everything that needs topology and geometry
    av = triangle_area_vectors(pts, tri)
    area = np.linalg.norm(av, axis=1)
    mean_len = float(triangle_edge_lengths(pts, tri).mean())
    flat = mesh.is_flat()
    n_comp, comp = _face_components(topo)
    problems = _shape_problems(pts, tri, topo, av, area, DEGENERATE_AREA_FACTOR * mean_len ** 2, flat)
    problems += _vertex_problems(mesh, topo)
    if not len(topo.inconsistent_edges):
        problems += _convention_problems(pts, tri, topo, comp, n_comp)
    problems += _requirement_problems(pts, topo, flat, require_closed, require_flat)
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


def _array_problems(pts, tri) -> list:
    """Stage 1: non-finite coordinates, a size out of range, vertex indices out of range, repeated vertices."""
    n = len(pts)
    problems = []
    bad_v = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if len(bad_v):
        problems.append("non-finite coordinates: " + examples(
            bad_v, lambda v: f"vertex {v} at {pts[v].tolist()}") + f" ({plural(len(bad_v), 'vertex', 'vertices')})")
    if not len(bad_v):
        extent = float(np.ptp(pts, axis=0).max()) if n else 0.0
        if not EXTENT_RANGE[0] <= extent <= EXTENT_RANGE[1]:
            # areas (length²) and curvatures (1/length) of such a mesh underflow or overflow float64
            problems.append(f"size out of range: the mesh spans {extent:.3g} (largest extent of its vertices), "
                            f"outside [{EXTENT_RANGE[0]:g}, {EXTENT_RANGE[1]:g}]; rescale its coordinates")
    out = (tri < 0) | (tri >= n)
    bad_t = np.flatnonzero(out.any(axis=1))
    if len(bad_t):
        problems.append(f"vertex index out of range 0..{n - 1}: " + examples(
            bad_t, lambda t: f"triangle {t} refers to vertex {tri[t][out[t]][0]} ({tri[t].tolist()})")
            + f" ({plural(len(bad_t), 'triangle')})")
    rep = np.flatnonzero((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2]))
    if len(rep):
        problems.append("degenerate triangles: " + examples(
            rep, lambda t: f"triangle {t} repeats a vertex {tri[t].tolist()}") + f" ({plural(len(rep), 'triangle')})")
    return problems


def _shape_problems(pts, tri, topo, av, area, tiny, flat) -> list:
    """Inconsistent orientation, degenerate triangles (area < ``tiny``), inverted (flat mesh) or folded
    (curved mesh) triangles."""
    problems = []
    degenerate = area < tiny
    inc = topo.inconsistent_edges
    if len(inc):
        problems.append("inconsistent orientation: " + examples(
            inc, lambda e: f"edge {tuple(topo.edges[e].tolist())} runs the same way in triangles "
                           f"{topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]}")
            + f" ({plural(len(inc), 'edge')}); " + (
                "fix with orient_consistently(mesh)" if not len(_relative_flips(topo, len(tri))[3]) else
                "the surface is non-orientable (like a Möbius strip): no flips make it consistent, and a "
                "shell needs a two-sided surface"))

    deg = np.flatnonzero(degenerate)
    if len(deg):
        problems.append("degenerate triangles: " + examples(
            deg, lambda t: f"triangle {t} has area {area[t]:.3g} < 1e-12 * (mean edge length)^2 = {tiny:.3g}; "
                           f"vertices {tri[t].tolist()}") + f" ({plural(len(deg), 'triangle')})")

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
            problems.append("inverted triangles: " + examples(
                inv, lambda t: f"triangle {t} has normal z {'<' if neg[t] else '>'} 0 "
                               f"(signed area {av[t, 2]:.3g}), vertices {tri[t].tolist()}")
                + f" ({plural(len(inv), 'triangle')}, against {int((~minority & ok).sum())} of the other sign)")
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
            problems.append("folded triangles: " + examples(
                fold, lambda e: f"at edge {tuple(topo.edges[e].tolist())} the normals of triangles "
                                f"{topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]} are "
                                f"{angle[e]:.1f} deg apart")
                + f" ({plural(len(fold), 'edge')})")
    return problems


def _vertex_problems(mesh, topo) -> list:
    """Unreferenced, coincident and non-manifold vertices."""
    pts, tri, n = mesh.points, mesh.triangles, mesh.n_vertices
    problems = []
    used = np.bincount(tri.ravel(), minlength=n) > 0
    unused = np.flatnonzero(~used)
    if len(unused):
        problems.append("unreferenced vertices (they leave singular rows in the stiffness): " + examples(
            unused, lambda v: f"vertex {v} at {pts[v].tolist()}")
            + f" ({plural(len(unused), 'vertex', 'vertices')}); remove them")

    twins = _coincident_vertices(pts, mesh.boundary)
    if len(twins):
        problems.append("coincident vertices (separate copies of one point, so the surface is cut there, as in "
                        "an unmerged STL file): " + examples(
                            twins, lambda pr: f"vertices {pr[0]} and {pr[1]} at {pts[pr[0]].tolist()}")
                        + f" ({plural(len(twins), 'pair')}); merge them, or name the cut as boundary curves "
                        "on both sides (like the annulus' slit)")
    bowtie = _nonmanifold_vertices(tri, topo)
    if len(bowtie):
        nfan = bowtie[:, 1]
        problems.append("non-manifold vertices: " + examples(
            range(len(bowtie)), lambda i: f"vertex {bowtie[i, 0]} at {pts[bowtie[i, 0]].tolist()} "
                                          f"has {nfan[i]} separate triangle fans")
            + f" ({plural(len(bowtie), 'vertex', 'vertices')}); a shell surface needs one fan per vertex")
    return problems


def _convention_problems(pts, tri, topo, comp, n_comp) -> list:
    """Normals against the convention (outward, +z on flat meshes), per connected component; only
    meaningful once the orientation is consistent."""
    problems = []
    closed_c, flat_c, score = _component_orientation_scores(pts, tri, topo, comp, n_comp)
    first_face = np.unique(comp, return_index=True)[1]
    inward = np.flatnonzero(closed_c & (score < 0))
    if len(inward):
        problems.append("inward normals on a closed surface: " + examples(
            inward, lambda c: f"component {c} (containing triangle {first_face[c]}) has signed volume "
                              f"{score[c]:.4g} < 0") + f" ({plural(len(inward), 'component')}); "
            "femshell wants outward normals: fix with orient_consistently(mesh)")
    down = np.flatnonzero(~closed_c & flat_c & (score < 0))
    if len(down):
        problems.append("flat surface with -z normals: " + examples(
            down, lambda c: f"component {c} (containing triangle {first_face[c]}) has projected area "
                            f"{score[c]:.4g} < 0") + f" ({plural(len(down), 'component')}); "
            "femshell wants +z normals on flat meshes: fix with orient_consistently(mesh)")
    return problems


def _requirement_problems(pts, topo, flat, require_closed, require_flat) -> list:
    """The optional requirements of :func:`check_mesh`: closed or open, flat or curved."""
    problems = []
    if require_closed is True and not topo.is_closed:
        b = topo.boundary_edges
        problems.append(f"mesh is not closed: {len(b)} boundary edges in {len(topo.boundary_edge_groups)} curve(s), "
                        "e.g. " + examples(b, lambda e: f"edge {tuple(topo.edges[e].tolist())} of triangle "
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
                        + examples(off, lambda v: f"vertex {v} at {pts[v].tolist()}", k=3)
                        + f" ({len(off)} vertices off that plane)")
    if require_flat is False and flat:
        problems.append("mesh is flat (all z equal) but a curved surface was required")
    return problems


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
