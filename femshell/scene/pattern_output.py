"""Files of a pattern continuation (:func:`femshell.coupled.pattern_continuation.continue_pattern`).

In ``directory``, with ``<label>`` the branch's label:

* ``<label>-branch.csv`` and ``<label>-branch.json``: one row per point (parameter, max c, patterned
  area, spot radius, number of spots, the leading μ's of the coupled dynamics, stable, sign of det J,
  special-point label); the JSON also holds the status and message;
* ``<label>-special-points.json`` and ``<label>-special-NN-<kind>.vtu``: every special point's state on
  its deformed surface (c, H, displacement) with its critical mode (``mode_0_c``, ``mode_0_normal``,
  ``mode_0_displacement``: J's null vector split into concentration and shape, max |δc| = 1);
* ``<label>-special-NN-<kind>-mode.png``: the critical mode's c and normal displacement (``pictures``);
* ``<label>-diagram-<y>.png``: bifurcation diagrams of max c, spot radius and patterned area against the
  parameter, stable solid, unstable dashed.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import io as fio
from ..analysis.spots import find_spots
from ..coupled.pattern_continuation import PARAMETERS, critical_mode_fields
from ..io.branches import _slug
from ..mesh.io import write_mesh

__all__ = ["write_pattern_branch", "pattern_measures", "DIAGRAM_COLUMNS"]

#: the columns drawn against the parameter, one diagram each
DIAGRAM_COLUMNS = {"max_c": "max c", "spot_radius": "spot radius", "patterned_area": "patterned area (c > c*)"}


def pattern_measures(problem, z) -> dict:
    """Columns of a branch row (``record`` of :func:`~femshell.coupled.pattern_continuation.continue_pattern`):
    max c, the patterned area A_l = |{c > c*}| on the deformed surface (exact for P1 c, no region ignored),
    the number of spots and the spot radius √(A_l/(π N_sp)) (NaN without spots)."""
    u, c = problem.split(z)
    points = problem.shell.positions(u)
    m = find_spots(points, problem.triangles, c, problem.params.c_star, min_area=0.0)
    return {"max_c": float(np.max(c)), "patterned_area": float(m.area_low), "n_spots": int(m.n_spots),
            "spot_radius": float(m.spot_radius)}


def _state_fields(problem, z, modes):
    """(deformed mesh, vertex fields) of the state z and its modes (dict name -> vector of unknowns)."""
    u, c = problem.split(z)
    mesh = problem.shell.mesh
    points = problem.shell.positions(u)
    _, H = problem.growth.mean_curvature(u)
    fields = {"c": c, "H": H, "displacement": points - mesh.points}
    for name, mode in modes.items():
        for key, value in critical_mode_fields(problem, z, mode).items():
            fields[f"{name}_{key[len('mode_'):]}"] = value
    return replace(mesh, points=points), fields


def write_pattern_branch(branch, problem, directory, *, parameter=None, pictures=True) -> dict:
    """Write the files of the module docstring; returns {what: path or list of paths}."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    label = _slug(branch.label)
    out = {"csv": fio.write_branch_csv(branch, directory / f"{label}-branch.csv")}
    rows = [{k: fio.finite_or_none(v) for k, v in r.items()} for r in branch.rows]
    out["json"] = fio.atomic_write_json(directory / f"{label}-branch.json", {
        "branch": branch.label, "parameter": parameter, "status": branch.status, "message": branch.message,
        "rows": rows})
    pictures_of_modes = []

    def mesh_writer(stem, z, modes):
        deformed, fields = _state_fields(problem, z, modes)
        path = stem.with_suffix(".vtu")
        write_mesh(deformed, path, point_data=fields)
        if pictures and "mode_0_c" in fields:
            from ..viz import view_grid     # deferred: pyvista

            pictures_of_modes.append(view_grid(
                deformed.points, deformed.triangles,
                {"mode c": fields["mode_0_c"], "mode w_n": fields["mode_0_normal"]},
                stem.parent / f"{stem.name}-mode.png", title=stem.name))
        return path

    out["special_points"] = fio.write_special_points(branch, directory, mesh_writer=mesh_writer, prefix=label)
    out["mode_pictures"] = pictures_of_modes
    if pictures and len(branch.rows) >= 2:
        from ..viz import bifurcation_diagram       # deferred: matplotlib

        xlabel = PARAMETERS[parameter][0] if parameter in PARAMETERS else "parameter"
        out["diagrams"] = [bifurcation_diagram(branch.table, x="parameter", y=y, path=directory / f"{label}-diagram-{y}.png",
                                               xlabel=xlabel, ylabel=text, title=f"{branch.label}: {text}")
                           for y, text in DIAGRAM_COLUMNS.items()
                           if np.any(np.isfinite(branch.column(y)))]
    return out
