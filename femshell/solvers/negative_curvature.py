"""Newton's answers to negative curvature: a Levenberg–Marquardt shift, and a step off a saddle.

* :func:`shift_to_positive`: factorise K + τD (D the positive diagonal of K) with τ growing until it
  is positive definite: its step −(K + τD)⁻¹∇Π is a descent direction where Newton's is not;
* :func:`is_saddle` and :func:`escape_saddle`: at a converged point with a negative eigenvalue, step
  along the eigenvector of the most negative one, to the side that lowers Π (theory §2.6).
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import scipy.sparse as sp

from .linear import smallest_eigenvalues
from .newton_result import NewtonError


def shift_to_positive(K, factorizer, times, tau_start=1e-6):
    """Factorise K + tau D with a tau (growing by 4 from ``tau_start``) that makes it positive definite.

    Each trial is a Cholesky attempt only (:meth:`Refactorizer.positive_definite`): the
    inertia of a failed trial is not needed, and a failing Cholesky costs about half an LDLᵀ.
    """
    d = K.diagonal()
    D = np.abs(d)
    D = np.where(D > 0, D, D.max() if D.max() > 0 else 1.0)
    shifted = K.tocsr(copy=True)
    tau = tau_start
    for _ in range(60):
        t = time.perf_counter()
        # on K's own pattern (a sparse sum would drop its exact zeros: a new pattern to analyse)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sp.SparseEfficiencyWarning)   # only if K lacks a diagonal entry
            shifted.setdiag(d + tau * D)
        fac = factorizer.positive_definite(shifted)
        times["factorize"] += time.perf_counter() - t
        if fac is not None:
            return fac, tau
        tau *= 4.0
    raise NewtonError("could not shift the Hessian to positive definite")


def is_saddle(K, n_neg) -> bool:
    """K has a negative eigenvalue (counted from the inertia, else from the smallest eigenvalue)."""
    if n_neg is not None:
        return n_neg > 0
    lam, _ = smallest_eigenvalues(K, k=1)
    return bool(lam[0] < 0)


#: amplitudes of the escape step, in units of max(|u|, 1): growing ones first; if none lowers the energy,
#: smaller ones (along a direction of negative curvature a small enough step always does: Π(u + t v) ≈
#: Π(u) + t ∇Π·v + ½ λ t² |v|² on both sides of a saddle, and positions in u make the first step ~1e-3 of
#: the shell's size, past the quartic turn of a mildly negative mode on a large shell)
ESCAPE_AMPLITUDES = (1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6)


def escape_saddle(problem, u, e, K, log):
    """Move from a saddle along the most negative curvature direction, to lower energy."""
    lam, vec = smallest_eigenvalues(K, k=1)
    v = vec[:, 0]
    scale = max(np.abs(u).max(), 1.0)
    for amp in ESCAPE_AMPLITUDES:
        best = None
        for s in (1.0, -1.0):
            un = u + s * amp * scale * v / np.abs(v).max()
            en = problem.energy(un)
            if np.isfinite(en) and en < e and (best is None or en < best[1]):
                best = (un, en)
        if best is not None:
            if log:
                log(f"    newton: left a saddle (eigenvalue {lam[0]:.3e}) along its mode, amplitude {amp:g}")
            return best[0], best[1], problem.gradient(best[0])
    raise NewtonError(f"at a saddle (eigenvalue {lam[0]:.3e}) but no step along its mode lowers the energy")
