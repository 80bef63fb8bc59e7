r"""External loads as potentials :math:`-W(q)` added to the strain energy.

Each load gives its work ``W`` and the gradient and Hessian of ``W`` with respect to
the full unknown vector ``q = [x.ravel(), theta]`` (Hessian as element blocks for
the assembler). Dead loads are linear in ``x`` (zero Hessian).

``PointForce(vertices, force)``        dead force on each listed vertex
``AreaLoad(traction)``                 dead force per unit rest area (gravity: (0, 0, -q))
``EdgeForce(curve, force)``            dead force per unit rest length along a boundary curve
``DeadPressure(p)``                    p times the rest area normal (does not follow the shell)
``FollowerPressure(p)``                :math:`W = p V(x)`, V the enclosed volume
                                       :math:`\tfrac16\sum x_0\cdot(x_1\times x_2)`:
                                       the force follows the normal; conservative on closed
                                       surfaces and on open ones whose rim is held
``EdgeMoment(curve, moment)``          bending moment per unit rest length on a boundary curve,
                                       :math:`W = M \sum_e L_e \varphi_e`, with
                                       :math:`\varphi_e` the rotation of the mid-edge normal
                                       about the edge, continued past ±π so a strip can roll
                                       into full circles
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .boundary import _curve_edges
from .bending import mid_edge_normals
from .element import float64


def _area_vectors(points, triangles):
    x = points[triangles]
    return 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])


def lumped_vertex_forces(mesh, traction_per_area):
    """Dead force per vertex from a traction per rest area: one third of each triangle to its vertices."""
    area = np.linalg.norm(_area_vectors(mesh.points, mesh.triangles), axis=1)
    f = np.zeros((mesh.n_vertices, 3))
    t = np.broadcast_to(np.asarray(traction_per_area, float), (mesh.n_triangles, 3))
    for k in range(3):
        np.add.at(f, mesh.triangles[:, k], t * area[:, None] / 3.0)
    return f


def _magnitude(name, value) -> float:
    """One finite number (a pressure, a moment per length), or a ValueError naming it."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be one finite number, got {value!r}") from None
    if not np.isfinite(v):
        raise ValueError(f"{name} must be one finite number, got {value!r}")
    return v


