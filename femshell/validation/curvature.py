r"""Mean curvature from the shell's own second fundamental form, on unstructured gmsh meshes.

H = ½ tr(a⁻¹ b) per element, with a, b from :meth:`ShellModel.fundamental_forms`
(theory §1.3: the chemistry's curvature comes from the shell itself). Three ways to
choose the edge angles θ (the rotation of each mid-edge normal about its edge, the
unknowns that complete the Morley-type element):

``zero angles``
    θ = 0: every mid-edge normal is the mean of its two face normals. This is the
    drawn mesh as the loop's rest state sees it (``model.initial_unknowns()``).
    Per element H scatters around 1/R on a sphere: the L2 error falls only slowly
    under refinement (13 % at 174 vertices, 7 % at 3 094: order ≈ 0.4) and the
    largest error not at all (60–100 %), because the mean of two face normals is not
    the surface normal at the edge midpoint to the order that b, a derivative of the
    normal, needs. Reported, no tolerance.
``relaxed angles``
    positions held at the drawn mesh, θ minimise the shell's bending energy for the
    exact target curvature (b̄ = k ā0 on the sphere, the exact cylinder form on the
    cylinder): what an equilibrium solve finds in a shape that is held. This
    converges fast (it measures how well the element can represent the surface), but
    it is told the answer through b̄, so it is a consistency check, not a
    measurement.
``loop definition``
    what :mod:`femshell.coupled` uses: the rest curvature is the mesh's own
    b_mesh (zero angles), the shape is deformed, the angles relax to the
    equilibrium for that rest state, and H is measured relative to the rest mesh,
    H = ½ tr(a⁻¹ b) − ½ tr(ā0⁻¹ b_mesh). Checked on a sphere of radius R stretched into
    a spheroid (z × (1 + ε)), whose mean curvature is known in closed form: the
    reference is H_spheroid − 1/R. Per element and averaged to the vertices (what the
    source P(H) sees).

Errors: L2 (area-weighted root mean square) over elements, relative to |H_ref|
(sphere 1/R, cylinder 1/(2R)), to the L2 norm of the reference change (loop
definition), and absolute × plate size on the flat plate (H = 0). Rows give the L2
error as the value (reference 0, so the error is the value) and the max error as a
reported row. Elements touching the boundary of the open cylinder are left out (a
free edge has no neighbour to define its mid-edge normal at θ = 0).
"""

from __future__ import annotations

import numpy as np

from ..geometry import element_to_vertex, mean_curvature, triangle_areas
from ..mesh.generators import cylinder, plate, sphere
from ..shell import Material, RestState, ShellModel, metric
from ..solvers.newton import minimize
from .common import finest_order
from .framework import Row, timed

NAME = "curvature"
DESCRIPTION = ("mean curvature from the shell's second fundamental form: sphere 1/R, cylinder 1/(2R), plate 0, "
               "spheroid relative to the rest sphere (the coupled loop's H), under refinement")
SOURCE = "exact: H = 1/R (sphere), 1/(2R) (cylinder), 0 (plane); closed-form mean curvature of a spheroid"

R = 1.0
EPS = 0.1
LEVELS = {"quick": [0.3, 0.2, 0.14], "full": [0.3, 0.2, 0.14, 0.1, 0.07]}
TOL_RELAXED = 0.01       # relaxed angles: L2 relative error at the finest level
TOL_LOOP = 0.05          # loop definition (spheroid), vertex-averaged, finest level


class _AnglesOnly:
    """The shell energy as a function of the edge angles alone, positions held at ``points``."""

    def __init__(self, model: ShellModel, points):
        self.model = model
        n3 = 3 * model.mesh.n_vertices
        model.q_fixed[:n3] = np.asarray(points, float).ravel()
        q = model.q_fixed.copy()
        self.base = q[model.free]
        free_idx = np.flatnonzero(model.free)
        self.idx = np.flatnonzero(free_idx >= n3)

    def full(self, v):
        u = self.base.copy()
        u[self.idx] = v
        return u

    def energy(self, v):
        return self.model.energy(self.full(v))

    def gradient(self, v):
        return self.model.gradient(self.full(v))[self.idx]

    def hessian(self, v):
        return self.model.hessian(self.full(v))[self.idx][:, self.idx]


