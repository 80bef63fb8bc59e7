r"""Stability of a stationary state in the coupled dynamics (theory §2.9): the chemistry evolves, the mechanics
follows quasi-statically.

At a root (u, c) of :class:`~femshell.coupled.stationary.StationaryProblem` with Jacobian
J = [[K, B], [C, A]] (K the shell Hessian), the shell stays in equilibrium, K δu + B δc = 0, and the
chemistry M dc/dt = F_c(u, c) linearises to

    M δċ = S δc,      S = A − C K⁻¹ B      (the Schur complement of the mechanical block),

so the state is stable when every eigenvalue μ of the generalised problem S v = μ M v has Re μ < 0
(M the lumped mass) and K is positive definite (the shell's own stability, theory §2.6). The shape
that goes with a concentration mode v is δu = −K⁻¹ B v.

``method="dense"`` forms S (K⁻¹ B by one sparse factorisation and n_c solves) and computes every μ;
``"shift-invert"`` finds the ``k`` eigenvalues nearest ``sigma`` with ARPACK on (S − σM)⁻¹ M, applied
by solving the full bordered system [[K, B], [C, A − σM]] [y; x] = [0; M v] (x = (S − σM)⁻¹ M v)
with one LU of it, without forming S.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._checks import finite as _finite, integer as _integer
from ..solvers.linear import LinearSolverError, factorize
from ..solvers.lu import LUFactorization

__all__ = ["CoupledStability", "coupled_stability", "DENSE_LIMIT", "ARNOLDI_VECTORS"]

#: largest number of vertices for which ``method="auto"`` forms S densely
DENSE_LIMIT = 1000
#: Arnoldi basis size of ``"shift-invert"`` (at least 2k + 1): where β dominates (D = 0 away from the
#: pattern) the μ cluster near −β, and ARPACK's default basis of 20 takes 3-4 times as many solves
ARNOLDI_VECTORS = 40


@dataclass
class CoupledStability:
    """Eigenvalues μ of S v = μ M v (ascending by −Re μ: the most unstable first), their concentration modes
    (n_c, k) normalised to max |v| = 1 with a positive largest entry, the shape modes δu = −K⁻¹ B v (n_u, k),
    the number of negative eigenvalues of the shell Hessian K, and ``stable``: K positive definite and every
    computed Re μ < 0 (with ``"shift-invert"`` only the k computed ones are known)."""

    eigenvalues: np.ndarray
    c_modes: np.ndarray
    shape_modes: np.ndarray
    n_negative_mechanical: int
    method: str

    @property
    def stable(self) -> bool:
        return self.n_negative_mechanical == 0 and bool(np.all(self.eigenvalues.real < 0))

    @property
    def leading(self) -> complex:
        """The eigenvalue of largest real part among those computed."""
        return self.eigenvalues[0]


def coupled_stability(problem, u, c, k: int = 6, method: str = "auto", sigma: float = 0.0) -> CoupledStability:
    """The eigenproblem of the module docstring at the state (u, c) (a root of ``problem``)."""
    if method not in ("auto", "dense", "shift-invert"):
        raise ValueError(f"method must be 'auto', 'dense' or 'shift-invert', got {method!r}")
    k = _integer("k", k, 1)
    sigma = _finite("sigma", sigma)
    n_u, n_c = problem.n_u, problem.n_c
    if method == "auto":
        method = "dense" if n_c <= DENSE_LIMIT else "shift-invert"
    if method == "shift-invert" and k >= n_c - 1:
        raise ValueError(f"k must be < n_vertices − 1 = {n_c - 1} for shift-invert, got {k}")
    z = problem.join(u, c)
    J = problem.jacobian(z)
    K, B, C, A = J[:n_u, :n_u], J[:n_u, n_u:], J[n_u:, :n_u], J[n_u:, n_u:]
    mass = problem.chemistry.mass_lumped(problem.shell.positions(u))
    try:
        shell_factor = factorize(K.tocsr(), kind="symmetric_indefinite")
    except LinearSolverError as exc:
        raise ValueError(f"the shell Hessian at this state is singular ({exc}): the reduced Jacobian is undefined "
                         "(a mechanical bifurcation)") from None
    n_negative = int(shell_factor.inertia[1]) if shell_factor.inertia is not None else -1
    if method == "dense":
        mu, modes = _dense(A, C, B, mass, shell_factor)
    else:
        mu, modes = _shift_invert(J, mass, n_u, k, sigma)
    order = np.argsort(-mu.real, kind="stable")[:k]
    modes = _normalised(modes[:, order])
    shapes = -shell_factor.solve(B @ modes.real)
    if np.iscomplexobj(modes):
        shapes = shapes - 1j * shell_factor.solve(B @ modes.imag)
    shell_factor.free()
    return CoupledStability(mu[order], modes, shapes, n_negative, method)


def _dense(A, C, B, mass, shell_factor):
    """Every eigenvalue of S v = μ M v, S = A − C K⁻¹ B formed densely."""
    KinvB = shell_factor.solve(B.toarray())
    S = A.toarray() - C @ KinvB
    return sla.eig(S, np.diag(mass))


def _shift_invert(J, mass, n_u, k, sigma):
    """The k eigenvalues nearest sigma, from ARPACK on (S − σM)⁻¹ M through one LU of the bordered system."""
    n_c = len(mass)
    shifted = J - sp.block_diag([sp.csr_matrix((n_u, n_u)), sigma * sp.diags(mass)])
    try:
        lu = LUFactorization(shifted)
    except LinearSolverError as exc:
        raise ValueError(f"sigma = {sigma:g} is an eigenvalue of the coupled dynamics ({exc}): shift it") from None

    def apply(v):
        rhs = np.concatenate([np.zeros(n_u), mass * v])
        return lu.solve(rhs)[n_u:]

    op = spla.LinearOperator((n_c, n_c), matvec=apply, dtype=float)
    nu, modes = spla.eigs(op, k=k, which="LM", ncv=min(n_c, max(2 * k + 1, ARNOLDI_VECTORS)))
    lu.free()
    return sigma + 1.0 / nu, modes


def _normalised(modes):
    out = np.array(modes, dtype=complex)
    for j in range(out.shape[1]):
        i = np.argmax(np.abs(out[:, j]))
        out[:, j] /= out[i, j]
    return out.real if np.allclose(out.imag, 0.0, atol=1e-12) else out
