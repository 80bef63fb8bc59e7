"""The triangulated surface that every other part of femshell works on.

A :class:`SurfaceMesh` is points, triangles and named boundary curves. Its
:attr:`~SurfaceMesh.topology` (edges, neighbours, boundary) is computed once on
first use and cached; the mesh is immutable so the cache stays valid.

Example
-------
>>> import numpy as np
>>> from femshell.mesh import SurfaceMesh
>>> m = SurfaceMesh(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
>>> m.topology.n_edges, m.topology.euler_characteristic
(3, 1)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .topology import Topology, build_topology


@dataclass(frozen=True, eq=False)
class SurfaceMesh:
    """A triangulated surface in 3D.

    Parameters
    ----------
    points : (n, 3) float array
        Vertex coordinates (length unit: the cell size).
    triangles : (m, 3) int array
        Vertex indices of each triangle, counter-clockwise seen from the normal side.
    boundary : dict of str -> (k, 2) int array
        Named boundary curves ("outer", "inner", "slit-a", ...) as lists of
        vertex pairs (segments). Curves not named here get the names
        ``"boundary-0"``, ``"boundary-1"``, ... by connected component.
    name : str
        Free text (which generator made it, with which parameters).
    """

    points: np.ndarray
    triangles: np.ndarray
    boundary: dict = field(default_factory=dict)
    name: str = ""

    def __post_init__(self):
        pts = np.array(self.points, dtype=float)
        if pts.ndim == 2 and pts.shape[1] == 2:
            pts = np.column_stack([pts, np.zeros(len(pts))])
        tri = np.array(self.triangles)
        if tri.size and not np.issubdtype(tri.dtype, np.integer):
            raise ValueError(f"triangles must be integer vertex indices, got dtype {tri.dtype}")
        if tri.size and (tri.ndim != 2 or tri.shape[1] != 3):
            raise ValueError(f"triangles must have shape (m, 3), got {tri.shape}")
        tri = tri.astype(np.int64) if tri.size else np.zeros((0, 3), np.int64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
        boundary = {} if self.boundary is None else self.boundary
        if not hasattr(boundary, "items"):
            raise ValueError("boundary must be a dict {curve name: (k, 2) vertex index pairs}, got "
                             f"{type(boundary).__name__}")
        bnd = {}
        for k, v in boundary.items():
            seg = np.asarray(v)
            if seg.size and (not np.issubdtype(seg.dtype, np.integer) or seg.size % 2):
                raise ValueError(f"boundary curve {k!r} must be (k, 2) integer vertex index pairs, got "
                                 f"shape {seg.shape}, dtype {seg.dtype}")
            bnd[str(k)] = seg.astype(np.int64).reshape(-1, 2)
        pts.setflags(write=False)
        tri.setflags(write=False)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "triangles", tri)
        object.__setattr__(self, "boundary", bnd)

    @property
    def n_vertices(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    @cached_property
    def topology(self) -> Topology:
        """Edges, neighbours and boundary curves, computed once (see :func:`build_topology`)."""
        return build_topology(self.triangles, self.n_vertices, self.boundary)

    def with_points(self, points) -> "SurfaceMesh":
        """The same triangulation at other vertex positions, sharing the cached topology."""
        new = SurfaceMesh(points, self.triangles, self.boundary, self.name)
        if "topology" in self.__dict__:
            object.__setattr__(new, "topology", self.topology)
        return new

    def is_flat(self, tol: float = 1e-9) -> bool:
        """True if every vertex lies in the plane z = const (within tol times the size)."""
        z = self.points[:, 2]
        size = max(np.ptp(self.points, axis=0).max(), 1e-300)
        return bool(np.ptp(z) <= tol * size)

    def __repr__(self):
        t = self.topology
        names = ", ".join(f"{k}: {len(v)}" for k, v in t.boundary_edge_groups.items()) or "none"
        return (f"SurfaceMesh({self.n_vertices} vertices, {self.n_triangles} triangles, "
                f"{t.n_edges} edges, Euler characteristic {t.euler_characteristic}, "
                f"boundary curves: {names}{', ' + self.name if self.name else ''})")
