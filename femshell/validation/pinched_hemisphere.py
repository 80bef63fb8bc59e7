"""Pinched hemisphere with an 18° hole: the benchmark of nearly inextensional bending with large
rigid rotations of its parts (MacNeal & Harder's test 4, here in the linear range).

A hemisphere of radius R = 10 and thickness t = 0.04 (E = 6.825e7, ν = 0.3) without the cap of
polar angle < 18° is loaded at the equator by four radial point forces of F = 2, 90° apart: outward at
azimuth 0° and 180°, inward at 90° and 270°. Both edges are free; the load is self-equilibrated, so
only the rigid motions are removed (:func:`femshell.shell.rigid_body_pins`, a statically determinate
support). The whole hemisphere is modelled, so that no symmetry condition enters; the equator is
meshed with a multiple of four segments so that each force acts at a vertex.

Measured: the outward displacement under the load at azimuth 0°, as half the change of the distance
between the two outward-loaded points, which no rigid motion changes (the support's pins sit where
the symmetric answer moves too, so a displacement read at one point would include the rigid motion
that holds them).

Reference: MacNeal & Harder's 0.094, the target of their test; they say it was computed for a
slightly different configuration, the hemisphere with the hole closed. Many later papers and
benchmark collections use 0.0924 (Simo, Fox & Rifai 1990) for thin and thick elements alike; it is
reported beside it. This element converges to 1.2 % above 0.0924 (transverse shear, which this
Kirchhoff–Love model lacks, would make a shell softer, not stiffer, so that is not the gap). The one
converged Kirchhoff–Love figure found for the holed hemisphere agrees with ours: Abaqus's eight-node
curved Kirchhoff element, 0.09345, 0.09353, 0.09357 on meshes halved twice, extrapolated 0.093597
(quoted in the hemisphere example of Krysl's FinEtoolsFlexStructures.jl; 0.1 % from our 0.09350).
The tolerance, 1 % against 0.094, is about twice this element's converged error (0.53 %).
"""

from __future__ import annotations

import math

import numpy as np

from ..mesh.generators import hemisphere
from ..shell import Material, PointForce, ShellModel
from .common import linear_response
from .framework import Row, timed

NAME = "pinched-hemisphere"
DESCRIPTION = ("hemisphere with an 18 deg hole (R=10, t=0.04), four radial point loads F=2 at the equator: "
               "displacement under the load vs 0.094 (MacNeal-Harder) and 0.0924")
SOURCE = ("MacNeal & Harder, Finite Elem. Anal. Des. 1 (1985) 3 (test 4, target 0.094); 0.0924 of Simo, Fox & "
          "Rifai, CMAME 79 (1990) 21, used by many later papers, reported")

R, T, E, NU, F, HOLE_DEG = 10.0, 0.04, 6.825e7, 0.3, 2.0, 18.0
REFERENCE, CONVERGED_ELEMENTS = 0.094, 0.0924
#: equator segments per mesh (multiples of four: a vertex under every force)
LEVELS = {"quick": [64, 92, 128], "full": [64, 92, 128, 180, 252, 360]}
#: the finest mesh's relative error against 0.094 must be below this (measured 0.53 % at 23 446 vertices,
#: 0.55 % at the quick level's 3 038)
TOLERANCE = 0.01


def _mesh(segments):
    """The hemisphere whose equator gmsh divides into ``segments`` edges (it rounds 2πR/h up)."""
    h = 2 * math.pi * R / (segments - 0.5)
    mesh = hemisphere(R, edge_length=h, hole_angle=math.radians(HOLE_DEG))
    at = [np.array([R * math.cos(a), R * math.sin(a), 0.0]) for a in (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)]
    idx = [int(np.argmin(np.linalg.norm(mesh.points - p, axis=1))) for p in at]
    off = max(float(np.linalg.norm(mesh.points[i] - p)) for i, p in zip(idx, at))
    if off > 1e-6 * R:
        raise RuntimeError(f"no vertex under a load (off by {off:.3g}) at edge length {h:.4g}: gmsh divided the "
                           "equator differently; choose another segment count")
    return mesh, h, idx


def run(level):
    segments = LEVELS[level]
    rows, previous = [], None
    for i, n in enumerate(segments):
        mesh, h, (a, b, c, d) = _mesh(n)
        with timed() as t:
            loads = [PointForce(mesh, [a], (F, 0.0, 0.0)), PointForce(mesh, [c], (-F, 0.0, 0.0)),
                     PointForce(mesh, [b], (0.0, -F, 0.0)), PointForce(mesh, [d], (0.0, F, 0.0))]
            model = ShellModel(mesh, Material(E, NU), T, [], loads)   # the drawn hemisphere is stress free
            disp = linear_response(model)
        outward = 0.5 * (disp[a, 0] - disp[c, 0])       # half the change of the distance, as a rigid motion leaves it
        inward = -0.5 * (disp[b, 1] - disp[d, 1])
        finest = i == len(segments) - 1
        rows.append(Row(f"displacement under the load @ h={h:.4g}", outward, REFERENCE, TOLERANCE if finest else None,
                        mesh.n_vertices, t()))
        if previous is not None:
            rows.append(Row(f"change of the displacement from the previous mesh @ h={h:.4g}",
                            outward - previous, None, None, mesh.n_vertices, 0.0))
        previous = outward
    rows += [Row("finest mesh's displacement against 0.0924 (Simo, Fox & Rifai)", outward,
                 CONVERGED_ELEMENTS, None, mesh.n_vertices, 0.0),
             # the answer's symmetry: the inward-loaded points move as much (measured 1.3e-4 off at 3 038 vertices,
             # 3.6e-5 at 5 943)
             Row("inward / outward displacement under the loads, finest mesh", inward / outward, 1.0, 5e-4,
                 mesh.n_vertices, 0.0)]
    return rows
