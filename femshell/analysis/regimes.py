r"""The regime of a pattern: decay, a single bulge, spots, ridges, mixed, or uniform (theory §1.1).

The regions are those of :func:`~femshell.analysis.find_spots`: the connected components of
{c > c*} (low contractility Λ, so grown tissue), each labelled "spot" or "ridge" by its
elongation A/(π r_in²). The rules, applied in this order to the pattern at the end of a run:

1. ``decay``: no region with c > c* (nothing grows: the seeded spot died out);
2. ``uniform``: the regions cover at least ``uniform_fraction`` (default 0.9) of the area:
   c > c* nearly everywhere, no pattern of separate regions;
3. ``ridges``: every region is a ridge (elongated lines or bands);
4. ``mixed``: both kinds, at least one ridge and at least one spot;
5. ``single bulge``: exactly one region, a spot;
6. ``spots``: two or more regions, all of them spots.

The classifier reads only the counts and the patterned fraction, so it applies equally to
:class:`~femshell.analysis.PatternMeasures` and to the ``pattern`` table of a run's
``summary.json`` (its ``n_spots``, ``n_ridges``, ``fraction_patterned``).

>>> classify_regime({"n_spots": 0, "n_ridges": 0, "fraction_patterned": 0.0})
'decay'
>>> classify_regime({"n_spots": 12, "n_ridges": 0, "fraction_patterned": 0.24})
'spots'
>>> classify_regime({"n_spots": 3, "n_ridges": 1, "fraction_patterned": 0.3})
'mixed'
"""

from __future__ import annotations

from .._checks import finite, integer
from .spots import PatternMeasures, find_spots

#: every regime :func:`classify_regime` returns, in the order of its rules
REGIMES = ("decay", "uniform", "ridges", "mixed", "single bulge", "spots")
#: a pattern whose regions cover at least this fraction of the area is "uniform"
UNIFORM_FRACTION = 0.9


def _counts(pattern):
    """(n_regions, n_ridges, fraction_patterned) of a PatternMeasures or of its ``as_dict`` table."""
    if isinstance(pattern, PatternMeasures):
        return pattern.n_spots, pattern.n_ridges, pattern.fraction_patterned
    try:
        n, ridges, frac = pattern["n_spots"], pattern["n_ridges"], pattern["fraction_patterned"]
    except (KeyError, TypeError):
        raise ValueError("a pattern is a PatternMeasures or a table with n_spots, n_ridges and "
                         f"fraction_patterned, got {pattern!r}") from None
    n, ridges = integer("pattern n_spots", n, 0), integer("pattern n_ridges", ridges, 0)
    if ridges > n:
        raise ValueError(f"pattern n_ridges = {ridges} exceeds n_spots = {n} (the regions of both kinds)")
    return n, ridges, finite("fraction_patterned", frac, 0.0, 1.0)


def classify_regime(pattern, *, uniform_fraction: float = UNIFORM_FRACTION) -> str:
    """The regime (one of :data:`REGIMES`) of a pattern, by the rules of the module docstring.

    ``pattern``: a :class:`~femshell.analysis.PatternMeasures` or a table with ``n_spots`` (regions of
    both kinds), ``n_ridges`` and ``fraction_patterned`` (A_l / A_tot in [0, 1]), as a run's summary holds.
    """
    uniform_fraction = finite("uniform_fraction", uniform_fraction, 0.0, 1.0)
    n, ridges, frac = _counts(pattern)
    if n == 0:
        return "decay"
    if frac >= uniform_fraction:
        return "uniform"
    if ridges == n:
        return "ridges"
    if ridges:
        return "mixed"
    return "single bulge" if n == 1 else "spots"


def regime_of_field(points, triangles, c, c_star: float, *, uniform_fraction: float = UNIFORM_FRACTION,
                    **spot_options) -> str:
    """:func:`classify_regime` of :func:`~femshell.analysis.find_spots` (``points``, ``triangles``, the
    vertex field ``c``, the threshold ``c_star``; ``spot_options``: its ``min_area``, ``ridge_elongation``)."""
    return classify_regime(find_spots(points, triangles, c, c_star, **spot_options),
                           uniform_fraction=uniform_fraction)
