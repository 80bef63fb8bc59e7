r"""Exchange of end states between neighbouring radii of the disk study.

Each case's end state is carried to the next smaller and the next larger R2 among the cases of its h and
resolution (:func:`neighbour_pairs`): swept in R2 at ε = 0.5 on its own mesh in steps of ``EXCHANGE_STEP`` · h
(:func:`~femshell.validation.disk.branches.sweep_radius`: a slowly growing or shrinking disk keeps its n-branch while that is stable),
interpolated onto the neighbour's mesh (:meth:`~.model.Disk.carried`), relaxed there by stable Newton in bounded
steps (``CARRY_MAX_STEP``) and checked as a case's end state. A case counts the lowest-energy result among its own
end state and those carried to it (:func:`~.measures.with_carried`): a state the snap at one R2 misses is found
there when it is a neighbour's end state.
"""

from __future__ import annotations

import json
import math

import numpy as np

from ...io import save_checkpoint
from ...shell.element import element_threads
from ..common import saved_state
from .branches import _quiet, stable_state, sweep_radius
from .cases import _case_disk, _case_meta, _in_workers, carried_checkpoint, case_checkpoint, check_saved, solve_case
from .measures import with_carried
from .model import EPS_END

#: R2/h step of the sweep (:func:`sweep_radius`) that carries a case's end state to the next R2 of its series
#: (the R2 studies' step: R2 by 0.0625 at h = 0.25)
EXCHANGE_STEP = 0.25


#: the carried state's relaxation on the neighbour's mesh takes steps of at most this · h (max-norm: positions,
#: and the dimensionless edge unknowns). Interpolated onto another mesh a wrinkled state gains mesh-scale kinks;
#: full Newton steps from there can cross saddles into an over-folded state, bounded steps relax it without one
CARRY_MAX_STEP = 0.08


def neighbour_pairs(cases):
    """(source, target) pairs of cases whose end states are exchanged (:func:`carried_to_neighbour`): each case
    and the next larger R2 among the cases of its h and resolution (one mesh density relative to R2), both ways.

    >>> neighbour_pairs([(2.0, 3.0, 8), (2.0, 4.0, 8), (2.0, 8.0, 16), (0.25, 3.0, 32)])
    [((2.0, 3.0, 8), (2.0, 4.0, 8)), ((2.0, 4.0, 8), (2.0, 3.0, 8))]
    """
    series = {}
    for c in cases:
        series.setdefault((c[0], c[2]), []).append(c)
    pairs = []
    for group in series.values():
        group = sorted(group, key=lambda c: c[1])
        for a, b in zip(group, group[1:]):
            pairs += [(a, b), (b, a)]
    return pairs


def exchange_radii(R2_from, R2_to, h, step=EXCHANGE_STEP):
    """Equal radius steps of at most ``step`` · h from R2_from (excluded) to R2_to (included).

    >>> exchange_radii(3.0, 2.5, 0.25)
    [2.9375, 2.875, 2.8125, 2.75, 2.6875, 2.625, 2.5625, 2.5]
    """
    n = max(1, math.ceil(abs(R2_to - R2_from) / (step * h) - 1e-9))
    return [round(R2_from + (R2_to - R2_from) * k / n, 12) for k in range(1, n + 1)]


