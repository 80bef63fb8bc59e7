r"""Sparse direct solvers for symmetric matrices: MKL PARDISO (pypardiso) or SciPy's SuperLU.

Solvers know matrices, not physics. :func:`factorize` returns a
:class:`Factorization` that solves K x = b for any number of right-hand sides,
reports the inertia (numbers of positive, negative and zero eigenvalues) of a
symmetric indefinite K — which is what a stability check needs: an equilibrium is
a stable one when the Hessian has no negative eigenvalue — and can be refactorised
with new values on the same sparsity pattern reusing the symbolic analysis (Newton
iterations change the values of the Hessian, never its pattern).

Back-ends (measurements in ``validation/benchmarks/linear_solvers.py``):

``"pardiso"``
    MKL PARDISO through pypardiso, on the upper triangle of K (explicit zero
    diagonal entries added where missing). ``kind="spd"`` uses mtype 2 (Cholesky),
    ``kind="symmetric_indefinite"`` mtype −2 (LDLᵀ with Bunch–Kaufman 1×1/2×2
    pivots, symmetric scaling and weighted matching), whose inertia PARDISO reports
    in iparm(22), iparm(23). pypardiso's own ``factorize``/``solve`` re-run the
    analysis for every new matrix (phase 12/13); here the phases are called
    directly: the analysis (METIS ordering, symbolic factorisation: phase 11) is
    kept and :meth:`Factorization.refactor` with an unchanged pattern runs only the
    numerical factorisation (phase 22). Memory held by MKL is released (phase −1)
    by :meth:`Factorization.free`, when a pattern is re-analysed, or when the
    object is garbage collected.

    Small pivots are perturbed (to ±10⁻¹³‖K‖) instead of stopping the
    factorisation. That happens for singular matrices and, because PARDISO only
    pivots within supernodes, also for some well-conditioned ones (zero diagonal
    entries): a probe solve with iterative refinement tells the cases apart —
    a residual above 1e-8 is reported as a singular matrix. SPD singularity is
    detected from the pivots (``pardiso_getdiag``): pivot / diagonal < 1e-12.
``"superlu"``
    ``scipy.sparse.linalg.splu`` in symmetric mode (``MMD_AT_PLUS_A`` ordering,
    diagonal pivots, ``SymmetricMode``): 5–10× faster than its defaults. When the
    factorisation kept the symmetric permutation (perm_r == perm_c),
    P K Pᵀ = L U with U = D Lᵀ, so the signs of diag(U) give the inertia (Sylvester's
    law); checked against dense eigenvalues on random indefinite matrices. It cannot
    be trusted when SuperLU pivoted off the diagonal (it does so at an exactly zero
    diagonal pivot, perm_r ≠ perm_c) or when the factors are inaccurate (no pivoting
    threshold: a probe solve with residual > 1e-8); the inertia is then counted
    from dense eigenvalues for n ≤ 2000 and is ``None`` (with a warning) above.
    No symbolic reuse: every refactor starts from scratch.
``"auto"``
    pardiso when pypardiso imports and finds MKL, else superlu.

The PARDISO handle and MKL's set-up are in :mod:`femshell.solvers.pardiso`, the input checks and
the upper-triangle pattern in :mod:`femshell.solvers.sparse_matrix`.

Errors are :class:`LinearSolverError` with a message that names the problem
(non-finite entries and where, empty or zero rows, asymmetry and where, zero
pivots and the unknown where they appeared, a non-positive-definite matrix
passed as ``"spd"``).

Example
-------
>>> import numpy as np, scipy.sparse as sp
>>> from femshell.solvers.linear import factorize
>>> K = sp.csr_matrix(np.array([[2., -1, 0], [-1, 2, -1], [0, -1, -3]]))
>>> f = factorize(K, kind="symmetric_indefinite")
>>> f.inertia
(2, 1, 0)
>>> np.allclose(K @ f.solve(np.ones(3)), 1)
True
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pardiso import _PARDISO_STATE, PARDISO_PERTURBATION_EXPONENT, _Pardiso, _pardiso_available
from .sparse_matrix import (_SINGULAR_HINT, LinearSolverError, _canonical_csr, _check_values, _PatternKey,
                            _UpperPattern)

__all__ = ["LinearSolverError", "Factorization", "factorize", "Refactorizer", "smallest_eigenvalues",
           "available_backends", "KINDS", "BACKENDS"]

KINDS = ("spd", "symmetric_indefinite")
BACKENDS = ("auto", "pardiso", "superlu")

#: SPD factorisations fail when a pivot d_i falls below this fraction of the
#: diagonal entry K_ii it came from. d_i ≥ λ_min and K_ii ≤ λ_max, so a ratio below
#: 1e-12 means a condition number above 1e12 — numerically singular in double
#: precision. A constant null space (a free body) gives about 1e-15 (measured).
PIVOT_TOL = 1e-12
#: a factorisation with perturbed pivots is accepted when the refined solution of a
#: random test system has at most this relative residual (else: singular)
PROBE_TOL = 1e-8
#: dense fall-back limit for the inertia when SuperLU had to leave the diagonal
DENSE_INERTIA_LIMIT = 2000


def available_backends() -> list:
    """Names of the back-ends usable in this Python (``"superlu"`` always is)."""
    return (["pardiso"] if _pardiso_available() else []) + ["superlu"]


def _resolve_backend(backend: str) -> str:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "auto":
        return "pardiso" if _pardiso_available() else "superlu"
    if backend == "pardiso" and not _pardiso_available():
        raise LinearSolverError(f"backend 'pardiso' requested but pypardiso/MKL is unusable here "
                                f"({_PARDISO_STATE['why']}); use backend='superlu' or 'auto'")
    return backend


# --------------------------------------------------------------------------- Factorization

def _check_spd_pivots(ratio, d, unknown, allow_singular):
    """Cholesky pivots d (ratio = d / |K_ii|): all must be positive and not negligible.

    A pivot within ±PIVOT_TOL of zero is a singular matrix (its sign is round-off),
    a clearly negative one an indefinite matrix.
    """
    k = int(np.argmin(ratio))
    if ratio[k] < PIVOT_TOL and abs(ratio[k]) < PIVOT_TOL:
        if allow_singular:
            return
        raise LinearSolverError(f"factorisation found a (near-)zero pivot at unknown {unknown[k]}: pivot / "
                                f"diagonal = {ratio[k]:.2g}: {_SINGULAR_HINT}")
    if ratio[k] <= 0:
        raise LinearSolverError(f"matrix is not positive definite: pivot {d[k]:.3g} at unknown {unknown[k]} "
                                f"(use kind='symmetric_indefinite' for an indefinite matrix)")


class Factorization:
    """A factorised symmetric matrix: solve, inertia, refactor with new values, free.

    Attributes
    ----------
    kind : "spd" | "symmetric_indefinite"
    backend : "pardiso" | "superlu"
    n : int
        Number of unknowns.
    inertia : tuple (n_positive, n_negative, n_zero) or None
        For ``"spd"`` a successful factorisation proves (n, 0, 0). For
        ``"symmetric_indefinite"``: PARDISO's pivot counts, or Sylvester's count on
        SuperLU's diagonal; ``None`` when it cannot be trusted (see module docstring).
    analysis_time, factor_time : float
        Wall seconds of the last call to :meth:`refactor` (or the constructor):
        ``factor_time`` is the whole factorisation, ``analysis_time`` the part spent
        in the symbolic analysis (0 when it was reused).
    n_analyses, n_factorizations : int
        How many analyses and numerical factorisations this object has done.
    factor_nnz : int or None
        Non-zeros of the factor (memory indicator), when the back-end reports it.
    """

    def __init__(self, K, kind="spd", backend="auto", *, check_symmetry=True, allow_singular=False,
                 pardiso_matching=True):
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        self.kind = kind
        self.backend = _resolve_backend(backend)
        self.check_symmetry = check_symmetry
        self.allow_singular = allow_singular
        self.n_analyses = 0
        self.n_factorizations = 0
        self.analysis_time = 0.0
        self.factor_time = 0.0
        self._inertia = None
        self._inertia_dense = None
        self._valid = False
        self.n_perturbed_pivots = 0
        self.probe_residual = None
        self.factor_nnz = None
        self._pattern = None
        self._impl = _Pardiso(kind, pardiso_matching) if self.backend == "pardiso" else None
        self._lu = None
        self._K = None
        try:
            self.refactor(K)
        except LinearSolverError as exc:
            # the symbolic analysis may be done: a caller refactorising the same pattern keeps it (Refactorizer)
            exc.factorization = self
            raise

    # ---- factorisation
    def refactor(self, K) -> "Factorization":
        """Factorise new values; reuse the symbolic analysis when the sparsity pattern is unchanged.

        Returns self. With PARDISO an unchanged pattern costs only the numerical
        factorisation (phase 22); SuperLU always starts from scratch.
        """
        self._valid = False                 # until this factorisation has succeeded
        self._inertia_dense = None
        K = _canonical_csr(K)
        # symmetry costs a sparse transpose: check it when the pattern is new (an
        # assembly bug shows there), not at every refactorisation of a Newton loop
        new_pattern = self._pattern is None or not self._pattern.same_pattern(K)
        _check_values(K, self.check_symmetry and new_pattern)
        self.n = K.shape[0]
        if self.backend == "pardiso":
            self._factor_pardiso(K, new_pattern)
        else:
            self._factor_superlu(K)
            if new_pattern:
                self._pattern = _PatternKey(K)
        self.n_factorizations += 1
        self._valid = True
        return self

    def _factor_pardiso(self, K, analyse):
        if analyse:
            self._pattern = _UpperPattern(K)
        U = self._pattern.matrix(K)
        t_an, t_f = self._impl.factor(U, analyse)
        if not analyse and self.kind == "symmetric_indefinite" and self._impl.inertia()[2]:
            # perturbed pivots with the scaling/matching of older values: analyse these values
            t_an2, t_f2 = self._impl.factor(U, True)
            t_an, t_f, analyse = t_an + t_an2, t_f + t_f2, True
        self._U = U
        self.analysis_time = t_an
        self.factor_time = t_an + t_f
        self.n_analyses += analyse
        self.factor_nnz = self._impl.factor_nnz()
        n = self.n
        if self.kind == "spd":
            d, a = self._impl.pivots()
            if d is not None:
                self._check_pivots(d, a)
            self._inertia = (n, 0, 0)
        else:
            pos, neg, pert = self._impl.inertia()
            self.n_perturbed_pivots = pert
            self._impl.set_refinement(pert > 0)
            self._valid = True
            self.probe_residual = None
            if pert:
                # Perturbed pivots come from a singular matrix OR from PARDISO's static
                # pivoting (pivots are only searched within supernodes): a random
                # well-conditioned matrix with zero diagonal entries (cond 7e3) got 3.
                # Iterative refinement repairs the second case, not the first; a probe
                # solve tells them apart.
                b = np.random.default_rng(0).standard_normal(n)
                x = self.solve(b)
                self.probe_residual = float(np.linalg.norm(self._full_matvec(x) - b) / np.linalg.norm(b))
                if self.probe_residual > PROBE_TOL and not self.allow_singular:
                    self._valid = False
                    d, a = self._impl.pivots()
                    where = ""
                    if d is not None:
                        i = int(np.argmin(np.abs(d)))
                        where = f" (smallest pivot {d[i]:.3g} at unknown {i})"
                    raise LinearSolverError(
                        f"factorisation found {pert} zero pivot(s){where} and the refined solution of a "
                        f"test system keeps a residual of {self.probe_residual:.1e}: {_SINGULAR_HINT}")
            self._inertia = (pos, neg, n - pos - neg)

    def _full_matvec(self, x):
        """K x from the stored upper triangle U: K = U + Uᵀ − diag(U)."""
        U = self._U
        return U @ x + U.T @ x - U.diagonal() * x

    def _check_pivots(self, d, a):
        """SPD: every pivot must be positive and not negligible against its diagonal entry."""
        scale = np.where(a != 0, np.abs(a), np.abs(a).max() if len(a) else 1.0)
        _check_spd_pivots(d / scale, d, np.arange(len(d)), self.allow_singular)

    def _factor_superlu(self, K):
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", sp.SparseEfficiencyWarning)
                lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                               options={"SymmetricMode": True})
        except RuntimeError as exc:
            if "singular" in str(exc).lower():
                raise LinearSolverError(f"factorisation found a zero pivot ({exc}): {_SINGULAR_HINT}") from None
            raise LinearSolverError(f"SuperLU failed: {exc}") from None
        self.factor_time = time.perf_counter() - t0
        self.analysis_time = 0.0
        self.n_analyses += 1
        self._lu = lu
        self._K = K
        self.factor_nnz = int(lu.nnz)
        n = self.n
        # Sylvester: if perm_r == perm_c = p, then P K Pᵀ = L U with unit-diagonal L and,
        # K being symmetric, U = D Lᵀ, so the signs of d = diag(U) are the inertia.
        # Pr[perm_r[i], i] = 1: pivot k belongs to the unknown i with perm_r[i] = k.
        symmetric_perm = np.array_equal(lu.perm_r, lu.perm_c)
        d = lu.U.diagonal()
        unk = np.empty(n, np.int64)
        unk[lu.perm_r] = np.arange(n)
        if self.kind == "spd":
            if not symmetric_perm:
                raise LinearSolverError("matrix is not positive definite: SuperLU met a zero diagonal pivot "
                                        "and pivoted off the diagonal; use kind='symmetric_indefinite'")
            a = K.diagonal()[unk]
            scale = np.where(a != 0, np.abs(a), 1.0)
            _check_spd_pivots(d / scale, d, unk, self.allow_singular)
            self._inertia = (n, 0, 0)
            return
        # indefinite: a pivot below 1e-13 · max|K| is a numerical zero (as PARDISO's perturbation)
        tiny = 10.0 ** -PARDISO_PERTURBATION_EXPONENT * np.abs(K.data).max()
        small = np.abs(d) <= tiny
        if small.any() and not self.allow_singular:
            k = int(np.flatnonzero(small)[0])
            where = f" at unknown {unk[k]}" if symmetric_perm else ""
            raise LinearSolverError(f"factorisation found {int(small.sum())} (near-)zero pivot(s){where}: "
                                    f"{_SINGULAR_HINT}")
        self.n_perturbed_pivots = int(small.sum())
        # Diagonal pivoting without a threshold is not backward stable: with large element
        # growth the factors describe a matrix far from K and the signs mean nothing. A
        # probe solve (before refinement) checks the factors.
        self._valid = True
        b = np.random.default_rng(0).standard_normal(n)
        self.probe_residual = float(np.linalg.norm(K @ lu.solve(b) - b) / np.linalg.norm(b))
        trusted = symmetric_perm and self.probe_residual <= PROBE_TOL
        if trusted:
            self._inertia = (int((d > tiny).sum()), int((d < -tiny).sum()), int(small.sum()))
        elif n <= DENSE_INERTIA_LIMIT:
            # count eigenvalues instead (O(n³), small matrices only): on first access
            self._inertia = None
            self._inertia_dense = K
        else:
            self._inertia = None
            warnings.warn("SuperLU: inertia unavailable (" + ("off-diagonal pivots" if not symmetric_perm else
                          f"unstable factors, test residual {self.probe_residual:.1e}") + "); use the pardiso "
                          "backend for stability checks", RuntimeWarning, stacklevel=4)

    @property
    def inertia(self):
        """(n_positive, n_negative, n_zero) eigenvalues of K, or None (see the class docstring)."""
        if self._inertia_dense is not None:
            K, self._inertia_dense = self._inertia_dense, None
            ev = np.linalg.eigvalsh(K.toarray())
            tol = K.shape[0] * np.finfo(float).eps * max(abs(ev).max(), 1e-300)
            self._inertia = (int((ev > tol).sum()), int((ev < -tol).sum()), int((abs(ev) <= tol).sum()))
        return self._inertia

    # ---- solving
    def solve(self, b):
        """Solve K x = b; ``b`` of shape (n,) or (n, k). Returns x of the same shape."""
        b = np.asarray(b, dtype=float)
        if b.shape[0] != self.n or b.ndim > 2:
            raise ValueError(f"right-hand side must have shape ({self.n},) or ({self.n}, k), got {b.shape}")
        if not np.all(np.isfinite(b)):
            raise LinearSolverError(f"right-hand side has {int((~np.isfinite(b)).sum())} non-finite entries")
        if not self._valid:
            raise LinearSolverError("no valid factorisation: it was freed or the last refactor() failed")
        if self.backend == "pardiso":
            x = self._impl.solve(self._U, np.asfortranarray(b))
            return x.reshape(b.shape)
        x = self._lu.solve(b)
        if self.kind == "symmetric_indefinite":
            # diagonal pivoting without a threshold is not backward stable: one step of
            # iterative refinement when the residual says so (a matrix-vector product)
            r = b - self._K @ x
            nb = np.linalg.norm(b)
            if nb > 0 and np.linalg.norm(r) > 1e-10 * nb:
                x = x + self._lu.solve(r)
        return x

    def free(self):
        """Release the factor now (PARDISO's memory is outside Python's garbage collector)."""
        self._valid = False
        if self._impl is not None:
            self._impl.free()
        self._lu = None
        self._K = None
        self._U = None
        self._pattern = None
        self._inertia_dense = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()

    def __repr__(self):
        return (f"Factorization({self.kind}, {self.backend}, n={getattr(self, 'n', '?')}, "
                f"inertia={self.inertia}, factor {self.factor_time:.3g} s)")


def factorize(K, kind: str = "spd", backend: str = "auto", *, reuse: Factorization | None = None,
              check_symmetry: bool = True, allow_singular: bool = False,
              pardiso_matching: bool = True) -> Factorization:
    r"""Factorise a sparse symmetric matrix K.

    Parameters
    ----------
    K : (n, n) sparse or dense matrix
        Symmetric; the full matrix is expected (PARDISO reads its upper triangle).
    kind : "spd" | "symmetric_indefinite"
        ``"spd"`` fails with :class:`LinearSolverError` when K is not positive definite.
    backend : "auto" | "pardiso" | "superlu"
    reuse : Factorization, optional
        A previous factorisation of the same kind and back-end (e.g. the last Newton
        iteration's): it is refactorised in place — reusing PARDISO's symbolic
        analysis if the pattern is unchanged — and returned.
    check_symmetry : bool
        Check |K − Kᵀ| ≤ 1e-10 max|K| whenever the sparsity pattern is new (one sparse
        transpose, ~5 % of a factorisation); refactorisations on a known pattern skip it.
    allow_singular : bool
        Return a factorisation even with (near-)zero pivots instead of raising;
        then ``n_perturbed_pivots`` says how many.
    pardiso_matching : bool
        Symmetric scaling and weighted matching (iparm(11), iparm(13)) in PARDISO's
        indefinite mode: robust for zero or small diagonal entries (saddle points).

    Returns
    -------
    Factorization
    """
    if reuse is not None and reuse.kind == kind and reuse.backend == _resolve_backend(backend):
        reuse.check_symmetry, reuse.allow_singular = check_symmetry, allow_singular
        return reuse.refactor(K)
    if reuse is not None:
        reuse.free()
    return Factorization(K, kind, backend, check_symmetry=check_symmetry, allow_singular=allow_singular,
                         pardiso_matching=pardiso_matching)


def _proves_positive_definite(inertia) -> bool:
    """An inertia (positive, negative, zero) with no negative and no zero eigenvalue; an unknown one proves nothing."""
    return inertia is not None and inertia[1] == 0 and inertia[2] == 0


def _analysed(exc: LinearSolverError, held: Factorization | None) -> Factorization | None:
    """The Cholesky to refactorise next after ``exc``: a new factorisation that failed keeps its symbolic
    analysis of the pattern (a Cholesky's depends on the pattern only), so the next matrix of the pattern
    costs a numerical factorisation, not a new analysis as well; else the one held, refactorised in place."""
    return getattr(exc, "factorization", None) or held


class Refactorizer:
    """Factorises a sequence of symmetric matrices with one sparsity pattern and reports their inertia.

    Newton iterations, and the Newton solves of a time or load stepping, factorise Hessians
    that change values but never pattern. A Refactorizer keeps its factorisations between
    calls, so PARDISO's symbolic analysis (ordering: about half of a first factorisation of
    a shell Hessian) is done once per pattern, not once per solve.

    With PARDISO it also tries Cholesky (``kind="spd"``) before LDLᵀ: a Cholesky that
    succeeds proves the inertia (n, 0, 0), which is all a stable equilibrium needs, and
    costs less than the symmetric-indefinite factorisation with its pivoting, scaling and
    matching (about 60 % of its time on a shell Hessian). A matrix
    that is not positive definite (or singular) makes the Cholesky fail and is factorised
    by LDLᵀ, which then gives the full inertia; after such a failure the next matrices go
    straight to LDLᵀ until one is positive definite again, so an indefinite stretch pays
    for one failed Cholesky, not one per matrix. With SuperLU
    (no symbolic reuse, the same cost for both kinds) it always uses LDLᵀ.

    ``refactorizer(K)`` returns the :class:`Factorization` of K (valid until the next
    call, and kept as ``last``); ``free()`` releases both factors. ``counts`` says how many Cholesky
    successes, Cholesky failures and LDLᵀ factorisations there were.

    Example
    -------
    >>> import numpy as np, scipy.sparse as sp
    >>> from femshell.solvers.linear import Refactorizer
    >>> r = Refactorizer()
    >>> r(sp.csr_matrix(np.diag([2.0, 1.0]))).inertia
    (2, 0, 0)
    >>> r(sp.csr_matrix(np.diag([2.0, -1.0]))).inertia
    (1, 1, 0)
    >>> r.free()
    """

    def __init__(self, backend: str = "auto", cholesky_first: bool = True):
        self.backend = _resolve_backend(backend)
        self.cholesky_first = cholesky_first and self.backend == "pardiso"
        self._spd = self._ldl = self._last = None
        self._try_spd = True
        self.counts = {"cholesky": 0, "cholesky_failed": 0, "ldlt": 0}

    @property
    def last(self) -> Factorization | None:
        """The factorisation returned by the last call if it is still valid (a failed or freed one: None)."""
        f = self._last
        return f if f is not None and f._valid else None

    def __call__(self, K) -> Factorization:
        self._last = None
        self._last = self._factorize(K)
        return self._last

    def _factorize(self, K) -> Factorization:
        if self.cholesky_first and self._try_spd:
            try:
                self._spd = factorize(K, kind="spd", backend=self.backend, reuse=self._spd)
                self.counts["cholesky"] += 1
                return self._spd
            except LinearSolverError as exc:
                # not positive definite, or singular: LDLᵀ below says which (or raises)
                self._spd = _analysed(exc, self._spd)
                self.counts["cholesky_failed"] += 1
                self._try_spd = False
        self._ldl = factorize(K, kind="symmetric_indefinite", backend=self.backend, reuse=self._ldl)
        self.counts["ldlt"] += 1
        self._try_spd = _proves_positive_definite(self._ldl.inertia)
        return self._ldl

    def positive_definite(self, K) -> Factorization | None:
        """The Cholesky factorisation of K if K is positive definite, else None (and ``last`` None).

        For a caller that needs only that answer, as a search for the shift that makes a
        Hessian positive definite does for each trial: a failed Cholesky is not followed by
        an LDLᵀ (which would cost a second, dearer factorisation to report an inertia that
        is not used). Without PARDISO (no Cholesky here) the LDLᵀ's inertia answers (None when
        it cannot be counted).
        """
        self._last = None
        try:
            if not self.cholesky_first:
                f = self._factorize(K)
                if not _proves_positive_definite(f.inertia):
                    return None
            else:
                f = self._spd = factorize(K, kind="spd", backend=self.backend, reuse=self._spd)
                self.counts["cholesky"] += 1
        except LinearSolverError as exc:   # not positive definite, or singular
            if self.cholesky_first:
                self._spd = _analysed(exc, self._spd)
                self.counts["cholesky_failed"] += 1
            return None
        self._last = f
        return f

    def restart(self):
        """Begin a new sequence (a new Newton solve): the next matrix tries Cholesky again, and the
        LDLᵀ is analysed afresh at its next use. PARDISO's LDLᵀ analysis (scaling and weighted
        matching) depends on the values it saw, the Cholesky's only on the pattern: so each solve's
        results depend only on its own matrices, as with a new Refactorizer, and a run resumed from
        a checkpoint repeats the uninterrupted one bit for bit. The Cholesky factor (and ``last``,
        if it is one) is kept."""
        if self._ldl is not None:
            self._ldl.free()
            self._ldl = None
        self._try_spd = True

    def free(self):
        for f in (self._spd, self._ldl):
            if f is not None:
                f.free()
        self._spd = self._ldl = self._last = None
        self._try_spd = True


# --------------------------------------------------------------------------- eigenvalues

def smallest_eigenvalues(K, k: int = 6, M=None, *, shift: float | None = None, return_vectors: bool = True,
                         backend: str = "auto", tol: float = 0.0, max_shifts: int = 12):
    r"""The k algebraically smallest eigenvalues λ of K v = λ M v (K symmetric, M SPD; M = I by default).

    Shift-invert Lanczos (``scipy.sparse.linalg.eigsh``) around σ < 0 with
    (K − σ M) factorised by :func:`factorize` (symmetric-indefinite, so K may be
    indefinite). By Sylvester's law the inertia of K − σ M counts the eigenvalues
    below σ; the k eigenvalues nearest σ are the k smallest exactly when they
    include all of those. If they do not (K has eigenvalues far below σ), σ is
    moved down and the step repeated.

    The default σ = −1e-6 · max|diag K| / max diag M is a small negative shift, so
    K − σ M is non-singular even for a free body (zero eigenvalues).

    Returns
    -------
    (w, V) like ``eigsh``: the k eigenvalues in ascending order and the
    M-orthonormal eigenvectors as columns of an (n, k) array; only w when
    ``return_vectors=False``.

    Example
    -------
    >>> import scipy.sparse as sp
    >>> L = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(50, 50)).tocsr()
    >>> w, V = smallest_eigenvalues(L - 0.1 * sp.identity(50), k=2)
    >>> bool(w[0] < 0), V.shape
    (True, (50, 2))
    """
    K = _canonical_csr(K)
    n = K.shape[0]
    if not (1 <= k <= n):
        raise ValueError(f"k must be in 1..{n}, got {k}")
    if M is not None:
        M = sp.diags(np.asarray(M, dtype=float)) if (not sp.issparse(M) and np.ndim(M) == 1) else sp.csr_matrix(M)
        if M.shape != K.shape:
            raise ValueError(f"M must have shape {K.shape}, got {M.shape}")
    if n <= max(400, 3 * k):
        import scipy.linalg as sla

        Kd = K.toarray()
        w, v = sla.eigh(Kd, None if M is None else M.toarray())
        return (w[:k], v[:, :k]) if return_vectors else w[:k]
    diag_m = np.ones(n) if M is None else M.diagonal()
    scale = np.abs(K.diagonal()).max() / max(diag_m.max(), 1e-300)
    sigma = -1e-6 * scale if shift is None else float(shift)
    Mop = sp.identity(n, format="csr") if M is None else M.tocsr()
    fac = None
    try:
        for _ in range(max_shifts):
            fac = factorize(K - sigma * Mop, kind="symmetric_indefinite", backend=backend, reuse=fac,
                            allow_singular=True)
            opinv = spla.LinearOperator((n, n), matvec=fac.solve, matmat=fac.solve, dtype=float)
            # a fixed start vector: ARPACK's default is random, which made saddle escapes (and so
            # whole runs) differ from one execution to the next
            v0 = np.random.default_rng(0).standard_normal(n)
            w, v = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=opinv, tol=tol, v0=v0)
            order = np.argsort(w)
            w, v = w[order], v[:, order]
            below = None if fac.inertia is None else fac.inertia[1]
            if below is None:
                warnings.warn("inertia unavailable: returning the k eigenvalues nearest the shift, which may "
                              "miss eigenvalues far below it", RuntimeWarning, stacklevel=2)
                break
            found_below = int((w < sigma).sum())
            if found_below >= below and below <= k:
                break
            # some eigenvalues below σ were not found: move σ below the lowest one found
            gap = max(sigma - w[0], abs(sigma), 1e-3 * scale)
            sigma = w[0] - 4.0 * gap
        else:
            warnings.warn(f"smallest_eigenvalues: no shift isolated the {k} smallest eigenvalues in "
                          f"{max_shifts} tries", RuntimeWarning, stacklevel=2)
    finally:
        if fac is not None:
            fac.free()
    return (w, v) if return_vectors else w
