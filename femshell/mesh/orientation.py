"""Orientation of a triangle mesh: neighbours that agree and femshell's normal convention,
outward on closed surfaces, +z on flat ones, away from the centroid on other open surfaces."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..geometry import triangle_area_vectors
from .surface import SurfaceMesh
from .topology import MeshError, examples, plural


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



def orient_consistently(mesh: SurfaceMesh) -> SurfaceMesh:
    """Flip triangles so that neighbours agree and normals follow femshell's convention (module docstring).

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
            f"component(s) {examples(bad_comps)} cannot be oriented consistently; e.g. edge "
            f"{tuple(topo.edges[e].tolist())} between triangles {topo.edge_faces[e, 0]} and {topo.edge_faces[e, 1]} "
            f"stays inconsistent ({plural(len(still), 'edge')} after propagation); a shell needs a two-sided surface")

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
