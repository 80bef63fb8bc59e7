r"""The disk study's cases: levels, solving each case once, checkpoints, worker processes and scaled twins.

A level lists (h, R2, resolution) cases and the settings they share (``LEVELS``). :func:`solve_cases` solves each
case by :func:`~.branches.follow`, in worker processes of one core each when there are cores to spare; with a
checkpoint directory each finished case is saved there and read back by a later call, checked and counted again
(:func:`check_saved`: a checkpoint whose state does not give its saved numbers is refused), so the rows are this
code's own. A case whose scaled problem (R2/h, R1/R2, mesh) another thinner case already solves takes that case's
end state magnified (:func:`with_twins`, :func:`~.model.twins`).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

from ...io import save_checkpoint
from ...shell.element import EDGE_UNKNOWN, element_threads
from ..common import saved_state
from .branches import follow
from .model import EPS_END, Disk, magnified, outer_radius, warm_up

#: (h, R2, resolution) cases of each level (resolution: edges per R2 along the grown circle; with
#: ``refine_inside`` the whole grown region r < R2 has that edge length) and the membrane law (SVK has no stable
#: state at h = 2, R2 <= 1.5: module docstring of :mod:`~.disk_wrinkles`). The thin disks' rims fold into lobes
#: across r = 0.6-1.0 R2, which needs the grown region refined throughout and, at h = 0.25, resolution 32 (on
#: edge 0.125 the lobes fold within one element row); one resolution gives the thin series one mesh density
#: relative to R2, and at R2 = 4 it would be edge 0.125 again, so the thin series stops at R2 = 3. h = 2 goes
#: past the paper's range to R2 = 24 (R2/h = 12, the thin disk's at R2 = 3): it is a dome up to R2 = 8. Both
#: disks of R2/h = 12 take resolution 32: with R1 = 10 R2 their deeper dome folds past what 24 carries.
#: ``rise_required`` makes the rise with R2 and with 1/h a pass criterion, as issue 4 asks; ``outer_factor``:
#: R1 = max(20, outer_factor · R2); ``pushes``: relaxation starts where the shell snaps
#: (:func:`~.branches.follow`)
LEVELS = {
    "quick": {"cases": [(2.0, 3.0, 5), (2.0, 4.0, 5)], "refine_inside": True, "law": "svk", "outer_factor": 5.0,
              "pushes": 4},
    "full": {"cases": [(2.0, r, 8) for r in (1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5)]
             + [(2.0, 8.0, 16), (2.0, 10.0, 20), (2.0, 12.0, 24)] + [(2.0, r, 32) for r in (16.0, 20.0, 24.0)]
             + [(0.25, r, 32) for r in (2.0, 2.5, 3.0)],
             "refine_inside": True, "law": "neo-hookean", "rise_required": True, "outer_factor": 10.0, "pushes": 4},
}


def case_record(r):
    """The numbers of one :func:`follow` result that the case's rows use (what its checkpoint keeps beside u)."""
    first = r["first"]
    return dict(count=int(r["count"]), rim=[int(r["rim"][0]), float(r["rim"][1])],
                eps_first=None if first is None else float(first.parameter),
                multiplicity=None if first is None else int(first.multiplicity),
                n_first=None if r["n_first"] is None else int(r["n_first"]),
                stretch_first=None if r["stretch_first"] is None else float(r["stretch_first"]),
                switches=len(r["switch_points"]), folds=len(r["folds"]), relaxed=bool(r["relaxed"]),
                n_negative_final=r["n_negative_final"], residual=float(r["residual"]),
                over_folded=int(r["over_folded"]), largest_turn=float(r["largest_turn"]), result=bool(r["result"]),
                energy=float(r["energy"]), wall_s=float(r["wall_s"]), candidates=r["candidates"],
                chosen=int(r["chosen"]))


def _case_meta(h, R2, resolution, cfg):
    """What a case's checkpoint must agree on with the run that reads it back."""
    return {"h": float(h), "R2": float(R2), "resolution": int(resolution), "R1": outer_radius(R2, cfg["outer_factor"]),
            "law": cfg["law"], "refine_inside": bool(cfg["refine_inside"]), "pushes": int(cfg["pushes"]),
            "eps_end": EPS_END, "edge_unknown": EDGE_UNKNOWN}


