"""A sweep's files: its manifest (the points and their state) and its results table, one row per point.

``DIR/manifest.json`` — the sweep's identity (base scene, mode, axes, [set], the points' keys and
values) and each point's state: ``pending``, ``submitted`` (queued or running on a worker),
``finished`` (the run ended: t_final or stationary), ``failed`` (a step failed, or an error outside
the run), ``interrupted``; with the worker, the attempts and the last message. Written atomically
by the client after every change.

``DIR/results.csv`` (and ``results.parquet`` when pyarrow is importable) — one row per point: its key,
the varied values, status, message, then the spec's measures (:data:`~femshell.sweep.spec.MEASURES`),
read from the point's ``summary.json``:

=======================  ===================================================================
t                        time reached (1/β)
stationary               whether the run stopped as stationary before t_final
regime                   :func:`femshell.analysis.classify_regime` of the final pattern
n_spots, n_ridges        regions of c > c* (both kinds), and the elongated ones among them
spot_radius, spacing     the paper's √(A_l/(π N)) and spacing (empty without spots; spacing needs two)
fraction_patterned       A_l / A_tot
max_c, max_H             largest concentration and mean curvature
max_face_angle_deg       largest change of the angle between neighbouring faces (resolution)
steps, wall_s            accepted steps and wall time of the run (all its invocations)
worker                   the Dask worker of the last attempt
=======================  ===================================================================
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from .. import io as fio
from ..analysis import classify_regime
from ..scene.rundir import RunDir
from .spec import MEASURES, short_names

MANIFEST = "manifest.json"
POINTS = "points"
RESULTS = "results"
#: a point's run statuses that end it (the run's FINAL of a time loop)
FINISHED = ("t_final", "stationary", "done")


def read_manifest(out: Path):
    """The manifest of the sweep in ``out`` (None: no sweep there)."""
    p = Path(out) / MANIFEST
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{p}: cannot read the sweep's manifest ({exc})") from None


def write_manifest(out: Path, manifest: dict) -> Path:
    return fio.atomic_write_json(Path(out) / MANIFEST, manifest)


def new_manifest(spec) -> dict:
    return {**spec.as_dict(), "description": spec.description, "measures": spec.measures,
            "plot": list(spec.plot_axes),
            "state": {p.key: {"status": "pending", "attempts": 0} for p in spec.points}}


def point_state(run_status: str) -> str:
    """The manifest state of a point whose run ended with ``run_status``."""
    if run_status in FINISHED:
        return "finished"
    return "interrupted" if run_status in ("interrupted", "paused") else "failed"


def measures_of(summary: dict | None) -> dict:
    """Every measure of :data:`MEASURES` that a run's ``summary.json`` gives (None where it has none)."""
    fin = (summary or {}).get("final") or {}
    pat = fin.get("pattern") or {}
    row = {m: None for m in MEASURES}
    if not fin:
        return row
    row.update(t=fin.get("t"), stationary=fin.get("stationary"), n_spots=pat.get("n_spots"),
               spot_radius=pat.get("spot_radius"), spacing=pat.get("spacing") if (pat.get("n_spots") or 0) > 1 else None,
               fraction_patterned=pat.get("fraction_patterned"), n_ridges=pat.get("n_ridges"), max_c=fin.get("max_c"),
               max_H=fin.get("max_H"), max_face_angle_deg=fin.get("max_fold_change_deg"), steps=summary.get("steps"),
               wall_s=summary.get("wall_s"))
    if pat:
        row["regime"] = classify_regime(pat)
    return row


def rows(out: Path, manifest: dict) -> list:
    """The results table's rows, one per point in the spec's order."""
    names = short_names(manifest["axes"])
    table = []
    for p in manifest["points"]:
        st = manifest["state"].get(p["key"], {})
        summ = RunDir(Path(out) / POINTS / p["key"]).summary()
        meas = measures_of(summ)
        meas["worker"] = st.get("worker")
        row = {"key": p["key"], **{names[a]: p["values"][a] for a in manifest["axes"]},
               "status": (summ or {}).get("status") or st.get("status"),
               "message": st.get("message") or (summ or {}).get("message")}
        row.update({m: meas[m] for m in manifest["measures"]})
        table.append(row)
    return table


def _cell(v):
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return v


def write_results(out: Path, table: list) -> list:
    """``results.csv`` (and ``results.parquet`` when pyarrow is importable) from the rows; the paths written."""
    out = Path(out)
    buf = io.StringIO()
    cols = list(table[0]) if table else ["key"]
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in table:
        w.writerow([_cell(r.get(c)) for c in cols])
    paths = [fio.atomic_write_text(out / f"{RESULTS}.csv", buf.getvalue())]
    try:
        import pyarrow as pa      # deferred: optional, and a large import
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    try:
        tab = pa.Table.from_pylist([{c: r.get(c) for c in cols} for r in table])
    except (pa.ArrowInvalid, pa.ArrowTypeError):      # a column of mixed types (an axis of 1 and 0.5, or of words)
        tab = pa.Table.from_pydict({c: _one_type([r.get(c) for r in table]) for c in cols})
    paths.append(fio.atomic_write(out / f"{RESULTS}.parquet", lambda p: pq.write_table(tab, p)))
    return paths


def _one_type(values: list) -> list:
    """A column's values as floats when all are numbers, else as strings (None kept)."""
    given = [v for v in values if v is not None]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in given):
        return [None if v is None else float(v) for v in values]
    return [None if v is None else str(v) for v in values]
