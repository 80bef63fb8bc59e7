"""Helpers shared by the validation cases."""

from __future__ import annotations

import math

import numpy as np

from ..io import load_checkpoint
from ..solvers.linear import factorize
from .framework import Row


def linear_response(model):
    """Linear (small-displacement) solution: one Newton step from the reference state, K0 du = -g0.

    For the classical linear benchmarks this is exactly the linear-theory answer of the
    same discretisation (the tangent at the undeformed state).
    """
    u0 = model.initial_unknowns()
    du = factorize(model.hessian(u0), kind="spd").solve(-model.gradient(u0))
    return model.positions(u0 + du) - model.mesh.points


def observed_order(n_vertices, errors):
    """Least-squares order p in err ~ h^p with h ~ n^(-1/2); None with fewer than 2 usable points."""
    n = np.asarray(n_vertices, float)
    e = np.asarray(errors, float)
    ok = (n > 0) & (e > 0) & np.isfinite(e)
    if ok.sum() < 2:
        return None
    slope = np.polyfit(np.log(n[ok]), np.log(e[ok]), 1)[0]
    return -2.0 * slope


#: meshes of a series that an order is fitted to: the finest, as validation/convergence.py does (the
#: coarse ones are often not yet in the asymptotic range, and one fit window gives one order)
ORDER_FIT_MESHES = 4


def finest_order(n_vertices, errors, meshes=ORDER_FIT_MESHES):
    """(p, k): :func:`observed_order` fitted to the k ≤ ``meshes`` finest meshes of a series."""
    pairs = sorted((n, e) for n, e in zip(n_vertices, errors) if n > 0 and e > 0 and math.isfinite(e))[-meshes:]
    return (observed_order(*zip(*pairs)) if pairs else None), len(pairs)


def order_row(quantity, rows):
    """A row reporting the convergence order fitted to the finest (up to ORDER_FIT_MESHES) rows whose
    quantity is ``quantity @ ...``."""
    sel = [r for r in rows if r.quantity.split(" @")[0] == quantity and r.rel_error is not None]
    p, k = finest_order([r.n_vertices for r in sel], [r.rel_error for r in sel])
    return [] if p is None else [Row(f"observed order of {quantity} (finest {k} meshes)", p)]


def saved_state(checkpoint, meta, keys=()):
    """The saved state of the checkpoint a run resumes from (or its ``.prev``), None when there is none.
    ValueError naming the difference when the saved meta differs from ``meta`` in any of its keys or in ``keys``
    (keys the current run may leave out of its meta)."""
    if checkpoint is None or not (checkpoint.exists() or checkpoint.with_name(checkpoint.name + ".prev").exists()):
        return None
    state, saved = load_checkpoint(checkpoint)
    differ = {k: (saved.get(k), meta.get(k)) for k in {*meta, *keys} if saved.get(k) != meta.get(k)}
    if differ:
        raise ValueError(f"{checkpoint} belongs to another run (saved, now: {differ}); remove it to start afresh")
    return state
