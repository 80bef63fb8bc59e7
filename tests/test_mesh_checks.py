"""Tests of femshell.mesh.checks: meshes broken on purpose, orientation repair, quality numbers."""

import re

import numpy as np
import pytest

from femshell.geometry import triangle_area_vectors
from femshell.mesh import (MeshError, MeshReport, SurfaceMesh, annulus, check_mesh, format_quality,
                           orient_consistently, quality_report)
from femshell.mesh.checks import warn_poor_quality


# --------------------------------------------------------------------------- meshes built by hand

def plate(nx=4, ny=3, lx=1.0, ly=1.0):
    """Structured plate of nx x ny squares, two +z triangles per square, z = 0."""
    x, y = np.meshgrid(np.linspace(0, lx, nx + 1), np.linspace(0, ly, ny + 1), indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tri = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return SurfaceMesh(pts, tri, name="plate")


def icosphere():
    """Icosahedron subdivided once and projected to the unit sphere: 42 vertices, 80 outward triangles."""
    t = (1 + np.sqrt(5)) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    # one midpoint per unique edge, then 4 children per face
    he = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges, inv = np.unique(he, axis=0, return_inverse=True)
    mid = len(v) + inv.reshape(-1, 3)                 # midpoints of (0,1), (1,2), (2,0)
    pts = np.vstack([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])])
    pts /= np.linalg.norm(pts, axis=1)[:, None]
    a, b, c = f.T
    ab, bc, ca = mid.T
    tri = np.concatenate([np.column_stack(x) for x in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])])
    return SurfaceMesh(pts, tri, name="icosphere")


def mobius(n=12):
    """Möbius strip: two rails of n vertices, the rails swap when the strip closes."""
    u = 2 * np.pi * np.arange(n) / n
    pts = []
    for s in (-0.3, 0.3):
        r = 1 + s * np.cos(u / 2)
        pts.append(np.column_stack([r * np.cos(u), r * np.sin(u), s * np.sin(u / 2)]))
    pts = np.vstack(pts)
    top, bot = np.arange(n), n + np.arange(n)
    top_next = np.append(top[1:], bot[0])              # the half twist
    bot_next = np.append(bot[1:], top[0])
    tri = np.concatenate([np.column_stack([top, bot, bot_next]), np.column_stack([top, bot_next, top_next])])
    return SurfaceMesh(pts, tri, name="mobius")


