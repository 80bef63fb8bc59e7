"""The symmetric sparse matrix as the linear-solver back-ends take it.

Canonical CSR (square, float64, sorted and summed entries), value checks that name the
problem and where (non-finite entries, zero rows, asymmetry), and the upper-triangle pattern
PARDISO's symmetric modes read, with a cached gather so a refactorisation on the same pattern
costs one indexing pass.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

_SINGULAR_HINT = ("the system is singular — are the rigid-body modes constrained "
                  "(a free shell has six) and every unknown coupled to the rest?")


class LinearSolverError(RuntimeError):
    """A matrix that cannot be factorised or solved; the message says why and where."""



def _canonical_csr(K) -> sp.csr_matrix:
    if not sp.issparse(K):
        K = np.asarray(K, dtype=float)
        if K.ndim != 2:
            raise ValueError(f"K must be a 2-D matrix, got shape {K.shape}")
        K = sp.csr_matrix(K)
    K = K.tocsr()
    if K.shape[0] != K.shape[1]:
        raise LinearSolverError(f"matrix must be square, got shape {K.shape}")
    if K.dtype != np.float64:
        if np.iscomplexobj(K.data):
            raise LinearSolverError("complex matrices are not supported")
        K = K.astype(np.float64)
    if not K.has_canonical_format:
        K = K.copy()
        K.sum_duplicates()                          # sorts indices too
    return K


def _row_of_entries(K):
    return np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))


def _check_values(K, check_symmetry: bool):
    """Raise LinearSolverError for NaN/inf entries, empty or zero rows, (optionally) asymmetry."""
    n = K.shape[0]
    bad = ~np.isfinite(K.data)
    if bad.any():
        rows = np.unique(_row_of_entries(K)[bad])
        what = " and ".join(w for w, m in (("NaN", np.isnan(K.data[bad]).any()),
                                            ("infinite", np.isinf(K.data[bad]).any())) if m)
        raise LinearSolverError(f"matrix has {what} entries in {len(rows)} row(s), first row {rows[0]} "
                                f"({int(bad.sum())} entries in all); the assembly produced non-finite values")
    # a row with no nonzero entry, by one pass over the rows' runs (a weighted bincount over the
    # entries' rows took 4x as long on a 25 000-vertex shell Hessian: 0.08 s per factorisation)
    nonempty = np.diff(K.indptr) > 0
    row_has = np.zeros(n, bool)
    if nonempty.any():
        row_has[nonempty] = np.logical_or.reduceat(K.data != 0, K.indptr[:-1][nonempty])
    zero = np.flatnonzero(~row_has)
    if len(zero):
        raise LinearSolverError(f"matrix has {len(zero)} zero (or empty) row(s), first row {zero[0]}: "
                                f"{_SINGULAR_HINT}")
    if check_symmetry and n:
        D = (K - K.T).tocsr()
        D.eliminate_zeros()
        if D.nnz:
            scale = np.abs(K.data).max()
            worst = np.argmax(np.abs(D.data))
            err = abs(D.data[worst])
            if err > 1e-10 * scale:
                i = _row_of_entries(D)[worst]
                j = D.indices[worst]
                raise LinearSolverError(
                    f"matrix is not symmetric: |K[{i},{j}] - K[{j},{i}]| = {err:.3g} "
                    f"(largest entry {scale:.3g}); a symmetric factorisation would use only one triangle")


class _PatternKey:
    """Just enough of a CSR pattern to recognise it again."""

    def __init__(self, K):
        self.n = K.shape[0]
        self.indptr_full = K.indptr.copy()
        self.indices_full = K.indices.copy()

    def same_pattern(self, K) -> bool:
        return (K.shape[0] == self.n and np.array_equal(K.indptr, self.indptr_full)
                and np.array_equal(K.indices, self.indices_full))


class _UpperPattern(_PatternKey):
    """Upper triangle of a canonical CSR pattern, with explicit (possibly zero) diagonal entries.

    ``values(K)`` maps K.data into the upper-triangle data through a cached gather,
    so refactorising on the same pattern costs one indexing pass.
    """

    def __init__(self, K):
        super().__init__(K)
        n = self.n
        rows = _row_of_entries(K)
        keep = K.indices >= rows
        src = np.flatnonzero(keep)
        has_diag = np.zeros(n, bool)
        has_diag[rows[keep & (K.indices == rows)]] = True
        miss = np.flatnonzero(~has_diag)
        r, c = rows[src], K.indices[src]
        if len(miss):
            # PARDISO's symmetric modes want every diagonal entry stored, even when zero
            r = np.concatenate([r, miss])
            c = np.concatenate([c, miss])
            src = np.concatenate([src, np.full(len(miss), -1)])
            order = np.lexsort((c, r))
            r, c, src = r[order], c[order], src[order]
        self.indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(r, minlength=n), out=self.indptr[1:])
        self.indices = c.astype(np.int32)
        self.indptr = self.indptr.astype(np.int32)
        self.src = src
        self._has_missing = len(miss) > 0

    def matrix(self, K) -> sp.csr_matrix:
        if self._has_missing:
            data = np.zeros(len(self.src))
            m = self.src >= 0
            data[m] = K.data[self.src[m]]
        else:
            data = K.data[self.src]
        U = sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n), copy=False)
        U.has_sorted_indices = True
        return U
