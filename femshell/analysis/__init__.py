"""Measures of fields on a triangulated surface: the seed paper's pattern measures (spots,
ridges, radius and spacing; :mod:`~femshell.analysis.spots`), the regime of a pattern
(:mod:`~femshell.analysis.regimes`), polar profiles (:mod:`~femshell.analysis.profiles`) and
wrinkle counts (:mod:`~femshell.analysis.wrinkles`).

Plain functions over arrays: ``points`` (n, 3), ``triangles`` (m, 3), vertex fields (n,);
lengths and areas in the units of ``points``, angles in radians. Nothing here knows the shell
or the time loop.
"""

from .fields import vertex_areas
from .profiles import PolarProfile, polar_profile
from .regimes import REGIMES, classify_regime, regime_of_field
from .spots import (PatternMeasures, Region, count_spots, find_spots, same_pattern, spot_radius,
                    spot_spacing)
from .wrinkles import azimuthal_power, azimuthal_spectrum, count_wrinkles

__all__ = ["vertex_areas", "spot_radius", "spot_spacing", "Region", "PatternMeasures", "find_spots",
           "count_spots", "same_pattern", "polar_profile", "PolarProfile", "azimuthal_spectrum", "azimuthal_power",
           "count_wrinkles", "REGIMES", "classify_regime", "regime_of_field"]
