"""Tests of femshell.mesh.generators: counts, topology, orientation, boundary names, determinism."""

import math

import numpy as np
import pytest

from femshell.mesh import MeshError, SurfaceMesh, annulus, cylinder, disk, hemisphere, plate, sphere, strip
from femshell.mesh.generators import edge_length_for_vertices


def normals(mesh):
    p = mesh.points[mesh.triangles]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def centroids(mesh):
    return mesh.points[mesh.triangles].mean(axis=1)


def signed_volume(mesh):
    p = mesh.points[mesh.triangles]
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0


def assert_valid(mesh, euler, names):
    """Manifold, consistently oriented, every boundary edge named, no unused vertex."""
    t = mesh.topology
    assert isinstance(mesh, SurfaceMesh)
    assert t.euler_characteristic == euler
    assert sorted(mesh.boundary) == sorted(names)
    assert len(t.inconsistent_edges) == 0
    assert sorted(t.boundary_edge_groups) == sorted(names)   # no unnamed "boundary-k" curve
    assert len(np.unique(mesh.triangles)) == mesh.n_vertices
    assert mesh.points.dtype == np.float64 and mesh.triangles.shape[1] == 3
    assert mesh.name


def assert_segments_run_with_surface_on_left(mesh, names):
    tri = mesh.triangles
    n = mesh.n_vertices
    directed = set((tri * n + tri[:, [1, 2, 0]]).ravel().tolist())
    for k in names:
        seg = mesh.boundary[k]
        assert all(int(i) * n + int(j) in directed for i, j in seg), k


# ----------------------------------------------------------------------------- sphere

@pytest.mark.parametrize("n", [500, 1000, 2500, 5000])      # 1000: gmsh alone gave 1 106
def test_sphere_vertex_count_within_3_percent(n):
    m = sphere(radius=30.0, n_vertices=n)
    assert abs(m.n_vertices - n) <= 0.03 * n


def test_sphere_closed_outward_and_round():
    R = 2.0
    m = sphere(radius=R, edge_length=0.25)
    assert_valid(m, 2, [])
    assert m.topology.is_closed
    assert np.allclose(np.linalg.norm(m.points, axis=1), R, rtol=1e-9)
    v = signed_volume(m)
    assert v > 0
    assert v == pytest.approx(4 / 3 * math.pi * R**3, rel=0.02)
    assert np.all(np.einsum("ij,ij->i", normals(m), centroids(m)) > 0)
    assert "sphere" in m.name and "radius=2" in m.name


def test_sphere_deterministic_for_seed():
    a = sphere(1.0, n_vertices=600, seed=3)
    b = sphere(1.0, n_vertices=600, seed=3)
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.triangles, b.triangles)


def test_edge_length_for_vertices_inverts_the_count_model():
    h = edge_length_for_vertices(1000, area=10.0, linear=3.0)
    from femshell.mesh.generators import _vertices_for_edge_length
    assert _vertices_for_edge_length(h, 10.0, 3.0) == pytest.approx(1000)


# ----------------------------------------------------------------------------- disk

def test_disk_plain():
    m = disk(radius=2.0, edge_length=0.25)
    assert_valid(m, 1, ["outer"])
    assert np.all(m.points[:, 2] == 0)
    assert np.all(normals(m)[:, 2] > 0)
    r = np.hypot(*m.points[np.unique(m.boundary["outer"])][:, :2].T)
    assert np.allclose(r, 2.0, rtol=1e-9)
    assert_segments_run_with_surface_on_left(m, ["outer"])


