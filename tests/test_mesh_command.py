"""`femshell mesh` on the command line: the foundation issue's acceptance examples."""

import subprocess
import sys

import numpy as np
import pytest

from femshell.geometry import triangle_area_vectors
from femshell.mesh import read_mesh


def _run(*args):
    return subprocess.run([sys.executable, "-m", "femshell.cli", *args], capture_output=True, text=True, timeout=300)


def test_sphere_command(tmp_path):
    out = tmp_path / "s.vtu"
    r = _run("mesh", "sphere", "--radius", "30", "--vertices", "2500", "-o", str(out))
    assert r.returncode == 0, r.stderr
    mesh = read_mesh(out)
    assert abs(mesh.n_vertices - 2500) <= 250
    assert mesh.topology.is_closed and mesh.topology.euler_characteristic == 2
    assert len(mesh.topology.inconsistent_edges) == 0
    # outward: positive enclosed volume, and every normal points away from the centre
    x = mesh.points[mesh.triangles]
    assert np.einsum("mi,mi->m", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() > 0
    assert (np.einsum("mi,mi->m", triangle_area_vectors(mesh.points, mesh.triangles), x.mean(1)) > 0).all()


def test_disk_command_has_inner_circle(tmp_path):
    out = tmp_path / "d.vtu"
    r = _run("mesh", "disk", "--radius", "10", "--inner-radius", "3", "-o", str(out))
    assert r.returncode == 0, r.stderr
    mesh = read_mesh(out)
    assert np.ptp(mesh.points[:, 2]) == 0
    inner = mesh.topology.edges[mesh.topology.boundary_edge_groups["inner"]]
    radius = np.linalg.norm(mesh.points[inner][..., :2], axis=-1)
    assert len(inner) >= 12 and np.allclose(radius, 3.0, rtol=1e-9)
    # a polygon: its segments close up around the origin
    angles = np.sort(np.arctan2(mesh.points[np.unique(inner), 1], mesh.points[np.unique(inner), 0]))
    assert np.diff(angles).max() < 2 * np.pi / 12


@pytest.mark.parametrize("args, words", [
    (["mesh", "sphere", "--radius", "-1", "-o", "x.vtu"], "--radius must be > 0"),
    (["mesh", "sphere", "--radius", "1", "-o", "x.txt"], ".vtu"),
    (["mesh", "hemisphere", "--hole-angle", "95", "-o", "x.vtu"], "(0, 90) degrees, got 95"),
    (["mesh", "cylinder", "--angle", "0", "400", "-o", "x.vtu"], "< 360 degrees, got 0 400"),
    (["mesh", "annulus", "-o", "x.vtu"], "--inner-radius and --outer-radius are required"),
    # an option the kind ignores, and gmsh's own failures, are usage errors, not tracebacks
    (["mesh", "plate", "--vertices", "7", "-o", "x.vtu"], "--vertices does not apply to plate (its options: "),
    (["mesh", "sphere", "--edge-length", "1e-300", "-o", "x.vtu"], "edge_length must be at least"),
    (["mesh", "cylinder", "--angle", "0", "1e-10", "-o", "x.vtu"], "which gmsh meshes as a full tube"),
    (["mesh", "hemisphere", "--hole-angle", "1e-6", "-o", "x.vtu"], "which gmsh does not cut at edge length"),
    (["mesh", "cylinder", "--angle", "0", "1e-6", "-o", "x.vtu"], "(an extreme option value? see femshell mesh "),
    # ranges that read as they are checked
    (["mesh", "sphere", "--radius", "inf", "-o", "x.vtu"], "radius must be in [1e-06, 100000]"),
    (["mesh", "disk", "--inner-radius", "1", "-o", "x.vtu"], "inner_radius must be in (0, 1), got 1.0"),
    (["mesh", "disk", "--inner-radius", "0.5", "--refine-inside", "-o", "x.vtu"],
     "refine_inside needs inner_edge_length"),
    (["mesh", "annulus", "--inner-radius", "1", "--outer-radius", "2", "--refine-inside", "-o", "x.vtu"],
     "--refine-inside does not apply to annulus"),
    (["mesh", "annulus", "--inner-radius", "1", "--outer-radius", "1.0000001", "-o", "x.vtu"],
     "too slender to mesh: edges must be at most the ring width outer_radius - inner_radius (1e-07)"),
])
def test_mesh_command_bad_input(tmp_path, args, words):
    r = _run(*[a if a != "x.vtu" and a != "x.txt" else str(tmp_path / a) for a in args])
    assert r.returncode != 0
    assert words in r.stderr
    assert "Traceback" not in r.stderr


def test_a_directory_as_output_is_named(tmp_path):
    (tmp_path / "d.vtu").mkdir()
    r = _run("mesh", "sphere", "-o", str(tmp_path / "d.vtu"), "--overwrite")
    assert r.returncode == 2 and "is a directory: give a file name ending in .vtu" in r.stderr


def test_existing_output_is_kept_unless_overwrite(tmp_path):
    out = tmp_path / "s.vtu"
    out.write_text("someone's file")
    r = _run("mesh", "sphere", "--vertices", "100", "-o", str(out))
    assert r.returncode == 2 and "exists; pass --overwrite" in r.stderr
    assert out.read_text() == "someone's file"
    r = _run("mesh", "sphere", "--vertices", "100", "-o", str(out), "--overwrite")
    assert r.returncode == 0, r.stderr
    assert read_mesh(out).topology.is_closed


def test_output_directories_that_cannot_be_used(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    r = _run("validate", "patch-tests", "--out", str(afile))      # refused before the case runs
    assert r.returncode == 2 and "is a file, not a directory" in r.stderr and "Traceback" not in r.stderr
    r = _run("mesh", "sphere", "--vertices", "100", "-o", str(afile / "s.vtu"))   # a parent that is a file
    assert r.returncode == 2 and r.stderr.startswith("femshell mesh: error: ") and "Traceback" not in r.stderr


def test_help_lists_every_subcommand():
    r = _run("--help")
    for sub in ("mesh", "validate", "run", "scenes"):
        assert sub in r.stdout
