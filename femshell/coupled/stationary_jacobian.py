r"""Element kernels of the stationary coupled Jacobian (theory §2.9): the derivatives that the shell's
own energy, gradient and Hessian do not give.

* :func:`force_stretch_derivative`: ∂(∇_q W_e)/∂s_e, the change of an element's force vector (21,) with
  its growth stretch, as the directional derivative of ∇_q W_e along d(ā, b̄, h̄)/ds
  (:meth:`~femshell.growth.GrowthRestState.rest_state_derivative`): the mixed second derivative of the
  element energy :func:`~femshell.shell.element.element_energy` in the rest state (ā, b̄, h̄), where
  ā⁻¹ and Ā = ½ √det ā are formed from ā inside the differentiated function;
* :func:`chemistry_element_derivatives`: the gradients in the element's 21 unknowns of its area
  A_T = ½ √det a, of A_T H_T (H_T = ½ tr(a⁻¹ b) − k_ref) and of the cotangent-stiffness product
  K_T(x) c_T (3,): what the lumped mass, the vertex mean curvature and the diffusion term of the
  chemistry residual depend on.

JAX (float64), ``vmap`` over elements in fixed chunks (:data:`CHUNK`), so one compilation per
membrane law serves every mesh. Plain functions over arrays: element stencils ``q`` (m, 21) and the
per-element edge data of :class:`~femshell.shell.ShellModel` (``edge_kind_el``, ``edge_direction_el``,
``face_edge_sign``).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..shell.bending import MidEdgeTangent
from ..shell.element import element_energy, float64
from ..shell.materials import membrane_law

__all__ = ["force_stretch_derivative", "chemistry_element_derivatives", "CHUNK"]

#: elements per compiled call (the last chunk is padded with copies of its first element)
CHUNK = 512


def _chunked(compiled, batched, shared):
    """``compiled(*batched_chunk, *shared)`` over chunks of :data:`CHUNK` elements, results concatenated."""
    m = len(batched[0])
    pieces = []
    for start in range(0, m, CHUNK):
        part = [a[start:start + CHUNK] for a in batched]
        k = len(part[0])
        if k < CHUNK:
            part = [np.concatenate([a, np.repeat(a[:1], CHUNK - k, axis=0)]) for a in part]
        with float64():
            out = compiled(*part, *shared)
        pieces.append(jax.tree_util.tree_map(lambda o: np.asarray(o)[:k], out))
    return jax.tree_util.tree_map(lambda *o: np.concatenate(o), *pieces)


def _energy_of_rest(q, abar, bbar, hbar, alpha, beta, kind, direction, sign, law):
    """:func:`element_energy` with the target metric ā itself as the argument (ā⁻¹ and Ā formed here)."""
    det = abar[0, 0] * abar[1, 1] - abar[0, 1] * abar[1, 0]
    abar_inv = jnp.array([[abar[1, 1], -abar[0, 1]], [-abar[1, 0], abar[0, 0]]]) / det
    return element_energy(q, abar_inv, bbar, 0.5 * jnp.sqrt(det), hbar, alpha, beta, kind, direction, sign,
                          law=law, formulation=MidEdgeTangent)


@functools.lru_cache(maxsize=None)
def _force_rate_kernel(law_name: str):
    law = membrane_law(law_name)

    def one(q, abar, bbar, hbar, dabar, dbbar, dhbar, kind, direction, sign, alpha, beta):
        def force(rest):
            return jax.grad(_energy_of_rest)(q, *rest, alpha, beta, kind, direction, sign, law)
        return jax.jvp(force, ((abar, bbar, hbar),), ((dabar, dbbar, dhbar),))[1]

    return jax.jit(jax.vmap(one, in_axes=(0,) * 10 + (None, None)))


def force_stretch_derivative(q, rest, rest_rate, kind, direction, sign, material):
    r"""∂(∇_q W_e)/∂s_e per element, (m, 21).

    q : (m, 21) element stencils; rest : (ā, b̄, h̄) per element ((m, 2, 2), (m, 2, 2), (m,));
    rest_rate : d(ā, b̄, h̄)/ds, the same shapes; kind, direction, sign : the shell's per-element
    edge data; material : :class:`~femshell.shell.Material` (its α, β and membrane law).
    """
    batched = [np.asarray(a, dtype=float) for a in (q, *rest, *rest_rate)]
    batched += [np.asarray(kind), np.asarray(direction, dtype=float), np.asarray(sign, dtype=float)]
    return _chunked(_force_rate_kernel(material.law), batched, (material.alpha, material.beta))


def _local_stiffness(x):
    """The P1 cotangent matrix (3, 3) of one triangle with vertices x (3, 3), as
    :meth:`femshell.chemistry.P1Assembler.local_stiffness`."""
    e = x[jnp.array([2, 0, 1])] - x[jnp.array([1, 2, 0])]          # e_k opposite vertex k
    n = jnp.cross(e[1], e[2])
    twice_area = jnp.sqrt(n @ n)
    half = -0.5 * jnp.stack([e[1] @ e[2], e[2] @ e[0], e[0] @ e[1]]) / twice_area
    return jnp.array([[half[1] + half[2], -half[2], -half[1]],
                      [-half[2], half[2] + half[0], -half[0]],
                      [-half[1], -half[0], half[0] + half[1]]])


def _chemistry_element(q, k_ref, c, kind, direction, sign):
    x = q[:9].reshape(3, 3)
    a, b = MidEdgeTangent.forms(x, q[9:18].reshape(3, 3), q[18:], kind, direction, sign)
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    area = 0.5 * jnp.sqrt(det)
    H = 0.5 * (a[1, 1] * b[0, 0] - a[0, 1] * b[1, 0] - a[1, 0] * b[0, 1] + a[0, 0] * b[1, 1]) / det - k_ref
    return area, area * H, _local_stiffness(x) @ c


@functools.lru_cache(maxsize=None)
def _chemistry_kernel():
    return jax.jit(jax.vmap(jax.jacfwd(_chemistry_element), in_axes=(0,) * 6))


def chemistry_element_derivatives(q, k_ref, c_elements, kind, direction, sign):
    r"""Gradients in the 21 element unknowns of A_T, A_T H_T and K_T(x) c_T.

    q : (m, 21) element stencils; k_ref : (m,) reference of H; c_elements : (m, 3) the concentration
    at each element's vertices. Returns (m, 21), (m, 21), (m, 3, 21).
    """
    batched = [np.asarray(q, dtype=float), np.asarray(k_ref, dtype=float), np.asarray(c_elements, dtype=float),
               np.asarray(kind), np.asarray(direction, dtype=float), np.asarray(sign, dtype=float)]
    return _chunked(_chemistry_kernel(), batched, ())
