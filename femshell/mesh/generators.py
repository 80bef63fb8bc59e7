"""Mesh generators for the standard femshell geometries (gmsh, OpenCASCADE kernel).

Every generator returns a :class:`~femshell.mesh.SurfaceMesh` with

* only the vertices used by triangles, numbered compactly in gmsh node order;
* femshell's orientation: outward normals on the sphere and
  the hemisphere (away from the centre), away from the axis on the cylinder,
  +z on flat meshes (checked per triangle against the known outward direction
  and flipped where needed);
* named boundary curves as vertex-pair segments taken from gmsh's line
  elements of the boundary curves; boundary segments run with the surface on
  their left (counter-clockwise seen from the normal side);
* ``name``: a short description with the parameters.

Lengths are in design units (the cell size); angles in
radians. Meshes are deterministic for a given ``seed``: gmsh runs on one
thread with ``Mesh.RandomSeed = seed`` and a fixed algorithm (Frontal-Delaunay).

Resolution is given either as a target ``edge_length`` or as a target number
of vertices ``n_vertices``; the conversion between them is calibrated on
measured gmsh meshes (see :func:`edge_length_for_vertices`). When neither is
given, the edge length defaults to a tenth of the characteristic size
(radius, shorter side, ring width).

gmsh is not thread-safe: call the generators from one thread at a time. If
gmsh is already initialised (by the caller), the generators work in a
temporary model of that session, restore the options they change and leave
the session running; otherwise they initialise gmsh and finalise it again.

Example
-------
>>> from femshell.mesh.generators import sphere
>>> m = sphere(radius=30.0, n_vertices=2500)
>>> m.topology.euler_characteristic, m.topology.is_closed
(2, True)
"""

from __future__ import annotations

import math

import numpy as np

from .gmsh_session import (MESH_ALGORITHM, _away_from_axis, _extract, _finish, _generate,  # noqa: F401
                           _gmsh_model, _on, _radial, _uniform_size, _up)
from .surface import SurfaceMesh

__all__ = ["sphere", "disk", "plate", "strip", "annulus", "cylinder", "hemisphere",
           "edge_length_for_vertices"]

#: Largest mesh a generator will try to build (a guard against typos such as edge_length=1e-4).
MAX_VERTICES = 5_000_000
#: Range of the geometric sizes (radius, length, width) the generators accept (see ``_size``).
MIN_SIZE, MAX_SIZE = 1e-6, 1e5

# Calibration of n_vertices <-> edge_length (measured with gmsh 4.15, algorithm 6, for
# 500..100 000 vertices, see validation/benchmarks/mesh_timing.py): a surface of area A
# meshed with target edge length h gets  V = factor * 2A / (sqrt(3) h^2) + linear / h
# vertices, where the first term counts equilateral triangles (2 per vertex) and the
# linear term is the excess along curves (boundaries, seams, poles),
# linear = sum(coefficient * length). gmsh packs doubly curved surfaces slightly denser.
AREA_FACTOR = 1.022           # sphere, hemisphere
AREA_FACTOR_FLAT = 1.0        # plane and cylinder (developable surfaces)
SPHERE_LINEAR = 4.96          # times the radius: seam + pole excess of the OCC sphere
BOUNDARY_LINEAR = 0.7         # times the boundary length (extra vertices along boundaries)


# ----------------------------------------------------------------------------- validation

def _positive(name, value, upper=None, upper_text=None, lower=0.0, closed=True):
    """``value`` as a float in (lower, upper] (``closed=False``: (lower, upper)), or a ValueError
    naming ``name`` and the range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    hi = "inf" if upper is None else (upper_text or f"{upper:g}")
    bracket = "]" if upper is not None and closed else ")"
    if (not math.isfinite(v) or v <= lower or (upper is not None and v > upper)
            or (upper is not None and not closed and v >= upper)):
        raise ValueError(f"{name} must be in ({lower:g}, {hi}{bracket}, got {value!r}")
    return v


def _size(name, value):
    """A geometric size (radius, length, width) in [MIN_SIZE, MAX_SIZE], or a ValueError naming the range.

    gmsh works with an absolute geometric tolerance: outside this range (a sphere of radius 1e-8
    comes out non-manifold, one of 1e6 without triangles) the generators fail, so a size there asks
    for other units instead.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not MIN_SIZE <= v <= MAX_SIZE:       # NaN and inf included
        raise ValueError(f"{name} must be in [{MIN_SIZE:g}, {MAX_SIZE:g}] (the range the mesh generator handles: "
                         f"choose units that bring the geometry into it), got {value!r}")
    return v


