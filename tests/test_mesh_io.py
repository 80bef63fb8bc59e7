"""Tests of femshell.mesh.io (round trips, atomic writes, errors) and of the files in meshes/."""

import os
from pathlib import Path

import numpy as np
import pytest

from femshell.mesh import MeshError, SurfaceMesh, annulus, plate, read_mesh, sphere, write_mesh

MESHES = Path(__file__).resolve().parent.parent / "meshes"
FORMATS = ["msh", "vtu", "xdmf"]


@pytest.fixture(scope="module")
def slit_ring():
    return annulus(0.5, 1.0, edge_length=0.2, slit=True)


def assert_same_mesh(a, b):
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.triangles, b.triangles)
    assert list(a.boundary) == list(b.boundary)
    for k in a.boundary:
        assert np.array_equal(a.boundary[k], b.boundary[k]), k


@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_with_boundary_names(tmp_path, slit_ring, ext):
    path = tmp_path / f"ring.{ext}"
    write_mesh(slit_ring, path)
    back = read_mesh(path)
    assert_same_mesh(slit_ring, back)
    assert back.topology.euler_characteristic == 1
    assert back.name == path.name


@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_closed_surface_and_interior_curve(tmp_path, ext):
    from femshell.mesh import disk

    s = sphere(1.0, edge_length=0.4)
    write_mesh(s, tmp_path / f"s.{ext}")
    back = read_mesh(tmp_path / f"s.{ext}")
    assert_same_mesh(s, back)
    assert back.boundary == {}
    d = disk(1.0, edge_length=0.25, inner_radius=0.5)
    write_mesh(d, tmp_path / f"d.{ext}")
    assert_same_mesh(d, read_mesh(tmp_path / f"d.{ext}"))


@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_data(tmp_path, slit_ring, ext):
    m = slit_ring
    pd = {"c": np.linspace(0, 1, m.n_vertices), "u": m.points * 2.0}
    cd = {} if ext == "msh" else {"s": np.arange(m.n_triangles, dtype=float), "k": np.arange(m.n_triangles)}
    write_mesh(m, tmp_path / f"d.{ext}", point_data=pd, cell_data=cd)
    back, pd2, cd2 = read_mesh(tmp_path / f"d.{ext}", with_data=True)
    assert_same_mesh(m, back)
    assert sorted(pd2) == sorted(pd)
    for k in pd:
        assert np.array_equal(pd2[k], pd[k])
    assert sorted(cd2) == sorted(cd)
    for k in cd:
        assert np.array_equal(cd2[k], cd[k])


def test_msh_refuses_cell_data(tmp_path, slit_ring):
    with pytest.raises(ValueError, match="cell_data"):
        write_mesh(slit_ring, tmp_path / "x.msh", cell_data={"s": np.zeros(slit_ring.n_triangles)})
    assert not list(tmp_path.iterdir())


def test_data_shape_and_reserved_names_checked(tmp_path, slit_ring):
    with pytest.raises(ValueError, match="one row per vertex"):
        write_mesh(slit_ring, tmp_path / "x.vtu", point_data={"c": np.zeros(3)})
    with pytest.raises(ValueError, match="one row per triangle"):
        write_mesh(slit_ring, tmp_path / "x.vtu", cell_data={"c": np.zeros(3)})
    with pytest.raises(ValueError, match="reserved"):
        write_mesh(slit_ring, tmp_path / "x.vtu", cell_data={"boundary_id": np.zeros(slit_ring.n_triangles)})


def test_xdmf_writes_h5_next_to_it_and_moves_with_it(tmp_path, slit_ring):
    write_mesh(slit_ring, tmp_path / "a.xdmf")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "a.xdmf"]
    other = tmp_path / "moved"
    other.mkdir()
    for name in ("a.h5", "a.xdmf"):
        os.replace(tmp_path / name, other / name)
    assert_same_mesh(slit_ring, read_mesh(other / "a.xdmf"))


@pytest.mark.parametrize("ext", FORMATS)
def test_write_is_atomic(tmp_path, slit_ring, ext, monkeypatch):
    path = tmp_path / f"m.{ext}"
    small = plate(1.0, 1.0, edge_length=0.5, structured=True)
    write_mesh(small, path)
    write_mesh(slit_ring, path)                 # overwrite in place
    assert_same_mesh(slit_ring, read_mesh(path))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    import meshio

    def broken(filename, *args, **kwargs):
        Path(filename).write_text("half a file")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken)
    with pytest.raises(OSError, match="disk full"):
        write_mesh(small, path)
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == before                      # old file intact, no temporary left behind


def test_creates_missing_directory(tmp_path, slit_ring):
    path = tmp_path / "a" / "b" / "m.vtu"
    write_mesh(slit_ring, path)
    assert path.is_file()


