"""What a frame and a picture of a run show: the fields written per step, the picture's field, the
side view and the rigid alignment of a free shell."""

from __future__ import annotations

import math

import numpy as np



# ----------------------------------------------------------------------------- output fields

def energy_fields(model, u):
    mem, bend = model.energy_parts(u)
    area = np.asarray(model.rest.area, dtype=float)
    return mem / area, bend / area


def frame_fields(wanted, *, model, u, s, H_vertex, c=None, contractility=None):
    """(point_data, cell_data) of one frame, restricted to ``wanted``."""
    pts = model.positions(u)
    pd, cd = {}, {}
    if "c" in wanted and c is not None:
        pd["c"] = c
    if "H" in wanted:
        pd["H"] = H_vertex
    if "Lambda" in wanted and c is not None:
        pd["Lambda"] = contractility(c)
    if "displacement" in wanted:
        pd["displacement"] = pts - model.mesh.points
    if "stretch" in wanted:
        cd["stretch"] = s
    if "thickness" in wanted:
        cd["thickness"] = np.asarray(model.rest.thickness, dtype=float)
    if any(f in wanted for f in ("energy_density", "membrane_energy_density", "bending_energy_density")):
        mem, bend = energy_fields(model, u)
        if "energy_density" in wanted:
            cd["energy_density"] = mem + bend
        if "membrane_energy_density" in wanted:
            cd["membrane_energy_density"] = mem
        if "bending_energy_density" in wanted:
            cd["bending_energy_density"] = bend
    return pts, pd, cd


def rigid_align(X, x):
    """``x`` moved rigidly (rotation + translation, Kabsch) onto the reference ``X`` (for pictures)."""
    X = np.asarray(X, float)
    x = np.asarray(x, float)
    cX, cx = X.mean(axis=0), x.mean(axis=0)
    U, _, Vt = np.linalg.svd((x - cx).T @ (X - cX))
    dd = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1.0, 1.0, dd]) @ Vt
    return (x - cx) @ R + cX


def side_picture(viz, mesh, x, scalars, path, title, cmap):
    """side.png: the side view (coloured by radius) of a curved shell; for a shell that was flat, an
    oblique view (the shape turned 35° about x, then 25° about z) coloured like the top view:
    a strip rolled about y is edge-on in the side view."""
    if not mesh.is_flat():
        return viz.side_view(x, mesh.triangles, path, title=title, cmap=cmap)
    a, b = math.radians(35.0), math.radians(25.0)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    c = x.mean(axis=0)
    xo = (x - c) @ (rz @ rx).T + c
    return viz.side_view(xo, mesh.triangles, path, scalars=scalars, title=f"{title} (oblique view)", cmap=cmap)


def picture_field(name, points, model, u, *, c=None, H=None, s=None, contractility=None):
    if name == "c":
        return "c", c
    if name == "Lambda":
        return "Lambda", contractility(c)
    if name == "H":
        return "H", H
    if name == "displacement":
        return "|displacement|", np.linalg.norm(points - model.mesh.points, axis=1)
    if name == "z":
        return "z", points[:, 2]
    if name == "radius":
        return "radius", np.linalg.norm(points - points.mean(axis=0), axis=1)
    if name == "stretch":
        return "stretch", s
    if name == "thickness":
        return "thickness", np.asarray(model.rest.thickness, float)
    mem, bend = energy_fields(model, u)
    return name, {"energy_density": mem + bend, "membrane_energy_density": mem, "bending_energy_density": bend}[name]