def _case_disk(meta):
    return Disk(meta["h"], meta["R2"], meta["resolution"], R1=meta["R1"], law=meta["law"],
                refine_inside=meta["refine_inside"])


def solve_case(meta, checkpoint=None, log=None):
    """One case: (disk, u at ε = 0.5, :func:`case_record`). With ``checkpoint`` (an .npz path) a finished case is
    read back from it (no solve; one of another case or setting is refused, ValueError naming the difference), and
    a solved one is saved there."""
    state = saved_state(checkpoint, meta)
    if state is not None:
        d = _case_disk(meta)
        if len(state["u"]) != len(d.model.initial_unknowns()):
            raise ValueError(f"{checkpoint} has {len(state['u'])} unknowns, this mesh "
                             f"{len(d.model.initial_unknowns())}: another mesh generator made it; remove it to start "
                             "afresh")
        record = json.loads(str(state["record"]))
        check_saved(d, state["u"], record, "n_negative_final", checkpoint)
        return d, state["u"], record
    r = follow(meta["h"], meta["R2"], meta["resolution"], log=log, law=meta["law"],
               refine_inside=meta["refine_inside"], R1=meta["R1"], pushes=meta["pushes"])
    record = case_record(r)
    if checkpoint is not None:
        try:        # a state or record with a NaN is not saved (its rows fail): the next call solves it again
            save_checkpoint(checkpoint, {"u": r["u"], "record": json.dumps(record, allow_nan=False)}, meta)
        except ValueError as exc:
            if log:
                log(f"    not checkpointed: {exc}")
    return r["disk"], r["u"], record


#: a saved state's energy, computed again when it is read back, agrees with the saved one to this (relative)
SAVED_ENERGY_RTOL = 1e-9


def check_saved(d, u, saved, negative_key, checkpoint):
    """Check a state u of disk d read back from ``checkpoint`` as a final state (:meth:`Disk.final_check`) and
    count it again: a ValueError naming the difference when its count, negative eigenvalues, being a result or
    energy (to ``SAVED_ENERGY_RTOL``) differ from the ``saved`` numbers (a record, or a carried candidate whose
    negative eigenvalues are under ``negative_key``). So the rows of a resumed run are this code's own, and a
    checkpoint made by other code is refused rather than reported."""
    now = d.end_state(u)
    was = dict(count=saved["count"], n_negative=saved[negative_key], result=bool(saved["result"]))
    differ = {k: (was[k], now[k]) for k in was if was[k] != now[k]}
    if saved["energy"] is not None and not (now["energy"] is not None and abs(now["energy"] - saved["energy"])
                                             <= SAVED_ENERGY_RTOL * abs(saved["energy"])):
        differ["energy"] = (saved["energy"], now["energy"])
    if differ:
        raise ValueError(f"{checkpoint}: its state checked again differs from what it saved (saved, now: {differ}); "
                         "other code made it: remove it to solve the case afresh")


def _solve_case_in_worker(meta, checkpoint, echo):
    """:func:`solve_case` in a worker process; it prints its log lines, prefixed by the case."""
    tag = f"[h={meta['h']:g} R2={meta['R2']:g}]"
    solve_case(meta, checkpoint, log=(lambda m: print(f"{tag} {m.strip()}", flush=True)) if echo else None)


