r"""The mid-edge bending formulation: the second fundamental form of one element from its
stencil (a geometrically nonlinear Morley element; docs/theory.md §1, second fundamental form).

Stencil of an element: own vertices :math:`x_0, x_1, x_2`, the vertices :math:`p_0, p_1, p_2`
across the local edges (edge ``k`` is opposite vertex ``k``) and one edge unknown
:math:`\theta_k` per edge.

**Mid-edge normals.** On an interior edge with unit tangent :math:`t` (global edge orientation)
and face normals :math:`n_f, n_g`, the mean normal is :math:`m = (n_f + n_g)/|n_f + n_g|` (on a
free boundary edge :math:`m = n_f`) and the mid-edge normal is

.. math::  n_e = (m + \theta\, t \times m)/\sqrt{1 + \theta^2},

``m`` turned about the edge by :math:`\arctan\theta`; it stays on the side of the faces,
:math:`n_e \cdot m > 0`, for every θ (an angle unknown, :math:`\cos\theta\, m + \sin\theta\,
t \times m`, turns past ±π/2 and reads a kink as curvature of the opposite sign). On a clamped
edge :math:`n_e` is the prescribed rest normal; on a symmetry-plane edge the unit vector in the
plane normal to the edge.

**Second fundamental form.** Interpolating the normal with the Crouzeix–Raviart functions
:math:`1 - 2\lambda_k`, :math:`b_{ij} = \partial_i x \cdot \partial_j n` is exactly

.. math::  b = 2 \begin{pmatrix} q_0 + q_1 & q_0 \\ q_0 & q_0 + q_2 \end{pmatrix},
           \qquad q_k = s_k h_k, \quad s_k = n_{e_k} \cdot c_k,

with :math:`c_k` the outward in-plane unit conormal of edge ``k`` and :math:`h_k` the altitude
onto it: only the component of :math:`n_e` across the edge enters. For small deflections this is
the Morley element (exact for quadratic deflections), which converges on unstructured meshes.
With outward normals a sphere of radius R has :math:`b \approx a/R` on average.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

# edge kinds, per (element, local edge)
INTERIOR, FREE, CLAMPED, SYMMETRY = 0, 1, 2, 3

#: what the edge unknowns are, recorded in checkpoints: the tangent of the turning angle
EDGE_UNKNOWN = "tangent"


def _unit(v):
    return v / jnp.sqrt(jnp.sum(v * v))


def turned_normal(m, t, theta):
    r""":math:`n_e = (m + \theta\, t \times m)/\sqrt{1 + \theta^2}`: m turned about the edge t by arctan θ."""
    return (m + theta * jnp.cross(t, m)) / jnp.sqrt(1.0 + theta * theta)


def _prescribed_or_turned(kind, m, t, theta, direction, nf):
    """The mid-edge normal of an edge of any kind: turned (interior, free), ``direction`` (clamped)
    or in the symmetry plane with normal ``direction``."""
    rotated = turned_normal(m, t, theta)
    # only a symmetry edge takes the cross product: on any other edge it can vanish (an edge turned
    # onto its stored direction), and its NaN derivative would leak through the outer where
    sym = _unit(jnp.where(kind == SYMMETRY, jnp.cross(direction, t), nf))
    sym = sym * jnp.sign(jax.lax.stop_gradient(jnp.dot(sym, nf)) + 1e-300)
    return jnp.where(kind == CLAMPED, direction, jnp.where(kind == SYMMETRY, sym, rotated))


def mid_edge_normals(x, p, theta, kind, direction, sign):
    """The three mid-edge unit normals of one element and its unit face normal.

    x, p : (3, 3) own and across-edge vertices; theta : (3,) edge unknowns;
    kind : (3,) edge kinds; direction : (3, 3) clamped normal or symmetry-plane normal;
    sign : (3,) +1/-1 orientation of the local edge against the global edge.
    """
    nf = _unit(jnp.cross(x[1] - x[0], x[2] - x[0]))
    out = []
    for k in range(3):
        a, b = x[(k + 1) % 3], x[(k + 2) % 3]
        t = sign[k] * _unit(b - a)
        ng = _unit(jnp.cross(a - b, p[k] - b))
        m = _unit(nf + jnp.where(kind[k] == INTERIOR, 1.0, 0.0) * ng)
        out.append(_prescribed_or_turned(kind[k], m, t, theta[k], direction[k], nf))
    return jnp.stack(out), nf


def curvature_of_q(q, start=0):
    """b = 2 [[q0 + q1, q0], [q0, q0 + q2]]: the second fundamental form, linear in (q0, q1, q2) =
    q[start:start + 3] (read entry by entry, so that derivatives sum in one fixed order)."""
    i, j, k = start, start + 1, start + 2
    return 2.0 * jnp.array([[q[i] + q[j], q[i]], [q[i], q[i] + q[k]]])


def fundamental_forms(x, p, theta, kind, direction, sign):
    """First and second fundamental forms (2x2 each) in the element's barycentric coordinates,
    a = [e_i · e_j] with e_1 = x_1 − x_0, e_2 = x_2 − x_0."""
    e1, e2 = x[1] - x[0], x[2] - x[0]
    a = jnp.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
    ne, nf = mid_edge_normals(x, p, theta, kind, direction, sign)
    twice_area = jnp.sqrt(a[0, 0] * a[1, 1] - a[0, 1] * a[0, 1])  # explicit: jnp.linalg.det is an LU call
    s, h = [], []
    for k in range(3):
        d = x[(k + 2) % 3] - x[(k + 1) % 3]
        length = jnp.sqrt(d @ d)
        conormal = jnp.cross(d, nf) / length
        s.append(ne[k] @ conormal)
        h.append(twice_area / length)
    return a, curvature_of_q((s[0] * h[0], s[1] * h[1], s[2] * h[2]))


def edge_q(y, k, kind, direction, sign):
    """:math:`q_k = s_k h_k` of local edge ``k`` from its 13 unknowns y = [x0, x1, x2, p_k, theta_k].

    ``kind=None``: an interior edge, without the clamped/symmetry branches. Same arithmetic as
    :func:`fundamental_forms`.
    """
    x = y[:9].reshape(3, 3)
    p, th = y[9:12], y[12]
    nf = _unit(jnp.cross(x[1] - x[0], x[2] - x[0]))
    a, b = x[(k + 1) % 3], x[(k + 2) % 3]
    t = sign * _unit(b - a)
    ng = _unit(jnp.cross(a - b, p - b))
    if kind is None:
        ne = turned_normal(_unit(nf + ng), t, th)
    else:
        m = _unit(nf + jnp.where(kind == INTERIOR, 1.0, 0.0) * ng)
        ne = _prescribed_or_turned(kind, m, t, th, direction, nf)
    e1, e2 = x[1] - x[0], x[2] - x[0]
    twice_area = jnp.sqrt((e1 @ e1) * (e2 @ e2) - (e1 @ e2) * (e1 @ e2))
    d = b - a
    length = jnp.sqrt(d @ d)
    conormal = jnp.cross(d, nf) / length
    return (ne @ conormal) * (twice_area / length)


class MidEdgeTangent:
    """The mid-edge formulation as one swappable piece: what the element needs of it.

    ``forms(x, p, theta, kind, direction, sign) -> (a, b)``; ``edge_q(y, k, kind, direction, sign)``,
    the per-edge number b is linear in; ``curvature(q, start) -> b``; ``normals`` the mid-edge
    normals (loads that act on rotations use them); ``edge_unknown`` what θ is.
    """

    name = "mid-edge-tangent"
    edge_unknown = EDGE_UNKNOWN
    forms = staticmethod(fundamental_forms)
    edge_q = staticmethod(edge_q)
    curvature = staticmethod(curvature_of_q)
    normals = staticmethod(mid_edge_normals)
