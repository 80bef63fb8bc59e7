r"""The pseudo-arclength corrector: residuals, bordered solves, Newton on the hyperplane, tangent, eigenvalues.

One :class:`_Engine` serves one continuation run: the problem's residual r(u, λ) = ∂Π/∂u,
Jacobian K = ∂²Π/∂u² and g_λ = ∂r/∂λ are callables of the problem; the arclength norm is

.. math:: \|(\delta u, \delta\lambda)\|^2 = \frac1n \sum_i w_i\, \delta u_i^2
          + \left(\frac{\delta\lambda}{\lambda_{\rm scale}}\right)^2 .

The bordered system [[K, g_λ], [cᵀ, d]] [δu; δλ] = [b; β] is solved by block elimination on one
factorisation of K (K x₁ = b, K x₂ = −g_λ, δλ = (β − cᵀx₁)/(d + cᵀx₂)), with the full (n+1)
matrix (SuperLU) as fall-back. Step failures raise :class:`_StepFailure`; the caller halves ds.

A **non-gradient** problem (a residual r(u, λ) and its Jacobian J = ∂r/∂u, not symmetric:
``problem.residual``, ``problem.jacobian``; see :mod:`femshell.solvers.continuation`) runs through
the same bordered solves on an LU factorisation of J (:class:`~femshell.solvers.lu.LUFactorization`);
each point records the sign of det J instead of an inertia, and the problem's own
``stability(u)`` (optional) instead of the eigenvalues of K.

The corrector refactorises only when it pays (``linear_solver="krylov"``, the default): its
iterations solve K x₁ = b and K x₂ = −g_λ by Krylov iterations preconditioned by the factorisation
held from the last point or iteration (:class:`~femshell.solvers.krylov.HeldFactor`, CG or GMRES by
its inertia) and factorise K only when those do not serve. :meth:`_Engine.finish` always factorises
a point's own Hessian (unless the corrector's last, negligible correction was made on it), so each
accepted point's inertia, and its stability, is exact.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .krylov import HeldFactor
from .linear import LinearSolverError, factorize
from .lu import LUFactorization

#: up to this many unknowns the smallest eigenvalues come from a dense eigensolver
DENSE_EIG_LIMIT = 50
#: shift (times max|diag K|) of the eigensolver when K itself cannot be factorised
SHIFT = 1e-10
#: relative accuracy asked of the Lanczos eigenvalues (shift-invert Ritz residuals)
EIG_TOL = 1e-12
#: relative residual of the corrector's Krylov solves (an inexact Newton step: its error is
#: corrected by the next iteration, and the corrector converges on the true residual)
CORRECTOR_KRYLOV_RTOL = 1e-6
#: values of ``_Engine(linear_solver=...)``, and the one taken when none is given
LINEAR_SOLVERS = ("krylov", "direct")
DEFAULT_LINEAR_SOLVER = "krylov"


class _StepFailure(Exception):
    """A trial step (or the location of a special point) failed; the message says why."""


class _SingularTangent(_StepFailure):
    """The bordered system of the tangent is singular (at a fold or branch point)."""


@dataclass
class _Point:
    """A converged point (u, λ) with what :meth:`_Engine.finish` adds: K, inertia, tangent, eigenvalues."""

    u: np.ndarray
    lam: float
    iterations: int = 0
    K: object = None
    fac: object = None
    t_u: np.ndarray | None = None
    t_lam: float = math.nan
    n_negative: int | None = None
    eigenvalues: np.ndarray | None = None    # the ones nearest zero, ascending
    eigenvectors: np.ndarray | None = None
    eig_offset: int | None = None            # eigenvalues[i] is the (eig_offset + i)-th smallest
    energy: float = math.nan
    tangent_failed: bool = False
    det_sign: int | None = None              # sign of det J (non-gradient problems; 0: J singular)
    stability: dict | None = None            # problem.stability(u) (non-gradient problems)
    # both join the branch's residual scale when the point is accepted (not for trial or location points)
    predictor_residual: float = 0.0
    parameter_residual: float = 0.0          # |∂r/∂λ| · parameter_scale


class _Engine:
    """Residuals, bordered solves, corrector and point evaluation for one problem and norm."""

    def __init__(self, problem, weights, parameter_scale, *, backend, rtol, atol, xtol, max_iter, fd_step,
                 n_eigs, log, linear_solver=None):
        self.p = problem
        self.general = is_residual_problem(problem)
        self.lam_scale = float(parameter_scale)
        self.w = np.asarray(weights, float)
        self.n = len(self.w)
        self.wl = 1.0 / self.lam_scale**2
        self.backend = backend
        self.rtol, self.atol, self.xtol = rtol, atol, xtol
        self.max_iter = max_iter
        self.fd_step = fd_step
        self.n_eigs = n_eigs
        self.log = log
        self.rscale = 0.0
        self._lam = None
        self._fac = None
        linear_solver = linear_solver or DEFAULT_LINEAR_SOLVER
        if linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {linear_solver!r}")
        # the held factorisation preconditions CG/GMRES by a symmetric factor: gradient problems only
        self._held = HeldFactor(rtol=CORRECTOR_KRYLOV_RTOL) if linear_solver == "krylov" and not self.general \
            else None
        self.counts = {"gradient": 0, "hessian": 0, "factorize": 0, "bordered_full": 0, "eigen": 0,
                       "krylov_solves": 0, "krylov_iterations": 0}

    # ---- problem access
    def diagnose(self, P):
        """The problem's reading of point P (``problem.diagnose``, optional; see minimize), or None."""
        diagnose = getattr(self.p, "diagnose", None)
        if not callable(diagnose):
            return None
        self.set(P.lam)
        return diagnose(P.u)

    def set(self, lam):
        if lam != self._lam:
            try:
                self.p.set_parameter(lam)
            except ValueError as exc:   # outside the parameter's range (a growth strain <= -1): a failed step
                self._lam = None
                raise _StepFailure(f"the problem refused parameter {lam:.9g}: {exc}") from None
            self._lam = lam

    def residual(self, u, lam):
        self.set(lam)
        self.counts["gradient"] += 1
        r = np.asarray(self.p.residual(u) if self.general else self.p.gradient(u), float)
        if r.shape != (self.n,):
            raise ValueError(f"problem.{'residual' if self.general else 'gradient'}(u) returned shape {r.shape} for {self.n} unknowns; it must return "
                             f"one value per unknown (is u0 the problem's vector of unknowns?)")
        return r

    def dlam(self, u, lam):
        self.set(lam)
        if hasattr(self.p, "parameter_derivative"):
            try:
                gl = np.asarray(self.p.parameter_derivative(u), float)
            except ValueError as exc:   # its difference step left the parameter's range
                self._lam = None        # the problem's parameter may be left at the refused value
                raise _StepFailure(f"∂r/∂λ at parameter {lam:.9g}: {exc}") from None
            if gl.shape != (self.n,):
                raise ValueError(f"problem.parameter_derivative(u) returned shape {gl.shape} for {self.n} unknowns")
            return gl
        step = self.fd_step * max(abs(lam), self.lam_scale)
        gp = self.residual(u, lam + step)
        gm = self.residual(u, lam - step)
        self.set(lam)
        return (gp - gm) / (2.0 * step)

    def hessian(self, u, lam):
        self.set(lam)
        self.counts["hessian"] += 1
        K = sp.csr_matrix(self.p.jacobian(u) if self.general else self.p.hessian(u))
        if K.shape != (self.n, self.n):
            raise ValueError(f"problem.{'jacobian' if self.general else 'hessian'}(u) returned shape {K.shape} for {self.n} unknowns; it must be "
                             f"({self.n}, {self.n})")
        return K

    def factor(self, K):
        """Symmetric-indefinite factorisation of K (LU of J for a non-gradient problem), or None when it is
        (numerically) singular."""
        self.counts["factorize"] += 1
        if self.general:
            self.release()
            try:
                self._fac = LUFactorization(K)
            except LinearSolverError:
                self._fac = None
            return self._fac
        try:
            self._fac = factorize(K, kind="symmetric_indefinite", backend=self.backend, reuse=self._fac)
        except LinearSolverError:
            self.release()
        if self._held is not None:
            self._held.hold(self._fac)
        return self._fac

    def _krylov_bordered(self, K, gl, c, d, rhs_u, rhs_l):
        """The bordered solve by block elimination on Krylov solves with the held factorisation, or None
        when it does not serve (then K is factorised)."""
        held = self._held
        if held is None or not held.usable(self.n):
            return None
        before = (held.solves, held.iterations)
        try:
            x2 = held.solve(K, -gl)
            x1 = None if x2 is None else (held.solve(K, rhs_u) if np.any(rhs_u) else np.zeros(self.n))
        finally:
            self.counts["krylov_solves"] += held.solves - before[0]
            self.counts["krylov_iterations"] += held.iterations - before[1]
        if x1 is None:
            return None
        cvec = c if np.ndim(c) else np.zeros(self.n)
        schur = d + float(cvec @ x2)
        if not (np.isfinite(schur) and abs(schur) > 1e-12 * (abs(d) + np.linalg.norm(cvec) * np.linalg.norm(x2))):
            return None
        dl = (rhs_l - float(cvec @ x1)) / schur
        return x1 + dl * x2, dl

    # ---- norm
    def dot(self, au, al, bu, bl):
        return float(au @ (self.w * bu)) / self.n + self.wl * al * bl

    def norm(self, au, al):
        return math.sqrt(max(self.dot(au, al, au, al), 0.0))

    def border(self, t_u, t_lam):
        """Row (c, d) of the constraint ⟨(δu, δλ), t⟩_W."""
        return self.w * t_u / self.n, self.wl * t_lam

    # ---- linear algebra
    def solve_bordered(self, K, fac, gl, c, d, rhs_u, rhs_l):
        """Solve [[K, gl], [cᵀ, d]] [du; dl] = [rhs_u; rhs_l] (rhs_u None: zero).

        Block elimination on the factorisation of K (two right-hand sides), with up to two
        steps of iterative refinement on the bordered residual (cheap: the same factor);
        the full bordered matrix is solved only when that does not give a residual below
        1e-8 of the terms, K could not be factorised, or the Schur complement vanishes.
        """
        if fac is not None:
            try:
                n = K.shape[0]
                cvec = c if np.ndim(c) else np.zeros(n)
                bu = np.zeros(n) if rhs_u is None else np.asarray(rhs_u, float)
                x2 = -fac.solve(gl)
                cx2 = float(cvec @ x2)
                schur = d + cx2
                size = abs(d) + np.linalg.norm(cvec) * np.linalg.norm(x2)
                if np.isfinite(schur) and abs(schur) > 1e-12 * size:
                    du, dl = np.zeros(n), 0.0
                    ru, rl = bu, float(rhs_l)
                    for _ in range(3):
                        x1 = fac.solve(ru) if np.any(ru) else np.zeros(n)
                        ddl = (rl - float(cvec @ x1)) / schur
                        du, dl = du + x1 + ddl * x2, dl + ddl
                        Kdu = K @ du
                        ru = bu - Kdu - gl * dl
                        rl = float(rhs_l) - float(cvec @ du) - d * dl
                        ref = max(np.linalg.norm(bu), np.linalg.norm(Kdu), np.linalg.norm(gl) * abs(dl), 1e-300)
                        if not np.all(np.isfinite(du)):
                            break
                        if np.linalg.norm(ru) <= 1e-8 * ref:
                            return du, dl
            except LinearSolverError:
                pass
        return self._full_bordered(K, gl, c, d, rhs_u, rhs_l)

    def _full_bordered(self, K, gl, c, d, rhs_u, rhs_l):
        self.counts["bordered_full"] += 1
        n = K.shape[0]
        crow = np.zeros(n) if not np.ndim(c) else c
        A = sp.bmat([[K, sp.csr_matrix(gl.reshape(-1, 1))],
                     [sp.csr_matrix(crow.reshape(1, -1)), sp.csr_matrix(np.array([[d]]))]], format="csc")
        b = np.concatenate([np.zeros(n) if rhs_u is None else rhs_u, [rhs_l]])
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                x = spla.splu(A).solve(b)
        except RuntimeError as exc:
            raise _SingularTangent(f"the bordered system is singular ({exc})") from None
        res = A @ x - b
        if not np.all(np.isfinite(x)) or np.linalg.norm(res) > 1e-6 * max(np.linalg.norm(b), np.linalg.norm(A @ x),
                                                                          1e-300):
            raise _SingularTangent("the bordered system is numerically singular")
        return x[:n], float(x[n])

    def eigs(self, K, k, vectors=False, fac=None):
        """The k eigenvalues of K nearest zero, ascending: (w, V or None, offset).

        ``w[i]`` is the (offset + i)-th smallest eigenvalue of K (offset from the inertia),
        V the orthonormal eigenvectors. Shift-invert Lanczos about 0 reuses ``fac`` (a
        symmetric-indefinite factorisation of K) when given; otherwise K − σI, σ a tiny
        negative shift, is factorised. (None, None, None) when the eigensolver fails.
        """
        n = K.shape[0]
        k = int(min(k, n))
        if k <= 0:
            return None, None, None
        self.counts["eigen"] += 1
        own = None
        try:
            if n <= DENSE_EIG_LIMIT or k >= n - 1:
                w, v = sla.eigh(K.toarray())
                sel = np.sort(np.argsort(np.abs(w), kind="stable")[:k])
                return w[sel], (v[:, sel] if vectors else None), int(sel[0])
            sigma = 0.0
            if fac is None or fac.inertia is None:
                sigma = -SHIFT * np.abs(K.diagonal()).max()
                own = factorize(K - sigma * sp.identity(n, format="csr"), kind="symmetric_indefinite",
                                backend=self.backend, allow_singular=True)
                fac = own
            below = None if fac.inertia is None else int(fac.inertia[1])
            op = spla.LinearOperator((n, n), matvec=fac.solve, matmat=fac.solve, dtype=float)
            # tol: ARPACK's default (machine precision) costs 5-20x more Lanczos iterations on
            # clustered shell spectra (cos/sin pairs) for the same printed digits (measured)
            # a fixed start vector: ARPACK's default is random, and runs should repeat bit for bit
            v0 = np.random.default_rng(0).standard_normal(n)
            w, v = spla.eigsh(K, k=k, sigma=sigma, which="LM", OPinv=op, tol=EIG_TOL, v0=v0)
            order = np.argsort(w)
            w, v = w[order], v[:, order]
            offset = None if below is None else below - int((w < sigma).sum())
            return w, (v if vectors else None), offset
        except Exception as exc:  # ARPACK non-convergence, singular shift
            if self.log:
                self.log(f"    continuation: eigensolver failed ({type(exc).__name__}: {exc})")
            return None, None, None
        finally:
            if own is not None:
                own.free()

    # ---- corrector
    def correct(self, u_p, lam_p, t=None, lam_fixed=None, max_dist=None, update_scale=True):
        """Newton from the predictor on r = 0 and the hyperplane ⟂ t (or at fixed λ). Raises _StepFailure.

        Converged when |r| ≤ rtol · scale + atol, scale the largest of this corrector's first
        residual, the predictor residuals of the accepted steps and |g_λ| · parameter_scale seen
        on the branch, or when the Newton correction is below xtol in the weighted norm. The
        point carries its first residual (``predictor_residual``; 0 with ``update_scale=False``,
        for a start far from equilibrium) for the caller to add to the scale on acceptance.
        """
        u = np.array(u_p, float)
        lam = float(lam_p if lam_fixed is None else lam_fixed)
        if t is None and lam_fixed is None:
            raise ValueError("correct needs a tangent or a fixed parameter")
        c, d = (0.0, 1.0) if lam_fixed is not None else self.border(*t)
        last_step = math.inf
        res0 = None
        K = fac = None
        res_krylov = None       # |r| before a step made on Krylov solves, to judge its contraction
        for it in range(self.max_iter + 1):
            r = self.residual(u, lam)
            res = float(np.linalg.norm(r))
            if not np.isfinite(res):
                raise _StepFailure(f"non-finite residual at corrector iteration {it}")
            if res_krylov is not None:
                self._held.judge(res_krylov, res)
            if res0 is None:
                res0 = res
                scale = max(self.rscale, res)
            if res <= self.rtol * scale + self.atol or last_step <= self.xtol:
                break
            if it == self.max_iter:
                raise _StepFailure(f"corrector did not converge in {self.max_iter} iterations "
                                   f"(|r| = {res:.3e}, last correction {last_step:.2e})")
            if it >= 2 and res > 1e3 * max(res0, 1e-300):
                raise _StepFailure(f"corrector diverges (|r| {res0:.2e} -> {res:.2e})")
            gl = self.dlam(u, lam)
            K = self.hessian(u, lam)
            if lam_fixed is not None:
                N = lam - lam_fixed
            else:
                N = self.dot(t[0], t[1], u - u_p, lam - lam_p)
            step = self._krylov_bordered(K, gl, c, d, -r, -N)
            res_krylov = None if step is None else res
            if step is None:
                fac = self.factor(K)
                step = self.solve_bordered(K, fac, gl, c, d, -r, -N)
            du, dl = step
            if lam_fixed is not None:
                dl = 0.0
            u = u + du
            lam = lam + dl
            last_step = self.norm(du, dl)
            if not np.isfinite(last_step):
                raise _StepFailure("non-finite Newton correction")
            if max_dist is not None and self.norm(u - u_p, lam - lam_p) > max_dist:
                raise _StepFailure(f"corrector left the neighbourhood of the predictor "
                                   f"(distance {self.norm(u - u_p, lam - lam_p):.3g} > {max_dist:.3g})")
        P = _Point(u, lam, iterations=it, predictor_residual=res0 if update_scale else 0.0)
        if K is not None and last_step <= self.xtol:
            # the last Hessian was taken a negligible distance away: the point's own (factorised now if
            # the last step was made on Krylov solves, for its exact inertia)
            P.K, P.fac = K, (fac if res_krylov is None else self.factor(K))
        return P

    def finish(self, P, ref=None, direction=1.0, n_eigs=None, vectors=False):
        """Hessian, inertia, tangent (oriented along ``ref`` or ``direction``), eigenvalues, energy.

        For a non-gradient problem: the Jacobian, the sign of its determinant (``det_sign``, 0 when
        J is singular) and the tangent; no eigenvalues, no energy (NaN).
        """
        if P.K is None:
            P.K = self.hessian(P.u, P.lam)
            P.fac = self.factor(P.K)
        fac = P.fac
        P.n_negative = None
        if fac is not None and fac is not self._fac:
            fac = None  # refactored since: not this point's factorisation
        if self.general:
            if fac is None:
                fac = self.factor(P.K)
            P.det_sign = 0 if fac is None else fac.det_sign
        elif fac is not None and fac.inertia is not None:
            P.n_negative = int(fac.inertia[1])
        gl = self.dlam(P.u, P.lam)
        if ref is None:
            c, d = 0.0, self.wl * direction
        else:
            c, d = self.border(*ref)
        try:
            z, tau = self.solve_bordered(P.K, fac, gl, c, d, None, 1.0)
            nt = self.norm(z, tau)
            if not (np.isfinite(nt) and nt > 0):
                raise _SingularTangent("zero tangent")
            P.t_u, P.t_lam = z / nt, tau / nt
        except _StepFailure:
            if ref is None:
                raise
            # exactly at a singular point (a pitchfork makes the bordered matrix singular too):
            # keep the reference tangent
            P.t_u, P.t_lam = ref[0].copy(), float(ref[1])
            P.tangent_failed = True
        P.parameter_residual = float(np.linalg.norm(gl)) * self.lam_scale
        k = 0 if self.general else (self.n_eigs if n_eigs is None else n_eigs)
        if k > 0:
            P.eigenvalues, P.eigenvectors, P.eig_offset = self.eigs(P.K, k, vectors=vectors, fac=fac)
            if P.n_negative is None and P.eigenvalues is not None and P.eig_offset is not None:
                P.n_negative = P.eig_offset + int((P.eigenvalues < 0).sum())
        self.set(P.lam)
        P.energy = math.nan if self.general else float(self.p.energy(P.u))
        P.fac = None  # the shared factorisation object is refactored by the next point
        return P

    def stability(self, P):
        """``problem.stability(u)`` at P (a dict with "stable"), cached on P; None when the problem has none."""
        fn = getattr(self.p, "stability", None)
        if not self.general or not callable(fn):
            return None
        if P.stability is None:
            self.set(P.lam)
            st = fn(P.u)
            if not isinstance(st, dict) or "stable" not in st:
                raise TypeError("problem.stability(u) must return a dict with a 'stable' entry (bool)")
            P.stability = st
        return P.stability

    def null_vector(self, P, iterations=4, transpose=False):
        """The right (``transpose``: left) null vector of J at P: inverse iteration on its LU (on J plus a
        tiny shift where J is exactly singular), Euclidean-normalised with its largest entry positive; None
        when it cannot be computed."""
        if P.K is None:
            P.K = self.hessian(P.u, P.lam)
        fac = self.factor(P.K)
        if fac is None:   # exactly singular: a nearby shift
            scale = max(abs(P.K).max(), 1e-300)
            fac = self.factor(P.K + 1e-12 * scale * sp.identity(self.n, format="csr"))
            if fac is None:
                return None
        x = np.random.default_rng(0).standard_normal(self.n)
        for _ in range(iterations):
            x = fac.solve(x, transpose=transpose)
            nx = np.linalg.norm(x)
            if not (np.isfinite(nx) and nx > 0):
                return None
            x /= nx
        return x if x[np.argmax(np.abs(x))] > 0 else -x

    def release(self):
        """Free the shared factorisation (PARDISO memory)."""
        if self._fac is not None:
            try:
                self._fac.free()
            except Exception:
                pass
            self._fac = None


def is_residual_problem(problem) -> bool:
    """True for a non-gradient problem: it has ``residual`` and ``jacobian`` (and no ``hessian``)."""
    return (callable(getattr(problem, "residual", None)) and callable(getattr(problem, "jacobian", None))
            and not callable(getattr(problem, "hessian", None)))
