r"""The mechanochemical shell in time (theory §1.1–1.4, §2.8): parameters, initial conditions, time-step
control, the staggered loop and what it reports.

* :mod:`femshell.coupled.parameters`: :class:`MechanochemicalModel` (the paper's defaults, once);
* :mod:`femshell.coupled.initial`: :func:`gaussian_spot`, :class:`InitialSpot`;
* :mod:`femshell.coupled.stepping`: :class:`TimeStepping`, :func:`feedback_gain`,
  :func:`feedback_step_limit`, :func:`stable_extrapolation`, :func:`held_source_error`, :func:`error_step_factor`;
* :mod:`femshell.coupled.records`: :class:`StepRecord`, :class:`RunResult`, :class:`CoupledError`;
* :mod:`femshell.coupled.observers`: :class:`LoopObservers`, the caller's callbacks;
* :mod:`femshell.coupled.equilibrium`: the stable equilibrium of the grown shell (Newton, snaps, ramp);
* :mod:`femshell.coupled.state`: the checkpoint state (``state_dict`` / ``load_state_dict``);
* :mod:`femshell.coupled.loop`: :class:`CoupledLoop`;
* :mod:`femshell.coupled.stationary`: stationary states as one system in (u, c), its exact Jacobian
  (:mod:`femshell.coupled.stationary_jacobian`) and Newton on it (:func:`stationary_state`);
* :mod:`femshell.coupled.stationary_stability`: their stability in the coupled dynamics (:func:`coupled_stability`);
* :mod:`femshell.coupled.pattern_continuation`: their continuation in a model parameter
  (``continue_pattern``, imported from there: it loads the continuation machinery).
"""

from ..growth import REST_CURVATURES, GrowthRestState
from .initial import InitialSpot, gaussian_spot
from .loop import CoupledLoop
from .observers import LoopObservers
from .parameters import MechanochemicalModel
from .records import CoupledError, RunResult, StepRecord
from .state import STATE_VERSION
from .stationary import StationaryProblem, StationaryResult, stationary_state
from .stationary_stability import CoupledStability, coupled_stability
from .stepping import (SOURCE_RULES, STEP_CONTROLS, TimeStepping, error_step_factor, feedback_gain, feedback_step_limit,
                       held_source_error, stable_extrapolation)

__all__ = ["MechanochemicalModel", "GrowthRestState", "InitialSpot", "gaussian_spot", "TimeStepping",
           "StepRecord", "RunResult", "CoupledError", "CoupledLoop", "LoopObservers", "REST_CURVATURES",
           "feedback_gain", "feedback_step_limit", "stable_extrapolation", "SOURCE_RULES", "STATE_VERSION",
           "STEP_CONTROLS", "held_source_error", "error_step_factor",
           "StationaryProblem", "StationaryResult", "stationary_state", "CoupledStability", "coupled_stability"]