def _relax(model, points):
    prob = _AnglesOnly(model, points)
    v0 = np.zeros(len(prob.idx))
    res = minimize(prob, v0, rtol=1e-10, atol=1e-14, stable=False, log=None)
    return prob.full(res.u)


def _l2(err, area):
    return float(np.sqrt(np.sum(area * err**2) / np.sum(area)))


def _error_rows(label, h, H, Href, area, scale, n, wall, tol=None):
    err = (H - Href) / scale
    return [Row(f"{label}: L2 error @ h={h}", _l2(err, area), 0.0, tol, n, wall),
            Row(f"{label}: max error @ h={h}", float(np.max(np.abs(err))), None, None, n, wall)]


def _cylinder_form(points, triangles, radius):
    """Exact b of the cylinder in each element's barycentric coordinates (outward normal)."""
    x = points[triangles]
    e = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)            # (m, 2, 3)
    c = x.mean(axis=1)
    phi = np.column_stack([-c[:, 1], c[:, 0], np.zeros(len(c))])
    phi /= np.linalg.norm(phi, axis=1)[:, None]
    t = np.einsum("mik,mk->mi", e, phi)
    return np.einsum("mi,mj->mij", t, t) / radius


def spheroid_mean_curvature(points, a, c):
    """Outward mean curvature of x²/a² + y²/a² + z²/c² = 1 at ``points`` (projected on it first)."""
    p = np.asarray(points, float)
    ax = np.array([a, a, c])
    p = p / np.sqrt(np.sum((p / ax) ** 2, axis=1))[:, None]
    hh = np.sqrt(np.sum(p**2 / ax**4, axis=1))
    return (np.sum(ax**2) - np.sum(p**2, axis=1)) / (2.0 * (a * a * c) ** 2 * hh**3)


def _sphere_rows(h, last):
    mesh = sphere(R, edge_length=h)
    n = mesh.n_vertices
    rows = []
    with timed() as t:
        a0 = metric(mesh.points, mesh.triangles)
        model = ShellModel(mesh, Material(1.0, 0.3), RestState(a0, a0 / R, 0.01))
        a, b = model.fundamental_forms(model.initial_unknowns())
        H0 = mean_curvature(a, b)
        area = triangle_areas(mesh.points, mesh.triangles)
    rows += _error_rows("sphere H, zero angles", h, H0, 1 / R, area, 1 / R, n, t())
    with timed() as t:
        u = _relax(model, mesh.points)
        a, b = model.fundamental_forms(u)
        H1 = mean_curvature(a, b)
    rows += _error_rows("sphere H, relaxed angles", h, H1, 1 / R, area, 1 / R, n, t(), TOL_RELAXED if last else None)

    # the coupled loop's definition on a spheroid: rest = the sphere mesh at zero angles
    with timed() as t:
        b_mesh = model.fundamental_forms(model.initial_unknowns())[1]
        loop_model = ShellModel(mesh, Material(1.0, 0.3), RestState(a0, b_mesh, 0.01))
        k_ref = mean_curvature(a0, b_mesh)
        moved = mesh.points * np.array([1.0, 1.0, 1.0 + EPS])
        u = _relax(loop_model, moved)
        a, b = loop_model.fundamental_forms(u)
        Hrel = mean_curvature(a, b, k_ref)
        x = moved[mesh.triangles].mean(axis=1)
        ref = spheroid_mean_curvature(x, R, R * (1 + EPS)) - 1 / R
        area_d = triangle_areas(moved, mesh.triangles)
        scale = _l2(ref, area_d)
        Hv = element_to_vertex(Hrel, moved, mesh.triangles)
        ref_v = spheroid_mean_curvature(moved, R, R * (1 + EPS)) - 1 / R
        va = np.zeros(n)
        for k in range(3):
            va += np.bincount(mesh.triangles[:, k], area_d / 3, minlength=n)
    rows += _error_rows(f"spheroid z*{1 + EPS:g}: H - H_rest (loop definition), elements", h, Hrel, ref, area_d,
                        scale, n, t())
    rows += _error_rows(f"spheroid z*{1 + EPS:g}: H - H_rest (loop definition), vertices", h, Hv, ref_v, va,
                        scale, n, t(), TOL_LOOP if last else None)

    # the literal rest curvature of theory §1.1, b̄ = k0 ā0 (rest_curvature="k0"): H relative to k0
    with timed() as t:
        u = _relax(model, moved)
        a, b = model.fundamental_forms(u)
        Hk = mean_curvature(a, b, 1 / R)
        Hkv = element_to_vertex(Hk, moved, mesh.triangles)
    rows += _error_rows(f"spheroid z*{1 + EPS:g}: H - k0 (k0 rest), elements", h, Hk, ref, area_d, scale, n, t())
    rows += _error_rows(f"spheroid z*{1 + EPS:g}: H - k0 (k0 rest), vertices", h, Hkv, ref_v, va, scale, n, t())
    return rows


