"""The records a continuation returns: :class:`Branch` (its table and states) and :class:`SpecialPoint`.

Data only: writing them is :func:`femshell.io.write_branch_csv` and
:func:`femshell.io.write_special_points`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Branch", "SpecialPoint", "ContinuationError", "LABELS"]

#: table labels of the special points
LABELS = {"fold": "LP", "branch": "BP", "possible_branch": "BP?"}


class ContinuationError(RuntimeError):
    """The continuation could not start (the first point did not converge, bad arguments)."""


@dataclass
class SpecialPoint:
    """A fold ("fold"), branch point ("branch") or possible symmetric bifurcation ("possible_branch").

    ``located``: False when the point was detected (dλ/ds or the inertia changed sign over a
    step) but not located, even on cut steps; it is then a bracket: ``parameter`` is NaN,
    ``bracket`` the step's parameter range, ``u`` the step's end (at ``info["state_parameter"]``),
    no ``modes``, and ``info["reason"]`` says why.
    ``u``, ``parameter``: the state; ``tangent``: (t_u, t_λ) of the branch there;
    ``eigenvalues``: the eigenvalues of K nearest zero there, ascending; ``modes``: (n, multiplicity) the
    critical eigenvector(s) (Euclidean-orthonormal, each with its largest entry positive);
    ``n_negative_before/after``: the inertia on either side; ``bracket``: the parameter values of the final bracket;
    ``s``: arclength from the start of the branch; ``step``: index of the last accepted
    step before it.
    """

    kind: str
    parameter: float
    s: float
    u: np.ndarray
    tangent: tuple
    eigenvalues: np.ndarray
    modes: np.ndarray
    multiplicity: int
    n_negative_before: int | None
    n_negative_after: int | None
    step: int
    bracket: tuple = (math.nan, math.nan)
    located: bool = True
    info: dict = field(default_factory=dict)
    weights: np.ndarray | None = field(default=None, repr=False)
    parameter_scale: float = 1.0

    @property
    def label(self) -> str:
        return LABELS.get(self.kind, self.kind)

    @property
    def row_label(self) -> str:
        """The label in the branch table: "BP", or "BP not located" for a bracket."""
        return self.label if self.located else f"{self.label} not located"

    def summary(self) -> str:
        if not self.located:
            return (f"{self.label} between parameters {self.bracket[0]:.10g} and {self.bracket[1]:.10g}, not located "
                    f"({self.info.get('reason', '')}), negative eigenvalues {self.n_negative_before} -> "
                    f"{self.n_negative_after}")
        if self.n_negative_before is None and not len(self.eigenvalues):     # a non-gradient problem's
            return f"{self.label} at parameter {self.parameter:.10g} (s = {self.s:.6g}), det J changes sign"
        return (f"{self.label} at parameter {self.parameter:.10g} (s = {self.s:.6g}), multiplicity "
                f"{self.multiplicity}, negative eigenvalues {self.n_negative_before} -> {self.n_negative_after}, "
                f"eigenvalues {np.array2string(np.asarray(self.eigenvalues)[:6], precision=3)}")


class Branch:
    """A followed branch: table rows, states, special points, and why it stopped.

    ``rows``: list of dicts, one per accepted point and per located special point, in
    arclength order (a point detected but not located labels the row of the step's end),
    with ``step, s, parameter, energy, n_negative, stable, eig_0..`` (eigenvalues nearest zero,
    ascending), ``dlam_ds, ds, iterations, special ("", "LP", "BP", "BP?"), branch, wall_s`` and the
    columns of ``record(u)``. ``states``: the matching ``(u, lam)`` (None entries when
    ``keep_states=False``; the last point is always kept). ``status``: ``"lam_stop"``,
    ``"max_steps"``, ``"fold"``, ``"branch"``, ``"ds_min"``, ``"callback"``;
    ``message`` says more; ``origin``: the :class:`SpecialPoint` a branch made by
    :func:`switch_branch` starts from (else None).
    """

    def __init__(self, label="branch", weights=None, parameter_scale=1.0):
        self.label = label
        self.rows: list[dict] = []
        self.states: list = []
        self.special_points: list[SpecialPoint] = []
        self.status = "running"
        self.message = ""
        self.weights = weights
        self.parameter_scale = parameter_scale
        self.wall_s = 0.0
        self.origin: SpecialPoint | None = None   # the branch point a switched branch starts from
        self._last = None

    def __len__(self):
        return len(self.rows)

    def __repr__(self):
        return (f"Branch({self.label!r}, {len(self.rows)} rows, {len(self.special_points)} special points, "
                f"status={self.status!r})")

    @property
    def columns(self) -> list:
        keys = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        return keys

    @property
    def table(self) -> dict:
        """Columns as a dict of lists (the input format of :func:`femshell.viz.bifurcation_diagram`)."""
        return {k: [r.get(k) for r in self.rows] for k in self.columns}

    def column(self, name, special=True) -> np.ndarray:
        """One column as a float array; ``special=False`` leaves out the special-point rows."""
        return np.array([np.nan if r.get(name) is None else r.get(name) for r in self.rows
                         if special or not r.get("special")], dtype=float)

    @property
    def last(self):
        """(u, lam) of the last accepted point (also inside a callback; None before the first)."""
        return self._last