def test_unknown_extension(tmp_path, slit_ring):
    with pytest.raises(ValueError, match=r"\.msh.*\.vtu.*\.xdmf"):
        write_mesh(slit_ring, tmp_path / "m.stl")
    (tmp_path / "m.xyz").write_text("1 2 3\n")
    with pytest.raises(ValueError, match=r"femshell reads what meshio reads: .*\.obj.*\.stl"):
        read_mesh(tmp_path / "m.xyz")


@pytest.mark.parametrize("ext", ["obj", "stl", "ply", "off", "vtk"])
def test_every_surface_format_meshio_reads(tmp_path, ext):
    """Only .msh, .vtu and .xdmf were read (issue 65, item 7)."""
    import meshio

    m = sphere(1.0, n_vertices=60)
    path = tmp_path / f"s.{ext}"
    meshio.write(path, meshio.Mesh(m.points, [("triangle", m.triangles)]))
    back = read_mesh(path)
    assert back.n_vertices == m.n_vertices and back.n_triangles == m.n_triangles
    tol = 1e-6 if ext == "stl" else 0.0                   # binary STL stores float32
    corners = np.sort(back.points[back.triangles].reshape(len(back.triangles), -1).round(5), axis=0)
    assert np.allclose(corners, np.sort(m.points[m.triangles].reshape(len(m.triangles), -1).round(5), axis=0),
                       atol=tol + 1e-5)
    assert back.topology.n_edges == m.topology.n_edges     # connected as the original


def _ascii_stl(path, points, triangles, jitter):
    """An ASCII STL whose corners are written per facet, each copy moved by up to ``jitter``."""
    rng = np.random.default_rng(1)
    lines = ["solid s"]
    for t in triangles:
        lines += ["facet normal 0 0 0", "outer loop"]
        corners = points[t] + jitter * rng.uniform(-1, 1, (3, 3))
        lines += [f"vertex {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in corners]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join(lines + ["endsolid s", ""]))


def test_stl_duplicated_vertices_are_refused_or_merged_on_request(tmp_path):
    m = sphere(1.0, n_vertices=60)
    path = tmp_path / "soup.stl"
    _ascii_stl(path, m.points, m.triangles, jitter=1e-12)
    with pytest.raises(MeshError, match=r"vertices coincide with another.*merge_vertices = true"):
        read_mesh(path)
    with pytest.warns(RuntimeWarning, match=rf"merged \d+ vertices .* -> {m.n_vertices} vertices"):
        back = read_mesh(path, merge_vertices=True)
    assert back.n_vertices == m.n_vertices and back.topology.n_edges == m.topology.n_edges
    assert back.topology.boundary_edge_groups == {} or not any(len(v) for v in back.boundary.values())
    # vertices apart by more than the tolerance stay apart (a slit in a .vtu is never merged unasked)
    ring = annulus(0.5, 1.0, edge_length=0.3, slit=True)
    write_mesh(ring, tmp_path / "ring.vtu")
    assert read_mesh(tmp_path / "ring.vtu").n_vertices == ring.n_vertices


def test_missing_file(tmp_path):
    path = tmp_path / "nothing.vtu"
    with pytest.raises(FileNotFoundError, match="nothing.vtu"):
        read_mesh(path)


def test_file_without_triangles(tmp_path):
    import meshio

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]])
    meshio.write(tmp_path / "lines.vtu", meshio.Mesh(pts, [("line", np.array([[0, 1], [1, 2]]))]))
    with pytest.raises(MeshError, match="no triangles"):
        read_mesh(tmp_path / "lines.vtu")


def test_other_faces_and_bad_indices_are_refused(tmp_path):
    import meshio

    # half a plate as two triangles, half as a quad: reading only the triangles would drop half of it
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]])
    mixed = [("triangle", np.array([[0, 1, 2], [0, 2, 3]])), ("quad", np.array([[1, 4, 5, 2]]))]
    meshio.write(tmp_path / "mixed.vtu", meshio.Mesh(pts, mixed))
    with pytest.raises(MeshError, match=r"cells other than triangles \(quad\)"):
        read_mesh(tmp_path / "mixed.vtu")
    # a negative index with unused points in the file was renumbered to the last point
    meshio.write(tmp_path / "neg.vtu", meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2], [0, 2, -1]]))]))
    with pytest.raises(MeshError, match=r"triangle 1 has vertex index -1, outside \[0, 5\]"):
        read_mesh(tmp_path / "neg.vtu")


def test_nothing_non_finite_is_written(tmp_path, slit_ring):
    pts = np.array(slit_ring.points)
    pts[3, 0] = np.nan
    with pytest.raises(ValueError, match="1 vertices with non-finite coordinates"):
        write_mesh(SurfaceMesh(pts, slit_ring.triangles, slit_ring.boundary), tmp_path / "x.vtu")
    c = np.zeros(slit_ring.n_vertices)
    c[0] = np.inf
    with pytest.raises(ValueError, match="data 'c' has 1 non-finite values"):
        write_mesh(slit_ring, tmp_path / "x.vtu", point_data={"c": c})
    with pytest.raises(ValueError, match="data 'name' must be numbers, got dtype <U1"):
        write_mesh(slit_ring, tmp_path / "x.vtu", point_data={"name": np.full(slit_ring.n_vertices, "a")})
    assert not (tmp_path / "x.vtu").exists()
    with pytest.raises(ValueError, match="slit must be True or False, got 'no'"):
        annulus(0.5, 1.0, edge_length=0.2, slit="no")