def test_disk_inner_circle_conforms_and_is_refined():
    R, r, h, hi = 10.0, 3.0, 1.0, 0.4
    m = disk(radius=R, edge_length=h, inner_radius=r, inner_edge_length=hi)
    assert_valid(m, 1, ["outer", "inner"])
    t = m.topology
    # "inner" is an interior curve: its segments are edges with two triangles
    inner_edges = t.boundary_edge_groups["inner"]
    assert np.all(t.edge_faces[inner_edges, 1] >= 0)
    # its vertices lie on the circle to rounding, and the segments close the circle
    iv = np.unique(m.boundary["inner"])
    assert np.allclose(np.hypot(*m.points[iv][:, :2].T), r, rtol=1e-9)
    seg_len = np.linalg.norm(np.diff(m.points[m.boundary["inner"]], axis=1)[:, 0], axis=1)
    assert seg_len.sum() == pytest.approx(2 * math.pi * r, rel=0.01)
    assert len(iv) == len(m.boundary["inner"])
    assert seg_len.mean() == pytest.approx(hi, rel=0.25)
    # counter-clockwise about +z
    p = m.points[m.boundary["inner"]]
    assert np.all(p[:, 0, 0] * p[:, 1, 1] - p[:, 0, 1] * p[:, 1, 0] > 0)
    # no triangle crosses the circle: all vertices of a triangle on one side (or on it)
    rv = np.hypot(m.points[:, 0], m.points[:, 1])[m.triangles]
    assert not np.any((rv.min(axis=1) < r - 1e-9) & (rv.max(axis=1) > r + 1e-9))
    # refinement: edges near the circle are shorter than far away
    e = t.edges
    mid = np.hypot(*(0.5 * (m.points[e[:, 0]] + m.points[e[:, 1]]))[:, :2].T)
    length = np.linalg.norm(m.points[e[:, 0]] - m.points[e[:, 1]], axis=1)
    assert length[np.abs(mid - r) < hi].mean() < 0.7 * length[mid > 8.0].mean()
    assert np.all(normals(m)[:, 2] > 0)
    assert_segments_run_with_surface_on_left(m, ["outer"])


def test_disk_refined_inside_has_the_inner_edge_length_across_the_inner_disk():
    R, r, h, hi = 10.0, 3.0, 1.0, 0.25
    band = disk(radius=R, edge_length=h, inner_radius=r, inner_edge_length=hi)
    m = disk(radius=R, edge_length=h, inner_radius=r, inner_edge_length=hi, refine_inside=True)
    assert_valid(m, 1, ["outer", "inner"])
    assert "refine_inside" in m.name and "refine_inside" not in band.name

    def lengths(mesh, lo, hi_):
        e = mesh.topology.edges
        mid = np.hypot(*(0.5 * (mesh.points[e[:, 0]] + mesh.points[e[:, 1]]))[:, :2].T)
        sel = (mid > lo) & (mid < hi_)
        return np.linalg.norm(mesh.points[e[sel, 0]] - mesh.points[e[sel, 1]], axis=1).mean()

    # at the centre, 3 away from the circle: the band-only mesh has grown to about 0.25 + 0.3 (3 - 0.25)
    assert lengths(m, 0.0, 1.0) == pytest.approx(hi, rel=0.2)
    assert lengths(band, 0.0, 1.0) > 2.5 * hi
    # along the circle both are refined alike, and far outside both reach the outer size
    assert lengths(m, r - 0.2, r + 0.2) == pytest.approx(lengths(band, r - 0.2, r + 0.2), rel=0.15)
    assert lengths(m, 8.5, 9.5) == pytest.approx(h, rel=0.25)


def test_disk_inner_circle_without_refinement():
    m = disk(radius=1.0, edge_length=0.1, inner_radius=0.5)
    assert_valid(m, 1, ["outer", "inner"])
    iv = np.unique(m.boundary["inner"])
    assert np.allclose(np.hypot(*m.points[iv][:, :2].T), 0.5, rtol=1e-9)


def test_disk_n_vertices():
    m = disk(radius=10.0, n_vertices=1000)
    assert abs(m.n_vertices - 1000) <= 100


# ----------------------------------------------------------------------------- plate, strip

SIDES = {"left": (0, 0.0), "right": (0, "lx"), "bottom": (1, 0.0), "top": (1, "ly")}


def check_rectangle(m, lx, ly):
    assert_valid(m, 1, list(SIDES))
    assert np.all(normals(m)[:, 2] > 0)
    for k, (col, val) in SIDES.items():
        val = {"lx": lx, "ly": ly}.get(val, val)
        assert np.allclose(m.points[np.unique(m.boundary[k]), col], val, atol=1e-12), k
    assert_segments_run_with_surface_on_left(m, list(SIDES))
    area = 0.5 * np.linalg.norm(normals(m), axis=1).sum()
    assert area == pytest.approx(lx * ly, rel=1e-12)
    assert m.points[:, 0].min() == pytest.approx(0.0) and m.points[:, 0].max() == pytest.approx(lx)


def test_plate_unstructured():
    m = plate(2.0, 1.0, edge_length=0.2)
    check_rectangle(m, 2.0, 1.0)
    assert np.all(m.points[:, 2] == 0)


