r"""The discrete Kirchhoff–Love element: one triangle, its three neighbours' far vertices,
and one rotation angle per edge (a geometrically nonlinear Morley element).

Unknowns of one element (21): own vertices :math:`x_0, x_1, x_2`, the vertices
:math:`p_0, p_1, p_2` across the local edges (edge ``k`` is opposite vertex ``k``),
and the edge angles :math:`\theta_0, \theta_1, \theta_2`.

**First fundamental form.** With :math:`e_1 = x_1 - x_0`, :math:`e_2 = x_2 - x_0`
(barycentric coordinates :math:`u = \lambda_1, v = \lambda_2`),
:math:`a = [e_i \cdot e_j]`.

**Mid-edge normals.** On an interior edge with unit tangent :math:`t` (global edge
orientation) and face normals :math:`n_f, n_g`, the mean normal is
:math:`m = (n_f + n_g)/|n_f + n_g|` (on a free boundary edge :math:`m = n_f`), and
the mid-edge normal is :math:`n_e = \cos\theta\, m + \sin\theta\, (t \times m)`:
the edge angle rotates it about the edge. On a clamped edge :math:`n_e` is the
prescribed rest normal; on a symmetry-plane edge it is the unit vector in the plane
normal to the edge.

**Second fundamental form.** Interpolating the normal with the Crouzeix–Raviart
functions :math:`1 - 2\lambda_k` and :math:`b_{ij} = \partial_i x \cdot \partial_j n`
gives exactly

.. math::  b = 2 \begin{pmatrix} s_0 h_0 + s_1 h_1 & s_0 h_0 \\ s_0 h_0 & s_0 h_0 + s_2 h_2 \end{pmatrix},
           \qquad s_k = n_{e_k} \cdot c_k,

with :math:`c_k` the outward in-plane unit conormal of edge ``k`` and :math:`h_k` the
altitude onto it. Only the component of :math:`n_e` across the edge enters, which
is why one angle per edge suffices. For small deflections :math:`w` this is the
Morley element (exact for quadratic :math:`w`), which converges on unstructured
meshes, unlike hinge (dihedral-angle) springs. With outward normals a sphere of
radius R has :math:`b = a/R` (positive).

**Energy** (design.md 1.2, St Venant–Kirchhoff in metric form):

.. math::  W = \bar A \left[\frac{\bar h}{4} \|\bar a^{-1} a - I\|^2
              + \frac{\bar h^3}{12} \|\bar a^{-1}(b - \bar b)\|^2\right],\quad
           \|M\|^2 = \frac{\alpha}{2} (\operatorname{tr} M)^2 + \beta \operatorname{tr}(M^2).

Exact gradients and Hessians come from JAX automatic differentiation of
:func:`element_energy`, in float64, vectorised over all elements.
"""

from __future__ import annotations

