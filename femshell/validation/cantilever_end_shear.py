"""Cantilever strip under a tip shear force: the large-deflection elastica benchmark."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_bvp

from ..mesh.generators import strip
from ..shell import Clamped, EdgeForce, Material, ShellModel, flat_rest_state
from ..solvers.newton import follow_load
from .framework import Row, timed

NAME = "cantilever-end-shear"
DESCRIPTION = "strip L=10, b=1, h=0.1, tip force P up to 4 EI/L^2: tip displacements vs the elastica"
SOURCE = ("elastica solved here as a boundary-value problem (scipy solve_bvp); Sze, Liu & Lo, Finite Elem. "
          "Anal. Des. 40 (2004) 1551 list -u = 3.29, w = 6.70 at P = 4")

L, WIDTH, THICK, E, NU = 10.0, 1.0, 0.1, 1.2e6, 0.0
P_MAX = 4.0  # in units of EI / L^2 (= 1 here)
LEVELS = {"quick": ([0.5], 8), "full": ([1.0, 0.5, 0.25, 0.125], 16)}
CHECK = (1.0, 2.0, 4.0)


def elastica_tip(p):
    """Tip (-u, w) of an inextensible cantilever, EI theta'' = -P cos(theta), theta(0) = 0, theta'(L) = 0."""
    s = np.linspace(0, L, 401)

    def rhs(s, y):  # y = theta, theta', x, z ; EI = 1 with P in EI/L^2 units scaled by L^2
        return np.vstack([y[1], -p / L**2 * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])

    def bc(ya, yb):
        return np.array([ya[0], yb[1], ya[2], ya[3]])

    guess = np.zeros((4, s.size))
    guess[2] = s
    sol = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=100000)
    return L - sol.y[2, -1], sol.y[3, -1]


def run(level):
    sizes, n_steps = LEVELS[level]
    EI = E * WIDTH * THICK**3 / 12
    rows = []
    for i, h in enumerate(sizes):
        mesh = strip(L, WIDTH, edge_length=h, structured=True, diagonal="alternate")
        tip = mesh.topology.boundary_vertex_groups["right"]
        finest = i == len(sizes) - 1
        with timed() as t:
            force = P_MAX * EI / L**2 / WIDTH  # per unit length of the tip edge
            model = ShellModel(mesh, Material(E, NU), flat_rest_state(mesh.points, mesh.triangles, THICK),
                               [Clamped("left")], [EdgeForce(mesh, "right", (0.0, 0.0, force))])
            factors = np.linspace(0, 1, n_steps + 1)[1:]
            results = follow_load(model, model.initial_unknowns(), factors, log=None, rtol=1e-8)
        for p in CHECK:
            k = int(np.argmin(np.abs(factors * P_MAX - p)))
            x = model.positions(results[k].u)
            ref_u, ref_w = elastica_tip(p)
            tol = 0.01 if finest else None
            rows.append(Row(f"-u tip at P={p:g} @ h={h}", -(x[tip, 0] - mesh.points[tip, 0]).mean(), ref_u, tol,
                            mesh.n_vertices, t()))
            rows.append(Row(f"w tip at P={p:g} @ h={h}", (x[tip, 2] - mesh.points[tip, 2]).mean(), ref_w, tol,
                            mesh.n_vertices, t()))
    rows.append(Row("elastica -u tip at P=4 (check of the reference)", elastica_tip(4.0)[0], 3.289, 1e-3))
    rows.append(Row("elastica w tip at P=4 (check of the reference)", elastica_tip(4.0)[1], 6.700, 1e-3))
    return rows
