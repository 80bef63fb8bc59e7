r"""The shell element: a material law and the mid-edge bending formulation combined into one
energy of one triangle, with its gradient and Hessian batched over all elements.

Unknowns of one element (21): own vertices :math:`x_0, x_1, x_2`, the vertices
:math:`p_0, p_1, p_2` across the local edges and one edge unknown :math:`\theta_k` per edge
(:mod:`femshell.shell.bending`). The energy (docs/theory.md §2, Energy;
:mod:`femshell.shell.materials`) is

.. math::  W = \bar A \left[\bar h\, \psi(\bar a^{-1} a)
              + \frac{\bar h^3}{12} \|\bar a^{-1}(b - \bar b)\|^2\right].

Exact gradients and Hessians come from JAX automatic differentiation of :func:`element_energy`,
in float64 (the membrane/bending stiffness ratio is ~(R/h)²), vectorised over all elements; the
kernels switch jax's float64 mode on around each call (:func:`float64`), leaving ``jax.config``
as it is.

**Split Hessian.** W depends on the unknowns only through the six numbers
:math:`z = (a_{11}, a_{12}, a_{22}, q_0, q_1, q_2)` (b is linear in q; W is quadratic in z for
St Venant–Kirchhoff). The metric entries depend only on the 9 own-vertex coordinates,
quadratically, and :math:`q_k` only on the 13 unknowns :math:`y_k = (x_0, x_1, x_2, p_k, \theta_k)`, so

.. math::  \nabla^2 W = J^T \frac{\partial^2 W}{\partial z^2} J
           + \sum_{ij} \frac{\partial W}{\partial a_{ij}} \nabla^2 a_{ij}
           + \sum_k \frac{\partial W}{\partial q_k} \nabla^2 q_k,
           \qquad J = \partial z / \partial (x, p, \theta)\ (6 \times 21),

with :math:`\nabla^2 a_{ij}` constant and three 13×13 Hessians of
:func:`~femshell.shell.bending.edge_q` (forward over reverse mode, in the 10 relative unknowns
:math:`r = (x_1 - x_0, x_2 - x_0, p_k - x_0, \theta_k)`, as :math:`q_k` is translation invariant).
This is ``jax.hessian(element_energy)`` up to rounding, at a fraction of the cost; elements whose
three edges are interior use a kernel without the clamped/symmetry branches
(:meth:`Kernels.hessian_grouped`).

**Hessian kernels.** :meth:`Kernels.evaluate` computes the Hessians by the same split in compiled
C (:mod:`femshell.shell.fast_element`, ``hessian_kernel="compiled"``, the default; JAX where no C
compiler works) or by the JAX code above (``"jax"``, the reference the tests check the other against).
"""

from __future__ import annotations

import functools
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import jax
import jax.numpy as jnp
import numpy as np

from ..config import element_threads
from . import fast_element
from .bending import (CLAMPED, EDGE_UNKNOWN, FREE, INTERIOR, SYMMETRY, MidEdgeTangent, edge_q,  # noqa: F401
                      fundamental_forms, mid_edge_normals, turned_normal)
from .materials import MEMBRANE_LAWS, NeoHookean, StVenantKirchhoff, membrane_law, norm2  # noqa: F401


def float64():
    """The context the kernels are traced and run in: jax's float64 mode, for this thread only.

    >>> import jax.numpy as jnp
    >>> with float64():
    ...     jnp.zeros(1).dtype
    dtype('float64')
    """
    return jax.enable_x64(True)


def _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, law):
    bend = abar_inv @ (b - bbar)
    return (area * hbar * law.membrane(abar_inv @ a, alpha, beta),
            area * hbar**3 / 12.0 * law.bending(bend, alpha, beta))


def element_membrane_bending(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign,
                             law=StVenantKirchhoff, formulation=MidEdgeTangent):
    """The membrane and bending parts of :func:`element_energy` separately (for output)."""
    a, b = formulation.forms(q[:9].reshape(3, 3), q[9:18].reshape(3, 3), q[18:], kind, direction, sign)
    return _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, law)


def element_energy(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign, law=StVenantKirchhoff,
                   formulation=MidEdgeTangent):
    """Strain energy of one element.

    q : (21,) [x0, x1, x2, p0, p1, p2 (3 each), theta0, theta1, theta2];
    abar_inv, bbar : (2, 2) inverse target metric and target curvature;
    area : target area; hbar : target thickness; alpha, beta : material constants;
    kind, direction, sign : per local edge (:func:`~femshell.shell.bending.mid_edge_normals`);
    law : a membrane law of :mod:`femshell.shell.materials`; formulation : the bending formulation.
    """
    mem, bend = element_membrane_bending(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign,
                                         law, formulation)
    return mem + bend


