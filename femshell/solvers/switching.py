"""Branch switching at a branch point: start a new branch along a critical mode and follow it.

The start is (u*, λ*) + a·t_new, t_new = (φ, 0) made W-orthogonal to the old branch's tangent
and normalised (φ a critical mode or a combination of modes); the first corrector works on the
hyperplane through the start orthogonal to t_new, so it cannot fall back onto the old branch.
"""

from __future__ import annotations

import math

import numpy as np

from .arclength import continuation
from .branch import Branch, SpecialPoint

__all__ = ["switch_branch"]


def switch_branch(problem, special_point: SpecialPoint, mode=None, amplitude=None, *, ds=None, sign=+1,
                  label=None, **options) -> Branch:
    r"""Start a new branch at a branch point and follow it with :func:`continuation`.

    Parameters
    ----------
    special_point : a :class:`SpecialPoint` of kind "branch" or "possible_branch".
    mode : None (the first critical mode), an int (that critical mode), an array of
        ``multiplicity`` coefficients (a combination of the critical modes, e.g. cos/sin
        of a double disk mode), or a full vector of the unknowns.
    amplitude : distance a of the first point from the branch point in the weighted
        arclength norm (default: ``ds``); its sign (or ``sign=-1``) picks the half of a
        pitchfork.
    ds : first step on the new branch (default: |amplitude| or 0.1).
    options : passed to :func:`continuation` (ds_max, lam_stop, max_steps, record, ...).
        The weights and parameter scale of the original branch are used unless given.

    The start is (u*, λ*) + a·t_new, t_new = (φ, 0) made W-orthogonal to the old tangent
    and normalised; the first corrector works on the hyperplane orthogonal to t_new
    through that start, so it cannot fall back onto the old branch near u*.
    """
    p = _check_switch_point(special_point)
    n = len(p.u)
    phi = _critical_vector(p, mode)
    weights = options.pop("weights", p.weights)
    if weights is None:
        weights = problem.dof_weights() if hasattr(problem, "dof_weights") else np.ones(n)
    weights = np.broadcast_to(np.asarray(weights, float), (n,))
    lam_scale = options.pop("parameter_scale", p.parameter_scale)
    if not (np.isfinite(lam_scale) and lam_scale > 0):
        raise ValueError(f"parameter_scale must be a finite number > 0, got {lam_scale}")
    wl = 1.0 / lam_scale**2

    def dot(au, al, bu, bl):
        return float(au @ (weights * bu)) / n + wl * al * bl

    tu, tl = p.tangent
    tnorm = math.sqrt(dot(tu, tl, tu, tl))
    tu, tl = tu / tnorm, tl / tnorm
    proj = dot(phi, 0.0, tu, tl)
    nu_, nl = phi - proj * tu, -proj * tl
    nn = math.sqrt(max(dot(nu_, nl, nu_, nl), 0.0))
    if not nn > 0:
        raise ValueError("the chosen mode is parallel to the old branch's tangent")
    nu_, nl = nu_ / nn, nl / nn
    if amplitude is None:
        amplitude = ds if ds is not None else 0.1
    a = float(amplitude) * (1.0 if sign >= 0 else -1.0)
    if not (math.isfinite(a) and a != 0):
        raise ValueError(f"amplitude must be a finite number != 0 (the jump onto the new branch), got {amplitude}")
    if ds is None:
        ds = abs(a) if a != 0 else 0.1
    s_ = 1.0 if a >= 0 else -1.0
    u_start = p.u + a * nu_
    lam_start = p.parameter + a * nl
    branch = continuation(problem, u_start, lam_start, ds=ds, initial_tangent=(s_ * nu_, s_ * nl),
                          weights=weights, parameter_scale=lam_scale,
                          label=label or f"from {p.label} at {p.parameter:.6g}", **options)
    branch.origin = p
    return branch


def _check_switch_point(p):
    """``p`` if it is a located branch point with critical modes, else a clear error."""
    if not isinstance(p, SpecialPoint):
        raise TypeError(f"special_point must be a SpecialPoint (from branch.special_points), got {type(p).__name__}")
    if p.kind not in ("branch", "possible_branch"):
        raise ValueError(f"branch switching needs a branch point, got a {p.kind!r} point "
                         f"(at a fold the branch turns; continue through it instead)")
    if not p.located or p.modes.shape[1] == 0:
        raise ValueError(f"the branch point between parameters {p.bracket[0]:.8g} and {p.bracket[1]:.8g} was detected "
                         f"but not located, so it has no critical mode to switch along ({p.info.get('reason', '')}); "
                         "follow the branch again with a smaller ds_max")
    return p


def _critical_vector(p, mode):
    """The vector of unknowns to switch along: a critical mode, a combination of them, or ``mode`` itself."""
    n = len(p.u)
    if mode is None:
        phi = p.modes[:, 0]
    elif np.ndim(mode) == 0:
        i = int(mode)
        if not 0 <= i < p.modes.shape[1]:
            raise ValueError(f"mode index must be in 0..{p.modes.shape[1] - 1}, got {mode}")
        phi = p.modes[:, i]
    else:
        coeffs = np.asarray(mode, float).ravel()
        if len(coeffs) == p.modes.shape[1]:
            phi = p.modes @ coeffs
        elif len(coeffs) == n:
            phi = coeffs
        else:
            raise ValueError(f"mode must have {p.modes.shape[1]} coefficients (the multiplicity) or {n} "
                             f"entries (a vector of unknowns), got {len(coeffs)}")
    return phi
