"""K⁻¹ for an SPD sparse K by SuperLU, PARDISO (through :mod:`femshell.solvers.linear`) or pyamg.

The inner solver of :mod:`.prestress` and of the shift-invert eigenproblem of
:mod:`.eigenproblem`, with setup and solve timings.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..solvers.linear import factorize


class _InverseOperator:
    """``K^{-1}`` for an SPD sparse K by one of several back-ends, with setup and solve timings."""

    def __init__(self, K, solver="splu", rtol=1e-10, maxiter=300):
        self.K = K = sp.csr_matrix(K)
        self.solver = solver
        self.n_solves = 0
        self.solve_s = 0.0
        self.iterations = 0
        t0 = time.perf_counter()
        if solver == "splu":
            lu = spla.splu(sp.csc_matrix(K), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
            self._solve = lu.solve
        elif solver == "pardiso":
            self._fac = factorize(K, kind="spd", backend="pardiso")
            self._solve = self._fac.solve
        elif solver == "pyamg":
            import pyamg   # optional dependency, only for this solver

            ml = pyamg.smoothed_aggregation_solver(K, symmetry="symmetric", max_coarse=500)
            M = ml.aspreconditioner(cycle="V")

            def solve(b):
                res = []
                # FGMRES, not CG: with CG some right-hand sides that ARPACK produces stagnated
                # at a residual of 1e-5 (measured on the Morley plate matrix)
                x = ml.solve(b, tol=rtol, accel="fgmres", maxiter=maxiter, residuals=res)
                self.iterations += len(res)
                if not res or res[-1] > rtol * max(res[0], 1e-300) * 10:
                    raise RuntimeError(f"pyamg-preconditioned FGMRES did not reach {rtol:g} in {maxiter} "
                                       f"iterations (residual ratio {res[-1] / res[0]:.1e}); "
                                       "use solver='splu' or 'pardiso'")
                return x

            self._ml, self._M = ml, M
            self._solve = solve
        else:
            raise ValueError(f"unknown solver '{solver}' (splu, pardiso, pyamg)")
        self.setup_s = time.perf_counter() - t0

    def __call__(self, b):
        t0 = time.perf_counter()
        x = self._solve(np.asarray(b, float).ravel())
        self.solve_s += time.perf_counter() - t0
        self.n_solves += 1
        return x

    def operator(self):
        n = self.K.shape[0]
        return spla.LinearOperator((n, n), matvec=self, dtype=float)
