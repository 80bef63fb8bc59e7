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
        rows = np.repeat(local, k, axis=1).ravel()          # (m*k*k,)
        cols = np.tile(local, (1, k)).ravel()
        keep = (rows >= 0) & (cols >= 0)
        self._mat_keep = np.flatnonzero(keep)
        key = rows[keep] * self.n + cols[keep]
        uniq, self._mat_target = np.unique(key, return_inverse=True)
        r, c = np.divmod(uniq, self.n)
        self.indptr = np.searchsorted(r, np.arange(self.n + 1)).astype(np.int64)
        self.indices = c.astype(np.int32 if self.n < 2**31 else np.int64)
        self.nnz = len(uniq)

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
        v = np.asarray(element_matrices).ravel()[self._mat_keep]
        data = np.bincount(self._mat_target, weights=v, minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
