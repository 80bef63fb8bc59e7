"""Scatter of per-element vectors and matrices into global arrays with a cached pattern.

The sparsity pattern of the Hessian never changes for a given mesh and set of
constrained unknowns, so the map from element entries to CSR storage positions is
computed once; each assembly is then one ``np.bincount``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class SparseAssembler:
    """Assemble ``(m, k)`` element vectors and ``(m, k, k)`` element matrices.

    Parameters
    ----------
    dofs : (m, k) int array
        Global unknown of each element entry.
    free : (n,) bool array
        Which global unknowns are kept; entries touching a fixed unknown are
        dropped and the result is indexed by free unknowns only.

    Example
    -------
    >>> import numpy as np
    >>> asm = SparseAssembler(np.array([[0, 1], [1, 2]]), np.ones(3, bool))
    >>> asm.matrix(np.ones((2, 2, 2))).toarray()
    array([[1., 1., 0.],
           [1., 2., 1.],
           [0., 1., 1.]])
    """

    def __init__(self, dofs: np.ndarray, free: np.ndarray):
        dofs = np.asarray(dofs, np.int64)
        free = np.asarray(free, bool)
        m, k = dofs.shape
        self.n_total = len(free)
        self.free_index = np.full(self.n_total, -1, np.int64)
        self.free_index[free] = np.arange(int(free.sum()))
        self.n = int(free.sum())
        local = self.free_index[dofs]                       # (m, k), -1 where fixed
        self._vec_keep = local.ravel() >= 0
        self._vec_target = local.ravel()[self._vec_keep]
        self.indptr, self.indices, self._mat_target, self.nnz = _matrix_pattern(local, self.n)

    def slots_of(self, other: "SparseAssembler"):
        """Positions in this pattern's CSR data of the entries of ``other``'s pattern (same unknowns), or
        None when ``other`` has an entry this pattern lacks."""
        if other.n != self.n:
            return None
        keys = np.repeat(np.arange(self.n), np.diff(self.indptr)) * self.n + self.indices
        other_keys = np.repeat(np.arange(other.n), np.diff(other.indptr)) * other.n + other.indices
        slots = np.searchsorted(keys, other_keys)
        if np.any(slots >= len(keys)) or not np.array_equal(keys[np.minimum(slots, len(keys) - 1)], other_keys):
            return None
        return slots

    def vector(self, element_vectors: np.ndarray) -> np.ndarray:
        """Sum element vectors (m, k) into the free unknowns."""
        v = np.asarray(element_vectors).ravel()[self._vec_keep]
        return np.bincount(self._vec_target, weights=v, minlength=self.n)

    def matrix(self, element_matrices: np.ndarray) -> sp.csr_matrix:
        """Sum element matrices (m, k, k) into a CSR matrix over the free unknowns."""
        # entries touching a fixed unknown go to one extra bin, cut off after the sum
        data = np.bincount(self._mat_target, weights=np.asarray(element_matrices).ravel(), minlength=self.nnz + 1)
        return sp.csr_matrix((data[: self.nnz], self.indices, self.indptr), shape=(self.n, self.n))


def _matrix_pattern(local: np.ndarray, n: int):
    """CSR pattern (indptr, indices) of the sum of the element matrices over ``n`` free unknowns, the
    position in it of every element matrix entry (an (m k²,) array; ``nnz``, one past the last, for
    an entry touching a fixed unknown, marked -1 in ``local``) and ``nnz``.

    The element rows (e, a) are grouped by their unknown (a sort of m k integers), their columns
    sorted within each row by scipy's CSR index sort, and repeated columns merged: the same pattern
    and positions as ``np.unique`` of the m k² keys row · n + col in about a quarter of the time
    (no sort of, and fewer allocations of, m k² arrays), and one cached m k² array instead of two.
    """
    m, k = local.shape
    block_row = local.ravel()
    blocks = np.flatnonzero(block_row >= 0)
    order = blocks[np.argsort(block_row[blocks], kind="stable")]
    cols = local[order // k]                                        # (rows, k), grouped by row
    keep = cols >= 0
    counts = np.bincount(block_row[order], weights=keep.sum(axis=1), minlength=n).astype(np.int64)
    start = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    entry = (order[:, None] * k + np.arange(k))[keep]               # e k² + a k + b, exact in float64
    grouped = sp.csr_matrix((entry.astype(np.float64), cols[keep].astype(np.int32 if n < 2**31 else np.int64),
                             start), shape=(n, n))
    grouped.has_sorted_indices = False
    grouped.sort_indices()
    c = grouped.indices
    first = np.empty(len(c), bool)                                  # first of its (row, col) in the row
    if len(c):
        first[0] = True
        np.not_equal(c[1:], c[:-1], out=first[1:])
        first[start[:-1][counts > 0]] = True
    ordinal = np.cumsum(first)
    nnz = int(ordinal[-1]) if len(c) else 0
    target = np.full(m * k * k, nnz, np.int64)
    target[grouped.data.astype(np.int64)] = ordinal - 1
    indptr = np.concatenate([[0], ordinal])[start]
    return indptr, c[first], target, nnz
