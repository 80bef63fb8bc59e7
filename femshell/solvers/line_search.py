"""Backtracking line search on an energy along a descent direction (Armijo), with a residual fallback.

Used by Newton (:mod:`femshell.solvers.newton`) and its quasi-Newton phase
(:mod:`femshell.solvers.quasi_newton`). ``problem`` has ``energy(u)``, ``gradient(u)`` and
optionally ``energy_and_gradient(u)`` (tried at the full step, whose gradient is needed next).
"""

from __future__ import annotations

import numpy as np


def line_search(problem, u, e, g, d, c1=1e-4, max_halvings=30, max_step=None):
    """Backtracking Armijo search on the energy; near convergence, on the residual norm.

    The direction is scaled to a max-norm of ``max_step``. A step is taken when the energy
    falls (Armijo), or, where energy differences are below round-off (1e-12 |Π|), when the
    residual falls: so the energy may rise by that round-off band, no more.
    """
    slope = g @ d
    if slope >= 0:  # not a descent direction (should not happen with a positive definite system)
        d = -g
    if max_step is not None:
        big = np.abs(d).max()
        if big > max_step:
            d = d * (max_step / big)
    slope = g @ d
    r0 = np.linalg.norm(g)
    alpha = 1.0
    both = getattr(problem, "energy_and_gradient", None)
    for _ in range(max_halvings):
        un = u + alpha * d
        gn = None
        if both is not None and alpha == 1.0:
            en, gn = both(un)
        else:
            en = problem.energy(un)
        if np.isfinite(en):
            # energy differences below round-off cannot rank steps: judge by the residual
            roundoff = 1e-12 * max(abs(e), 1e-300)
            if en <= e + c1 * alpha * slope or abs(en - e) <= roundoff:
                if gn is None:
                    gn = problem.gradient(un)
                if np.all(np.isfinite(gn)) and (en < e - roundoff or np.linalg.norm(gn) < r0):
                    return un, en, gn, True
        alpha *= 0.5
    return u, e, g, False
