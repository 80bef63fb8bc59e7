"""Combinatorics of a triangle mesh: edges, neighbours, boundary curves.

Conventions (used by every element in femshell):

* local edge ``k`` of a triangle is the edge opposite its local vertex ``k``,
  running from vertex ``(k+1) % 3`` to vertex ``(k+2) % 3``;
* a global edge ``e`` is stored as ``edges[e] = (i, j)`` with ``i < j``;
  ``face_edge_sign[f, k]`` is +1 when triangle ``f`` runs along its local edge
  ``k`` from ``i`` to ``j``, -1 otherwise (on a consistently oriented mesh the
  two triangles of an interior edge have opposite signs);
* ``face_opposite[f, k]`` is the vertex of the *neighbouring* triangle across
  local edge ``k`` that is not on the edge (-1 on the boundary); this is the
  extra vertex of the Kirchhoff bending stencil.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


class MeshError(ValueError):
    """A mesh that femshell cannot compute on; the message names the defect and where."""


@dataclass(frozen=True, eq=False)
class Topology:
    """Cached connectivity of a triangle mesh (see module docstring for conventions)."""

    n_vertices: int
    triangles: np.ndarray          # (m, 3)
    edges: np.ndarray              # (ne, 2), edges[e, 0] < edges[e, 1]
    face_edges: np.ndarray         # (m, 3) global edge of local edge k
    face_edge_sign: np.ndarray     # (m, 3) +1 / -1, see module docstring
    edge_faces: np.ndarray         # (ne, 2) faces of each edge, -1 when missing
    edge_local: np.ndarray         # (ne, 2) local index k of the edge in each face, -1
    face_neighbors: np.ndarray     # (m, 3) triangle across local edge k, -1 on boundary
    face_opposite: np.ndarray      # (m, 3) vertex across local edge k, -1 on boundary
    boundary_edge_groups: dict     # name -> global edge indices, in curve order where possible
    inconsistent_edges: np.ndarray  # interior edges whose two faces disagree in orientation

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @property
    def n_faces(self) -> int:
        return len(self.triangles)

    @property
    def boundary_edges(self) -> np.ndarray:
        """Indices of edges with exactly one triangle."""
        return np.flatnonzero(self.edge_faces[:, 1] < 0)

    @property
    def boundary_vertices(self) -> np.ndarray:
        return np.unique(self.edges[self.boundary_edges])

    @property
    def boundary_vertex_groups(self) -> dict:
        """name -> sorted vertex indices on that boundary curve."""
        return {k: np.unique(self.edges[e]) for k, e in self.boundary_edge_groups.items()}

    @property
    def is_closed(self) -> bool:
        return len(self.boundary_edges) == 0

    @property
    def euler_characteristic(self) -> int:
        """V - E + F, counting only vertices used by a triangle."""
        used = len(np.unique(self.triangles)) if self.n_faces else 0
        return used - self.n_edges + self.n_faces


def edge_key(i, j, n_vertices):
    """A unique integer for the undirected edge {i, j}."""
    i, j = np.minimum(i, j), np.maximum(i, j)
    return i.astype(np.int64) * n_vertices + j


def build_topology(triangles: np.ndarray, n_vertices: int, named_boundary: dict | None = None) -> Topology:
    """Compute the :class:`Topology` of a triangle mesh in O(m log m), no Python loop over elements.

    Raises :class:`MeshError` for vertex indices out of range, degenerate
    (repeated-vertex) triangles and edges shared by more than two triangles,
    naming the offending triangle or edge.
    """
    tri = np.asarray(triangles)
    if tri.size and not np.issubdtype(tri.dtype, np.integer):     # 1.7 would become vertex 1
        raise MeshError(f"triangles must be integer vertex indices, got dtype {tri.dtype}")
    tri = tri.astype(np.int64)
    m = len(tri)
    if m == 0:
        raise MeshError("mesh has no triangles")
    bad = np.flatnonzero((tri < 0).any(1) | (tri >= n_vertices).any(1))
    if len(bad):
        raise MeshError(f"triangle {bad[0]} has vertex index out of range 0..{n_vertices - 1}: "
                        f"{tri[bad[0]].tolist()} ({len(bad)} such triangle{'s' if len(bad) > 1 else ''})")
    rep = np.flatnonzero((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2]))
    if len(rep):
        raise MeshError(f"triangle {rep[0]} repeats a vertex: {tri[rep[0]].tolist()} "
                        f"({len(rep)} such triangle{'s' if len(rep) > 1 else ''})")

    a = tri[:, [1, 2, 0]].ravel()  # half-edge k of face f: tri[f,(k+1)%3] -> tri[f,(k+2)%3]
    b = tri[:, [2, 0, 1]].ravel()
    keys = edge_key(a, b, n_vertices)
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    if counts.max() > 2:
        e = np.flatnonzero(counts > 2)[0]
        i, j = divmod(int(uniq[e]), n_vertices)
        faces = np.flatnonzero(inverse == e) // 3
        raise MeshError(f"non-manifold edge ({i}, {j}) is shared by {counts[e]} triangles {faces.tolist()} "
                        f"({int((counts > 2).sum())} such edges); a shell surface allows at most two")
    edges = np.column_stack(divmod(uniq, n_vertices)).astype(np.int64)
    ne = len(edges)
    face_edges = inverse.reshape(m, 3)
    face_edge_sign = np.where(a < b, 1, -1).reshape(m, 3)

    order = np.argsort(inverse, kind="stable")
    first = np.zeros(ne, np.int64)
    first[1:] = np.cumsum(counts)[:-1]
    he0 = order[first]
    he1 = np.where(counts == 2, order[np.minimum(first + 1, len(order) - 1)], -1)
    edge_faces = np.column_stack([he0 // 3, np.where(he1 >= 0, he1 // 3, -1)])
    edge_local = np.column_stack([he0 % 3, np.where(he1 >= 0, he1 % 3, -1)])

    face_neighbors = np.full((m, 3), -1, np.int64)
    face_opposite = np.full((m, 3), -1, np.int64)
    inner = np.flatnonzero(counts == 2)
    f0, k0 = edge_faces[inner, 0], edge_local[inner, 0]
    f1, k1 = edge_faces[inner, 1], edge_local[inner, 1]
    face_neighbors[f0, k0] = f1
    face_neighbors[f1, k1] = f0
    face_opposite[f0, k0] = tri[f1, k1]
    face_opposite[f1, k1] = tri[f0, k0]
    inconsistent = inner[face_edge_sign[f0, k0] == face_edge_sign[f1, k1]]

    groups = _boundary_groups(edges, np.flatnonzero(counts == 1), n_vertices, named_boundary or {})
    for arr in (edges, face_edges, face_edge_sign, edge_faces, edge_local, face_neighbors, face_opposite):
        arr.setflags(write=False)
    return Topology(n_vertices, tri, edges, face_edges, face_edge_sign, edge_faces, edge_local,
                    face_neighbors, face_opposite, groups, inconsistent)


def _boundary_groups(edges, boundary_edges, n_vertices, named):
    """Map named boundary segments to edge indices; group the rest by connected component."""
    keys = edges[:, 0] * n_vertices + edges[:, 1]
    groups = {}
    claimed = np.zeros(len(edges), bool)
    for name, seg in named.items():
        seg = np.asarray(seg, np.int64).reshape(-1, 2)
        if len(seg) == 0:
            continue
        k = edge_key(seg[:, 0], seg[:, 1], n_vertices)
        pos = np.searchsorted(keys, k)
        pos = np.minimum(pos, len(keys) - 1)
        found = keys[pos] == k
        if not found.all():
            s = seg[~found][0]
            raise MeshError(f"boundary curve '{name}' has segment ({s[0]}, {s[1]}) that is not an edge of the mesh")
        groups[name] = pos
        claimed[pos] = True
    rest = boundary_edges[~claimed[boundary_edges]]
    if len(rest):
        labels = _edge_components(edges[rest], n_vertices)
        for c in range(labels.max() + 1):
            groups[f"boundary-{c}"] = rest[labels == c]
    return groups


def _edge_components(seg, n_vertices):
    """Connected-component label of each segment of a set of edges."""
    n = len(seg)
    g = coo_matrix((np.ones(n), (seg[:, 0], seg[:, 1])), shape=(n_vertices, n_vertices))
    _, lab = connected_components(g, directed=False)
    # renumber components in order of first appearance so names are deterministic
    comp = lab[seg[:, 0]]
    _, first, inv = np.unique(comp, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))
    return rank[inv]


#: How many examples a message lists before "...".
N_EXAMPLES = 5


def examples(values, fmt=str, k=N_EXAMPLES) -> str:
    """'a, b, c, ...' listing the first k items."""
    values = list(values)
    text = ", ".join(fmt(v) for v in values[:k])
    return text + (", ..." if len(values) > k else "")


def plural(n: int, word: str, words: str | None = None) -> str:
    """'1 such triangle', '3 such triangles' ('vertex' / 'vertices' via ``words``)."""
    return f"{n} such {word if n == 1 else (words or word + 's')}"

