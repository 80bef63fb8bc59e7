"""Quasi-Newton iterations on a held factorisation: a Newton solve's start that assembles no Hessian.

In a time or load stepping the previous solve's converged Hessian is factorised (its stability
check); :func:`lagged_quasi_newton` (L-BFGS from that factor) starts the next solve with it
(``minimize(quasi_newton=...)``, :mod:`femshell.solvers.newton`).
"""

from __future__ import annotations

import time

import numpy as np

from .line_search import line_search


def lagged_quasi_newton(problem, u, e, g, factorization, tol, max_iter, times, memory=8, stall=4, max_step=None):
    r"""L-BFGS from an earlier Hessian's factorisation: minimise Π without assembling a Hessian.

    The inverse-Hessian approximation starts from :math:`H_0 = K_0^{-1}`, the held
    factorisation of a positive definite Hessian of a nearby problem (in a time or load
    stepping: the previous step's converged state), and is corrected by the last ``memory``
    pairs :math:`s_k = u_{k+1} - u_k`, :math:`y_k = \nabla\Pi_{k+1} - \nabla\Pi_k` (two-loop
    recursion, Nocedal & Wright, Numerical Optimization, alg. 7.4); a pair with
    :math:`s_k \cdot y_k \le 0` is skipped so that the approximation stays positive definite
    and every direction is a descent one. Each iteration costs one back-substitution and an
    energy/gradient line search instead of a Hessian assembly and a factorisation. With
    :math:`K_0` close to the current Hessian the iteration contracts like Newton's after a
    few steps (superlinearly).

    Stops when :math:`|\nabla\Pi| \le` ``tol``, after ``max_iter`` iterations, when the
    line search fails, or when ``stall`` iterations in a row did not halve the residual (a
    Hessian that has moved too far: Newton is cheaper from there). Steps are capped to a
    max-norm of ``max_step`` as Newton's are. Returns (u, Π, ∇Π, iterations); the state
    returned has an energy no higher than the start (to the line search's round-off band).
    """
    t0 = time.perf_counter()
    pairs = []
    slow = 0
    it = 0
    res = np.linalg.norm(g)
    while it < max_iter and res > tol:
        q = g.copy()
        alphas = []
        for s, y, rho in reversed(pairs):
            a = rho * (s @ q)
            q -= a * y
            alphas.append(a)
        r = factorization.solve(q)
        for (s, y, rho), a in zip(pairs, reversed(alphas)):
            r += s * (a - rho * (y @ r))
        un, en, gn, ok = line_search(problem, u, e, g, -r, max_step=max_step)
        if not ok:
            break
        it += 1
        s, y = un - u, gn - g
        sy = float(s @ y)
        if sy > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
            pairs = (pairs + [(s, y, 1.0 / sy)])[-memory:]
        res_new = np.linalg.norm(gn)
        slow = slow + 1 if res_new > 0.5 * res else 0
        u, e, g, res = un, en, gn, res_new
        if slow >= stall:
            break
    times["quasi_newton"] = times.get("quasi_newton", 0.0) + time.perf_counter() - t0
    return u, e, g, it
