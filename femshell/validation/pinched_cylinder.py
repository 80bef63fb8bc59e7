"""Pinched cylinder with rigid end diaphragms: the membrane–bending benchmark (one-eighth model)."""

from __future__ import annotations

import numpy as np

from ..mesh.generators import cylinder
from ..shell import Material, PointForce, Prescribed, ShellModel, Symmetry, flat_rest_state
from .common import linear_response, order_row
from .framework import Row, timed

NAME = "pinched-cylinder"
DESCRIPTION = "pinched cylinder (R=300, L=600, t=3): deflection under the unit load -> 1.82488e-5"
SOURCE = "MacNeal & Harder, Finite Elem. Anal. Des. 1 (1985) 3; Belytschko et al., CMAME 73 (1989) 25"

R, LENGTH, T, E, NU, LOAD = 300.0, 600.0, 3.0, 3e6, 0.3, 1.0
REFERENCE = 1.82488e-5
LEVELS = {"quick": [15.0, 7.0, 3.0], "full": [40.0, 25.0, 15.0, 10.0, 7.0, 5.0, 3.5, 2.5, 2.0]}


def run(level):
    sizes = LEVELS[level]
    rows = []
    for i, h in enumerate(sizes):
        # one eighth: 0 <= theta <= pi/2, 0 <= z <= L/2; load at theta = 0, z = L/2
        mesh = cylinder(R, LENGTH / 2, edge_length=h, angle_range=(0.0, np.pi / 2))
        tip = int(np.argmin(np.linalg.norm(mesh.points - [R, 0.0, LENGTH / 2], axis=1)))
        with timed() as t:
            model = ShellModel(mesh, Material(E, NU), flat_rest_state(mesh.points, mesh.triangles, T),
                               [Prescribed("bottom", components=(0, 1)), Symmetry("x"), Symmetry("y"),
                                Symmetry("z", LENGTH / 2)],
                               [PointForce(mesh, [tip], (-LOAD / 4, 0.0, 0.0))])
            model.set_rest_state(model.stress_free_rest_state())  # the drawn cylinder is stress free
            w = -linear_response(model)[tip, 0]
        rows.append(Row(f"deflection under load @ h={h}", w, REFERENCE, 0.01 if i == len(sizes) - 1 else None,
                        mesh.n_vertices, t()))
    return rows + order_row("deflection under load", rows)