def signed_volume(mesh):
    p = mesh.points[mesh.triangles]
    return np.einsum("mi,mi->", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6


def with_triangles(mesh, tri):
    return SurfaceMesh(mesh.points, tri, name=mesh.name)


def flip(tri, faces):
    tri = np.array(tri)
    tri[faces] = tri[faces][:, [0, 2, 1]]
    return tri


# --------------------------------------------------------------------------- good meshes

def test_good_plate_passes():
    r = check_mesh(plate(), require_flat=True, require_closed=False)
    assert isinstance(r, MeshReport)
    assert (r.n_vertices, r.n_triangles, r.n_components) == (20, 24, 1)
    assert r.is_flat and not r.is_closed and r.euler_characteristic == 1
    assert r.area == pytest.approx(1.0)
    assert r.warnings == ()
    assert "mesh OK" in str(r)


def test_good_icosphere_passes():
    m = icosphere()
    assert (m.n_vertices, m.n_triangles) == (42, 80)
    assert signed_volume(m) > 0
    r = check_mesh(m, require_closed=True, require_flat=False)
    assert r.is_closed and r.euler_characteristic == 2 and r.n_boundary_edges == 0


# --------------------------------------------------------------------------- one test per defect

def test_nonfinite_coordinates_named():
    m = plate()
    pts = np.array(m.points)
    pts[7, 1] = np.nan
    pts[11, 0] = np.inf
    with pytest.raises(MeshError) as err:
        check_mesh(m.with_points(pts))
    msg = str(err.value)
    assert "non-finite" in msg and "vertex 7 at [" in msg and "vertex 11 at [inf" in msg
    assert "2 such vertices" in msg


@pytest.mark.parametrize("scale", [0.0, 1e-200, 1e200])
def test_collapsed_or_overflowing_mesh_is_out_of_range(scale):
    # areas (length²) of such meshes underflow to 0 or overflow to inf: the mesh is refused by its size
    m = icosphere()
    span = re.escape(f"{2 * scale:.3g}")
    with pytest.raises(MeshError, match=rf"size out of range: the mesh spans {span} .* outside \[1e-09, 1e\+08\]"):
        check_mesh(m.with_points(np.array(m.points) * scale))


def test_surface_mesh_arguments_are_checked():
    m = icosphere()
    assert SurfaceMesh(m.points, m.triangles, None).boundary == {}
    with pytest.raises(ValueError, match="boundary must be a dict .* got list"):
        SurfaceMesh(m.points, m.triangles, [[0, 1]])
    with pytest.raises(ValueError, match="boundary curve 'a' must be .* dtype float64"):
        SurfaceMesh(m.points, m.triangles, {"a": [[0.5, 1.0]]})
    from femshell.mesh.topology import build_topology

    with pytest.raises(MeshError, match="triangles must be integer vertex indices, got dtype float64"):
        build_topology(np.array(m.triangles, float) + 0.7, m.n_vertices)


def test_index_out_of_range_named():
    m = plate()
    tri = np.array(m.triangles)
    tri[3, 1] = 99
    with pytest.raises(MeshError) as err:
        check_mesh(with_triangles(m, tri))
    msg = str(err.value)
    assert "out of range 0..19" in msg and "triangle 3 refers to vertex 99" in msg and "1 such triangle" in msg


def test_nonmanifold_edge_named():
    m = plate()
    # a fin on the interior edge (0, 5) (diagonal of the first square, triangles 0 and 12)
    pts = np.vstack([m.points, [[0.1, 0.1, 1.0]]])
    tri = np.vstack([m.triangles, [[0, 5, 20]]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "non-manifold edge (0, 5)" in msg and "[0, 12, 24]" in msg and "1 such edges" in msg


def test_inconsistent_orientation_names_edge_and_triangles():
    m = icosphere()
    tri = flip(m.triangles, [5])
    with pytest.raises(MeshError) as err:
        check_mesh(with_triangles(m, tri))
    msg = str(err.value)
    assert "inconsistent orientation" in msg and "3 such edges" in msg
    found = re.findall(r"edge \((\d+), (\d+)\) runs the same way in triangles (\d+) and (\d+)", msg)
    assert len(found) == 3
    for i, j, f0, f1 in found:
        assert {int(i), int(j)} <= set(tri[5].tolist())
        assert 5 in (int(f0), int(f1))


def test_degenerate_triangle_named_with_area():
    # triangle 2 is a sliver of three collinear points between two good triangles
    pts = np.array([[0., 0, 0], [1, 0, 0], [2, 0, 0], [1, 1, 0]])
    tri = np.array([[0, 1, 3], [1, 2, 3], [0, 2, 1]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "degenerate triangles: triangle 2 has area 0 <" in msg and "1 such triangle" in msg
    assert "orientation" not in msg and "inverted" not in msg


def test_repeated_vertex_is_degenerate():
    m = plate()
    tri = np.array(m.triangles)
    tri[4] = [5, 6, 5]
    with pytest.raises(MeshError, match=r"triangle 4 repeats a vertex \[5, 6, 5\]"):
        check_mesh(with_triangles(m, tri))


def test_inverted_triangle_on_flat_mesh_named():
    # square fan around a centre vertex; the centre is pulled out below edge (0, 1),
    # so triangle 0 turns over while the index order stays consistent
    pts = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, -0.5, 0]])
    tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "inverted triangles: triangle 0 has normal z < 0" in msg and "1 such triangle" in msg
    assert "orientation" not in msg


def test_folded_triangle_on_curved_mesh_named():
    # triangle 1 is turned back over triangle 0 across edge (1, 2)
    pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0.1, 0.1, 0.2]])
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "folded triangles: at edge (1, 2) the normals of triangles 0 and 1" in msg