@pytest.mark.parametrize("diagonal", ["right", "left", "alternate", "crossed"])
def test_plate_structured(diagonal):
    m = plate(2.0, 1.0, edge_length=0.25, structured=True, diagonal=diagonal)
    check_rectangle(m, 2.0, 1.0)
    cells = 8 * 4
    if diagonal == "crossed":
        assert m.n_vertices == 9 * 5 + cells and m.n_triangles == 4 * cells
    else:
        assert m.n_vertices == 9 * 5 and m.n_triangles == 2 * cells


def test_plate_structured_right_diagonals():
    m = plate(1.0, 1.0, edge_length=0.5, structured=True, diagonal="right")
    e = m.points[m.topology.edges]
    d = e[:, 1] - e[:, 0]
    diag = (np.abs(d[:, 0]) > 1e-12) & (np.abs(d[:, 1]) > 1e-12)
    assert np.all(d[diag, 0] * d[diag, 1] > 0)   # every diagonal from lower left to upper right


def test_plate_structured_n_vertices():
    m = plate(1.0, 1.0, n_vertices=441, structured=True)
    assert m.n_vertices == 441
    # crossed: (1/h + 1)^2 grid vertices and 1/h^2 cell centres (the centres were left out: 925 for 500)
    m = plate(1.0, 1.0, n_vertices=481, structured=True, diagonal="crossed")
    assert m.n_vertices == 481
    assert strip(10.0, 1.0, n_vertices=11 * 101, structured=True).n_vertices == 11 * 101
    assert strip(10.0, 1.0, n_vertices=12, structured=True).n_vertices == 22   # at least one cell across


def test_strip():
    m = strip(length=5.0, width=0.5, edge_length=0.1)
    check_rectangle(m, 5.0, 0.5)
    assert m.name.startswith("strip")
    s = strip(4.0, 1.0, edge_length=0.5, structured=True)
    check_rectangle(s, 4.0, 1.0)


# ----------------------------------------------------------------------------- annulus

def test_annulus():
    m = annulus(0.5, 1.0, edge_length=0.1)
    assert_valid(m, 0, ["outer", "inner"])
    assert np.all(normals(m)[:, 2] > 0)
    for k, r in (("outer", 1.0), ("inner", 0.5)):
        assert np.allclose(np.hypot(*m.points[np.unique(m.boundary[k])][:, :2].T), r, rtol=1e-9)
    assert_segments_run_with_surface_on_left(m, ["outer", "inner"])


def test_annulus_slit():
    m = annulus(0.5, 1.0, edge_length=0.1, slit=True)
    assert_valid(m, 1, ["outer", "inner", "slit-a", "slit-b"])
    assert np.all(normals(m)[:, 2] > 0)
    a, b = m.boundary["slit-a"], m.boundary["slit-b"]
    # the two sides are separate vertices at the same places, on the positive x-axis
    assert len(a) == len(b) >= 5
    assert not set(a.ravel().tolist()) & set(b.ravel().tolist())
    va, vb = np.unique(a), np.unique(b)
    assert np.allclose(m.points[va, 1], 0.0) and np.all(m.points[va, 0] >= 0.5 - 1e-12)
    pa = np.sort(m.points[va, 0])
    pb = np.sort(m.points[vb, 0])
    assert np.array_equal(pa, pb)
    assert pa[0] == pytest.approx(0.5) and pa[-1] == pytest.approx(1.0)
    # slit-a borders the triangles above the slit, slit-b those below
    t = m.topology
    for name, sign in (("slit-a", 1), ("slit-b", -1)):
        faces = t.edge_faces[t.boundary_edge_groups[name], 0]
        assert np.all(t.edge_faces[t.boundary_edge_groups[name], 1] < 0)     # boundary edges
        assert np.all(sign * centroids(m)[faces, 1] > 0)
    # segment by segment, the two sides coincide
    assert np.allclose(np.sort(m.points[a].sum(axis=1)[:, 0]), np.sort(m.points[b].sum(axis=1)[:, 0]))
    assert_segments_run_with_surface_on_left(m, ["outer", "inner", "slit-a", "slit-b"])
    # the boundary is one closed loop: outer, slit-b, inner, slit-a
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    be = t.edges[t.boundary_edges]
    g = coo_matrix((np.ones(len(be)), (be[:, 0], be[:, 1])), shape=(m.n_vertices,) * 2)
    _, label = connected_components(g, directed=False)
    assert len(np.unique(label[be[:, 0]])) == 1
    assert np.all(np.bincount(be.ravel(), minlength=m.n_vertices)[np.unique(be)] == 2)
    # exactly the slit vertices are duplicated: every other position appears once
    assert len(np.unique(m.points, axis=0)) == m.n_vertices - len(vb)


