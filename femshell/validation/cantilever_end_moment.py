"""Cantilever strip rolled up by an end moment: the large-rotation benchmark with an exact answer."""

from __future__ import annotations

import numpy as np

from ..mesh.generators import strip
from ..shell import Clamped, EdgeMoment, Material, ShellModel, flat_rest_state
from ..solvers.newton import follow_load
from .framework import Row, timed

NAME = "cantilever-end-moment"
DESCRIPTION = "strip L=12, b=1, h=0.1 under an end moment up to Mmax=2 pi EI/L: tip displacements vs exact circle"
SOURCE = ("exact (pure bending into a circular arc): theta = 2 pi M/Mmax, -u = L (1 - sin(theta)/theta), "
          "w = L (1 - cos(theta))/theta; Sze, Liu & Lo, Finite Elem. Anal. Des. 40 (2004) 1551")

L, WIDTH, THICK, E, NU = 12.0, 1.0, 0.1, 1.2e6, 0.0
LEVELS = {"quick": ([0.125], 8), "full": ([0.5, 0.25, 0.125, 0.0625], 32)}
CHECK = (0.25, 0.5, 0.75, 1.0)  # fractions of Mmax reported


def exact_tip(fraction):
    theta = 2 * np.pi * fraction
    return L * (1 - np.sin(theta) / theta), L * (1 - np.cos(theta)) / theta


def run(level):
    sizes, n_steps = LEVELS[level]
    EI = E * WIDTH * THICK**3 / 12
    m_max = 2 * np.pi * EI / L
    rows = []
    for i, h in enumerate(sizes):
        mesh = strip(L, WIDTH, edge_length=h, structured=True, diagonal="alternate")
        tip = mesh.topology.boundary_vertex_groups["right"]
        finest = i == len(sizes) - 1
        with timed() as t:
            model = ShellModel(mesh, Material(E, NU), flat_rest_state(mesh.points, mesh.triangles, THICK),
                               [Clamped("left")], [EdgeMoment("right", -m_max / WIDTH)])
            factors = np.linspace(0, 1, n_steps + 1)[1:]
            results = follow_load(model, model.initial_unknowns(), factors, log=None, rtol=1e-8)
        for frac in CHECK:
            k = int(np.argmin(np.abs(factors - frac)))
            x = model.positions(results[k].u)
            u_tip = -(x[tip, 0] - mesh.points[tip, 0]).mean()
            w_tip = (x[tip, 2] - mesh.points[tip, 2]).mean()
            ref_u, ref_w = exact_tip(frac)
            tol = 0.01 if finest else None
            rows.append(Row(f"-u tip at M={frac:g} Mmax @ h={h}", u_tip, ref_u, tol, mesh.n_vertices, t()))
            if frac < 1.0:  # at a full circle w returns to 0: judge u only
                rows.append(Row(f"w tip at M={frac:g} Mmax @ h={h}", w_tip, ref_w, tol, mesh.n_vertices, t()))
    return rows