def _vector3(name, value, n_rows=None) -> np.ndarray:
    """A finite 3-vector (or, with ``n_rows``, one per row: shape (n_rows, 3)), or a ValueError naming it."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = None
    shapes = [(3,)] + ([(n_rows, 3)] if n_rows is not None else [])
    if v is None or v.shape not in shapes or not np.all(np.isfinite(v)):
        want = " or ".join(str(s) for s in shapes)
        raise ValueError(f"{name} must be finite numbers of shape {want}, got {value!r}"[:300])
    return v


@dataclass
class DeadLoad:
    """A fixed force per vertex, (n, 3): the base of all dead loads."""

    forces: np.ndarray

    def __post_init__(self):
        f = np.asarray(self.forces, dtype=float)
        if f.ndim != 2 or f.shape[1] != 3 or not np.all(np.isfinite(f)):
            raise ValueError(f"forces must be finite numbers of shape (n_vertices, 3), got shape {f.shape}"
                             + ("" if f.ndim != 2 or f.shape[1] != 3 else " with NaN or infinity"))

    def setup(self, model):
        if len(self.forces) != model.mesh.n_vertices:
            raise ValueError(f"dead load has forces for {len(self.forces)} vertices, the mesh has "
                             f"{model.mesh.n_vertices}")
        self._f = np.zeros(model.n_total)
        self._f[: 3 * model.mesh.n_vertices] = np.asarray(self.forces, float).ravel()

    def work(self, q):
        return float(self._f @ q)

    def gradient(self, q):
        return self._f

    def hessian_blocks(self, q):
        return None


def PointForce(mesh, vertices, force) -> DeadLoad:
    """The same force (3,) on each listed vertex."""
    v = np.atleast_1d(np.asarray(vertices))
    v = v.astype(np.int64) if v.size == 0 else v
    force = np.asarray(force, float)
    if v.dtype.kind not in "iu" or v.ndim != 1 or np.any((v < 0) | (v >= mesh.n_vertices)):
        raise ValueError(f"vertices must be indices in [0, {mesh.n_vertices - 1}], got {vertices!r}")
    if force.shape != (3,) or not np.all(np.isfinite(force)):
        raise ValueError(f"force must be 3 finite numbers, got {force.tolist()!r}")
    f = np.zeros((mesh.n_vertices, 3))
    f[v] += force
    return DeadLoad(f)


def AreaLoad(mesh, traction) -> DeadLoad:
    """Force per unit rest area, e.g. gravity (0, 0, -q): (3,), or (m, 3) one per triangle."""
    return DeadLoad(lumped_vertex_forces(mesh, _vector3("traction", traction, mesh.n_triangles)))


def DeadPressure(mesh, pressure) -> DeadLoad:
    """Pressure p along the rest normals (does not rotate with the shell)."""
    pressure = _magnitude("pressure", pressure)
    av = _area_vectors(mesh.points, mesh.triangles)
    f = np.zeros((mesh.n_vertices, 3))
    for k in range(3):
        np.add.at(f, mesh.triangles[:, k], pressure * av / 3.0)
    return DeadLoad(f)


def EdgeForce(mesh, curve, force_per_length) -> DeadLoad:
    """Force per unit rest length on a boundary curve, half of each edge to its two vertices."""
    edges = mesh.topology.edges[_curve_edges(mesh, curve)]
    length = np.linalg.norm(mesh.points[edges[:, 1]] - mesh.points[edges[:, 0]], axis=1)
    f = np.zeros((mesh.n_vertices, 3))
    g = np.outer(length / 2.0, _vector3("force_per_length", force_per_length))
    np.add.at(f, edges[:, 0], g)
    np.add.at(f, edges[:, 1], g)
    return DeadLoad(f)


def _volume(x):
    return jnp.dot(x[0], jnp.cross(x[1], x[2])) / 6.0


_vol_grad = jax.jit(jax.vmap(jax.grad(lambda q: _volume(q.reshape(3, 3)))))
_vol_hess = jax.jit(jax.vmap(jax.hessian(lambda q: _volume(q.reshape(3, 3)))))


@dataclass
class FollowerPressure:
    """Pressure p > 0 pushing along the current outward normal: W = p V(x)."""

    pressure: float

    def __post_init__(self):
        self.pressure = _magnitude("pressure", self.pressure)

    def setup(self, model):
        tri = model.mesh.triangles
        self._dofs = (3 * tri[:, :, None] + np.arange(3)).reshape(-1, 9)
        self._n = model.n_total

    def work(self, q):
        x = q[self._dofs].reshape(-1, 3, 3)
        return float(self.pressure * np.einsum("mi,mi->m", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6.0)

    def gradient(self, q):
        with float64():
            g = np.asarray(_vol_grad(q[self._dofs]))
        return self.pressure * np.bincount(self._dofs.ravel(), g.ravel(), minlength=self._n)

    def hessian_blocks(self, q):
        with float64():
            return self._dofs, self.pressure * np.asarray(_vol_hess(q[self._dofs]))


def _edge_rotation(q, kind, direction, sign, k, reference_normal, axis):
    """Angle of the mid-edge normal of local edge k about ``axis`` from ``reference_normal``."""
    x = q[:9].reshape(3, 3)
    p = q[9:18].reshape(3, 3)
    ne, _ = mid_edge_normals(x, p, q[18:], kind, direction, sign)
    n = ne[k]
    return jnp.arctan2(jnp.dot(jnp.cross(reference_normal, n), axis), jnp.dot(reference_normal, n))


_ROTATION = jax.jit(jax.vmap(_edge_rotation))
_ROTATION_GRAD = jax.jit(jax.vmap(jax.grad(_edge_rotation)))
_ROTATION_HESS = jax.jit(jax.vmap(jax.hessian(_edge_rotation)))


@dataclass
class EdgeMoment:
    """Moment per unit rest length about a boundary curve, right-handed about the curve's direction
    of travel (counter-clockwise around a +z-normal flat sheet).

    The rotation angle is measured from the rest mid-edge normal; ``update_branch``
    moves the reference along with accepted states so the angle grows past ±π.
    """

    curve: str
    moment: float

    def __post_init__(self):
        self.moment = _magnitude("moment", self.moment)

    def setup(self, model):
        t = model.mesh.topology
        e = _curve_edges(model.mesh, self.curve)
        self._faces = t.edge_faces[e, 0]
        self._local = t.edge_local[e, 0]
        x = model.mesh.points
        # axis: the edge as its triangle runs along it, so it is consistent along the curve
        tri_f = t.triangles[self._faces]
        a = tri_f[np.arange(len(e)), (self._local + 1) % 3]
        b = tri_f[np.arange(len(e)), (self._local + 2) % 3]
        axis = x[b] - x[a]
        self._length = np.linalg.norm(axis, axis=1)
        self._axis = axis / self._length[:, None]
        self._dofs = model.element_dofs[self._faces]
        self._kind = model.edge_kind_el[self._faces]
        self._dir = model.edge_direction_el[self._faces]
        self._sign = model.face_edge_sign[self._faces]
        nf = np.cross(x[t.triangles[self._faces, 1]] - x[t.triangles[self._faces, 0]],
                      x[t.triangles[self._faces, 2]] - x[t.triangles[self._faces, 0]])
        self._ref = nf / np.linalg.norm(nf, axis=1)[:, None]
        self._offset = np.zeros(len(e))
        self._n = model.n_total
        self._phi, self._dphi, self._ddphi = _ROTATION, _ROTATION_GRAD, _ROTATION_HESS

    def _call(self, fn, q):
        with float64():
            return np.asarray(fn(q[self._dofs], self._kind, self._dir, self._sign, self._local, self._ref, self._axis))

    def angles(self, q):
        """Rotation of each edge's normal from its rest normal, continuous across ±π."""
        return self._offset + self._call(self._phi, q)

    def update_branch(self, q):
        """Move the reference to the current normals (call after each accepted step, so that
        no single step rotates an edge by more than π)."""
        rel = self._call(self._phi, q)
        self._offset = self._offset + rel
        c, s = np.cos(rel)[:, None], np.sin(rel)[:, None]
        r, a = self._ref, self._axis
        self._ref = c * r + s * np.cross(a, r) + (1 - c) * np.sum(a * r, 1)[:, None] * a

    def work(self, q):
        return float(self.moment * np.sum(self._length * self.angles(q)))

    def gradient(self, q):
        g = self._call(self._dphi, q) * (self.moment * self._length)[:, None]
        return np.bincount(self._dofs.ravel(), g.ravel(), minlength=self._n)

    def hessian_blocks(self, q):
        h = self._call(self._ddphi, q) * (self.moment * self._length)[:, None, None]
        return self._dofs, h
