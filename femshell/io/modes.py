"""Buckling modes on disk: one VTU (ParaView) of the state with each mode as a vertex vector field,
and a CSV of the critical values.

``modes.vtu``: points = the state's positions, point data ``mode_1`` … ``mode_k`` (displacement
vectors, largest length 1; ParaView's *Warp By Vector* shows a mode), triangles as cells. Written
atomically (:mod:`femshell.io.files`).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from .files import atomic_write, atomic_write_text
from .series import _check_field

__all__ = ["write_modes_vtu", "write_buckling_csv"]


def write_modes_vtu(path, points, triangles, modes) -> Path:
    """``modes`` (k, n, 3) vertex displacements of k modes on the state ``points`` (n, 3), ``triangles`` (m, 3)."""
    import meshio      # deferred: meshio loads its format plugins on import

    pts = np.asarray(points, dtype=float)
    n = len(pts)
    pdata = {f"mode_{i + 1}": _check_field("point", f"mode_{i + 1}", d, n, "vertex") for i, d in enumerate(modes)}
    mesh = meshio.Mesh(pts, [("triangle", np.asarray(triangles))], point_data=pdata)
    return atomic_write(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))


def write_buckling_csv(path, parameters, increments) -> Path:
    """``mode, parameter, increment``: one row per mode (the critical parameter p₀ + μ and μ)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["mode", "parameter", "increment"])
    for i, (p, mu) in enumerate(zip(parameters, increments)):
        w.writerow([i + 1, repr(float(p)), repr(float(mu))])
    return atomic_write_text(path, out.getvalue())