import os

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)  # shells need float64: membrane/bending stiffness ratio ~ (R/h)^2
# compiling the element Hessian takes seconds; keep the compiled code between runs
if jax.config.jax_compilation_cache_dir is None:
    jax.config.update("jax_compilation_cache_dir",
                      os.environ.get("FEMSHELL_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "femshell-jax")))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)

import jax.numpy as jnp  # noqa: E402

# edge kinds, per (element, local edge)
INTERIOR, FREE, CLAMPED, SYMMETRY = 0, 1, 2, 3


def _unit(v):
    return v / jnp.sqrt(jnp.sum(v * v))


def mid_edge_normals(x, p, theta, kind, direction, sign):
    """The three mid-edge unit normals of one element and its unit face normal.

    x, p : (3, 3) own and across-edge vertices; theta : (3,) edge angles;
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
        rotated = jnp.cos(theta[k]) * m + jnp.sin(theta[k]) * jnp.cross(t, m)
        sym = _unit(jnp.cross(direction[k], t))
        sym = sym * jnp.sign(jax.lax.stop_gradient(jnp.dot(sym, nf)) + 1e-300)
        ne = jnp.where(kind[k] == CLAMPED, direction[k], jnp.where(kind[k] == SYMMETRY, sym, rotated))
        out.append(ne)
    return jnp.stack(out), nf


def fundamental_forms(x, p, theta, kind, direction, sign):
    """First and second fundamental forms (2x2 each) in the element's barycentric coordinates."""
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
    q0, q1, q2 = s[0] * h[0], s[1] * h[1], s[2] * h[2]
    b = 2.0 * jnp.array([[q0 + q1, q0], [q0, q0 + q2]])
    return a, b


def norm2(M, alpha, beta):
    """(alpha/2) (tr M)^2 + beta tr(M^2): the St Venant–Kirchhoff quadratic form."""
    tr = M[0, 0] + M[1, 1]
    return 0.5 * alpha * tr * tr + beta * jnp.sum(M * M.T)


def element_energy(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
    """Strain energy of one element.

    q : (21,) [x0, x1, x2, p0, p1, p2 (3 each), theta0, theta1, theta2];
    abar_inv, bbar : (2, 2) inverse target metric and target curvature;
    area : target area; hbar : target thickness; alpha, beta : material constants.
    """
    x = q[:9].reshape(3, 3)
    p = q[9:18].reshape(3, 3)
    a, b = fundamental_forms(x, p, q[18:], kind, direction, sign)
    strain = abar_inv @ a - jnp.eye(2)
    bend = abar_inv @ (b - bbar)
    return area * (0.25 * hbar * norm2(strain, alpha, beta) + hbar**3 / 12.0 * norm2(bend, alpha, beta))


def element_membrane_bending(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
    """The membrane and bending parts of :func:`element_energy` separately (for output)."""
    x = q[:9].reshape(3, 3)
    p = q[9:18].reshape(3, 3)
    a, b = fundamental_forms(x, p, q[18:], kind, direction, sign)
    strain = abar_inv @ a - jnp.eye(2)
    bend = abar_inv @ (b - bbar)
    return (area * 0.25 * hbar * norm2(strain, alpha, beta),
            area * hbar**3 / 12.0 * norm2(bend, alpha, beta))


_AXES = (0, 0, 0, 0, 0, None, None, 0, 0, 0)
CHUNK_SMALL, CHUNK = 256, 4096


def _batched(fn):
    """Vectorise ``fn`` over elements in fixed-size chunks.

    JAX compiles once per array shape; two fixed chunk sizes (the bulk in big chunks,
    the rest in small ones, the last padded with copies of element 0) mean two
    compilations serve every mesh size with little wasted work, and bound the memory
    of the (m, 21, 21) Hessian intermediates.
    """
    compiled = jax.jit(jax.vmap(fn, in_axes=_AXES))

    def run(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        per_element = [q, abar_inv, bbar, area, hbar, kind, direction, sign]
        m = len(q)
        # big chunks for the bulk, small ones for the rest: little padding at any size
        n_big = m // CHUNK if m - (m // CHUNK) * CHUNK < CHUNK - CHUNK_SMALL else m // CHUNK + 1
        starts = [(i * CHUNK, CHUNK) for i in range(n_big)]
        starts += [(s, CHUNK_SMALL) for s in range(n_big * CHUNK, m, CHUNK_SMALL)]
        pieces = []
        for start, size in starts:
            part = [a[start:start + size] for a in per_element]
            k = len(part[0])
            if k < size:
                part = [np.concatenate([a, np.repeat(a[:1], size - k, axis=0)]) for a in part]
            out = compiled(part[0], part[1], part[2], part[3], part[4], alpha, beta, part[5], part[6], part[7])
            pieces.append(jax.tree_util.tree_map(lambda o: np.asarray(o)[:k], out))
        if len(pieces) == 1:
            return pieces[0]
        return jax.tree_util.tree_map(lambda *o: np.concatenate(o), *pieces)

    return run


batch_energy = _batched(element_energy)
batch_value_and_grad = _batched(jax.value_and_grad(element_energy))
batch_hessian = _batched(jax.hessian(element_energy))
batch_parts = _batched(element_membrane_bending)


def _forms(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
    return fundamental_forms(q[:9].reshape(3, 3), q[9:18].reshape(3, 3), q[18:], kind, direction, sign)


batch_forms = _batched(_forms)