def test_unreferenced_vertices_named():
    m = plate()
    pts = np.vstack([m.points, [[5., 5, 0], [6, 6, 0]]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, m.triangles))
    msg = str(err.value)
    assert "unreferenced vertices" in msg and "vertex 20 at [5.0, 5.0, 0.0]" in msg and "vertex 21" in msg
    assert "2 such vertices" in msg


def test_coincident_vertices_named_unless_a_named_cut():
    # triangle soup (an unmerged STL file): 80 triangles, 240 corners, 42 points: 198 copies
    m = icosphere()
    pts = m.points[m.triangles].reshape(-1, 3)
    with pytest.raises(MeshError, match=r"coincident vertices .* \(198 such pairs\); merge them"):
        check_mesh(SurfaceMesh(pts, np.arange(len(pts)).reshape(-1, 3)))
    # a crack: one triangle takes a copy of the interior vertex 6 (at (0.25, 2/3))
    m = plate()
    pts = np.vstack([m.points, m.points[6]])
    tri = np.array(m.triangles)
    first = np.argwhere(tri == 6)[0]
    tri[first[0], first[1]] = len(pts) - 1
    with pytest.raises(MeshError, match=r"coincident vertices .*: vertices 6 and 20 at \[0.25, 0.666"):
        check_mesh(SurfaceMesh(pts, tri))
    # the annulus' slit: both copies on named boundary curves, a deliberate cut
    check_mesh(annulus(0.5, 1.0, edge_length=0.2, slit=True))
    with pytest.raises(TypeError, match="check_mesh takes a SurfaceMesh, got tuple"):
        check_mesh((pts, tri))


def test_bowtie_vertex_named():
    # two triangles touching only at vertex 2
    pts = np.array([[0., 0, 0], [1, 0, 0], [0.5, 0.5, 0], [0, 1, 0], [1, 1, 0]])
    tri = np.array([[0, 1, 2], [2, 4, 3]])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "non-manifold vertices: vertex 2 at [0.5, 0.5, 0.0] has 2 separate triangle fans" in msg
    assert "1 such vertex" in msg


def test_bowtie_between_two_spheres():
    # two icospheres sharing one vertex: each fan is closed, but there are two of them
    s = icosphere()
    # place the second sphere so its vertex k coincides with the first sphere's vertex 0
    k = int(np.argmin(s.points @ s.points[0]))       # antipode of vertex 0
    pts2 = s.points - s.points[k] + s.points[0]
    tri2 = s.triangles + s.n_vertices
    tri2[tri2 == s.n_vertices + k] = 0
    keep = np.ones(len(pts2), bool)                  # vertex k of the copy is unused: drop it
    keep[k] = False
    pts = np.vstack([s.points, pts2[keep]])
    remap = np.concatenate([np.arange(s.n_vertices), s.n_vertices + np.cumsum(keep) - 1])
    tri = np.vstack([s.triangles, remap[tri2]])
    with pytest.raises(MeshError, match=r"vertex 0 at .* has 2 separate triangle fans"):
        check_mesh(SurfaceMesh(pts, tri))


def test_require_closed_and_flat():
    with pytest.raises(MeshError, match=r"not closed: 14 boundary edges in 1 curve"):
        check_mesh(plate(), require_closed=True)
    with pytest.raises(MeshError, match="closed .* open surface was required"):
        check_mesh(icosphere(), require_closed=False)
    with pytest.raises(MeshError, match=r"not flat: .*vertex \d+ at"):
        check_mesh(icosphere(), require_flat=True)
    with pytest.raises(MeshError, match="flat .* curved surface was required"):
        check_mesh(plate(), require_flat=False)


def test_nearly_flat_plate_names_the_lifted_vertex():
    m = plate()
    pts = np.array(m.points)
    pts[9, 2] = 0.01
    with pytest.raises(MeshError, match=r"not flat: .*vertex 9 at \[.*\] \(1 vertices off"):
        check_mesh(m.with_points(pts), require_flat=True)