def test_damaged_file(tmp_path):
    (tmp_path / "bad.vtu").write_text("<VTKFile>not really</VTKFile>")
    with pytest.raises(MeshError, match="bad.vtu"):
        read_mesh(tmp_path / "bad.vtu")


@pytest.mark.parametrize("name", ["text.vtu", "text.msh", "empty.vtu"])
def test_unreadable_file_is_a_mesh_error_not_an_exit(tmp_path, name):
    # meshio prints and calls sys.exit(1) for these: the message must come back as a MeshError
    (tmp_path / name).write_text("" if name.startswith("empty") else "just some text\n")
    with pytest.raises(MeshError, match=f"cannot read mesh file .*{name}: Couldn't read file"):
        read_mesh(tmp_path / name)


def test_foreign_file_without_names(tmp_path):
    # a plain meshio file: lines without names or ids are one curve, stray points are dropped
    import meshio

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]])
    meshio.write(tmp_path / "f.vtu", meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2]])),
                                                         ("line", np.array([[0, 1]]))]))
    m = read_mesh(tmp_path / "f.vtu")
    assert m.n_vertices == 3
    assert list(m.boundary) == ["curve-0"]


def test_write_rejects_non_mesh(tmp_path):
    with pytest.raises(TypeError, match="write_mesh needs a SurfaceMesh, got dict"):
        write_mesh({"points": []}, tmp_path / "x.vtu")


# ----------------------------------------------------------------------------- meshes/

READY = {
    "sphere_r1_500.msh": (2, [], 450, 550),
    "disk_r10_R2_3.vtu": (1, ["inner", "outer"], 300, 1500),
    "plate_1x1.vtu": (1, ["bottom", "left", "right", "top"], 100, 200),
    "annulus_slit.vtu": (1, ["inner", "outer", "slit-a", "slit-b"], 250, 450),
    "cylinder_r1_l2.vtu": (0, ["bottom", "top"], 300, 500),
    "hemisphere_r1.vtu": (1, ["equator"], 250, 450),
}


@pytest.mark.parametrize("name", sorted(READY))
def test_ready_meshes_load(name):
    euler, names, lo, hi = READY[name]
    path = MESHES / name
    assert path.stat().st_size < 300 * 1024
    m = read_mesh(path)
    assert isinstance(m, SurfaceMesh)
    assert m.topology.euler_characteristic == euler
    assert sorted(m.boundary) == names
    assert sorted(m.topology.boundary_edge_groups) == names
    assert lo <= m.n_vertices <= hi
    assert len(m.topology.inconsistent_edges) == 0


def test_ready_meshes_listed_in_readme():
    readme = (MESHES / "README.md").read_text()
    on_disk = {p.name for p in MESHES.iterdir() if p.suffix in (".msh", ".vtu", ".xdmf")}
    assert on_disk == set(READY)
    for name in READY:
        assert name in readme


GEO = {
    "sphere.geo": ({"h": 0.4}, 2, []),
    "plate.geo": ({"lx": 2.0, "h": 0.25}, 1, ["bottom", "left", "right", "top"]),
    "disk_inner_circle.geo": ({"h": 2.0, "h_in": 1.0}, 1, ["inner", "outer"]),
    "annulus.geo": ({"h": 0.15}, 0, ["inner", "outer"]),
    "cylinder.geo": ({"h": 0.3}, 0, ["bottom", "top"]),
    "cylinder.geo:panel": ({"h": 0.3, "full": 0, "t0": -0.5, "t1": 1.5}, 1, ["bottom", "side-a", "side-b", "top"]),
    "hemisphere.geo": ({"h": 0.3}, 1, ["equator"]),
    "hemisphere.geo:hole": ({"h": 0.2, "hole": 0.4}, 0, ["equator", "hole"]),
}


@pytest.mark.parametrize("case", sorted(GEO))
def test_geo_sources_mesh_and_read_back(tmp_path, case):
    """Each .geo meshes with gmsh (parameters overridden) and reads back with its physical curve names."""
    import gmsh

    params, euler, names = GEO[case]
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        for k, v in params.items():
            gmsh.parser.setNumber(k, [v])   # seen by DefineConstant; gmsh.open would clear them
        gmsh.merge(str(MESHES / case.split(":")[0]))
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "g.msh"))
    finally:
        gmsh.finalize()
    m = read_mesh(tmp_path / "g.msh")
    assert m.topology.euler_characteristic == euler
    assert sorted(m.boundary) == names
    assert sorted(m.topology.boundary_edge_groups) == names
    assert m.n_vertices < 2000
