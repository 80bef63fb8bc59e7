"""The geometrically nonlinear Kirchhoff–Love shell (docs/theory.md §1–§3): material laws, the
mid-edge bending formulation, the element that combines them, rest state, boundary conditions,
loads and the assembled model."""

from .bending import MidEdgeTangent
from .boundary import Clamped, Prescribed, SimplySupported, Symmetry, rigid_body_pins
from .loads import (AreaLoad, DeadLoad, DeadPressure, EdgeForce, EdgeMoment, FollowerPressure,
                    PointForce)
from .materials import MEMBRANE_LAWS, Material, NeoHookean, StVenantKirchhoff
from .model import PrestressWarning, ShellModel
from .rest_state import RestState, flat_rest_state, metric, natural_curvature, uniform_growth

__all__ = ["ShellModel", "PrestressWarning", "Material", "StVenantKirchhoff", "NeoHookean", "MEMBRANE_LAWS", "MidEdgeTangent",
           "RestState", "flat_rest_state", "natural_curvature", "uniform_growth", "metric", "Clamped",
           "SimplySupported", "Symmetry", "Prescribed", "rigid_body_pins", "DeadLoad", "PointForce", "AreaLoad",
           "EdgeForce", "DeadPressure", "FollowerPressure", "EdgeMoment"]
