r"""Rigid motions of a shell state and the inverse of a stiffness restricted to their complement.

A shell held by no (or too few) supports has the rigid motions Z in the null space of its Hessian
at every equilibrium: translations t and rotations ξ × x of the vertex positions x, with the edge
unknowns (turning angles relative to the faces) unchanged. Instead of pinning vertices, the
operators here work on the orthogonal complement of Z (docs/guide/continuation.md): a solve of
``K x = b`` with ``Zᵀ x = 0`` is one symmetric-indefinite factorisation of the bordered matrix

.. math:: \begin{pmatrix} K & s Z \\ s Z^T & 0 \end{pmatrix}
          \begin{pmatrix} x \\ y \end{pmatrix} = \begin{pmatrix} P b \\ 0 \end{pmatrix},

(s a scale of K's diagonal), whose inertia is that of K on the complement plus (r, r, 0) for the
r border rows: so it also counts K's negative eigenvalues there (Sylvester's law).

An eigen solver whose inner product is K's (ARPACK's regular-inverse and buckling modes) needs K
positive definite, not only on the complement: the rigid parts of its vectors, unseen by a
semidefinite norm, grow from round-off and spoil the Ritz values. The lifted matrix
K + s Z Zᵀ is definite (K on the complement, s on Z), and its inverse is the deflated one plus
Z Zᵀ / s (:func:`lifted`, :meth:`DeflatedInverse.lifted`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..solvers.linear import factorize

__all__ = ["rigid_motions", "DeflatedInverse", "lifted"]


def rigid_motions(model, u, du=None):
    """Orthonormal basis Z (n_free, r) of the rigid motions at state u that the model's constraints allow;
    with ``du`` (a direction of the free unknowns) also their rate Ż along it, (Z, Ż).

    The six motions (three translations, three rotations about the centroid of the positions x(u))
    in the full unknowns, combined so that every fixed unknown stays at zero (a symmetry plane keeps
    the motions within it, a clamped edge none: r = 0), restricted to the free unknowns and
    orthonormalised. Ż applies the same combination to the rotations of the moved positions,
    ξ × (ẋ − mean ẋ) (translations do not change).
    """
    n = model.mesh.n_vertices
    fixed = ~model.free

    def raw(x, rotations_only=False):
        Z = np.zeros((model.n_total, 6))
        c = x - x.mean(axis=0)
        for k in range(3):
            if not rotations_only:
                Z[k: 3 * n: 3, k] = 1.0
            axis = np.zeros(3)
            axis[k] = 1.0
            Z[: 3 * n, 3 + k] = np.cross(axis, c).ravel()
        return Z

    x = model.positions(u)
    Z = raw(x)
    combine = np.eye(6)
    if fixed.any():
        _, s, vt = np.linalg.svd(Z[fixed], full_matrices=True)
        rank = int(np.sum(s > 1e-9 * s.max()))
        combine = vt[rank:].T
    Zf = (Z @ combine)[model.free]
    if Zf.shape[1] == 0:
        return Zf if du is None else (Zf, Zf)
    q, r = np.linalg.qr(Zf)
    if du is None:
        return q
    rate = (raw(model.mode_displacements(du), rotations_only=True) @ combine)[model.free]
    return q, np.linalg.solve(r.T, rate.T).T


def remove_rigid_part(x, Z):
    """x (n_free,) or (n_free, k) minus its orthogonal projection on the columns of Z (orthonormal)."""
    return x - Z @ (Z.T @ x) if Z.shape[1] else x


def lifted(K, Z, scale):
    """x ↦ (K + scale Z Zᵀ) x: K with its rigid null space Z (orthonormal) lifted to ``scale``."""
    return lambda x: K @ x + scale * (Z @ (Z.T @ x)) if Z.shape[1] else K @ x


class DeflatedInverse:
    """``(K on the complement of Z)⁻¹``: ``inv(b)`` solves K x = P b with Zᵀ x = 0 (P the orthogonal
    projector off Z, Z orthonormal), by one factorisation of the bordered matrix (module docstring).

    ``inertia``: (positive, negative, zero) eigenvalues of K on the complement, or None when the
    back-end cannot count them. ``scale``: the border's scale s, mean |diag K|. ``lifted(b, scale)``
    solves (K + scale Z Zᵀ) x = b. ``free()`` releases the factorisation.
    """

    def __init__(self, K, Z, backend="auto"):
        K = sp.csr_matrix(K)
        self.n, self.r = K.shape[0], Z.shape[1]
        self.Z = Z
        self.scale = float(np.abs(K.diagonal()).mean()) or 1.0
        if self.r:
            border = sp.csr_matrix(self.scale * Z)
            K = sp.bmat([[K, border], [border.T, None]], format="csr")
        self._fac = factorize(K, kind="symmetric_indefinite", backend=backend)
        inertia = self._fac.inertia
        self.inertia = None if inertia is None else (inertia[0] - self.r, inertia[1] - self.r, inertia[2])

    def __call__(self, b):
        b = remove_rigid_part(np.asarray(b, dtype=float), self.Z)
        rhs = np.concatenate([b, np.zeros((self.r,) + b.shape[1:])]) if self.r else b
        return remove_rigid_part(self._fac.solve(rhs)[: self.n], self.Z)

    def lifted(self, b, scale):
        """(K + scale Z Zᵀ)⁻¹ b = (this inverse) b + Z Zᵀ b / scale (module docstring)."""
        b = np.asarray(b, dtype=float)
        return self(b) + self.Z @ (self.Z.T @ b) / scale

    def free(self):
        self._fac.free()
