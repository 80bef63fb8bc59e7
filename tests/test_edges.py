"""Edges of the command line and of huge inputs (issue 65, items 4 and 6): each failed before its fix."""

import io
import re
import time

import pytest

from femshell.cli import main
from femshell.scene import SceneError, load_scene
from femshell.scene import estimate as est
from femshell.scene import build, runner


def test_a_table_given_with_set_merges_into_its_section():
    """--set 'material={E=2}' silently replaced the whole section (the membrane law fell back to SVK)."""
    base = load_scene("default")
    sc = load_scene("default", ["material={E=2}"])
    assert sc["material"]["E"] == 2
    assert {k: v for k, v in sc["material"].items() if k != "E"} == {k: v for k, v in base["material"].items()
                                                                       if k != "E"}
    assert base["material"]["law"] != "svk" and sc["material"]["law"] == base["material"]["law"]


def test_an_empty_out_is_refused(capsys):
    assert main(["run", "default", "--out", "", "--dry-run"]) == 2
    assert "--out is empty" in capsys.readouterr().err


def test_a_solver_kind_typo_is_named_once():
    with pytest.raises(SceneError) as err:
        load_scene("default", ["solver.kind=tiem"])
    assert 'did you mean "time"' in str(err.value) and 'kind = "None"' not in str(err.value)


def test_a_directory_given_as_a_scene_is_named_a_directory(tmp_path, capsys):
    (tmp_path / "summary.json").write_text("{}")
    assert main(["run", str(tmp_path), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "a directory, not a scene file" in err and "--resume" in err


def test_a_subcommands_usage_error_shows_its_usage(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["run", "default", "--bogus"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: femshell run") and "unrecognized arguments: --bogus" in err


def test_the_time_left_is_shown_only_when_it_means_something():
    p = runner.Progress(io.StringIO())
    p.history = [(0.0, 0.0), (10.0, 1e-7)]          # a huge t_final: 1e-8 of the run per step
    assert p.remaining() is None
    p.history = [(0.0, 0.0), (1000.0, 1e-3)]        # a rate that would take 11.6 days
    assert p.remaining() is None
    p.history = [(0.0, 0.0), (10.0, 0.1)]
    assert p.remaining() == pytest.approx(90.0)


def test_a_single_spots_spacing_is_a_dash():
    pattern = {"n_spots": 1, "spot_radius": 4.2, "spacing": 3.6e-15, "kind": "spots", "n_ridges": 0,
               "fraction_patterned": 0.5}
    fin = {"t": 1.0, "max_c": 1.0, "max_H": 0.1, "pattern": pattern, "non_elliptic_elements": 0}
    line = runner.TimeRunner.report_lines(None, fin)[0]
    assert "spacing –" in line and "e-15" not in line
    pattern.update(n_spots=2, spacing=7.5)
    assert "spacing 7.5" in runner.TimeRunner.report_lines(None, fin)[0]


# ----------------------------------------------------------------------------- item 4: huge meshes

def test_a_mesh_beyond_the_machines_memory_is_refused_before_meshing(monkeypatch, capsys):
    """--set mesh.n_vertices=5000000 --dry-run meshed for minutes past 3.7 GB without a word."""
    monkeypatch.setattr(runner, "machine_memory", lambda: (8e9, 6e9))

    def no_meshing(sc):
        raise AssertionError("gmsh was started")

    monkeypatch.setattr(runner, "make_mesh", no_meshing)
    monkeypatch.setattr(build, "make_mesh", no_meshing)
    assert main(["run", "default", "--set", "mesh.n_vertices=5000000", "--dry-run"]) == 2
    err = capsys.readouterr().err
    need = re.search(r"5000000 vertices needs about ([\d.e+]+) GB", err)
    fit = re.search(r"at most about (\d+) vertices fit", err)
    assert need and float(need.group(1)) > 8 and "this machine's 8 GB (6 GB available)" in err
    assert fit and 10_000 < int(fit.group(1)) < 5_000_000


def test_the_estimate_is_printed_and_large_meshes_say_they_progress(monkeypatch, capsys):
    assert main(["run", "default", "--set", "mesh.n_vertices=300", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "  estimate   ~" in out and "per time step" in out and "meshing about" not in out
    monkeypatch.setattr(runner, "LARGE_MESH", 200)
    assert main(["run", "default", "--set", "mesh.n_vertices=300", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "meshing about 300 vertices with gmsh" in out and "  meshed: " in out


def test_the_heartbeat_prints_while_its_block_runs():
    s = io.StringIO()
    with runner._heartbeat(s, "  still meshing", time.perf_counter(), every=0.02):
        time.sleep(0.2)
    n = s.getvalue().count("still meshing")
    time.sleep(0.1)
    assert n >= 2 and s.getvalue().count("still meshing") == n       # and stops with the block


def test_expected_vertices_follow_the_generators():
    from femshell.mesh import disk, plate, sphere

    cases = (({"kind": "sphere", "radius": 15.0, "edge_length": 1.5}, lambda: sphere(15.0, edge_length=1.5)),
             ({"kind": "plate", "lx": 2.0, "ly": 1.0, "edge_length": 0.1}, lambda: plate(2.0, 1.0, 0.1)),
             ({"kind": "disk", "radius": 5.0, "edge_length": 0.5}, lambda: disk(5.0, 0.5)))
    for section, make in cases:
        n = est.expected_vertices(section)
        assert abs(n - make().n_vertices) < 0.15 * n, section
    assert est.expected_vertices({"kind": "sphere", "n_vertices": 1234}) == 1234
    assert est.expected_vertices({"kind": "file", "file": "x.vtu"}) is None