# ----------------------------------------------------------------------------- cylinder

def test_cylinder_full():
    R, L = 1.0, 2.0
    m = cylinder(radius=R, length=L, edge_length=0.2)
    assert_valid(m, 0, ["bottom", "top"])
    assert np.allclose(np.hypot(m.points[:, 0], m.points[:, 1]), R, rtol=1e-9)
    c = centroids(m)
    radial = np.einsum("ij,ij->i", normals(m)[:, :2], c[:, :2])
    assert np.all(radial > 0)
    assert np.allclose(m.points[np.unique(m.boundary["bottom"]), 2], 0.0, atol=1e-12)
    assert np.allclose(m.points[np.unique(m.boundary["top"]), 2], L)
    assert_segments_run_with_surface_on_left(m, ["bottom", "top"])


def test_cylinder_panel():
    t0, t1 = -0.5, 1.0
    m = cylinder(radius=2.0, length=1.0, edge_length=0.2, angle_range=(t0, t1))
    assert_valid(m, 1, ["bottom", "top", "side-a", "side-b"])
    theta = np.arctan2(m.points[:, 1], m.points[:, 0])
    assert theta.min() == pytest.approx(t0) and theta.max() == pytest.approx(t1)
    assert np.allclose(theta[np.unique(m.boundary["side-a"])], t0)
    assert np.allclose(theta[np.unique(m.boundary["side-b"])], t1)
    assert np.all(np.einsum("ij,ij->i", normals(m)[:, :2], centroids(m)[:, :2]) > 0)
    assert_segments_run_with_surface_on_left(m, ["bottom", "top", "side-a", "side-b"])


# ----------------------------------------------------------------------------- hemisphere

