r"""Helpers of the curved-shell buckling cases: the first instability by continuation, Richardson extrapolation
with an observed order, the rows of a refinement ladder. Their linear buckling is the library's
(:func:`femshell.linear_buckling.shell_buckling_loads`: rigid motions deflated, no pins).
"""

from __future__ import annotations

import math

from scipy.optimize import brentq

from ..solvers.continuation import continuation
from .common import finest_order
from .framework import Row


def first_instability(problem, u0, lam_stop, *, ds=0.1, ds_max=0.2):
    """(parameter of the first fold or branch point, the SpecialPoint or None) of the branch from (u0, 0).

    The parameter is NaN when none was found before ``lam_stop`` or the point is only bracketed.
    """
    branch = continuation(problem, u0, 0.0, ds=ds, ds_max=ds_max, lam_stop=lam_stop, stop_at=("fold", "branch"),
                          n_eigs=3, log=None)
    first = next((p for p in branch.special_points if p.kind in ("fold", "branch")), None)
    return (math.nan if first is None else first.parameter), first


def instability_kind(point):
    """"fold", "branch", "branch (not located)" or "none": how a continuation's first instability shows."""
    return "none" if point is None else point.kind + ("" if point.located else " (not located)")


def richardson(n_vertices, values, order):
    """The extrapolation of the two finest values with error ∝ h^order, h ∝ n_vertices^(−1/2)."""
    (n1, v1), (n2, v2) = sorted(zip(n_vertices, values))[-2:]
    r = math.sqrt(n2 / n1)                   # h1 / h2
    return v2 + (v2 - v1) / (r**order - 1.0)


def order_from_values(n_vertices, values):
    """The order p of v(h) = v∞ + C h^p through the three finest values (h ∝ n^(−1/2)), without a reference;
    None with fewer than three values or when their differences do not shrink monotonically."""
    pts = sorted(zip(n_vertices, values))[-3:]
    if len(pts) < 3:
        return None
    (n1, v1), (n2, v2), (n3, v3) = pts
    h1, h2, h3 = (n ** -0.5 for n in (n1, n2, n3))
    ratio = (v2 - v1) / (v3 - v2) if v3 != v2 else math.inf
    if not (math.isfinite(ratio) and ratio > 1):
        return None

    def mismatch(p):
        return (h1**p - h2**p) / (h2**p - h3**p) - ratio

    if mismatch(0.05) * mismatch(12.0) > 0:
        return None
    return float(brentq(mismatch, 0.05, 12.0))


def convergence_rows(quantity, n_vertices, values, tol, assumed_order=2.0):
    """Rows of a refinement ladder against reference 1: the order against the reference, the order from the
    values alone (three finest) and the Richardson estimate with it (with ``assumed_order`` when there are
    fewer than three meshes, reported only)."""
    rows = []
    p_ref, k = finest_order(n_vertices, [abs(v - 1.0) for v in values])
    if p_ref is not None:
        rows.append(Row(f"observed order of {quantity} error against the reference (finest {k} meshes)", p_ref))
    p = order_from_values(n_vertices, values)
    if p is not None:
        rows.append(Row(f"observed order of {quantity} from its three finest values", p))
        rows.append(Row(f"{quantity}, Richardson from the two finest meshes with that order",
                        richardson(n_vertices, values, p), 1.0, tol, max(n_vertices), 0.0))
    elif len(values) >= 2:
        rows.append(Row(f"{quantity}, Richardson from the two finest meshes with order {assumed_order:g} (assumed)",
                        richardson(n_vertices, values, assumed_order), 1.0, None, max(n_vertices), 0.0))
    return rows
