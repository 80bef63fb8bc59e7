"""What a Newton solve returns, or raises: :class:`NewtonResult` and :class:`NewtonError`.

Shared by the Newton driver (:mod:`femshell.solvers.newton`), its negative-curvature steps
(:mod:`femshell.solvers.negative_curvature`) and the load stepping built on it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class NewtonError(RuntimeError):
    """Newton did not converge; ``result`` holds the last iterate and the history, ``stalled`` says
    whether it gave up for lack of progress (``minimize(stall=...)``)."""

    def __init__(self, message, result=None, stalled=False):
        super().__init__(message)
        self.result = result
        self.stalled = stalled


@dataclass
class NewtonResult:
    u: np.ndarray
    converged: bool
    iterations: int
    energy: float
    residual: float
    residual_scale: float
    n_negative: int | None = None
    stable: bool | None = None
    history: list = field(default_factory=list)
    times: dict = field(default_factory=dict)
    #: iterations of the quasi-Newton phase on a held factorisation (``minimize(quasi_newton=...)``)
    quasi_newton_iterations: int = 0
    #: numerical factorisations done by this solve (Hessians, failed Cholesky attempts and shifted ones included)
    factorizations: int = 0
    #: Krylov solves on a held factorisation and their iterations (``linear_solver="krylov"``)
    krylov_solves: int = 0
    krylov_iterations: int = 0

    def summary(self) -> str:
        t = ", ".join(f"{k} {v:.2f}s" for k, v in self.times.items())
        st = "" if self.stable is None else (" stable" if self.stable else f" UNSTABLE ({self.n_negative} neg.)")
        return (f"{'converged' if self.converged else 'NOT converged'} in {self.iterations} iterations, "
                f"|r| = {self.residual:.3e} (scale {self.residual_scale:.3e}), energy {self.energy:.10g}{st}; {t}")


def newton_result(u, converged, it, e, res, scale, n_neg, history, times) -> NewtonResult:
    """The result at u after ``it`` iterations; ``n_neg`` negative eigenvalues (None: not counted) make
    ``stable`` (None when not counted)."""
    return NewtonResult(u, converged, it, e, res, scale, n_neg, None if n_neg is None else n_neg == 0,
                        history, dict(times))
