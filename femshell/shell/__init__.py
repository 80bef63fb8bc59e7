"""The geometrically nonlinear Kirchhoff–Love shell (design.md 1.2): element, rest state,
boundary conditions, loads and the assembled model."""

from .boundary import Clamped, Prescribed, SimplySupported, Symmetry, rigid_body_pins
from .loads import (AreaLoad, DeadLoad, DeadPressure, EdgeForce, EdgeMoment, FollowerPressure,
                    PointForce)
from .model import Material, ShellModel
from .rest_state import RestState, flat_rest_state, metric, natural_curvature, uniform_growth

__all__ = ["ShellModel", "Material", "RestState", "flat_rest_state", "natural_curvature",
           "uniform_growth", "metric", "Clamped", "SimplySupported", "Symmetry", "Prescribed",
           "rigid_body_pins", "DeadLoad", "PointForce", "AreaLoad", "EdgeForce", "DeadPressure",
           "FollowerPressure", "EdgeMoment"]