def _cylinder_rows(h, last):
    length = 2.0
    mesh = cylinder(R, length, edge_length=h)
    n = mesh.n_vertices
    rows = []
    with timed() as t:
        a0 = metric(mesh.points, mesh.triangles)
        model = ShellModel(mesh, Material(1.0, 0.3),
                           RestState(a0, _cylinder_form(mesh.points, mesh.triangles, R), 0.01))
        a, b = model.fundamental_forms(model.initial_unknowns())
        H0 = mean_curvature(a, b)
        area = triangle_areas(mesh.points, mesh.triangles)
        bnd = np.zeros(n, bool)
        bnd[mesh.topology.boundary_vertices] = True
        inner = ~bnd[mesh.triangles].any(axis=1)
    ref = 1 / (2 * R)
    rows += _error_rows("cylinder H, zero angles", h, H0[inner], ref, area[inner], ref, n, t())
    with timed() as t:
        u = _relax(model, mesh.points)
        a, b = model.fundamental_forms(u)
        H1 = mean_curvature(a, b)
    rows += _error_rows("cylinder H, relaxed angles", h, H1[inner], ref, area[inner], ref, n, t(),
                        TOL_RELAXED if last else None)
    return rows


def _plate_rows(h, last):
    size = 2.0
    mesh = plate(size, size, edge_length=h * size)
    n = mesh.n_vertices
    with timed() as t:
        a0 = metric(mesh.points, mesh.triangles)
        model = ShellModel(mesh, Material(1.0, 0.3), RestState(a0, np.zeros_like(a0), 0.01))
        a, b = model.fundamental_forms(model.initial_unknowns())
        H0 = mean_curvature(a, b)
        area = triangle_areas(mesh.points, mesh.triangles)
    return _error_rows("plate H*L, zero angles", h, H0, 0.0, area, 1 / size, n, t(), 1e-12 if last else None)


def run(level):
    sizes = LEVELS[level]
    rows = []
    for i, h in enumerate(sizes):
        last = i == len(sizes) - 1
        rows += _sphere_rows(h, last)
        rows += _cylinder_rows(h, last)
        rows += _plate_rows(h, last)
    for q in ("sphere H, zero angles: L2 error", "sphere H, relaxed angles: L2 error",
              "cylinder H, relaxed angles: L2 error",
              f"spheroid z*{1 + EPS:g}: H - H_rest (loop definition), vertices: L2 error"):
        rows += _order_rows(q, rows)
    return rows


def _order_rows(quantity, rows):
    """Observed order of ``quantity`` (rows whose value is the error, reference 0)."""
    sel = [r for r in rows if r.quantity.split(" @")[0] == quantity]
    p, k = finest_order([r.n_vertices for r in sel], [r.value for r in sel])
    return [] if p is None else [Row(f"observed order of {quantity} (finest {k} meshes)", p)]

