"""Circular plate under uniform pressure: centre deflection against Kirchhoff plate theory."""

from __future__ import annotations

import numpy as np

from ..mesh.generators import disk
from ..shell import Clamped, DeadPressure, Material, ShellModel, SimplySupported, flat_rest_state
from .common import linear_response, order_row
from .framework import Row, timed

NAME = "clamped-plate-pressure"
DESCRIPTION = "circular plate, uniform pressure: centre deflection vs q a^4/(64 D) (clamped) and simply supported"
SOURCE = ("Timoshenko & Woinowsky-Krieger, Theory of Plates and Shells (1959), sec. 62-63: "
          "w0 = q a^4/(64 D) clamped, q a^4 (5+nu)/(64 D (1+nu)) simply supported")

RADIUS, THICKNESS, NU, PRESSURE = 1.0, 0.01, 0.3, 1e-9
LEVELS = {"quick": [0.2, 0.1, 0.05], "full": [0.2, 0.1, 0.05, 0.035, 0.025, 0.0175, 0.0125]}


def run(level):
    mat = Material(E=1.0, nu=NU)
    D = mat.bending_stiffness(THICKNESS)
    cases = [("clamped", Clamped("outer"), PRESSURE * RADIUS**4 / (64 * D)),
             ("simply supported", SimplySupported("outer"),
              PRESSURE * RADIUS**4 * (5 + NU) / (64 * D * (1 + NU)))]
    sizes = LEVELS[level]
    rows = []
    for i, h in enumerate(sizes):
        mesh = disk(radius=RADIUS, edge_length=h)
        centre = int(np.argmin(np.linalg.norm(mesh.points[:, :2], axis=1)))
        finest = i == len(sizes) - 1
        for label, bc, ref in cases:
            with timed() as t:
                model = ShellModel(mesh, mat, flat_rest_state(mesh.points, mesh.triangles, THICKNESS), [bc],
                                   [DeadPressure(mesh, PRESSURE)])
                w = linear_response(model)[centre, 2]
            rows.append(Row(f"{label} centre deflection / reference @ h={h}", w / ref, 1.0,
                            0.01 if finest else None, mesh.n_vertices, t()))
    for label, _, _ in cases:
        rows += order_row(f"{label} centre deflection / reference", rows)
    return rows