_AXES = (0, 0, 0, 0, 0, None, None, 0, 0, 0)

#: how element energies, gradients and Hessians are computed: compiled C (the default) or JAX (the reference)
ELEMENT_KERNELS = ("compiled", "jax")


def check_element_kernel(name, key="hessian_kernel"):
    """``name`` if it is one of :data:`ELEMENT_KERNELS`, else a ValueError naming them (and ``key``)."""
    if name not in ELEMENT_KERNELS:
        raise ValueError(f"{key} must be one of {ELEMENT_KERNELS}, got {name!r}")
    return name
CHUNK_SMALL, CHUNK = 256, 4096
CHUNK_HESSIAN = 256


_pool = {"threads": 0, "executor": None, "lock": threading.Lock()}


def _executor(threads: int):
    """A pool of ``threads`` workers, kept between calls (made anew when the count changes or after a fork)."""
    with _pool["lock"]:
        if _pool["threads"] != threads:
            if _pool["executor"] is not None:
                _pool["executor"].shutdown(wait=False)
            _pool["executor"] = ThreadPoolExecutor(threads, thread_name_prefix="femshell-elements")
            _pool["threads"] = threads
        return _pool["executor"]


if hasattr(os, "register_at_fork"):      # a forked child has none of the parent's threads
    os.register_at_fork(after_in_child=lambda: _pool.update(threads=0, executor=None, lock=threading.Lock()))


def _batched(fn, chunk=None, chunk_small=None):
    """Vectorise ``fn`` over elements in fixed-size chunks.

    JAX compiles once per array shape; two fixed chunk sizes (the bulk in big chunks,
    the rest in small ones, the last padded with copies of element 0) mean two
    compilations serve every mesh size with little wasted work, and bound the memory
    of the (m, 21, 21) Hessian intermediates. The Hessian kernels use one small size
    (:data:`CHUNK_HESSIAN`): their intermediates stay in cache, which makes them about
    1.5x faster per element than in chunks of 4096, and compiling them once is costly.
    """
    chunk = CHUNK if chunk is None else chunk
    chunk_small = CHUNK_SMALL if chunk_small is None else chunk_small
    compiled = jax.jit(jax.vmap(fn, in_axes=_AXES))

    def run(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        per_element = [q, abar_inv, bbar, area, hbar, kind, direction, sign]
        m = len(q)
        # big chunks for the bulk, small ones for the rest: little padding at any size
        n_big, rest = divmod(m, chunk)
        n_big += rest > 0 and rest >= chunk - chunk_small
        starts = [(i * chunk, chunk) for i in range(n_big)]
        starts += [(s, chunk_small) for s in range(n_big * chunk, m, chunk_small)]

        def one(start_size):
            start, size = start_size
            part = [a[start:start + size] for a in per_element]
            k = len(part[0])
            if k < size:
                part = [np.concatenate([a, np.repeat(a[:1], size - k, axis=0)]) for a in part]
            with float64():        # per call: the mode is thread-local, and chunks run on worker threads
                out = compiled(part[0], part[1], part[2], part[3], part[4], alpha, beta, part[5], part[6], part[7])
                return jax.tree_util.tree_map(lambda o: np.asarray(o)[:k], out)

        threads = element_threads()
        # JAX releases the GIL while a compiled call runs: chunks on several threads run in parallel
        if threads > 1 and len(starts) > 1:
            pieces = list(_executor(threads).map(one, starts))
        else:
            pieces = [one(s) for s in starts]
        if len(pieces) == 1:
            return pieces[0]
        return jax.tree_util.tree_map(lambda *o: np.concatenate(o), *pieces)

    return run


def energy_of_forms(z, abar_inv, bbar, area, hbar, alpha, beta, law=StVenantKirchhoff, formulation=MidEdgeTangent):
    """:func:`element_energy` as a function of z = (a11, a12, a22, q0, q1, q2) (quadratic for SVK)."""
    a = jnp.array([[z[0], z[1]], [z[1], z[2]]])
    b = formulation.curvature(z, 3)
    mem, bend = _membrane_and_bending(a, b, abar_inv, bbar, area, hbar, alpha, beta, law)
    return mem + bend


# q_k is translation invariant: a function of r = (x1 - x0, x2 - x0, p_k - x0, theta_k) = T y (10 of 13)
_RELATIVE = np.zeros((10, 13))
_RELATIVE[np.arange(9), np.arange(3, 12)] = 1.0
_RELATIVE[np.arange(9), np.tile(np.arange(3), 3)] = -1.0
_RELATIVE[9, 12] = 1.0


_D = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])  # e_i = sum_v D[i, v] x_v
# Hessians of a11, a12, a22 in vertex space (times I3 per coordinate)
_METRIC_HESS = np.stack([2 * np.outer(_D[0], _D[0]), np.outer(_D[0], _D[1]) + np.outer(_D[1], _D[0]),
                         2 * np.outer(_D[1], _D[1])])