def test_normal_convention_errors():
    s = icosphere()
    with pytest.raises(MeshError, match="inward normals on a closed surface: component 0"):
        check_mesh(with_triangles(s, s.triangles[:, [0, 2, 1]]))
    p = plate()
    with pytest.raises(MeshError, match=r"flat surface with -z normals: component 0 \(containing triangle 0\)"):
        check_mesh(with_triangles(p, p.triangles[:, [0, 2, 1]]))


def test_several_defects_reported_together():
    m = plate()
    pts = np.vstack([m.points, [[5., 5, 0]]])
    tri = flip(m.triangles, [0])
    with pytest.raises(MeshError) as err:
        check_mesh(SurfaceMesh(pts, tri))
    msg = str(err.value)
    assert "defect kinds" in msg
    assert "inconsistent orientation" in msg and "unreferenced vertices" in msg and "inverted triangles" in msg


def test_poor_quality_is_a_warning_not_an_error():
    pts = np.array([[0., 0, 0], [1, 0, 0], [0.5, 0.01, 0]])
    r = check_mesh(SurfaceMesh(pts, [[0, 1, 2]]))
    assert r.warnings == ("mesh has 1 triangles with angles under 5 degrees (worst 1.1 at triangle 0); "
                          "expect poor accuracy",)
    assert warn_poor_quality(plate()) is None


# --------------------------------------------------------------------------- orientation repair

def test_orient_repairs_random_flips_on_icosphere():
    rng = np.random.default_rng(1)
    s = icosphere()
    for first_flipped in (False, True):
        faces = rng.choice(s.n_triangles, 30, replace=False)
        if first_flipped:
            faces = np.union1d(faces, [0])
        broken = with_triangles(s, flip(s.triangles, faces))
        assert len(broken.topology.inconsistent_edges) > 0
        fixed = orient_consistently(broken)
        assert len(fixed.topology.inconsistent_edges) == 0
        np.testing.assert_array_equal(fixed.triangles, s.triangles)   # outward everywhere
        assert signed_volume(fixed) > 0
        check_mesh(fixed, require_closed=True)


def test_orient_all_inward_sphere_turns_outward():
    s = icosphere()
    fixed = orient_consistently(with_triangles(s, s.triangles[:, [0, 2, 1]]))
    np.testing.assert_array_equal(fixed.triangles, s.triangles)


def test_orient_repairs_random_flips_on_plate():
    rng = np.random.default_rng(2)
    p = plate(6, 5)
    broken = with_triangles(p, flip(p.triangles, rng.choice(p.n_triangles, 25, replace=False)))
    fixed = orient_consistently(broken)
    assert (triangle_area_vectors(fixed.points, fixed.triangles)[:, 2] > 0).all()
    check_mesh(fixed, require_flat=True)
    # all -z: flipped to +z
    fixed = orient_consistently(with_triangles(p, p.triangles[:, [0, 2, 1]]))
    np.testing.assert_array_equal(fixed.triangles, p.triangles)


def test_orient_open_curved_surface_points_away_from_centroid():
    # the upper half of the icosphere (z > 0.1 at the centroid), given with inward normals
    s = icosphere()
    up = s.points[s.triangles].mean(axis=1)[:, 2] > 0.1
    cap = SurfaceMesh(s.points, s.triangles[up][:, [0, 2, 1]])
    used = np.unique(cap.triangles)
    remap = np.full(s.n_vertices, -1)
    remap[used] = np.arange(len(used))
    cap = SurfaceMesh(s.points[used], remap[cap.triangles])
    fixed = orient_consistently(cap)
    c = fixed.points[fixed.triangles].mean(axis=1)
    n = triangle_area_vectors(fixed.points, fixed.triangles)
    assert (np.einsum("mi,mi->m", n, c) > 0).all()            # outward from the sphere centre
    check_mesh(fixed, require_closed=False)