def carried_to_neighbour(d_from, u_from, d_to, log=None, checkpoint=None, meta=None):
    """The end state u_from of the case on disk ``d_from`` carried to the neighbouring case's disk ``d_to`` (the
    same h, another R2): swept in R2 at ε = 0.5 on its own mesh (:func:`sweep_radius`, :func:`exchange_radii`),
    so that it follows its n-branch while that is stable as a slowly growing disk would, then carried to d_to's
    mesh (:meth:`Disk.carried`), relaxed there by stable Newton in steps of at most ``CARRY_MAX_STEP`` · h and
    checked as a case's final state.

    Four relaxations from the snap are a sample of the many stable states past it (:mod:`femshell.validation.disk.branches`, step 3);
    the neighbours' states, carried over, are more of them. Returns (u on d_to, candidate: from_R2, count, rim,
    energy, result, n_negative, residual, over_folded, largest_turn). With ``checkpoint`` (an .npz path) the
    sweep is saved step by step beside it (``sweep-`` + its name, resumed) and the result in it (read back
    by a later call with the same ``meta``, :func:`carried_meta`).
    """
    state = saved_state(checkpoint, meta) if checkpoint is not None else None
    if state is not None:
        u, candidate = np.array(state["u"]), json.loads(str(state["candidate"]))
        check_saved(d_to, u, candidate, "n_negative", checkpoint)
        return u, candidate
    log = log or _quiet
    sweep_ck = None if checkpoint is None else checkpoint.with_name("sweep-" + checkpoint.name)
    radii = exchange_radii(d_from.R2, d_to.R2, d_from.h)
    _, states = sweep_radius(d_from, u_from, radii, log=log, checkpoint=sweep_ck, meta=meta)
    u, _ = stable_state(d_to.problem, d_to.carried(d_from, states[-1]), EPS_END, 600, log,
                        at=f"eps = {EPS_END:g} (carried from R2 = {d_from.R2:g})", max_step=CARRY_MAX_STEP * d_to.h)
    candidate = dict(from_R2=float(d_from.R2), **d_to.end_state(u, log=log))
    energy = candidate["energy"]
    log(f"    carried from R2 = {d_from.R2:g} to {d_to.R2:g}: {candidate['count']} wrinkles, energy "
        + ("not finite" if energy is None else f"{energy:.8g}") + ", "
        + ("a resolved stable equilibrium" if candidate["result"] else "not a result"))
    if checkpoint is not None and energy is not None:
        save_checkpoint(checkpoint, {"u": np.asarray(u), "candidate": json.dumps(candidate, allow_nan=False)}, meta)
    return u, candidate



def carried_meta(meta_from, meta_to):
    """What a carried state's checkpoint must agree on with the run that reads it back: both cases' metas
    (:func:`_case_meta`), the sweep's step and the relaxation's step bound."""
    return {"from": meta_from, "to": meta_to, "step": EXCHANGE_STEP, "max_step": CARRY_MAX_STEP}


def _carry_in_worker(meta_from, ck_from, meta_to, checkpoint, echo):
    """:func:`carried_to_neighbour` in a worker process, the source state read from its case's checkpoint."""
    tag = f"[h={meta_to['h']:g} R2={meta_from['R2']:g} -> {meta_to['R2']:g}]"
    log = (lambda m: print(f"{tag} {m.strip()}", flush=True)) if echo else None
    d_from, u_from, _ = solve_case(meta_from, ck_from)
    carried_to_neighbour(d_from, u_from, _case_disk(meta_to), log, checkpoint, carried_meta(meta_from, meta_to))


def exchange_states(cfg, solved, checkpoints=None, log=None):
    """Every case's end state carried to its neighbours (:func:`neighbour_pairs`) and the lowest result counted
    (:func:`with_carried`): {case: (disk, u, record)} like :func:`solve_cases`. With ``checkpoints`` each carried
    state is saved there (``carried-…-to-R2….npz``, its sweep beside it) and read back later, and the ones not yet
    saved are computed in worker processes as the cases are."""
    pairs = neighbour_pairs(cfg["cases"])
    metas = {c: _case_meta(*c, cfg) for c in cfg["cases"]}
    path = {}
    if checkpoints is not None:
        path = {(a, b): carried_checkpoint(checkpoints, a, b) for a, b in pairs}
        case_ck = {c: case_checkpoint(checkpoints, c) for c in cfg["cases"]}
        todo = [(a, b) for a, b in pairs if saved_state(path[a, b], carried_meta(metas[a], metas[b])) is None]
        workers = min(len(todo), element_threads())
        if todo and log:
            log(f"  {len(todo)} of {len(pairs)} end states to carry to a neighbouring R2"
                + (f", {workers} at once" if workers > 1 else ""))
        if workers > 1:
            _in_workers(workers, [(_carry_in_worker, metas[a], case_ck[a], metas[b], path[a, b], log is not None)
                                  for a, b in sorted(todo, key=lambda p: (-p[0][1] / p[0][0], -p[0][2]))])
    carried = {c: [] for c in cfg["cases"]}
    for a, b in pairs:
        d_from, u_from, _ = solved[a]
        carried[b].append(carried_to_neighbour(d_from, u_from, solved[b][0], log, path.get((a, b)),
                                               carried_meta(metas[a], metas[b])))
    return {c: (d, *with_carried(u, rec, carried[c])) for c, (d, u, rec) in solved.items()}

