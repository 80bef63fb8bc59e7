r"""Krylov solves of K x = b preconditioned by the factorisation of an earlier matrix K₀.

Newton iterations, continuation correctors and the solves of a time stepping factorise a
sequence of Hessians that change little from one to the next. A factorisation of an earlier
one, K₀ = L D Lᵀ, is then a preconditioner under which K₀⁻¹K is close to the identity: a few
Krylov iterations (each one back-substitution with the old factor and one product with K)
replace a new factorisation (theory §2.6).

* K₀ positive definite (a Cholesky factor, or an LDLᵀ whose inertia is (n, 0, 0)):
  preconditioned conjugate gradients. CG needs K positive definite too; a search direction of
  non-positive curvature pᵀKp ≤ 0 proves it is not, and the solve stops (reported: K's inertia
  has changed, the caller needs a new factorisation for it anyway).
* K₀ indefinite: GMRES, right-preconditioned by the LDLᵀ of K₀. MINRES would keep the short
  recurrence of a symmetric K but needs a positive-definite preconditioner, which an indefinite
  LDLᵀ is not (|D| in place of D would be one, but then no longer close to K⁻¹, and the few
  iterations are what pays); the GMRES basis of a few tens of vectors costs little beside the
  back-substitutions.

Either way the solve is judged by its true residual |b − K x| ≤ rtol |b| (one extra product),
and a solve that does not reach it in ``max_iter`` iterations is reported as not converged:
the caller refactorises. :class:`HeldFactor` is that policy for a Newton-type iteration (Newton,
the continuation corrector): which factorisation is held, the iteration budget, when to renew it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from .linear import Factorization, LinearSolverError

__all__ = ["KrylovSolve", "preconditioned_solve", "positive_definite_factor", "HeldFactor"]


@dataclass
class KrylovSolve:
    """Outcome of :func:`preconditioned_solve`: x, the iterations, whether |b − Kx| ≤ rtol |b| was
    reached, and the method ("cg" or "gmres"); ``negative_curvature``: CG met pᵀKp ≤ 0."""

    x: np.ndarray
    iterations: int
    converged: bool
    method: str
    negative_curvature: bool = False


def positive_definite_factor(factorization: Factorization) -> bool:
    """Whether the factorisation is of a positive definite matrix (a Cholesky, or inertia (n, 0, 0))."""
    if factorization.kind == "spd":
        return True
    inertia = factorization.inertia
    return inertia is not None and inertia[1] == 0 and inertia[2] == 0


def preconditioned_solve(K, factorization: Factorization, b, rtol: float = 1e-3, max_iter: int = 40) -> KrylovSolve:
    """Solve K x = b by CG (positive definite ``factorization``) or GMRES (indefinite), preconditioned
    by ``factorization`` (of an earlier matrix with K's shape), from x = 0; see the module docstring."""
    b = np.asarray(b, float)
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return KrylovSolve(np.zeros_like(b), 0, True, "none")
    with np.errstate(invalid="ignore", over="ignore"):     # a non-finite K: not converged, said below
        try:
            if positive_definite_factor(factorization):
                out = _pcg(K, factorization.solve, b, rtol * nb, max_iter)
            else:
                out = _gmres(K, factorization.solve, b, rtol, max_iter)
        except LinearSolverError:                           # a non-finite vector met the back-substitution
            return KrylovSolve(np.zeros_like(b), 0, False, "cg" if positive_definite_factor(factorization) else "gmres")
        if out.converged:
            out.converged = bool(np.linalg.norm(b - K @ out.x) <= rtol * nb)
    return out


def _pcg(K, precondition, b, tol, max_iter) -> KrylovSolve:
    """Preconditioned conjugate gradients, stopping at |r| ≤ tol or at a direction with pᵀKp ≤ 0."""
    x = np.zeros_like(b)
    r = b.copy()
    z = precondition(r)
    rz = float(r @ z)
    if not rz > 0:          # the preconditioner is not positive definite in practice
        return KrylovSolve(x, 0, False, "cg", negative_curvature=True)
    p = z.copy()
    for it in range(1, max_iter + 1):
        Kp = K @ p
        curvature = float(p @ Kp)
        if not curvature > 0:
            return KrylovSolve(x, it, False, "cg", negative_curvature=True)
        alpha = rz / curvature
        x += alpha * p
        r -= alpha * Kp
        if np.linalg.norm(r) <= tol:
            return KrylovSolve(x, it, True, "cg")
        z = precondition(r)
        rz_new = float(r @ z)
        if not rz_new > 0:
            return KrylovSolve(x, it, False, "cg", negative_curvature=True)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return KrylovSolve(x, max_iter, False, "cg")


def _gmres(K, precondition, b, rtol, max_iter) -> KrylovSolve:
    """One GMRES cycle of at most ``max_iter`` iterations, preconditioned by ``precondition``."""
    n = len(b)
    M = spla.LinearOperator((n, n), matvec=precondition, dtype=float)
    count = [0]

    def counted(_):
        count[0] += 1

    x, info = spla.gmres(K, b, M=M, rtol=rtol, atol=0.0, restart=max_iter, maxiter=1, callback=counted,
                         callback_type="pr_norm")
    return KrylovSolve(x, count[0], info == 0 and bool(np.all(np.isfinite(x))), "gmres")


class HeldFactor:
    """The factorisation that preconditions the Krylov solves of a Newton-type iteration, and when to renew it.

    ``solve(K, b)`` is the Krylov solution of K x = b (:func:`preconditioned_solve`, to a relative
    residual ``rtol``), or None when the held factorisation does not serve and K must be factorised:
    none held (or of another size), a solve that did not converge in ``MAX_ITER`` iterations, or a
    renewal asked for since (more than half of them used, or :meth:`judge` saw the residual contract
    by less than ``CONTRACTION``). ``MAX_ITER`` iterations (each a back-substitution with the held
    factor and a product with K) cost about half a refactorisation of a 25 000-vertex shell Hessian;
    the budget is a fixed number, not a measured time, so that runs repeat bit for bit.
    Call :meth:`hold` with each new factorisation.
    """

    MAX_ITER = 20
    CONTRACTION = 0.5

    def __init__(self, factorization: Factorization | None = None, rtol: float = 1e-3):
        self.factor = factorization
        self.rtol = rtol
        self.renew = False
        self.solves = self.iterations = 0

    def hold(self, factorization: Factorization | None):
        self.factor, self.renew = factorization, False

    def usable(self, n: int) -> bool:
        f = self.factor
        return not self.renew and f is not None and f._valid and f.n == n

    def solve(self, K, b):
        if not self.usable(len(b)):
            return None
        out = preconditioned_solve(K, self.factor, b, rtol=self.rtol, max_iter=self.MAX_ITER)
        self.solves += 1
        self.iterations += out.iterations
        if not out.converged:
            return None
        self.renew = out.iterations > self.MAX_ITER // 2
        return out.x

    def judge(self, res_old: float, res_new: float):
        """After a step on Krylov solves: renew the factorisation at the next iterate if |r| fell too little."""
        self.renew = self.renew or res_new > self.CONTRACTION * res_old
