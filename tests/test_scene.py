"""Scene files: validation errors, --set overrides, dry runs that build nothing (no solves here)."""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from femshell.cli import main
from femshell.scene import SceneError, list_scenes, load_scene, plan
from femshell.scene.schema import apply_overrides, dump_toml, parse_override, parse_scene, validate

SPHERE = """
description = "a test scene"
[mesh]
kind = "sphere"
radius = 5.0
n_vertices = 200
[shell]
thickness = 1.0
[solver]
kind = "time"
t_final = 1.0
"""

PLATE = """
description = "a clamped plate"
[mesh]
kind = "plate"
lx = 1.0
ly = 1.0
edge_length = 0.25
structured = true
[material]
nu = 0.3
[shell]
thickness = 0.01
thickness_mode = "uniform"
[growth]
law = "uniform"
[[boundary]]
type = "clamped"
curve = "left"
[solver]
kind = "continuation"
parameter = "growth.strain"
stop = 1e-3
"""


DISK_GROWTH = """
description = "a disk whose inner circle grows"
[mesh]
kind = "disk"
radius = 10.0
edge_length = 2.5
[shell]
thickness = 2.0
[growth]
law = "inner_region"
inner_radius = 3.0
[solver]
kind = "continuation"
parameter = "growth.strain"
stop = 0.5
"""