#: the thread counts a case worker runs with: each worker keeps to one core, the cases share the cores
WORKER_ENV = {"FEMSHELL_THREADS": "1", "MKL_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def case_checkpoint(checkpoints, case):
    """Where :func:`solve_cases` keeps the (h, R2, resolution) ``case`` in the directory ``checkpoints``."""
    return checkpoints / f"case-h{case[0]:g}-R2{case[1]:g}-res{case[2]}.npz"


def carried_checkpoint(checkpoints, source, target):
    """Where :func:`exchange_states` keeps the end state of case ``source`` carried to case ``target``."""
    return checkpoints / f"carried-h{source[0]:g}-R2{source[1]:g}-to-R2{target[1]:g}-res{source[2]}.npz"


def solve_cases(cfg, checkpoints=None, log=None):
    """Every case of a level: {(h, R2, resolution): (disk, u, record)}.

    Without ``checkpoints`` (a directory) the cases are solved here one after the other. With it each finished case
    is saved there (``case-h…-R2…-res….npz``) and read back by a later call, and the cases not yet saved are solved
    in as many worker processes as :func:`~femshell.shell.element.element_threads` gives (``FEMSHELL_THREADS=1``:
    one after the other, in this process), each on one core (``WORKER_ENV``), largest R2/h first."""
    metas = {c: _case_meta(*c, cfg) for c in cfg["cases"]}
    if checkpoints is None:
        return {c: solve_case(m, log=log) for c, m in metas.items()}
    path = {c: case_checkpoint(checkpoints, c) for c in cfg["cases"]}
    todo = sorted((c for c in cfg["cases"] if saved_state(path[c], metas[c]) is None),
                  key=lambda c: (-c[1] / c[0], -c[2]))
    workers = min(len(todo), element_threads())
    if todo and log:
        log(f"  {len(todo)} of {len(metas)} cases to solve ({len(metas) - len(todo)} read back from {checkpoints})"
            + (f", {workers} at once" if workers > 1 else ""))
    if workers > 1:
        _in_workers(workers, [(_solve_case_in_worker, metas[c], path[c], log is not None) for c in todo])
    return {c: solve_case(metas[c], path[c], log=log) for c in cfg["cases"]}


def _in_workers(workers, jobs):
    """Run ``jobs`` ((function, *args), in order) in ``workers`` spawned processes of one core each
    (``WORKER_ENV``), every one warmed up first; an error in a job is raised here."""
    saved_env = {k: os.environ.get(k) for k in WORKER_ENV}
    os.environ.update(WORKER_ENV)           # a spawned worker reads these when its libraries load
    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                 initializer=warm_up) as pool:
            for f in [pool.submit(*job) for job in jobs]:
                f.result()
    finally:
        for k, v in saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v



def with_twins(cfg, solved, twin, log=None):
    """Every case of the level ``cfg`` from ``solved`` ({case: (disk, u, record)} of the cases solved) and
    ``twin`` ({case: the case it is solved as}, :func:`twins`): a twin takes its problem's end state
    :func:`magnified` to its own disk, checked there as a final state (:meth:`Disk.final_check`) and counted
    there. Its record keeps the path's numbers (ε of the first bifurcation, switches, folds, the starts' counts,
    the carried states, energies scaled by s³ and radii by s); its final-state numbers become its own, and
    ``twin_of`` names the case solved."""
    out = {}
    for case, rep in twin.items():
        if case == rep:
            out[case] = solved[case]
            continue
        t0 = time.perf_counter()
        d_rep, u_rep, rec_rep = solved[rep]
        d = _case_disk(_case_meta(*case, cfg))
        u = magnified(d_rep, u_rep, d)
        end = d.end_state(u, log=log)
        s = d.h / d_rep.h
        s3 = s ** 3
        rec = dict(rec_rep, twin_of=[rep[0], rep[1]], n_negative_final=end.pop("n_negative"), **end,
                   candidates=[dict(c, energy=None if c["energy"] is None else c["energy"] * s3)
                               for c in rec_rep["candidates"]],
                   carried=[dict(c, energy=None if c["energy"] is None else c["energy"] * s3,
                                 from_R2=c["from_R2"] * s) for c in rec_rep.get("carried", [])],
                   counted_from=None if rec_rep.get("counted_from") is None else rec_rep["counted_from"] * s,
                   wall_s=time.perf_counter() - t0)
        if log:
            log(f"  h={case[0]:g} R2={case[1]:g}: h={rep[0]:g} R2={rep[1]:g}'s end state magnified by "
                f"{s:g}: {rec['count']} wrinkles, "
                + ("a resolved stable equilibrium" if rec["result"] else "not a result"))
        out[case] = (d, u, rec)
    return out