def _split_hessian(interior, law=StVenantKirchhoff, formulation=MidEdgeTangent):
    """The element Hessian by the split of the module docstring (``interior``: all edges interior)."""

    def edge_q_relative(r, k, kind, direction, sign):
        return formulation.edge_q(jnp.concatenate([jnp.zeros(3), r]), k, kind, direction, sign)

    def hessian(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        x = q[:9].reshape(3, 3)
        e1, e2 = x[1] - x[0], x[2] - x[0]
        z, hess = [e1 @ e1, e1 @ e2, e2 @ e2], []
        zero = jnp.zeros(3)
        rows = [jnp.concatenate([-2 * e1, 2 * e1, zero]), jnp.concatenate([-(e1 + e2), e2, e1]),
                jnp.concatenate([-2 * e2, zero, 2 * e2])]
        rows = [jnp.concatenate([r, jnp.zeros(12)]) for r in rows]
        for k in range(3):
            r = jnp.concatenate([q[3:9] - jnp.tile(q[:3], 2), q[9 + 3 * k:12 + 3 * k] - q[:3], q[18 + k:19 + k]])
            args = (k, None if interior else kind[k], direction[k], sign[k])
            grad = jax.grad(edge_q_relative)
            hr, gr = jax.jacfwd(lambda v: (grad(v, *args),) * 2, has_aux=True)(r)
            gk, hk = gr @ _RELATIVE, _RELATIVE.T @ hr @ _RELATIVE  # back to y = [x0, x1, x2, p_k, theta_k]
            z.append(edge_q_relative(r, *args))
            row = jnp.zeros(21).at[:9].set(gk[:9]).at[9 + 3 * k:12 + 3 * k].set(gk[9:12])
            rows.append(row.at[18 + k].set(gk[12]))
            hess.append(hk)
        z, J = jnp.stack(z), jnp.stack(rows)  # (6,), (6, 21)
        forms = (abar_inv, bbar, area, hbar, alpha, beta, law, formulation)
        dw = jax.grad(energy_of_forms)(z, *forms)
        H = J.T @ jax.hessian(energy_of_forms)(z, *forms) @ J
        hxx = jnp.kron(jnp.einsum("i,iab->ab", dw[:3], _METRIC_HESS), jnp.eye(3))
        for k in range(3):
            w = dw[3 + k] * hess[k]
            hxx = hxx + w[:9, :9]
            pk, tk = slice(9 + 3 * k, 12 + 3 * k), 18 + k
            H = H.at[:9, pk].add(w[:9, 9:12]).at[pk, :9].add(w[9:12, :9]).at[pk, pk].add(w[9:12, 9:12])
            H = H.at[:9, tk].add(w[:9, 12]).at[tk, :9].add(w[12, :9])
            H = H.at[pk, tk].add(w[9:12, 12]).at[tk, pk].add(w[12, 9:12]).at[tk, tk].add(w[12, 12])
        H = H.at[:9, :9].add(hxx)
        # forward-over-reverse Hessians are symmetric only up to rounding, which on badly
        # distorted elements reaches ~1e-8 of the largest entry: enough for a symmetric
        # factorisation's check to refuse the assembled matrix
        return 0.5 * (H + H.T)

    return hessian


class Kernels:
    """The batched energy, gradient, Hessian and parts of one membrane law combined with a bending
    formulation (compiled on first use): ``k.energy(*args)`` gives the (m,) element energies, with
    ``args`` those of :func:`element_energy` batched over elements (``alpha``, ``beta`` scalars).

    >>> k = kernels("neo-hookean")
    >>> k.law, k.formulation.name
    ('neo-hookean', 'mid-edge-tangent')
    """

    def __init__(self, law: str, formulation=MidEdgeTangent):
        law_type = membrane_law(law)

        def energy(*args):
            return element_energy(*args, law=law_type, formulation=formulation)

        def parts(*args):
            return element_membrane_bending(*args, law=law_type, formulation=formulation)

        self.law, self.formulation = law, formulation
        self.energy = _batched(energy)
        self.value_and_grad = _batched(jax.value_and_grad(energy))
        self.parts = _batched(parts)
        self.hessian = _batched(_split_hessian(False, law_type, formulation), CHUNK_HESSIAN, CHUNK_HESSIAN)
        self.hessian_interior = _batched(_split_hessian(True, law_type, formulation), CHUNK_HESSIAN, CHUNK_HESSIAN)
        self.forms = _batched(functools.partial(_forms, formulation=formulation))

    def evaluate(self, *args, gradient=False, hessian=False, interior=None, hessian_kernel="compiled",
                 gradient_kernel="compiled"):
        """The one entry point: element energies (m,), with their gradients (m, 21) if ``gradient``
        and Hessians (m, 21, 21) if ``hessian`` (``interior``: the elements whose three edges are
        interior, :meth:`hessian_grouped`; ``hessian_kernel`` and ``gradient_kernel``, for the Hessians
        and for the energies and gradients: one of :data:`ELEMENT_KERNELS`, compiled only for the
        mid-edge formulation). Returns (energies, gradients or None, Hessians or None);
        energies are None when only the Hessian is asked for (it does not need them).
        """
        energies = gradients = hessians = None
        if gradient or not hessian:
            if check_element_kernel(gradient_kernel, "gradient_kernel") == "compiled" and self._compiled():
                energies, gradients = fast_element.energies_and_gradients(self.law, *args, executor=_threads())
                gradients = gradients if gradient else None
            elif gradient:
                energies, gradients = self.value_and_grad(*args)
            else:
                energies = self.energy(*args)
        if hessian and check_element_kernel(hessian_kernel) == "compiled" and self._compiled():
            hessians = fast_element.hessians(self.law, *args, executor=_threads())
        elif hessian:
            interior = (np.asarray(args[7]) == INTERIOR).all(axis=1) if interior is None else interior
            hessians = self.hessian_grouped(interior, *args)
        return energies, gradients, hessians

    def _compiled(self) -> bool:
        """Whether the compiled C kernel serves this formulation (and a compiler built it)."""
        return self.formulation is MidEdgeTangent and fast_element.library() is not None

    def hessian_grouped(self, interior, q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign):
        """:attr:`hessian`, with the elements flagged in ``interior`` (all three edges
        interior) through the kernel without boundary branches; same result."""
        args = [q, abar_inv, bbar, area, hbar, kind, direction, sign]
        if interior.all():
            return self.hessian_interior(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign)
        if not interior.any():
            return self.hessian(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign)
        out = np.empty((len(q), 21, 21))
        for mask, fn in ((interior, self.hessian_interior), (~interior, self.hessian)):
            a = [np.asarray(v)[mask] for v in args]
            out[mask] = fn(a[0], a[1], a[2], a[3], a[4], alpha, beta, a[5], a[6], a[7])
        return out


def _threads():
    """The element kernels' thread pool, or None on one thread."""
    threads = element_threads()
    return _executor(threads) if threads > 1 else None


def _forms(q, abar_inv, bbar, area, hbar, alpha, beta, kind, direction, sign, formulation=MidEdgeTangent):
    return formulation.forms(q[:9].reshape(3, 3), q[9:18].reshape(3, 3), q[18:], kind, direction, sign)


_KERNELS = {}


def kernels(law: str = "svk", formulation=MidEdgeTangent) -> Kernels:
    """The :class:`Kernels` of a membrane law and bending formulation, built once per process."""
    key = (law, formulation)
    if key not in _KERNELS:
        _KERNELS[key] = Kernels(law, formulation)
    return _KERNELS[key]


_SVK = kernels("svk")
batch_energy = _SVK.energy
batch_value_and_grad = _SVK.value_and_grad
batch_hessian = _SVK.hessian
batch_hessian_interior = _SVK.hessian_interior
batch_hessian_grouped = _SVK.hessian_grouped
batch_parts = _SVK.parts


batch_forms = _SVK.forms
