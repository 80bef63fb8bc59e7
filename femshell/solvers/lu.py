r"""Sparse LU of an unsymmetric matrix (SuperLU) with the sign of its determinant.

SuperLU factorises P_r J P_c = L U with partial pivoting (P_r) and a fill-reducing column order
(P_c), L unit lower triangular, so

.. math:: \operatorname{sign}\det J = \operatorname{sign}(P_r)\,\operatorname{sign}(P_c)
          \prod_i \operatorname{sign} U_{ii} ,

the sign of a permutation being (−1)^(n − number of its cycles). The continuation of a
non-gradient problem (:mod:`femshell.solvers.corrector`) detects its branch points by sign
changes of det J: there is no inertia to count when J is not symmetric.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla

from .linear import LinearSolverError

__all__ = ["LUFactorization", "permutation_sign"]


def permutation_sign(perm) -> int:
    """+1 for an even permutation (perm[i] the image of i), −1 for an odd one."""
    perm = np.asarray(perm)
    n = len(perm)
    if n == 0:
        return 1
    graph = sp.csr_matrix((np.ones(n), (np.arange(n), perm)), shape=(n, n))
    n_cycles, _ = csgraph.connected_components(graph, directed=True, connection="weak")
    return -1 if (n - n_cycles) % 2 else 1


class LUFactorization:
    """J = P_rᵀ L U P_cᵀ by SuperLU; ``solve(b)`` (``transpose=True``: Jᵀ x = b), ``det_sign`` (±1).

    Raises :class:`~femshell.solvers.linear.LinearSolverError` when J is not square, has
    non-finite entries or is exactly singular. ``inertia`` is None (not a symmetric matrix).
    """

    kind = "lu"
    inertia = None

    def __init__(self, J):
        J = sp.csc_matrix(J, dtype=float)
        if J.shape[0] != J.shape[1]:
            raise LinearSolverError(f"LU needs a square matrix, got shape {J.shape}")
        if not np.all(np.isfinite(J.data)):
            raise LinearSolverError("the matrix has non-finite entries")
        self.n = J.shape[0]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self._lu = spla.splu(J)
        except RuntimeError as exc:          # "Factor is exactly singular"
            raise LinearSolverError(f"the matrix is singular ({exc})") from None
        diag = self._lu.U.diagonal()
        if not np.all(np.isfinite(diag)) or np.any(diag == 0):
            raise LinearSolverError("the matrix is singular (a zero pivot)")
        negative = int(np.count_nonzero(diag < 0))
        self.det_sign = (permutation_sign(self._lu.perm_r) * permutation_sign(self._lu.perm_c)
                         * (-1 if negative % 2 else 1))
        self.log_abs_det = float(np.sum(np.log(np.abs(diag))))

    def solve(self, b, transpose=False):
        b = np.asarray(b, dtype=float)
        x = self._lu.solve(b, trans="T" if transpose else "N")
        return x

    def free(self):
        self._lu = None

    def __repr__(self):
        return f"LUFactorization(n={self.n}, det_sign={self.det_sign:+d})"
