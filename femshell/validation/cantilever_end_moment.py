"""Cantilever strip rolled up by an end moment: the large-rotation benchmark with an exact answer.

The literature's answer is the inextensible elastica: a circle of the strip's length turned by
θ0 = 2π M/Mmax. The shell's energy (theory §1.2, ν = 0 here) measures bending against the rest
metric, λ²K² per unit rest length, so the rolled mid-surface also shortens: per unit width
L[(E t/8)(λ² − 1)² + (D/2) λ² K² − M K] is stationary at K = M/(D λ²), λ² = 1 − (t K)²/6 (K = θ/L,
λ the axial stretch). At t/L = 1/120 the tip moves by up to 1.6e-3 relative from the elastica's
(w at 0.75 Mmax): the limit the meshes converge to (at order 2), so the tolerances are against it
(:func:`exact_tip`); the elastica's values are reported beside them for the finest mesh.
"""

from __future__ import annotations

import numpy as np

from ..mesh.generators import strip
from ..shell import Clamped, EdgeMoment, Material, ShellModel, flat_rest_state
from ..solvers.newton import follow_load
from .framework import Row, timed

NAME = "cantilever-end-moment"
DESCRIPTION = "strip L=12, b=1, h=0.1 under an end moment up to Mmax=2 pi EI/L: tip displacements vs exact circle"
SOURCE = ("exact (pure bending into a circular arc of this shell model: theta = 2 pi (M/Mmax)/lambda^2, "
          "lambda^2 = 1 - (t theta/L)^2/6, -u = L - lambda L sin(theta)/theta, w = lambda L (1 - cos(theta))/theta; "
          "the inextensible elastica, lambda = 1, reported beside it); Sze, Liu & Lo, Finite Elem. Anal. Des. 40 "
          "(2004) 1551")

L, WIDTH, THICK, E, NU = 12.0, 1.0, 0.1, 1.2e6, 0.0
LEVELS = {"quick": ([0.125], 8), "full": ([0.5, 0.25, 0.125, 0.0625], 32)}
CHECK = (0.25, 0.5, 0.75, 1.0)  # fractions of Mmax reported
#: the finest mesh's relative error against exact_tip must be below this (the largest error,
#: w at 0.75 Mmax, 2.2e-3 at h = 0.125 and 5.5e-4 at h = 0.0625, falling 4.0x per halving of h)
TOLERANCE = {"quick": 6e-3, "full": 2e-3}


def exact_tip(fraction, thickness=THICK):
    """Tip displacements (−u, w) under M = ``fraction`` · Mmax: the rolled strip of this shell model
    (module docstring), or the inextensible elastica with ``thickness=0``.

    >>> from femshell.validation.cantilever_end_moment import exact_tip
    >>> [round(float(v), 4) for v in exact_tip(0.75, thickness=0.0)]     # L (1 - sin θ/θ), L (1 - cos θ)/θ
    [14.5465, 2.5465]
    >>> [round(float(v), 4) for v in exact_tip(0.75)]                    # t = 0.1: shortened, turned further
    [14.5455, 2.5424]
    """
    theta0 = 2 * np.pi * fraction
    lam2 = 1.0
    for _ in range(50):      # a contraction: the correction is O((t θ/L)²)
        theta = theta0 / lam2
        lam2 = 1.0 - (thickness * theta / L) ** 2 / 6
    lam = np.sqrt(lam2)
    return L - lam * L * np.sin(theta) / theta, lam * L * (1 - np.cos(theta)) / theta


def run(level):
    sizes, n_steps = LEVELS[level]
    EI = E * WIDTH * THICK**3 / 12
    m_max = 2 * np.pi * EI / L
    rows, elastica = [], []
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
            tol = TOLERANCE[level] if finest else None
            rows.append(Row(f"-u tip at M={frac:g} Mmax @ h={h}", u_tip, ref_u, tol, mesh.n_vertices, t()))
            if frac < 1.0:  # at a full circle w returns to 0: judge u only
                rows.append(Row(f"w tip at M={frac:g} Mmax @ h={h}", w_tip, ref_w, tol, mesh.n_vertices, t()))
            if finest:
                elastica.append((frac, u_tip, w_tip, mesh.n_vertices))
    for frac, u_tip, w_tip, n in elastica:     # the literature's inextensible answer, reported
        ref_u, ref_w = exact_tip(frac, thickness=0.0)
        rows.append(Row(f"-u tip at M={frac:g} Mmax, finest mesh, against the inextensible elastica", u_tip, ref_u,
                        None, n, 0.0))
        if frac < 1.0:
            rows.append(Row(f"w tip at M={frac:g} Mmax, finest mesh, against the inextensible elastica", w_tip,
                            ref_w, None, n, 0.0))
    return rows
