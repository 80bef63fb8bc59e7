"""The disk study of the seed paper's wrinkling test (the case :mod:`~femshell.validation.disk_wrinkles`).

* :mod:`~femshell.validation.disk.model`: the disk, its rest state and problem, its states moved between
  meshes and scales;
* :mod:`~femshell.validation.disk.measures`: the wrinkle count, the rim's lobes, which end state counts,
  the paper's counts;
* :mod:`~femshell.validation.disk.branches`: the equilibria followed in ε (continuation, branch switching,
  relaxation) and in R2;
* :mod:`~femshell.validation.disk.cases`: the levels' cases, checkpoints, worker processes, scaled twins;
* :mod:`~femshell.validation.disk.exchange`: end states carried to the neighbouring radii.
"""

from .branches import (DS, DS_MAX, FOLD_COSINE, LOCATE_RTOL, MAX_MODES, MAX_STEPS, MAX_SWITCHES, SWITCH_AMPLITUDE,
                       _follow_branch, _relax, follow, loss_of_stability, pushed_starts, stable_state, sweep_radius)
from .cases import (LEVELS, SAVED_ENERGY_RTOL, WORKER_ENV, _case_disk, _case_meta, carried_checkpoint,
                    case_checkpoint, case_record, check_saved, solve_case, solve_cases, with_twins)
from .exchange import (CARRY_MAX_STEP, EXCHANGE_STEP, carried_meta, carried_to_neighbour, exchange_radii,
                       exchange_states, neighbour_pairs)
from .measures import (COUNT_RADIUS, FLAT_TOL, INNER_RIM_RADII, PAPER_CHANGES, PAPER_R2_RANGE, PAPER_THIN, REL_TOL,
                       SAME_STATE_RTOL, paper_count, select_lowest, with_carried)
from .model import (EPS_END, EQUILIBRIUM_RTOL, NU, OUTER_FACTOR, Disk, eps_scale, magnified, meshed_alike,
                    outer_radius, scaled_problem, svk_ellipticity_stretch, twins, warm_up)

__all__ = ["CARRY_MAX_STEP", "COUNT_RADIUS", "DS", "DS_MAX", "EPS_END", "EQUILIBRIUM_RTOL", "EXCHANGE_STEP",
           "FLAT_TOL", "FOLD_COSINE", "INNER_RIM_RADII", "LEVELS", "LOCATE_RTOL", "MAX_MODES", "MAX_STEPS",
           "MAX_SWITCHES", "NU", "OUTER_FACTOR", "PAPER_CHANGES", "PAPER_R2_RANGE", "PAPER_THIN", "REL_TOL",
           "SAME_STATE_RTOL", "SAVED_ENERGY_RTOL", "SWITCH_AMPLITUDE", "WORKER_ENV", "Disk", "carried_checkpoint",
           "carried_meta", "carried_to_neighbour", "case_checkpoint", "case_record", "check_saved", "eps_scale",
           "exchange_radii", "exchange_states", "follow", "loss_of_stability", "magnified", "meshed_alike",
           "neighbour_pairs", "outer_radius", "paper_count", "pushed_starts", "scaled_problem", "select_lowest",
           "solve_case", "solve_cases", "stable_state", "svk_ellipticity_stretch", "sweep_radius", "twins",
           "warm_up", "with_carried", "with_twins"]
