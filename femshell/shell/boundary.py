"""Boundary conditions of the shell: which unknowns are fixed and how edge normals are held.

Each condition resolves, for a given mesh, into fixed position components (with
prescribed values) and, for the bending part, a kind per boundary edge
(free / clamped / symmetry, see :mod:`femshell.shell.bending`).

Conditions
----------
``Clamped(curve)``            positions and mid-edge normals fixed
``SimplySupported(curve)``    positions fixed, rotation free
``Symmetry(axis, value=0)``   mirror plane x_axis = value: that displacement
                              component is zero on the plane, mid-edge normals
                              lie in the plane
``Prescribed(curve|vertices, components, displacement)``  some displacement
                              components prescribed (diaphragms, supports)

Example
-------
>>> bcs = [Clamped("outer")]                       # doctest: +SKIP
>>> bcs = [Symmetry("x"), Symmetry("y"), Prescribed("bottom", components=(0, 1))]  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bending import CLAMPED, SYMMETRY

AXES = {"x": 0, "y": 1, "z": 2}


def _curve_vertices(mesh, curve):
    groups = mesh.topology.boundary_vertex_groups
    if curve not in groups:
        raise ValueError(f"mesh has no boundary curve '{curve}'; it has: {', '.join(groups) or 'none'}")
    return groups[curve]


def _curve_edges(mesh, curve):
    groups = mesh.topology.boundary_edge_groups
    if curve not in groups:
        raise ValueError(f"mesh has no boundary curve '{curve}'; it has: {', '.join(groups) or 'none'}")
    return groups[curve]


def _fix(fixed, values, rows, cols, new, what):
    """Fix ``values[rows, cols] = new``; a component an earlier condition fixed to another value is an error."""
    idx = np.ix_(rows, cols)
    # within the symmetry planes' tolerance (1e-8 of the mesh size): a clamped vertex on a plane agrees
    clash = fixed[idx] & ~np.isclose(values[idx], new, rtol=0.0, atol=1e-8 * max(np.ptp(values, axis=0).max(), 1e-300))
    if clash.any():
        r, c = np.argwhere(clash)[0]
        raise ValueError(f"{what} prescribes component {'xyz'[cols[c]]} of vertex {rows[r]} as "
                         f"{np.broadcast_to(new, clash.shape)[r, c]:.6g}, but an earlier boundary condition "
                         f"fixed it at {values[idx][r, c]:.6g}: contradictory boundary conditions")
    fixed[idx] = True
    values[idx] = new


@dataclass(frozen=True)
class Clamped:
    curve: str

    def apply(self, mesh, fixed, values, edge_kind, edge_direction):
        v = _curve_vertices(mesh, self.curve)
        _fix(fixed, values, v, [0, 1, 2], mesh.points[v], f"Clamped('{self.curve}')")
        edge_kind[_curve_edges(mesh, self.curve)] = CLAMPED


@dataclass(frozen=True)
class SimplySupported:
    curve: str

    def apply(self, mesh, fixed, values, edge_kind, edge_direction):
        v = _curve_vertices(mesh, self.curve)
        _fix(fixed, values, v, [0, 1, 2], mesh.points[v], f"SimplySupported('{self.curve}')")


@dataclass(frozen=True)
class Symmetry:
    """Mirror plane ``{x[axis] = value}``; applies to every vertex on it (within tol × mesh size)."""

    axis: str
    value: float = 0.0
    tol: float = 1e-8

    def apply(self, mesh, fixed, values, edge_kind, edge_direction):
        if self.axis not in AXES:
            raise ValueError(f"symmetry axis must be one of x, y, z, got '{self.axis}'")
        i = AXES[self.axis]
        size = np.ptp(mesh.points, axis=0).max()
        on = np.abs(mesh.points[:, i] - self.value) <= self.tol * size
        if not on.any():
            raise ValueError(f"no mesh vertex lies on the symmetry plane {self.axis} = {self.value}")
        _fix(fixed, values, np.flatnonzero(on), [i], np.full((int(on.sum()), 1), float(self.value)),
             f"Symmetry('{self.axis}', {self.value:g})")
        t = mesh.topology
        be = t.boundary_edges
        on_plane = be[on[t.edges[be]].all(axis=1)]
        edge_kind[on_plane] = SYMMETRY
        edge_direction[on_plane] = np.eye(3)[i]


@dataclass(frozen=True)
class Prescribed:
    """Prescribe displacement ``components`` of a curve's (or listed) vertices; zero by default."""

    curve: str | None = None
    vertices: tuple | None = None
    components: tuple = (0, 1, 2)
    displacement: tuple | None = None

    def apply(self, mesh, fixed, values, edge_kind, edge_direction):
        if (self.curve is None) == (self.vertices is None):
            raise ValueError("Prescribed needs exactly one of 'curve' or 'vertices'")
        if self.curve is not None:
            v = _curve_vertices(mesh, self.curve)
        else:
            v = np.atleast_1d(np.asarray(self.vertices))
            if v.dtype.kind not in "iu" or v.ndim != 1 or np.any((v < 0) | (v >= mesh.n_vertices)):
                raise ValueError(f"Prescribed vertices must be indices in [0, {mesh.n_vertices - 1}], "
                                 f"got {self.vertices!r}")
        comps = list(self.components)
        if not set(comps) <= {0, 1, 2}:
            raise ValueError(f"components must be among 0, 1, 2, got {comps}")
        u = np.zeros(3) if self.displacement is None else np.asarray(self.displacement, float)
        if u.shape != (3,) or not np.all(np.isfinite(u)):
            raise ValueError(f"displacement must be 3 finite numbers (x, y, z), got {self.displacement!r}")
        what = f"Prescribed({self.curve!r})" if self.curve is not None else "Prescribed(vertices=...)"
        _fix(fixed, values, v, comps, mesh.points[np.ix_(v, comps)] + u[comps], what)


def rigid_body_pins(points: np.ndarray) -> list[tuple[int, int]]:
    """Six (vertex, component) pairs whose fixing removes the rigid motions and nothing else.

    A: all three components of one vertex (translations); B, the vertex farthest
    from A: the two components most normal to AB (two rotations); C, the vertex
    farthest from the line AB: the component most normal to the plane ABC (the
    rotation about AB). The support is statically determinate, so it adds no
    reaction to a self-equilibrated load such as growth.
    """
    x = np.asarray(points, float)
    a = int(np.argmin(np.linalg.norm(x - x.mean(0), axis=1)))
    d = x - x[a]
    b = int(np.argmax(np.linalg.norm(d, axis=1)))
    ab = d[b] / np.linalg.norm(d[b])
    perp = d - np.outer(d @ ab, ab)
    c = int(np.argmax(np.linalg.norm(perp, axis=1)))
    normal = np.cross(ab, d[c])
    normal /= np.linalg.norm(normal)
    b_comps = np.argsort(np.abs(ab))[:2]
    c_comp = int(np.argmax(np.abs(normal)))
    return [(a, 0), (a, 1), (a, 2), (b, int(b_comps[0])), (b, int(b_comps[1])), (c, c_comp)]
