"""Continuation branches on disk: the branch as CSV and the states at its special points."""

from __future__ import annotations

import csv
import json
from io import StringIO
from pathlib import Path

import numpy as np

from .files import atomic_write_text, finite_or_none

def _csv_cell(v):
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return v


def write_branch_csv(branch, path) -> Path:
    """Write a :class:`~femshell.solvers.continuation.Branch`'s table as CSV, atomically.

    One column per key of any row (first-seen order), one line per row; floats in shortest
    round-trip form, booleans as 0/1, missing values empty. Returns the path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = StringIO()
    cols = branch.columns
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in branch.rows:
        w.writerow([_csv_cell(r.get(k)) for k in cols])
    return atomic_write_text(path, buf.getvalue())


def _slug(s):
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in str(s)) or "branch"


def write_special_points(branch, directory, mesh_writer=None, prefix=None) -> list:
    """Write every special point of ``branch``: ``mesh_writer(stem, u, modes)`` and a JSON summary.

    ``mesh_writer(stem: Path, u: ndarray, modes: dict[str, ndarray])`` gets the file stem
    ``directory/<prefix>-special-<k>-<kind>`` (it adds its own extension), the state and the
    critical modes (``"mode_0"``, ...) as vectors of the problem's unknowns, and may return the
    path it wrote. ``directory/<prefix>-special-points.json`` lists kind, parameter (null for a
    point not located: its ``bracket`` and ``located`` say so), multiplicity, eigenvalues, inertia
    and the file of each point (``prefix`` defaults to the
    branch's label). Returns what the writer returned (the stems when it returned None).
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    prefix = prefix or _slug(branch.label)
    out, meta = [], []
    for k, p in enumerate(branch.special_points):
        stem = directory / f"{prefix}-special-{k:02d}-{p.kind}"
        written = None
        if mesh_writer is not None:
            modes = {f"mode_{j}": p.modes[:, j] for j in range(p.modes.shape[1])}
            written = mesh_writer(stem, p.u, modes)
        out.append(written if written is not None else stem)
        meta.append({"kind": p.kind, "label": p.label, "parameter": finite_or_none(float(p.parameter)), "s": p.s,
                     "multiplicity": p.multiplicity, "n_negative_before": p.n_negative_before,
                     "n_negative_after": p.n_negative_after, "located": p.located,
                     "bracket": [finite_or_none(float(x)) for x in p.bracket],
                     "eigenvalues": [finite_or_none(float(x)) for x in np.asarray(p.eigenvalues)],
                     "step": p.step, "file": str(out[-1])})
    atomic_write_text(directory / f"{prefix}-special-points.json", json.dumps(
        {"branch": branch.label, "status": branch.status, "special_points": meta}, indent=1))
    return out