def test_orient_handles_several_components():
    s, p = icosphere(), plate()
    pts = np.vstack([s.points, p.points + [3.0, 0, 0]])
    tri = np.vstack([s.triangles[:, [0, 2, 1]], p.triangles[:, [0, 2, 1]] + s.n_vertices])
    fixed = orient_consistently(SurfaceMesh(pts, tri))
    np.testing.assert_array_equal(fixed.triangles, np.vstack([s.triangles, p.triangles + s.n_vertices]))
    assert check_mesh(fixed).n_components == 2
    # the plate component alone turned to -z is caught even though the whole mesh is not flat
    tri_down = np.vstack([s.triangles, p.triangles[:, [0, 2, 1]] + s.n_vertices])
    with pytest.raises(MeshError, match=r"-z normals: component 1 \(containing triangle 80\)"):
        check_mesh(SurfaceMesh(pts, tri_down))


def test_orient_returns_same_object_when_nothing_to_do():
    p = plate()
    assert orient_consistently(p) is p


def test_mobius_strip_is_non_orientable():
    m = mobius()
    assert m.topology.euler_characteristic == 0 and len(m.topology.boundary_edge_groups) == 1
    with pytest.raises(MeshError, match=r"non-orientable .* edge \(\d+, \d+\) between triangles \d+ and \d+"):
        orient_consistently(m)
    with pytest.raises(MeshError, match="inconsistent orientation") as err:
        check_mesh(m)
    # it was told to use orient_consistently, which refuses it (issue 65, item 6)
    assert "non-orientable" in str(err.value) and "orient_consistently" not in str(err.value)
    tri = plate().triangles.copy()
    tri[:2] = tri[:2, [0, 2, 1]]
    flipped = SurfaceMesh(plate().points, tri)
    with pytest.raises(MeshError, match="fix with orient_consistently"):      # an orientable one still is
        check_mesh(flipped)


# --------------------------------------------------------------------------- quality numbers

def test_quality_equilateral():
    tri = SurfaceMesh(np.array([[0., 0], [2, 0], [1, np.sqrt(3)]]), [[0, 1, 2]])
    r = quality_report(tri)
    assert r["min_angle_deg"] == pytest.approx(60) and r["max_angle_deg"] == pytest.approx(60)
    assert r["aspect_min"] == pytest.approx(1) and r["aspect_max"] == pytest.approx(1)
    assert r["edge_min"] == pytest.approx(2) and r["edge_spread"] == pytest.approx(1)
    assert r["area_total"] == pytest.approx(np.sqrt(3))
    assert r["n_min_angle_below_10"] == 0


def test_quality_right_isosceles():
    tri = SurfaceMesh(np.array([[0., 0], [1, 0], [0, 1]]), [[0, 1, 2]])
    r = quality_report(tri)
    assert r["min_angle_deg"] == pytest.approx(45) and r["max_angle_deg"] == pytest.approx(90)
    # inradius = area / semi-perimeter = (1/2) / (1 + sqrt2/2) = 1 / (2 + sqrt2);
    # aspect = sqrt2 / (2 sqrt3 / (2 + sqrt2)) = (1 + sqrt2) / sqrt3 = 1.3938...
    assert r["aspect_max"] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3))
    assert r["edge_max"] == pytest.approx(np.sqrt(2)) and r["edge_spread"] == pytest.approx(np.sqrt(2))
    assert r["area_min"] == pytest.approx(0.5)


def test_quality_counts_slivers_and_formats():
    m = plate()
    pts = np.array(m.points)
    pts[5] = [0.25, 0.02, 0]           # vertex 5 at (0.25, 1/3) pulled almost onto the row y = 0: slivers
    q = quality_report(m.with_points(pts))
    assert q["n_min_angle_below_10"] >= q["n_min_angle_below_5"] >= 1
    assert q["min_angle_deg"] < 5
    text = format_quality(q)
    assert "angle [deg]" in text and "aspect ratio" in text and "triangle" in text
    w = warn_poor_quality(m.with_points(pts))
    assert w.startswith(f"mesh has {q['n_min_angle_below_5']} triangles with angles under 5 degrees")
    assert f"at triangle {q['min_angle_triangle']}" in w
