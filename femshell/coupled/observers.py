r"""What the coupled loop reports and asks while it runs, supplied by its caller.

The loop measures and stores nothing itself: the caller passes these callbacks (the scene
runner wires femshell.analysis and the interrupt handling into them; the API may leave any
out). Checkpoints are requested through :meth:`~femshell.coupled.loop.CoupledLoop.run`'s
``checkpoint`` callback.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Callable, ContextManager

__all__ = ["LoopObservers"]


@dataclass(frozen=True)
class LoopObservers:
    """Callbacks of a :class:`~femshell.coupled.loop.CoupledLoop`; every one optional.

    Parameters
    ----------
    log : callable ``log(line)``
        Progress: one line per step, cut and notice.
    count_regions : callable ``count_regions(points, triangles, c, c_star) -> int``
        N_sp, the regions with c > c*, of each step's record (without it records carry
        n_spots = -1, "not counted").
    measure_pattern, same_pattern : callables ``measure_pattern(points, triangles, c, c_star)``
        (measures with ``n_spots`` and ``fraction_patterned``) and ``same_pattern(a, b, tol) -> bool``
        The pattern's clock of ``TimeStepping.stationary_pattern_time`` (needed when that is > 0).
    commit : callable returning a context manager
        Around the commit of an accepted step: hold interrupts there, so a step is never half taken.
    step_scope : callable returning a context manager
        Around one step of ``run`` with its callback and checkpoint (where an interrupt held by
        ``commit`` is raised).
    """

    log: Callable[[str], None] | None = None
    count_regions: Callable | None = None
    measure_pattern: Callable | None = None
    same_pattern: Callable | None = None
    commit: Callable[[], ContextManager] = contextlib.nullcontext
    step_scope: Callable[[], ContextManager] = contextlib.nullcontext

    @property
    def follows_patterns(self) -> bool:
        """Both pattern callbacks are given."""
        return self.measure_pattern is not None and self.same_pattern is not None