def test_hemisphere():
    R = 3.0
    m = hemisphere(radius=R, edge_length=0.4)
    assert_valid(m, 1, ["equator"])
    assert np.allclose(np.linalg.norm(m.points, axis=1), R, rtol=1e-9)
    assert m.points[:, 2].min() >= -1e-12
    assert np.allclose(m.points[np.unique(m.boundary["equator"]), 2], 0.0, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", normals(m), centroids(m)) > 0)
    area = 0.5 * np.linalg.norm(normals(m), axis=1).sum()
    assert area == pytest.approx(2 * math.pi * R**2, rel=0.01)
    assert_segments_run_with_surface_on_left(m, ["equator"])


def test_hemisphere_hole():
    R, hole = 1.0, 0.4
    m = hemisphere(radius=R, edge_length=0.1, hole_angle=hole)
    assert_valid(m, 0, ["equator", "hole"])
    assert np.allclose(m.points[np.unique(m.boundary["hole"]), 2], R * math.cos(hole))
    assert m.points[:, 2].max() == pytest.approx(R * math.cos(hole))
    assert np.all(np.einsum("ij,ij->i", normals(m), centroids(m)) > 0)


def test_hemisphere_n_vertices():
    m = hemisphere(radius=30.0, n_vertices=1000)
    assert abs(m.n_vertices - 1000) <= 100


@pytest.mark.parametrize("make", [
    lambda n: plate(2.0, 1.0, n_vertices=n),
    lambda n: strip(10.0, 1.0, n_vertices=n),
    lambda n: annulus(0.5, 1.0, n_vertices=n, slit=True),
    lambda n: cylinder(1.0, 3.0, n_vertices=n),
    lambda n: cylinder(1.0, 3.0, n_vertices=n, angle_range=(0.0, 2.0)),
    lambda n: hemisphere(1.0, n_vertices=n, hole_angle=1.0),
])
def test_n_vertices_all_generators(make):
    assert abs(make(800).n_vertices - 800) <= 80


# ----------------------------------------------------------------------------- determinism

def test_determinism_all_gmsh_generators():
    for make in (lambda: disk(1.0, edge_length=0.15, inner_radius=0.4, inner_edge_length=0.08, seed=2),
                 lambda: annulus(0.5, 1.0, edge_length=0.15, slit=True, seed=2),
                 lambda: cylinder(1.0, 1.0, edge_length=0.2, seed=2),
                 lambda: hemisphere(1.0, edge_length=0.2, hole_angle=0.3, seed=2)):
        a, b = make(), make()
        assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
        assert a.boundary.keys() == b.boundary.keys()
        assert all(np.array_equal(a.boundary[k], b.boundary[k]) for k in a.boundary)


# ----------------------------------------------------------------------------- gmsh session

def test_reuses_a_running_gmsh_session():
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("callers-model")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        sphere(1.0, edge_length=0.3)
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() == "callers-model"
        assert gmsh.model.getEntities(3) == [(3, 1)]
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 0.3
        assert not any(name.startswith("femshell") for name in gmsh.model.list())
    finally:
        gmsh.finalize()
    assert not gmsh.isInitialized()
    sphere(1.0, edge_length=0.5)
    assert not gmsh.isInitialized()


# ----------------------------------------------------------------------------- argument errors

@pytest.mark.parametrize("call, word", [
    (lambda: sphere(radius=-1.0), "radius"),
    (lambda: sphere(radius=float("nan")), "radius"),
    (lambda: sphere(radius="big"), "radius"),
    (lambda: sphere(n_vertices=5), "n_vertices"),
    (lambda: sphere(n_vertices=2.5e3), "n_vertices"),
    (lambda: sphere(n_vertices=100, edge_length=0.1), "not both"),
    (lambda: sphere(edge_length=0.0), "edge_length"),
    (lambda: sphere(edge_length=2.0), "edge_length"),
    (lambda: sphere(radius=1.0, edge_length=1e-5), "edge_length"),
    (lambda: sphere(seed=-1), "seed"),
    (lambda: sphere(seed=1.5), "seed"),
    (lambda: disk(inner_radius=2.0), "inner_radius"),
    (lambda: disk(inner_radius=1.0), "inner_radius"),
    (lambda: disk(inner_edge_length=0.01), "inner_radius"),
    (lambda: disk(inner_radius=0.5, refine_inside=True), "inner_edge_length"),
    (lambda: disk(edge_length=0.1, inner_radius=0.5, inner_edge_length=0.2), "inner_edge_length"),
    (lambda: plate(lx=0.0), "lx"),
    (lambda: plate(ly=-1.0), "ly"),
    (lambda: plate(diagonal="diagonal"), "diagonal"),
    (lambda: strip(width=0.0), "width"),
    (lambda: annulus(1.0, 0.5), "inner_radius"),
    (lambda: annulus(0.5, 1.0, edge_length=0.6), "edge_length"),
    (lambda: annulus(0.05, 1.0, edge_length=0.1, slit=True), "edge_length"),
    (lambda: cylinder(length=-2.0), "length"),
    (lambda: cylinder(angle_range=(1.0, 1.0)), "angle_range"),
    (lambda: cylinder(angle_range=(0.0, 7.0)), "angle_range"),
    (lambda: cylinder(angle_range=1.0), "angle_range"),
    (lambda: hemisphere(hole_angle=0.0), "hole_angle"),
    (lambda: hemisphere(hole_angle=math.pi / 2), "hole_angle"),
    # outside the range gmsh handles: 1e30 exhausted the memory, 1e-300 divided by zero
    (lambda: sphere(radius=1e30, n_vertices=500), r"radius must be in \[1e-06, 100000\]"),
    (lambda: sphere(radius=1e-300, n_vertices=500), r"radius must be in \[1e-06, 100000\]"),
    (lambda: plate(lx=1e7), "lx must be in"),
    (lambda: cylinder(length=1e-9), "length must be in"),
])
def test_argument_errors_name_the_parameter(call, word):
    with pytest.raises(ValueError, match=word):
        call()


def test_generated_meshes_pass_topology():
    # the named curves of every generator are edges of the mesh (topology raises MeshError otherwise)
    for m in (disk(1.0, edge_length=0.2, inner_radius=0.5), annulus(0.5, 1.0, 0.2, slit=True),
              cylinder(1.0, 1.0, 0.3, angle_range=(0.0, 1.0))):
        try:
            m.topology
        except MeshError as exc:  # pragma: no cover - the assertion message is the point
            pytest.fail(str(exc))


def test_meshing_keeps_the_callers_sigterm_handler():
    """gmsh.initialize resets SIGTERM; a run that handles it (orderly stop, checkpoint) must keep it.
    In a child process: without the handler the signal would end the test run."""
    import subprocess
    import sys

    code = ("import os, signal, time\n"
            "got = []\n"
            "signal.signal(signal.SIGTERM, lambda *a: got.append(1))\n"
            "from femshell.mesh import sphere\n"
            "sphere(1.0, n_vertices=100)\n"
            "os.kill(os.getpid(), signal.SIGTERM)\n"
            "time.sleep(0.05)\n"
            "print('handled', len(got))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "handled 1" in out.stdout, out.stderr[-500:]