def _seed(seed):
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**31:
        raise ValueError(f"seed must be an integer in [0, 2**31), got {seed!r}")
    return int(seed)


def _vertex_count(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 10 <= value <= MAX_VERTICES:
        raise ValueError(f"{name} must be an integer in [10, {MAX_VERTICES}], got {value!r}")
    return int(value)


def edge_length_for_vertices(n_vertices, area, linear=0.0, area_factor=AREA_FACTOR):
    """Target edge length (design units) that gives about ``n_vertices`` vertices.

    Solves ``n = area_factor * 2 area / (sqrt(3) h^2) + linear / h`` for h, the
    vertex count of a Frontal-Delaunay mesh of near-equilateral triangles (two
    triangles per vertex) plus the excess along curves. ``area`` in length^2,
    ``linear`` in length (e.g. ``BOUNDARY_LINEAR * perimeter``).

    >>> round(edge_length_for_vertices(2500, 4 * math.pi * 30**2, 4.96 * 30), 3)
    2.341
    """
    a = area_factor * 2.0 * area / math.sqrt(3.0)
    # a x^2 + linear x - n = 0 with x = 1/h; positive root
    x = (-linear + math.sqrt(linear * linear + 4.0 * a * n_vertices)) / (2.0 * a)
    return 1.0 / x


def _vertices_for_edge_length(h, area, linear=0.0, area_factor=AREA_FACTOR):
    # (area / h) / h: h * h underflows to 0 for h below 1e-162
    return area_factor * 2.0 * (area / h) / (math.sqrt(3.0) * h) + linear / h


def _resolution(edge_length, n_vertices, area, linear, size, size_name, area_factor=AREA_FACTOR_FLAT,
                default_divisions=10):
    """Resolve (edge_length | n_vertices | neither) to a validated edge length."""
    if edge_length is not None and n_vertices is not None:
        raise ValueError("give either edge_length or n_vertices, not both")
    finest = edge_length_for_vertices(MAX_VERTICES, area, linear, area_factor)
    if finest > size:
        # edges must fit the narrowest dimension, and edges that fine exceed the vertex limit: no valid mesh
        raise ValueError(f"the geometry is too slender to mesh: edges must be at most the {size_name} ({size:g}), "
                         f"and edges that short give more than {MAX_VERTICES} vertices (at least {finest:.3g} "
                         "needed); make the narrowest dimension larger against the others")
    if n_vertices is not None:
        h = edge_length_for_vertices(_vertex_count("n_vertices", n_vertices), area, linear, area_factor)
        return min(h, size)
    if edge_length is None:
        return size / default_divisions
    h = _positive("edge_length", edge_length, size, f"{size:g} (the {size_name})")
    est = _vertices_for_edge_length(h, area, linear, area_factor)
    if est > MAX_VERTICES:
        limit = edge_length_for_vertices(MAX_VERTICES, area, linear, area_factor)
        raise ValueError(f"edge_length must be at least {limit:.3g} "
                         f"for this geometry (edge_length={edge_length!r} would give about {est:.3g} vertices, "
                         f"limit {MAX_VERTICES})")
    return h


# ----------------------------------------------------------------------------- generators

def sphere(radius=1.0, n_vertices=None, edge_length=None, seed=0) -> SurfaceMesh:
    """Closed sphere of radius ``radius`` centred at the origin, outward normals.

    Give the resolution as ``n_vertices`` (calibrated: within a few per cent
    for 500..100 000 vertices) or ``edge_length`` (design units); default
    ``radius / 10`` (about 1 500 vertices). Euler characteristic 2, no boundary.

    >>> m = sphere(radius=30.0, n_vertices=2500, seed=0)
    >>> abs(m.n_vertices - 2500) < 250
    True
    """
    R = _size("radius", radius)
    seed = _seed(seed)
    h = _resolution(edge_length, n_vertices, 4 * math.pi * R * R, SPHERE_LINEAR * R, R, "radius", AREA_FACTOR)

    def mesh_with(h):
        with _gmsh_model(seed) as gmsh:
            gmsh.model.occ.addSphere(0, 0, 0, R)
            _uniform_size(gmsh, h)
            _generate(gmsh, "the sphere")
            surfaces = [t for _, t in gmsh.model.getEntities(2)]
            points, tri, _ = _extract(gmsh, surfaces, lambda xyz: None)
        return h, points, tri

    h, points, tri = mesh_with(h)
    if n_vertices is not None and abs(len(points) - n_vertices) > 0.03 * n_vertices:
        # gmsh's count has isolated spikes (radius 30: 1 004 vertices at h = 3.725, 1 106 at 3.729,
        # 1 074 at 3.75, 970 at 3.775): a size 1 % either side misses the spike; keep the closest
        tries = [(h, points, tri)] + [mesh_with(h * f) for f in (0.99, 1.01)]
        h, points, tri = min(tries, key=lambda m: abs(len(m[1]) - n_vertices))
    return _finish(points, tri, {}, _radial, f"sphere radius={R:g} edge_length={h:.4g} seed={seed}")


def disk(radius=1.0, edge_length=None, n_vertices=None, inner_radius=None, inner_edge_length=None,
         seed=0, refine_inside=False) -> SurfaceMesh:
    """Flat disk of radius ``radius`` in the plane z = 0, centred at the origin, +z normals.

    Boundary curve ``"outer"`` (r = radius). With ``inner_radius`` the circle
    r = inner_radius is built into the mesh (mesh edges follow it, its vertices
    lie on it to rounding) and returned as ``"inner"``: it is an INTERIOR curve
    (edges with a triangle on each side), listed in ``boundary`` so that users
    find it by name; its segments run counter-clockwise. Tell the inner and the
    outer region apart by triangle centroids (r < inner_radius).
    ``inner_edge_length`` refines the mesh near the circle: the size is
    ``inner_edge_length`` within one inner edge length of the circle and grows
    linearly (gradient 0.3) to ``edge_length`` away from it. With ``refine_inside`` the whole
    inner disk has ``inner_edge_length`` (for fields that vary across it, not only along the
    circle), and the size grows the same way outside.

    ``n_vertices`` converts to a uniform edge length (the refinement adds vertices).

    >>> m = disk(radius=10.0, edge_length=1.0, inner_radius=3.0, inner_edge_length=0.5)
    >>> sorted(m.boundary), m.topology.euler_characteristic
    (['inner', 'outer'], 1)
    """
    R = _size("radius", radius)
    seed = _seed(seed)
    h = _resolution(edge_length, n_vertices, math.pi * R * R, BOUNDARY_LINEAR * 2 * math.pi * R, R, "radius")
    r = None if inner_radius is None else _positive("inner_radius", inner_radius, R, f"{R:g}", closed=False)
    hi = None
    if refine_inside and inner_edge_length is None:
        raise ValueError("refine_inside needs inner_edge_length (the edge length inside)")
    if inner_edge_length is not None:
        if r is None:
            raise ValueError("inner_edge_length needs inner_radius")
        hi = _positive("inner_edge_length", inner_edge_length, h, f"{h:g} (the edge_length)")
        fine_area = math.pi * (r + hi) ** 2 if refine_inside else 4 * math.pi * r * hi
        if _vertices_for_edge_length(hi, fine_area, 0.0) > MAX_VERTICES:
            raise ValueError(f"inner_edge_length={inner_edge_length!r} is too small for inner_radius={r:g}")
    tol = 1e-7 * R
    with _gmsh_model(seed) as gmsh:
        occ = gmsh.model.occ
        outer = occ.addDisk(0, 0, 0, R, R)
        if r is not None:
            inner = occ.addDisk(0, 0, 0, r, r)
            # fragment: the disk splits into the inner disk and the ring, sharing the circle
            occ.fragment([(2, outer)], [(2, inner)])
        occ.synchronize()
        if hi is not None and hi < h:
            f = gmsh.model.mesh.field
            if refine_inside:
                # the radius itself as the "distance": the size is hi up to r + hi
                dist = f.add("MathEval")
                f.setString(dist, "F", "Sqrt(x*x + y*y)")
                d0 = r + hi
            else:
                # the distance to the inner circle, the curve of length 2 pi r
                circles = [c for _, c in gmsh.model.getEntities(1)
                           if abs(gmsh.model.occ.getMass(1, c) - 2 * math.pi * r) < 1e-6 * R]
                dist = f.add("Distance")
                f.setNumbers(dist, "CurvesList", circles)
                # the distance is sampled at points along the curve: space them well below hi
                f.setNumber(dist, "Sampling", int(math.ceil(4 * math.pi * r / hi)) + 20)
                d0 = hi
            thr = f.add("Threshold")
            f.setNumber(thr, "InField", dist)
            f.setNumber(thr, "SizeMin", hi)
            f.setNumber(thr, "SizeMax", h)
            f.setNumber(thr, "DistMin", d0)
            # grow the size with gradient 0.3: gentle enough for good triangles
            f.setNumber(thr, "DistMax", d0 + (h - hi) / 0.3)
            f.setAsBackgroundMesh(thr)
            gmsh.option.setNumber("Mesh.MeshSizeMin", hi)
            gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        else:
            _uniform_size(gmsh, h)
        _generate(gmsh, "the disk")

        def classify(xyz):
            rr = np.hypot(xyz[:, 0], xyz[:, 1])
            if _on(rr, R, tol):
                return "outer"
            if r is not None and _on(rr, r, tol):
                return "inner"
            return None

        points, tri, curves = _extract(gmsh, [t for _, t in gmsh.model.getEntities(2)], classify)
    points[:, 2] = 0.0
    name = f"disk radius={R:g} edge_length={h:.4g}"
    if r is not None:
        name += f" inner_radius={r:g}" + (f" inner_edge_length={hi:.4g}" if hi is not None else "")
        name += " refine_inside" if refine_inside and hi is not None else ""
    return _finish(points, tri, curves, _up, name + f" seed={seed}", interior=("inner",))


_DIAGONALS = ("right", "left", "alternate", "crossed")


def _structured_plate(lx, ly, h, diagonal):
    """Regular grid on [0,lx]x[0,ly] split into right triangles (numpy only, no gmsh)."""
    nx, ny = max(1, round(lx / h)), max(1, round(ly / h))
    x, y = np.linspace(0.0, lx, nx + 1), np.linspace(0.0, ly, ny + 1)
    X, Y = np.meshgrid(x, y, indexing="xy")
    points = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    vid = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    v00, v10 = vid[:-1, :-1].ravel(), vid[:-1, 1:].ravel()
    v01, v11 = vid[1:, :-1].ravel(), vid[1:, 1:].ravel()
    # cell (i, j) -> 2 triangles; all listed counter-clockwise (normal +z)
    right = np.stack([np.column_stack([v00, v10, v11]), np.column_stack([v00, v11, v01])], axis=1)
    left = np.stack([np.column_stack([v00, v10, v01]), np.column_stack([v10, v11, v01])], axis=1)
    if diagonal == "right":
        tri = right.reshape(-1, 3)
    elif diagonal == "left":
        tri = left.reshape(-1, 3)
    elif diagonal == "alternate":
        j, i = np.divmod(np.arange(nx * ny), nx)
        tri = np.where(((i + j) % 2 == 0)[:, None, None], right, left).reshape(-1, 3)
    else:  # crossed: a centre vertex per cell, four triangles
        c = len(points) + np.arange(nx * ny)
        centres = 0.25 * (points[v00] + points[v10] + points[v01] + points[v11])
        points = np.vstack([points, centres])
        tri = np.stack([np.column_stack([v00, v10, c]), np.column_stack([v10, v11, c]),
                        np.column_stack([v11, v01, c]), np.column_stack([v01, v00, c])], axis=1).reshape(-1, 3)
    chain = lambda v: np.column_stack([v[:-1], v[1:]])  # noqa: E731
    curves = {"bottom": chain(vid[0, :]), "right": chain(vid[:, -1]),
              "top": chain(vid[-1, ::-1]), "left": chain(vid[::-1, 0])}
    return points, tri, curves, (nx, ny)


def _rectangle(lx, ly, edge_length, n_vertices, structured, diagonal, seed, kind):
    _check_diagonal(diagonal)
    seed = _seed(seed)
    if structured and n_vertices is not None and edge_length is None:
        # the grid has (lx/h + 1)(ly/h + 1) vertices, plus lx ly / h^2 cell centres when crossed:
        # solve c a / h^2 + b / h + 1 = n for h exactly
        n = _vertex_count("n_vertices", n_vertices)
        a, b = lx * ly * (2 if diagonal == "crossed" else 1), lx + ly
        edge_length = min(2 * a / (-b + math.sqrt(b * b + 4 * a * (n - 1))), min(lx, ly))
        n_vertices = None
    h = _resolution(edge_length, n_vertices, lx * ly, BOUNDARY_LINEAR * 2 * (lx + ly), min(lx, ly),
                    "shorter side")
    if structured:
        points, tri, curves, (nx, ny) = _structured_plate(lx, ly, h, diagonal)
        name = f"{kind} lx={lx:g} ly={ly:g} structured {nx}x{ny} diagonal={diagonal}"
        return _finish(points, tri, curves, _up, name)
    tol = 1e-7 * max(lx, ly)
    with _gmsh_model(seed) as gmsh:
        gmsh.model.occ.addRectangle(0, 0, 0, lx, ly)
        _uniform_size(gmsh, h)
        _generate(gmsh, f"the {kind}")

        def classify(xyz):
            for key, col, val in (("left", 0, 0.0), ("right", 0, lx), ("bottom", 1, 0.0), ("top", 1, ly)):
                if _on(xyz[:, col], val, tol):
                    return key
            return None

        points, tri, curves = _extract(gmsh, [t for _, t in gmsh.model.getEntities(2)], classify)
    points[:, 2] = 0.0
    return _finish(points, tri, curves, _up, f"{kind} lx={lx:g} ly={ly:g} edge_length={h:.4g} seed={seed}")


def _check_diagonal(diagonal):
    if diagonal not in _DIAGONALS:
        raise ValueError(f"diagonal must be one of {', '.join(_DIAGONALS)}; got {diagonal!r}")


def plate(lx=1.0, ly=1.0, edge_length=None, structured=False, seed=0, *, diagonal="right",
          n_vertices=None) -> SurfaceMesh:
    """Flat rectangle [0, lx] x [0, ly] in z = 0 (corner at the origin), +z normals.

    Boundary curves ``"left"`` (x = 0), ``"right"`` (x = lx), ``"bottom"``
    (y = 0), ``"top"`` (y = ly). Default ``edge_length = min(lx, ly) / 10``.

    ``structured=True`` builds a regular grid of right triangles with numpy
    (no gmsh; ``seed`` is unused): round(lx/h) x round(ly/h) cells, split
    along the ``diagonal``: ``"right"`` (every cell from (x0,y0) to (x1,y1)),
    ``"left"`` (from (x1,y0) to (x0,y1)), ``"alternate"`` (right and left in a
    checkerboard) or ``"crossed"`` (both diagonals: a centre vertex and four
    triangles per cell).

    >>> m = plate(2.0, 1.0, edge_length=0.5, structured=True)
    >>> m.n_vertices, m.n_triangles, sorted(m.boundary)
    (15, 16, ['bottom', 'left', 'right', 'top'])
    """
    lx = _size("lx", lx)
    ly = _size("ly", ly)
    return _rectangle(lx, ly, edge_length, n_vertices, structured, diagonal, seed, "plate")


def strip(length=10.0, width=1.0, edge_length=None, structured=False, seed=0, *, diagonal="right",
          n_vertices=None) -> SurfaceMesh:
    """A long plate [0, length] x [0, width] in z = 0: :func:`plate` with lx=length, ly=width.

    Boundary curves ``"left"`` (x = 0), ``"right"`` (x = length), ``"bottom"``
    (y = 0), ``"top"`` (y = width). Default ``edge_length = min(length, width) / 10``.

    >>> sorted(strip(10.0, 1.0, edge_length=0.25, structured=True).boundary)
    ['bottom', 'left', 'right', 'top']
    """
    length = _size("length", length)
    width = _size("width", width)
    return _rectangle(length, width, edge_length, n_vertices, structured, diagonal, seed, "strip")


def _cut_slit(points, tri, curves):
    """Duplicate the vertices of the "slit" curve for the triangles below it (y < 0).

    The slit lies on the positive x-axis, so every triangle that touches a slit
    vertex is on one side of it; its centroid's y tells which.
    """
    slit = curves.pop("slit")
    n = len(points)
    sv = np.unique(slit)
    dup = np.full(n, -1, np.int64)
    dup[sv] = n + np.arange(len(sv))
    below = points[tri].mean(axis=1)[:, 1] < 0
    tri = tri.copy()
    sub = tri[below]
    tri[below] = np.where(dup[sub] >= 0, dup[sub], sub)
    points = np.vstack([points, points[sv]])
    for key, seg in curves.items():
        # segments of inner/outer that touch a slit end: below the slit if the other end is
        lower = points[seg].mean(axis=1)[:, 1] < 0
        curves[key] = np.where(lower[:, None] & (dup[seg] >= 0), dup[seg], seg)
    curves["slit-a"] = slit
    curves["slit-b"] = dup[slit]
    return points, tri, curves


def annulus(inner_radius=0.5, outer_radius=1.0, edge_length=None, slit=False, seed=0, *,
            n_vertices=None) -> SurfaceMesh:
    """Flat ring inner_radius <= r <= outer_radius in z = 0, centred at the origin, +z normals.

    Boundary curves ``"outer"`` and ``"inner"``; Euler characteristic 0.
    Default ``edge_length = (outer_radius - inner_radius) / 10``.

    ``slit=True`` cuts the ring along the ray y = 0, x > 0 (a mesh line): the
    slit vertices are duplicated, so the ring is topologically a rectangle
    (Euler characteristic 1) with two more boundary curves: ``"slit-a"`` is the
    side bordered by the triangles with y > 0 (angle 0+; the original vertex
    indices) and ``"slit-b"`` the side bordered by the triangles with y < 0
    (angle 2 pi-; the duplicated vertices, appended at the end of ``points``).
    The two sides have the same coordinates: ``points[slit_a] == points[slit_b]``
    segment by segment.

    >>> m = annulus(0.5, 1.0, edge_length=0.1, slit=True)
    >>> sorted(m.boundary), m.topology.euler_characteristic
    (['inner', 'outer', 'slit-a', 'slit-b'], 1)
    """
    R = _size("outer_radius", outer_radius)
    r = _positive("inner_radius", inner_radius, R, f"{R:g}", closed=False)
    seed = _seed(seed)
    if not isinstance(slit, (bool, np.bool_)):
        raise ValueError(f"slit must be True or False, got {slit!r}")
    # a slit adds the embedded line and its duplicated vertices: about 1.5 vertices per edge length
    linear = BOUNDARY_LINEAR * 2 * math.pi * (R + r) + (1.5 * (R - r) if slit else 0.0)
    h = _resolution(edge_length, n_vertices, math.pi * (R * R - r * r), linear, R - r,
                    "ring width outer_radius - inner_radius")
    if slit and h > r:
        # triangles at the inner end of the slit must not reach round to x < 0
        raise ValueError(f"edge_length must be at most inner_radius={r:g} for a slit annulus, got {h:g}")
    tol = 1e-7 * R
    with _gmsh_model(seed) as gmsh:
        occ = gmsh.model.occ
        ring, _ = occ.cut([(2, occ.addDisk(0, 0, 0, R, R))], [(2, occ.addDisk(0, 0, 0, r, r))])
        if slit:
            line = occ.addLine(occ.addPoint(r, 0, 0), occ.addPoint(R, 0, 0))
            # fragment embeds the segment in the ring: mesh edges will run along it
            occ.fragment(ring, [(1, line)])
        _uniform_size(gmsh, h)
        _generate(gmsh, "the annulus")

        def classify(xyz):
            rr = np.hypot(xyz[:, 0], xyz[:, 1])
            if _on(rr, R, tol):
                return "outer"
            if _on(rr, r, tol):
                return "inner"
            if _on(xyz[:, 1], 0.0, tol) and np.all(xyz[:, 0] > 0):
                return "slit"
            return None

        points, tri, curves = _extract(gmsh, [t for _, t in gmsh.model.getEntities(2)], classify)
    points[:, 2] = 0.0
    if slit:
        points, tri, curves = _cut_slit(points, tri, curves)
    name = f"annulus inner_radius={r:g} outer_radius={R:g} edge_length={h:.4g}{' slit' if slit else ''} seed={seed}"
    return _finish(points, tri, curves, _up, name)


def cylinder(radius=1.0, length=1.0, edge_length=None, angle_range=None, seed=0, *,
             n_vertices=None) -> SurfaceMesh:
    """Open cylinder x^2 + y^2 = radius^2, 0 <= z <= length, normals pointing away from the axis.

    Full cylinder: boundary curves ``"bottom"`` (z = 0) and ``"top"``
    (z = length), Euler characteristic 0. With ``angle_range=(theta0, theta1)``
    (radians, 0 < theta1 - theta0 < 2 pi) a cylindrical panel theta0 <= theta
    <= theta1 with two more curves ``"side-a"`` (theta = theta0) and
    ``"side-b"`` (theta = theta1); Euler characteristic 1.
    Default ``edge_length = min(radius, length) / 10``.

    >>> m = cylinder(1.0, 2.0, edge_length=0.2)
    >>> sorted(m.boundary), m.topology.euler_characteristic
    (['bottom', 'top'], 0)
    """
    R = _size("radius", radius)
    L = _size("length", length)
    seed = _seed(seed)
    if angle_range is None:
        t0, t1 = 0.0, 2 * math.pi
    else:
        try:
            t0, t1 = (float(t) for t in angle_range)
        except (TypeError, ValueError):
            raise ValueError(f"angle_range must be a pair (theta0, theta1) in radians, got {angle_range!r}") from None
        if not (math.isfinite(t0) and math.isfinite(t1) and 0 < t1 - t0 < 2 * math.pi):
            raise ValueError(f"angle_range=(theta0, theta1) must have 0 < theta1 - theta0 < 2 pi, got {angle_range!r}")
    span = t1 - t0
    perimeter = 2 * R * span + (2 * L if angle_range is not None else 0.0)
    h = _resolution(edge_length, n_vertices, R * span * L, BOUNDARY_LINEAR * perimeter, min(R, L),
                    "smaller of radius and length")
    tol = 1e-7 * max(R, L)
    with _gmsh_model(seed) as gmsh:
        occ = gmsh.model.occ
        if angle_range is None:
            curve = occ.addCircle(0, 0, 0, R)
        else:
            curve = occ.addCircle(0, 0, 0, R, angle1=t0, angle2=t1)
        # sweeping the circle (arc) along z gives the lateral surface only, no caps
        occ.extrude([(1, curve)], 0, 0, L)
        _uniform_size(gmsh, h)
        _generate(gmsh, "the cylinder")
        side_a = np.array([math.cos(t0), math.sin(t0)])
        side_b = np.array([math.cos(t1), math.sin(t1)])

        def classify(xyz):
            if _on(xyz[:, 2], 0.0, tol):
                return "bottom"
            if _on(xyz[:, 2], L, tol):
                return "top"
            if angle_range is not None:   # on the full cylinder the vertical line is the seam
                if _on(xyz[:, :2] - R * side_a, 0.0, tol):
                    return "side-a"
                if _on(xyz[:, :2] - R * side_b, 0.0, tol):
                    return "side-b"
            return None

        points, tri, curves = _extract(gmsh, [t for _, t in gmsh.model.getEntities(2)], classify)
    if angle_range is not None and not {"side-a", "side-b"} <= set(curves):
        # gmsh closes an arc within round-off of 0 or 2 pi into a full circle
        raise ValueError(f"angle_range=({t0:.6g}, {t1:.6g}) spans {span:.3g} rad, which gmsh meshes as "
                         f"{'a full tube' if 'bottom' in curves else 'no panel'}: the span must stay clear of 0 and "
                         "of 2 pi (for the full cylinder give no angle_range)")
    name = f"cylinder radius={R:g} length={L:g} edge_length={h:.4g}"
    if angle_range is not None:
        name += f" angle_range=({t0:.4g}, {t1:.4g})"
    return _finish(points, tri, curves, _away_from_axis, name + f" seed={seed}")


def hemisphere(radius=1.0, edge_length=None, n_vertices=None, hole_angle=None, seed=0) -> SurfaceMesh:
    """Upper hemisphere |x| = radius, z >= 0, outward normals (away from the centre).

    Boundary curve ``"equator"`` (z = 0). With ``hole_angle`` (polar angle in
    radians, 0 < hole_angle < pi/2) the cap around the pole with polar angle
    < hole_angle is left out and its rim is the boundary curve ``"hole"``
    (z = radius cos(hole_angle)); Euler characteristic 1 without, 0 with the hole.
    Default ``edge_length = radius / 10``.

    >>> m = hemisphere(1.0, edge_length=0.2, hole_angle=0.5)
    >>> sorted(m.boundary), m.topology.euler_characteristic
    (['equator', 'hole'], 0)
    """
    R = _size("radius", radius)
    seed = _seed(seed)
    if hole_angle is not None:
        hole = _positive("hole_angle", hole_angle, math.pi / 2, "pi/2")
        if hole >= math.pi / 2:
            raise ValueError(f"hole_angle must be in (0, pi/2), got {hole_angle!r}")
    else:
        hole = 0.0
    area = 2 * math.pi * R * R * math.cos(hole)
    perimeter = 2 * math.pi * R * (1 + math.sin(hole))
    # the pole and half the seam of the OCC sphere add vertices as on the sphere; a hole removes the pole
    linear = BOUNDARY_LINEAR * perimeter + (0.5 * SPHERE_LINEAR * R if hole == 0 else 0.0)
    h = _resolution(edge_length, n_vertices, area, linear, R, "radius", AREA_FACTOR)
    z_hole = R * math.cos(hole)
    tol = 1e-7 * R
    with _gmsh_model(seed) as gmsh:
        occ = gmsh.model.occ
        # a solid zone of the ball between latitudes 0 and pi/2 - hole; keep only its spherical face
        ball = occ.addSphere(0, 0, 0, R, angle1=0.0, angle2=math.pi / 2 - hole)
        occ.synchronize()
        faces = gmsh.model.getBoundary([(3, ball)], oriented=False)
        occ.remove([(3, ball)])
        occ.synchronize()
        flat = [(2, t) for _, t in faces if gmsh.model.getType(2, t) == "Plane"]
        occ.remove(flat, recursive=True)   # sub-entities still used by the spherical face stay
        _uniform_size(gmsh, h)
        _generate(gmsh, "the hemisphere")

        def classify(xyz):
            if _on(xyz[:, 2], 0.0, tol):
                return "equator"
            if hole > 0 and _on(xyz[:, 2], z_hole, tol):
                return "hole"
            return None   # the seam meridian of the OCC sphere

        points, tri, curves = _extract(gmsh, [t for _, t in gmsh.model.getEntities(2)], classify)
    if hole > 0 and "hole" not in curves:
        raise ValueError(f"hole_angle={hole:.3g} rad makes a hole of radius {R * math.sin(hole):.3g}, which gmsh "
                         f"does not cut at edge length {h:.3g}: give a hole at least an edge wide, or no hole_angle")
    name = f"hemisphere radius={R:g} edge_length={h:.4g}"
    if hole > 0:
        name += f" hole_angle={hole:.4g}"
    return _finish(points, tri, curves, _radial, name + f" seed={seed}")