def write(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


@pytest.fixture
def errors_of(tmp_path, monkeypatch):
    """Errors of a scene text written to ./scene.toml (named as a user would type it)."""
    monkeypatch.chdir(tmp_path)

    def get(_tmp, text, overrides=()):
        write(tmp_path, text)
        with pytest.raises(SceneError) as e:
            load_scene("scene.toml", overrides)
        return e.value.errors
    return get


# ----------------------------------------------------------------------------- embedded scenes

def test_embedded_scenes_are_valid_and_described():
    scenes = list_scenes()
    assert list(scenes)[0] == "default"
    assert {"default", "sphere-spots", "sphere-ridges", "sphere-decay", "disk-wrinkles", "clamped-plate-buckling",
            "cantilever-roll-up"} <= set(scenes)
    for name, desc in scenes.items():
        assert desc and "\n" not in desc, name
        sc = load_scene(name)
        assert sc.name == name and sc["description"] == desc


def test_scenes_command_lists_and_prints(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("default ")
    assert main(["scenes", "disk-wrinkles"]) == 0
    assert "[mesh]" in capsys.readouterr().out
    assert main(["scenes", "nope"]) == 2
    assert main(["scenes", "sphere-decy"]) == 2
    assert "did you mean 'sphere-decay'?" in capsys.readouterr().err


def test_unknown_scene_name_suggests():
    with pytest.raises(SceneError, match="did you mean 'sphere-spots'"):
        load_scene("sphere-spot")


# ----------------------------------------------------------------------------- validation errors

def test_out_of_range_names_key_and_range(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE + "[material]\nnu = 0.7\n")
    assert errs == ["scene.toml: [material] nu = 0.7 is out of range: 0 <= nu <= 0.5"]


@pytest.mark.parametrize("extra, expected", [
    ("[material]\nnuu = 0.3\n", "[material] unknown key 'nuu'; did you mean 'nu'?"),
    ("[materail]\nnu = 0.3\n", "[materail] is not a section; did you mean [material]?"),
    ("[growth]\nlaw = \"contractility\"\nc_str = 0.2\n", "unknown key 'c_str'; did you mean 'c_star'?"),
    ("[growth]\nlaw = \"contractility\"\nlam_min = 20.0\n", "lam_max = 15 is out of range: lam_min = 20 <= lam_max"),
    ("[growth]\nlaw = \"contractility\"\nb = -1.0\n", "[growth] b = -1.0 is out of range: 0 < b"),
    ("[chemistry]\nD = -0.1\n", "[chemistry] D = -0.1 is out of range: 0 <= D"),
    ("[chemistry]\nD = 1e300\n", "[chemistry] D = 1e+300 is out of range: a non-zero number's magnitude must be in "
                                  "[1e-30, 1e+30]"),
    ("[initial]\npole = [0.0, 0.0, 1e-40]\n", "[initial] pole = [0.0, 0.0, 1e-40] is out of range: a non-zero"),
    ("[initial]\nwidth = \"wide\"\n", "[initial] width = \"wide\" must be a number, got a string"),
    ("[output]\nevery = 1.5\n", "[output] every = 1.5 must be an integer"),
    ("[output]\nfields = [\"c\", \"Lamda\"]\n", "unknown field 'Lamda'; did you mean 'Lambda'?"),
    ("[[boundary]]\ntype = \"clamped\"\ncurve = \"outer\"\n", "a sphere mesh is closed and has no boundary curve"),
    ("[[loads]]\ntype = \"dead_pressure\"\npressure = 1.0\n", "not supported by the time loop"),
    ("[material]\nlaw = \"neohookean\"\n", 'is not one of "svk", "neo-hookean"; did you mean "neo-hookean"?'),
])
def test_each_error_is_one_clear_line(tmp_path, errors_of, extra, expected):
    errs = errors_of(tmp_path, SPHERE + extra)
    assert any(expected in e for e in errs), errs
    assert all(e.startswith("scene.toml: ") and "\n" not in e for e in errs)


def test_natural_curvature_must_be_finite(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE, ["shell.natural_curvature=nan"])
    assert errs == ['scene.toml: [shell] natural_curvature = nan must be a finite number or one of "mesh"']


def test_shell_thickness_type_and_range(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE.replace("thickness = 1.0", 'thickness = "2"'))
    assert any("[shell] thickness = \"2\" must be a number, got a string" in e for e in errs)
    errs = errors_of(tmp_path, SPHERE.replace("thickness = 1.0", "thickness = 0.0"))
    assert any("[shell] thickness = 0.0 is out of range: 0 < thickness" in e for e in errs)


def test_inconsistent_combinations(tmp_path, errors_of):
    errs = errors_of(tmp_path, PLATE + "[chemistry]\nD = 0.1\n")
    assert any("[chemistry] is given but solver.kind = \"continuation\" has no chemistry" in e for e in errs)
    errs = errors_of(tmp_path, PLATE.replace('"growth.strain"', '"growth.strian"'))
    assert any("parameter = \"growth.strian\" is not one of" in e and "did you mean \"growth.strain\"" in e
               for e in errs)
    errs = errors_of(tmp_path, PLATE.replace('"growth.strain"', '"loads.factor"'))
    assert any("parameter = \"loads.factor\" but the scene has no [[loads]]" in e for e in errs)
    errs = errors_of(tmp_path, PLATE.replace('curve = "left"', 'curve = "lft"'))
    assert any("curve = \"lft\" is not a boundary curve of the plate mesh; did you mean \"left\"?" in e for e in errs)
    errs = errors_of(tmp_path, PLATE.replace('kind = "continuation"', 'kind = "time"'))
    assert any("law = \"uniform\" cannot run in time" in e for e in errs)
    errs = errors_of(tmp_path, PLATE + "[mesh2]\n")
    assert len(errs) == 1 and "[mesh2] is not a section; did you mean [mesh]?" in errs[0]
    # a continuation that would start or stop outside its parameter's range (was met only mid-run)
    errs = errors_of(tmp_path, PLATE.replace("stop = 1e-3", "start = -2.0\nstop = 1e-3"))
    assert errs == ["scene.toml: [solver] start = -2 is out of range for growth.strain: > -1 (a stretch 1 + g > 0)"]


def test_contradictory_continuation_and_initial_keys_are_refused(tmp_path, errors_of):
    # accepted before: a stop at the scene's own start (a traceback after the build), stop_at / switch_branch
    # without detection (a long run that never stopped at the branch point), a zero elongation direction
    # (silently y). Keys made inert by a switch a user flips with --set (switch_branch = false, initial.kind =
    # "none") stay accepted: the embedded scenes carry them
    errs = errors_of(tmp_path, PLATE.replace("stop = 1e-3", "stop = 0.0"))
    assert errs == ["scene.toml: [solver] stop = 0 equals the start (growth.strain) = 0: nothing to follow"]
    errs = errors_of(tmp_path, PLATE + 'detect = false\nstop_at = ["branch"]\nswitch_branch = true\n')
    assert [e.split("] ")[1].split(" ")[0] for e in errs] == ["stop_at", "switch_branch"]
    assert all("needs detect = true" in e for e in errs)
    errs = errors_of(tmp_path, DISK_GROWTH, ["growth.inner_radius=12.0"])
    assert errs == ['scene.toml: [growth] inner_radius = 12 is out of range: 0 < R2 < the disk\'s radius 10 (r < R2 '
                    'would cover the whole disk; law = "uniform" grows it all)']
    errs = errors_of(tmp_path, DISK_GROWTH, ["solver.parameter=growth.inner_radius", "growth.transition=0.2",
                                             "solver.stop=10.0"])
    assert len(errs) == 1 and errs[0].startswith("scene.toml: [solver] stop = 10 is out of range: 0 < R2 <")
    errs = errors_of(tmp_path, SPHERE + "[initial]\ndirection = [0.0, 0.0, 0.0]\n")
    assert errs == ["scene.toml: [initial] direction = [0, 0, 0] must be a non-zero vector"]


def test_key_of_another_kind_is_named(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE.replace("radius = 5.0", "radius = 5.0\nwidth = 2.0"))
    assert any("[mesh] width is not used by kind = \"sphere\"" in e for e in errs)
    errs = errors_of(tmp_path, PLATE.replace("stop = 1e-3", "stop = 1e-3\nt_final = 3.0"))
    assert any("[solver] t_final is not used by kind = \"continuation\"" in e for e in errs)


def test_missing_mesh_file_and_bad_toml(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE.replace('kind = "sphere"\nradius = 5.0\nn_vertices = 200',
                                              'file = "meshes/nothing.vtu"'))
    assert any("[mesh] file = \"meshes/nothing.vtu\": no such file" in e for e in errs)
    errs = errors_of(tmp_path, SPHERE + "[material\n")
    assert len(errs) == 1 and "not valid TOML" in errs[0]


def test_all_errors_are_reported_at_once(tmp_path, errors_of):
    errs = errors_of(tmp_path, SPHERE + "[material]\nnu = 0.9\nE = -1.0\n")
    assert len(errs) == 2


# ----------------------------------------------------------------------------- overrides

def test_parse_override_values():
    assert parse_override("solver.t_final=5") == (["solver", "t_final"], 5)
    assert parse_override("mesh.kind=disk") == (["mesh", "kind"], "disk")
    assert parse_override("output.pictures=false") == (["output", "pictures"], False)
    assert parse_override("initial.pole=[0, 1, 0]") == (["initial", "pole"], [0, 1, 0])
    with pytest.raises(SceneError, match="expected KEY=VALUE"):
        parse_override("solver.t_final")


def test_overrides_apply_and_are_validated(tmp_path):
    p = write(tmp_path, SPHERE.replace("n_vertices = 200", "edge_length = 1.0"))
    sc = load_scene(str(p), ["mesh.n_vertices=150", "solver.t_final=0.5"])
    assert sc["mesh"]["n_vertices"] == 150 and sc["mesh"]["edge_length"] is None   # the last resolution wins
    assert sc["solver"]["t_final"] == 0.5
    with pytest.raises(SceneError, match=r"\[solver\] unknown key 't_finl'; did you mean 't_final'"):
        load_scene(str(p), ["solver.t_finl=3"])
    raw = parse_scene(PLATE, "x")
    out = apply_overrides(raw, ["boundary.0.curve=right"])
    assert out["boundary"][0]["curve"] == "right" and raw["boundary"][0]["curve"] == "left"


def test_overrides_are_named_in_the_description():
    """A run's scene, summary and header say which values differ from the file's."""
    sc = load_scene("sphere-single-bulge", ["mesh.radius=15", "chemistry.D=0.5"])
    assert sc["description"] == load_scene("sphere-single-bulge")["description"] + \
        " [--set mesh.radius=15 chemistry.D=0.5]"
    assert load_scene("sphere-single-bulge", ["description=R = 15", "mesh.radius=15"])["description"] == "R = 15"
    raw = parse_scene(PLATE, "x")
    assert apply_overrides(raw, ["boundary.0.curve=right"], note=False)["description"] == raw["description"]


def test_dump_toml_round_trip():
    for name in list_scenes():
        sc = load_scene(name)
        again = validate(parse_scene(dump_toml(sc.data), "x"), name=name, label="x", source=sc.source)
        assert again.data == sc.data and again.config == sc.config, name


# ----------------------------------------------------------------------------- the command line

def test_cli_bad_scene_exit_2_no_traceback_and_no_output_touched(tmp_path, capsys):
    p = write(tmp_path, SPHERE + "[material]\nnu = 0.7\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    code = main(["run", str(p), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip() == f"femshell run: error: {p}: [material] nu = 0.7 is out of range: 0 <= nu <= 0.5"
    assert "Traceback" not in err
    assert sorted(x.name for x in out.iterdir()) == ["keep.txt"]
    assert not (tmp_path / "scene-out").exists()


def test_cli_bad_scene_in_a_subprocess(tmp_path):
    p = write(tmp_path, PLATE.replace('curve = "left"', 'curve = "outer"'))
    r = subprocess.run([sys.executable, "-m", "femshell.cli", "run", str(p), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "is not a boundary curve of the plate mesh" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()


def test_run_help_documents_set():
    r = subprocess.run([sys.executable, "-m", "femshell.cli", "run", "--help"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0
    for word in ("--set KEY=VALUE", "--resume", "--overwrite", "--dry-run", "--max-steps"):
        assert word in r.stdout


# ----------------------------------------------------------------------------- dry runs build nothing

DRY = """
import sys, json
from femshell import chemistry, coupled
from femshell.shell import model
def refuse(what):
    def init(*a, **k):
        raise AssertionError(f"a dry run built a {what}")
    return init
model.ShellModel.__init__ = refuse("ShellModel")          # a dry run must not even build the shell,
coupled.CoupledLoop.__init__ = refuse("CoupledLoop")      # nor the time loop,
chemistry.ReactionDiffusion.__init__ = refuse("ReactionDiffusion")    # nor the chemistry
from femshell.scene import run_scene
run_scene(sys.argv[1], dry_run=True, overrides=sys.argv[2:])
mods = ["femshell.solvers.continuation", "pyvista", "jax"]
print(json.dumps({m: m in sys.modules for m in mods}))
"""


# the model's parameter classes (femshell.coupled) give the scene's physical defaults, so they are imported;
# nothing is built from them
@pytest.mark.parametrize("scene, overrides, imported", [
    ("clamped-plate-buckling", ["mesh.edge_length=0.3"], {"femshell.solvers.continuation": False}),
    ("default", ["mesh.n_vertices=200"], {"femshell.solvers.continuation": False}),
])
def test_dry_run_builds_and_imports_nothing(tmp_path, scene, overrides, imported):
    r = subprocess.run([sys.executable, "-c", DRY, scene, *overrides], capture_output=True, text=True, timeout=180,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    mods = json.loads(lines[-1])
    for m, v in imported.items():
        assert mods[m] is v, (m, mods)
    assert not mods["pyvista"]
    text = "\n".join(lines[:-1])
    assert "unknowns" in text and "nothing computed" in text
    assert list(tmp_path.iterdir()) == []           # nothing written


def test_plan_flags(tmp_path):
    sc = load_scene("clamped-plate-buckling", ["mesh.edge_length=0.3"])
    lines, flags = plan(sc)
    assert flags["continuation"] and not flags["chemistry"] and not flags["time_loop"]
    assert "not built  chemistry, diffusion operator, time loop, loads" in "\n".join(lines)
    sc = load_scene("default", ["mesh.n_vertices=200", "chemistry.D=0"])
    _, flags = plan(sc)
    assert flags["chemistry"] and flags["time_loop"] and not flags["diffusion_operator"] and not flags["continuation"]
    _, flags = plan(load_scene("default", ["mesh.n_vertices=200", "chemistry.D=0.4"]))
    assert flags["diffusion_operator"]
    _, flags = plan(load_scene("cantilever-roll-up", ["mesh.edge_length=1.0"]))
    assert flags["loads"] and flags["unknowns"] > 0 and flags["solver"] == "static"


def test_dry_run_cli(capsys, tmp_path):
    assert main(["run", "disk-wrinkles", "--dry-run", "--set", "mesh.edge_length=2.5", "--set",
                 "mesh.inner_edge_length=1.5", "--out", str(tmp_path / "d")]) == 0
    out = capsys.readouterr().out
    assert "pseudo-arclength continuation in growth.strain" in out and "not built  chemistry" in out
    assert "curves outer, inner (interior)" in out      # the refinement circle is no boundary
    assert not (tmp_path / "d").exists()


def test_mesh_file_scene_and_its_curves(tmp_path):
    from femshell.mesh import plate, write_mesh
    from femshell.scene import make_mesh

    write_mesh(plate(1.0, 1.0, edge_length=0.25, structured=True), tmp_path / "p.vtu")
    text = PLATE.replace('kind = "plate"\nlx = 1.0\nly = 1.0\nedge_length = 0.25\nstructured = true',
                         'file = "p.vtu"')
    p = write(tmp_path, text)
    sc = load_scene(str(p))
    assert sc["mesh"]["kind"] == "file" and sc["mesh"]["file"] == str((tmp_path / "p.vtu").resolve())
    lines, flags = plan(sc)
    assert flags["n_vertices"] == 25
    p = write(tmp_path, text.replace('curve = "left"', 'curve = "west"'))
    with pytest.raises(SceneError, match=r"curve = \"west\" is not a boundary curve of p.vtu \(curves: "):
        make_mesh(load_scene(str(p)))


def test_resume_on_a_changed_mesh_file_is_refused(tmp_path, capsys):
    """A mesh file rewritten between a run and its --resume (same vertex count) would continue the
    run on another shape: refused, naming it; the run there is untouched."""
    from femshell.cli import main
    from femshell.mesh import plate, write_mesh
    from femshell.mesh.surface import SurfaceMesh

    m = plate(1.0, 1.0, edge_length=0.25, structured=True)
    write_mesh(m, tmp_path / "p.vtu")
    text = PLATE.replace('kind = "plate"\nlx = 1.0\nly = 1.0\nedge_length = 0.25\nstructured = true',
                         'file = "p.vtu"').replace("stop = 1e-3", "stop = 1e-3\nmax_steps = 4\nn_eigs = 0")
    p = write(tmp_path, text)
    out = tmp_path / "run"
    args = ["run", str(p), "--out", str(out), "-q", "--set", "output.pictures=false"]
    assert main(args + ["--max-steps", "1"]) == 0
    pts = m.points.copy()
    pts[:, 2] = 0.1 * pts[:, 0] ** 2                   # the same plate, curved
    write_mesh(SurfaceMesh(pts, m.triangles, m.boundary), tmp_path / "p.vtu")
    before = {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()}
    assert main(["run", "--out", str(out), "--resume", "-q"]) == 2
    assert "was made on another mesh: the scene's mesh has as many vertices, but other triangles or vertex " \
           "positions (was its mesh file changed?)" in capsys.readouterr().err
    assert {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()} == before
    write_mesh(m, tmp_path / "p.vtu")                   # the original back: the resume goes on
    assert main(["run", "--out", str(out), "--resume", "-q"]) == 0


def test_resume_from_another_directory_with_another_scene_is_refused(tmp_path, capsys):
    """The run's mesh file moved away: its stored scene no longer validates as it stands. A scene
    with the same mesh (moved) but another thickness must still be refused, not resumed as if equal;
    the same scene with the moved mesh resumes."""
    from femshell.cli import main
    from femshell.mesh import plate, write_mesh

    write_mesh(plate(1.0, 1.0, edge_length=0.25, structured=True), tmp_path / "p.vtu")
    text = PLATE.replace('kind = "plate"\nlx = 1.0\nly = 1.0\nedge_length = 0.25\nstructured = true',
                         'file = "p.vtu"').replace("stop = 1e-3", "stop = 1e-3\nmax_steps = 4\nn_eigs = 0")
    p = write(tmp_path, text)
    out = tmp_path / "run"
    assert main(["run", str(p), "--out", str(out), "-q", "--set", "output.pictures=false", "--max-steps", "1"]) == 0
    (tmp_path / "b").mkdir()
    (tmp_path / "p.vtu").rename(tmp_path / "b" / "p.vtu")
    q = write(tmp_path / "b", text.replace("thickness = 0.01", "thickness = 0.02"))
    before = {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()}
    assert main(["run", str(q), "--out", str(out), "--resume", "-q", "--set", "output.pictures=false"]) == 2
    err = capsys.readouterr().err
    assert "made with another scene than the one given now" in err and "[shell] thickness: 0.01 in the run" in err
    assert "[mesh] file" not in err                       # the move alone is no difference: the content is checked
    assert {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()} == before
    # the same scene beside the moved mesh resumes
    q = write(tmp_path / "b", text)
    assert main(["run", str(q), "--out", str(out), "--resume", "-q", "--set", "output.pictures=false"]) == 0


def test_mesh_file_with_a_defect_is_a_scene_error(tmp_path):
    """A drawn mesh is checked like a generated one: a collapsed triangle is named, not met in the model."""
    from femshell.mesh import plate, write_mesh
    from femshell.mesh.surface import SurfaceMesh
    from femshell.scene import make_mesh

    m = plate(1.0, 1.0, edge_length=0.25, structured=True)
    pts = m.points.copy()
    pts[6] = pts[7]                           # vertex 6 onto its neighbour: two triangles of area 0
    write_mesh(SurfaceMesh(pts, m.triangles, m.boundary), tmp_path / "p.vtu")
    text = PLATE.replace('kind = "plate"\nlx = 1.0\nly = 1.0\nedge_length = 0.25\nstructured = true',
                         'file = "p.vtu"')
    with pytest.raises(SceneError, match=r"(?s)\[mesh\] file: mesh 'p.vtu' is invalid .*degenerate triangles: triangle 3 has area 0"):
        make_mesh(load_scene(str(write(tmp_path, text))))


def test_free_mesh_file_of_two_pieces_is_a_scene_error(tmp_path):
    """Only one piece would be pinned against rigid motion: the other's Hessian is singular."""
    from femshell.mesh import plate, write_mesh
    from femshell.mesh.surface import SurfaceMesh
    from femshell.scene import make_mesh

    m = plate(1.0, 1.0, edge_length=0.25, structured=True)
    two = SurfaceMesh(np.vstack([m.points, m.points + [2.0, 0.0, 0.0]]),
                      np.vstack([m.triangles, m.triangles + m.n_vertices]))
    write_mesh(two, tmp_path / "two.vtu")
    text = PLATE.replace('kind = "plate"\nlx = 1.0\nly = 1.0\nedge_length = 0.25\nstructured = true',
                         'file = "two.vtu"')
    free = text.split("[[boundary]]")[0] + "[solver]" + text.split("[solver]")[1]
    with pytest.raises(SceneError, match="two.vtu has 2 separate pieces; a free shell is pinned"):
        make_mesh(load_scene(str(write(tmp_path, free))))
    # supports on one piece only: the other is named, with where it is
    from femshell.mesh import read_mesh

    first = next(k for k, v in read_mesh(tmp_path / "two.vtu").topology.boundary_vertex_groups.items()
                 if v.max() < m.n_vertices)
    one = text.replace('curve = "left"', f'curve = "{first}"')
    with pytest.raises(SceneError, match=r"2 separate pieces and 1 of them no support \(piece 1: 25 vertices "
                                         r"around \[2.5, 0.5, 0.0\]\)"):
        make_mesh(load_scene(str(write(tmp_path, one))))


def test_membrane_law_reaches_the_shell(tmp_path):
    from femshell.scene.build import coupled_parameters

    params, _, _ = coupled_parameters(load_scene(write(tmp_path, SPHERE + "[material]\nlaw = \"neo-hookean\"\n")))
    assert params.material.law == "neo-hookean"
    params, _, _ = coupled_parameters(load_scene(write(tmp_path, SPHERE)))
    assert params.material.law == "svk"                      # design.md 1.2 by default


def test_a_time_scene_passes_its_source_rule_to_the_loop():
    from femshell.coupled import SOURCE_RULES
    from femshell.scene.build import coupled_parameters
    from femshell.scene.schema import SOLVER_KEYS

    assert SOLVER_KEYS["time"]["source_rule"].choices == SOURCE_RULES     # the schema offers what the loop knows
    assert coupled_parameters(load_scene("default"))[1].source_rule == "extrapolated"
    scene = load_scene("default", ["solver.source_rule=start"])
    assert coupled_parameters(scene)[1].source_rule == "start"
    with pytest.raises(SceneError, match='source_rule = "midpoint" is not one of "start", "extrapolated"'):
        load_scene("default", ["solver.source_rule=midpoint"])


def test_a_time_scene_passes_its_step_control_to_the_loop():
    from femshell.coupled import STEP_CONTROLS
    from femshell.scene.build import coupled_parameters
    from femshell.scene.schema import SOLVER_KEYS

    assert SOLVER_KEYS["time"]["step_control"].choices == STEP_CONTROLS
    assert coupled_parameters(load_scene("default"))[1].step_control == "stretch"
    stepping = coupled_parameters(load_scene("default", ["solver.step_control=error", "solver.error_tol=0.02",
                                                         "solver.error_ds_max=0.3"]))[1]
    assert (stepping.step_control, stepping.error_tol, stepping.error_ds_max) == ("error", 0.02, 0.3)
    with pytest.raises(SceneError, match='step_control = "time" is not one of "stretch", "error"'):
        load_scene("default", ["solver.step_control=time"])
    with pytest.raises(SceneError, match="error_tol"):
        load_scene("default", ["solver.error_tol=0"])


def test_sections_are_typed_and_the_physical_defaults_are_the_models(tmp_path, monkeypatch):
    import femshell.coupled as coupled
    from femshell.scene.config import ChemistryConfig, InitialConfig, TimeSolver

    sc = load_scene(write(tmp_path, SPHERE))
    assert isinstance(sc.chemistry, ChemistryConfig) and isinstance(sc.initial, InitialConfig)
    assert isinstance(sc.solver, TimeSolver) and sc.solver.t_final == sc["solver"]["t_final"]
    model, spot, stepping = coupled.MechanochemicalModel(), coupled.InitialSpot(), coupled.TimeStepping()
    assert (sc.material.nu, sc.growth.lam_max, sc.chemistry.w, sc.chemistry.Hs) == \
        (model.nu, model.lam_max, model.w, model.Hs)
    assert (sc.initial.pole, sc.initial.distance, sc.solver.dt_max) == (spot.pole, spot.distance, stepping.dt_max)
    # a default is read from the model's class when a scene is checked, not copied into the scene's
    monkeypatch.setattr(coupled.MechanochemicalModel.__dataclass_fields__["w"], "default", 7.0)
    assert load_scene(write(tmp_path, SPHERE)).chemistry.w == 7.0
