"""End to end through the command line: every embedded scene at a tiny size, outputs, resume, kill -9.

Runs go through ``femshell.cli.main`` in this process (JAX compiles once for all of
them); the kill -9 test runs ``femshell run`` in a subprocess.
"""

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time

import meshio
import numpy as np
import pytest

from femshell.cli import main
from femshell.io import load_checkpoint, read_pvd, save_checkpoint
from femshell.mesh import SurfaceMesh
from femshell.scene import SceneError, list_scenes, load_scene, run_scene

SPHERE_TINY = ["mesh.n_vertices=150", "solver.t_final=0.04", "output.every=1"]
# with D > 0: on 150 vertices the deformed mesh has obtuse triangles, whose negative cotangent
# weights let c dip below 0 (clipped, with a warning)
SPHERE_TINY_DIFFUSION = ["mesh.n_vertices=300", "solver.t_final=0.04", "output.every=1"]
TINY = {
    "default": SPHERE_TINY_DIFFUSION,
    "sphere-seeded-spots": SPHERE_TINY,
    "sphere-regime-single-bulge": SPHERE_TINY_DIFFUSION,
    "sphere-regime-mixed": SPHERE_TINY_DIFFUSION,
    # its seed (c > c* within r = 1.75) bends the shell only on a finer mesh: on 300 vertices the largest
    # energy density is ~1e-5, and the unstrained cells' round-off (~1e-17) exceeds the check's 1e-12 of it
    "sphere-regime-decay": ["mesh.n_vertices=800", "solver.t_final=0.04", "output.every=1"],
    "sphere-spots": SPHERE_TINY,
    "sphere-ridges": SPHERE_TINY,
    "sphere-decay": SPHERE_TINY,
    "sphere-single-bulge": SPHERE_TINY,
    "sphere-propagation": SPHERE_TINY_DIFFUSION,
    "sphere-large-spots": SPHERE_TINY_DIFFUSION,
    "sphere-small": SPHERE_TINY,
    "sphere-uniform-thickness": SPHERE_TINY,
    "sphere-icosahedral": SPHERE_TINY,
    "disk-wrinkles": ["mesh.edge_length=2.5", "mesh.inner_edge_length=1.5", "solver.max_steps=4", "solver.n_eigs=2",
                      "solver.stop=0.3"],
    "clamped-plate-buckling": ["mesh.edge_length=0.4", "solver.stop=1.1e-4", "solver.switch_stop=1.05e-4",
                               "solver.max_steps=6", "solver.n_eigs=2"],
    "cantilever-roll-up": ["mesh.edge_length=0.5", "solver.steps=8"],
}
WITH_PICTURES = {"default", "clamped-plate-buckling"}


def sets(items):
    out = []
    for s in items:
        out += ["--set", s]
    return out


def run(scene, out, extra=(), overrides=(), pictures=False):
    args = ["run", scene, "--out", str(out), "-q", *sets(overrides)]
    if not pictures:
        args += ["--set", "output.pictures=false"]
    return main(args + list(extra))


def check_series(out, min_frames=2):
    entries = read_pvd(out / "series.pvd")
    assert len(entries) >= min_frames
    times = [t for t, _ in entries]
    assert times == sorted(times) and len(set(times)) == len(times)
    last = None
    for _, path in entries:
        m = meshio.read(path)
        tri = [c for c in m.cells if c.type == "triangle"][0].data
        assert m.points.shape[1] == 3 and tri.shape[1] == 3 and tri.max() < len(m.points)
        assert np.all(np.isfinite(m.points))
        for name, v in m.point_data.items():
            assert len(v) == len(m.points) and np.all(np.isfinite(v)), name
        for name, v in m.cell_data.items():
            assert len(v[0]) == len(tri) and np.all(np.isfinite(v[0])), name
        if "c" in m.point_data:
            assert m.point_data["c"].min() >= 0
        last = m
    return entries, last


def test_tiny_set_covers_every_embedded_scene():
    assert set(TINY) == set(list_scenes())


@pytest.mark.parametrize("scene", sorted(TINY))
def test_embedded_scene_runs_tiny(scene, tmp_path):
    out = tmp_path / scene
    code = run(scene, out, overrides=TINY[scene], pictures=scene in WITH_PICTURES)
    summary = json.loads((out / "summary.json").read_text())
    assert code == 0, summary
    assert summary["scene"] == scene and summary["steps"] >= 1 and summary["wall_s"] > 0
    entries, m = check_series(out)
    assert {"displacement", "H"} <= set(m.point_data)
    assert {"thickness", "energy_density", "stretch"} <= set(m.cell_data)
    assert np.all(m.cell_data["thickness"][0] > 0)
    ed = m.cell_data["energy_density"][0]
    assert np.all(ed >= -1e-12 * max(np.abs(ed).max(), 1e-300))      # >= 0 up to round-off
    kind = summary["solver"]
    if kind == "time":
        assert {"c", "Lambda"} <= set(m.point_data)
        assert summary["status"] in ("t_final", "stationary")
        assert summary["final"]["non_elliptic_elements"] == 0           # these scenes stay elliptic
        lam = m.point_data["Lambda"]
        assert np.all((lam >= 10 - 1e-9) & (lam <= 15 + 1e-9))
    elif kind == "continuation":
        assert (out / "branch.csv").exists()
        assert summary["final"]["rows"] >= 2
        if scene == "disk-wrinkles":
            # the disk's first mode is a dome, n = 0 (counted from k = 1 up, a trace of tilt made it "1 wave")
            assert [sp["mode_n"] for sp in summary["final"]["special_points"]] == [0]
    else:
        assert summary["final"]["load_factor"] == 1.0
    if scene in WITH_PICTURES:
        pics = summary["files"]["pictures"]
        assert "pictures/top.png" in pics and "pictures/side.png" in pics
        if kind == "continuation":
            assert "pictures/bifurcation.png" in pics
        for p in pics:
            assert (out / p).stat().st_size > 1000
    state, meta = load_checkpoint(out / "checkpoint.npz")
    assert meta["step"] == summary["steps"]


# ----------------------------------------------------------------------------- resume

RESUME = ["mesh.n_vertices=150", "solver.t_final=0.12", "output.every=1"]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("full") / "run"
    assert run("default", out, overrides=RESUME) == 0
    return out


def assert_same_run(a, b):
    sa, ma = load_checkpoint(a / "checkpoint.npz")
    sb, mb = load_checkpoint(b / "checkpoint.npz")
    assert ma["step"] == mb["step"]
    for k in ("c", "u"):
        assert np.array_equal(sa[k], sb[k]), k          # bit for bit
    assert sa["t"] == sb["t"] and sa["dt"] == sb["dt"]
    ea, eb = read_pvd(a / "series.pvd"), read_pvd(b / "series.pvd")
    assert [t for t, _ in ea] == [t for t, _ in eb]
    fa, fb = meshio.read(ea[-1][1]), meshio.read(eb[-1][1])
    assert np.array_equal(fa.points, fb.points)
    for k in fa.point_data:
        assert np.array_equal(fa.point_data[k], fb.point_data[k]), k


def test_resume_after_max_steps_is_bitwise_identical(uninterrupted, tmp_path):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "2"], overrides=RESUME) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "paused" and s["steps"] == 2
    # a second run into the same directory without --resume is refused, nothing touched
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert run("default", out, overrides=RESUME) == 2
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    assert run("default", out, extra=["--resume"], overrides=RESUME) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["resumes"] == 1 and summary["setting_changes"] == []
    assert_same_run(uninterrupted, out)
    # resuming a finished run does nothing
    assert run("default", out, extra=["--resume"], overrides=RESUME) == 0


def test_resume_can_cap_the_time_step(uninterrupted, tmp_path, capsys):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "2"], overrides=RESUME) == 0
    # dt_initial may not exceed dt_max; the source rule may change too
    cap = ["solver.dt_max=0.004", "solver.dt_initial=0.001", "solver.source_rule='start'"]
    capsys.readouterr()
    args = ["run", "default", "--out", str(out), "--resume", *sets(RESUME + cap), "--set", "output.pictures=false"]
    assert main(args) == 0
    said = capsys.readouterr().out
    assert "changed since the run's last invocation: " in said and "solver.dt_max " in said
    assert "-> 0.004" in said and "solver.source_rule 'extrapolated' -> 'start'" in said
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "t_final" and s["final"]["t"] == pytest.approx(0.12)
    [made] = s["setting_changes"]
    assert made["step"] == 2 and {c["key"]: c["to"] for c in made["changes"]} == {
        "solver.dt_max": 0.004, "solver.dt_initial": 0.001, "solver.source_rule": "start"}
    times = [t for t, _ in read_pvd(out / "series.pvd")]
    assert max(np.diff(times[2:])) <= 0.004 * (1 + 1e-12)      # every step after the resume within the cap
    assert s["steps"] > load_checkpoint(uninterrupted / "checkpoint.npz")[1]["step"]
    assert load_checkpoint(out / "checkpoint.npz")[0]["extrapolate"] == 0     # the held source in use
    scene = (out / "scene.toml").read_text()
    assert "dt_max = 0.004" in scene and 'source_rule = "start"' in scene
    # another solver key is still refused, by name
    assert run("default", out, extra=["--resume"], overrides=RESUME + ["solver.ds_max=0.01"]) == 2
    assert "[solver] ds_max: " in capsys.readouterr().err


def test_resume_reports_changes_against_the_checkpoints_scene(tmp_path):
    """A resume killed before its first checkpoint leaves a newer scene.toml: the steps were made with the
    checkpoint's scene, so resuming with that scene records no change."""
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "2"], overrides=RESUME) == 0
    scene = out / "scene.toml"
    text = scene.read_text()
    assert 'source_rule = "extrapolated"' in text   # as a killed resume with another source rule leaves it:
    scene.write_text(text.replace('source_rule = "extrapolated"', 'source_rule = "start"'))
    assert run("default", out, extra=["--resume"], overrides=RESUME) == 0
    assert json.loads((out / "summary.json").read_text())["setting_changes"] == []


def test_ctrl_c_checkpoints_and_resumes(uninterrupted, tmp_path, monkeypatch):
    from femshell.coupled import CoupledLoop

    out = tmp_path / "run"
    real = CoupledLoop.advance
    calls = {"n": 0}

    def interrupting(self):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(CoupledLoop, "advance", interrupting)
    assert run("default", out, overrides=RESUME) == 130
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["steps"] == 2 and "--resume" in s["message"]
    assert load_checkpoint(out / "checkpoint.npz")[1]["step"] == 2
    monkeypatch.setattr(CoupledLoop, "advance", real)
    # the command the message suggests works as given, although the run had --set overrides
    command = s["message"].split("continue with: femshell ")[1].split()
    assert command == ["run", "--out", str(out), "--resume"]
    assert main(command + ["-q"]) == 0
    assert_same_run(uninterrupted, out)


@pytest.mark.usefixtures("ctrl_c_raises")
def test_ctrl_c_while_a_frame_is_written_keeps_that_frame(uninterrupted, tmp_path, monkeypatch):
    """SIGINT arriving while step 2's frame is written: the frame and the checkpoint of step 2 are
    written before the run stops, and the resumed run has every frame of the uninterrupted one."""
    from femshell import io as fio

    out = tmp_path / "run"
    real = fio.TimeSeriesWriter.write
    calls = {"n": 0}

    def signalled(self, *a, **k):
        calls["n"] += 1
        if calls["n"] == 3:                   # frames of t = 0, step 1, step 2
            signal.raise_signal(signal.SIGINT)
        return real(self, *a, **k)

    monkeypatch.setattr(fio.TimeSeriesWriter, "write", signalled)
    assert run("default", out, overrides=RESUME) == 130
    assert json.loads((out / "summary.json").read_text())["steps"] == 2
    assert load_checkpoint(out / "checkpoint.npz")[1]["step"] == 2
    assert len(read_pvd(out / "series.pvd")) == 3
    monkeypatch.setattr(fio.TimeSeriesWriter, "write", real)
    assert run("default", out, extra=["--resume"], overrides=RESUME) == 0
    assert_same_run(uninterrupted, out)
    assert [t for t, _ in read_pvd(out / "series.pvd")] == [t for t, _ in read_pvd(uninterrupted / "series.pvd")]


@pytest.mark.usefixtures("ctrl_c_raises")
def test_ctrl_c_while_a_finished_run_writes_its_results_keeps_them_consistent(tmp_path, monkeypatch, capsys):
    """A Ctrl-C while summary.json was written left the previous one (12 steps behind the checkpoint, seen
    by interrupting runs at random); one while the pictures were drawn lost the summary too."""
    from femshell import io as fio
    from femshell.scene import runner

    real_summary, real_pictures = fio.write_summary, runner.TimeRunner.pictures

    def signalled_summary(*a, **k):
        signal.raise_signal(signal.SIGINT)
        return real_summary(*a, **k)

    def signalled_pictures(self):
        signal.raise_signal(signal.SIGINT)
        return real_pictures(self)

    monkeypatch.setattr(fio, "write_summary", signalled_summary)
    out = tmp_path / "a"
    assert run("default", out, overrides=SPHERE_TINY) == 130       # interrupted, as any stopped run
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "t_final" and s["steps"] == load_checkpoint(out / "checkpoint.npz")[1]["step"]
    monkeypatch.setattr(fio, "write_summary", real_summary)
    monkeypatch.setattr(runner.TimeRunner, "pictures", signalled_pictures)
    out = tmp_path / "b"
    assert run("default", out, overrides=SPHERE_TINY, pictures=True) == 130
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "t_final" and s["steps"] == load_checkpoint(out / "checkpoint.npz")[1]["step"]
    assert "interrupted while drawing the final pictures" in capsys.readouterr().err


@pytest.mark.usefixtures("ctrl_c_raises")
@pytest.mark.parametrize("renderer", ["raises", "swallows", "import-error"])
def test_ctrl_c_while_the_final_pictures_are_drawn_has_one_outcome(tmp_path, monkeypatch, capsys, renderer):
    """A Ctrl-C while the pictures were drawn gave an ImportError from VTK, a swallowed signal or
    "pictures skipped", always exit 0 (issue 65, item 3). Now: exit 130, the run finished with its
    pictures pending, and --resume draws them."""
    from femshell.scene import runner

    real_pictures = runner.TimeRunner.pictures

    def ctrl_c_in_the_renderer(self):
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            if renderer == "raises":
                raise
            if renderer == "import-error":          # as VTK's import machinery turns it
                raise ImportError("cannot import name 'vtkRenderingOpenGL2' (simulated)") from None
        return real_pictures(self)

    monkeypatch.setattr(runner.TimeRunner, "pictures", ctrl_c_in_the_renderer)
    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY, pictures=True) == 130
    assert "interrupted while drawing the final pictures" in capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "t_final" and s["files"]["pictures_pending"] and s["files"]["pictures"] == []
    monkeypatch.undo()
    if renderer == "swallows":              # femshell render draws them as well as --resume
        assert main(["render", str(out), "--no-movie", "--every", "1000"]) == 0
    else:
        assert main(["run", "--out", str(out), "--resume", "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert "pictures/top.png" in s["files"]["pictures"] and not s["files"]["pictures_pending"]
    assert (out / "pictures" / "top.png").stat().st_size > 1000
    capsys.readouterr()
    assert main(["run", "--out", str(out), "--resume"]) == 0
    assert "nothing to do" in capsys.readouterr().out


def _second_step_raises(monkeypatch, exc):
    """The coupled loop's second step raises ``exc``."""
    from femshell.coupled import CoupledLoop

    real, calls = CoupledLoop.advance, {"n": 0}

    def failing(self):
        calls["n"] += 1
        if calls["n"] == 2:
            raise exc
        return real(self)

    monkeypatch.setattr(CoupledLoop, "advance", failing)


def test_failed_step_stops_with_checkpoint_and_no_nan(tmp_path, monkeypatch):
    from femshell.coupled import CoupledError

    _second_step_raises(monkeypatch, CoupledError("step 2: Newton diverged (simulated)"))
    out = tmp_path / "run"
    assert run("default", out, overrides=RESUME) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "Newton diverged" in s["message"] and s["steps"] == 1
    assert load_checkpoint(out / "checkpoint.npz")[1]["step"] == 1
    check_series(out, min_frames=2)


def test_overwrite_and_render(uninterrupted, tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert run("default", out, overrides=["mesh.n_vertices=150", "solver.t_final=0.02"]) == 0
    assert run("default", out, extra=["--overwrite"], overrides=["mesh.n_vertices=150", "solver.t_final=0.02"]) == 0
    assert (out / "notes.txt").read_text() == "mine"
    assert main(["run", "default", "--out", str(out), "--resume", "--overwrite"]) == 2
    capsys.readouterr()
    assert main(["render", str(uninterrupted), "--every", "2"]) == 0
    assert "rendered" in capsys.readouterr().out
    assert (uninterrupted / "movie.gif").stat().st_size > 1000
    assert sorted(p.name for p in (uninterrupted / "pictures").glob("top_*.png"))
    assert main(["render", str(tmp_path / "nothing")]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["render", str(tmp_path / "empty")]) == 2
    assert "no time series" in capsys.readouterr().err
    assert not any((tmp_path / "empty").iterdir())        # no pictures/ made in a directory that is no run


def test_temporaries_of_a_killed_writer_are_removed(tmp_path):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "1"], overrides=SPHERE_TINY) == 0
    (out / "pictures").mkdir(exist_ok=True)
    gone = subprocess.Popen([sys.executable, "-c", "pass"])     # the id of a process that has ended
    gone.wait()
    dead = gone.pid
    left = [out / f".checkpoint.npz.tmp-{dead}-0123abcd.npz", out / f".summary.json.tmp-{dead}-0123abcd.json",
            out / "pictures" / f".top.png.tmp-{dead}-0123abcd.png"]
    mine = [out / f".notes.txt.tmp-{dead}-0123abcd.txt", out / "pictures" / f".mine.png.tmp-{dead}-0123abcd.png",
            out / "pictures" / f".top_000003.png.tmp-{os.getpid()}-0123abcd.png"]    # its writer still runs
    for p in left + mine:
        p.write_text("x")
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY) == 0
    assert not any(p.exists() for p in left) and all(p.exists() for p in mine)


def test_a_warning_is_one_line_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "2"], overrides=SPHERE_TINY) == 0
    (out / "checkpoint.npz").write_bytes(b"torn")           # the resume falls back to checkpoint.npz.prev
    capsys.readouterr()
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY) == 0
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "checkpoint.npz.prev" in line]
    assert said and all(line.startswith("warning: ") for line in said)
    assert "RuntimeWarning" not in err and "load_checkpoint(" not in err


def test_the_summary_is_written_before_the_pictures(tmp_path, monkeypatch):
    """A renderer that dies natively (VTK without a usable OpenGL) must not leave a finished run
    without its summary; the movie is coloured by output.picture_field."""
    from femshell import viz
    from femshell.scene.runner import TimeRunner

    seen = {}
    pictures, render_run = TimeRunner.pictures, viz.render_run

    def pictures_after_the_summary(self):
        seen["summary"] = json.loads((self.rd.path / "summary.json").read_text())
        return pictures(self)

    def recording_render_run(*args, **kwargs):
        seen["render_run"] = kwargs
        return render_run(*args, **kwargs)

    monkeypatch.setattr(TimeRunner, "pictures", pictures_after_the_summary)
    monkeypatch.setattr(viz, "render_run", recording_render_run)
    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY + ["output.movie=true", "output.picture_field=H"],
               pictures=True) == 0
    assert seen["summary"]["status"] == "t_final" and seen["summary"]["files"]["pictures"] == []
    assert seen["render_run"]["field"] == "H" and seen["render_run"]["every"] == 1
    summary = json.loads((out / "summary.json").read_text())
    assert "movie.gif" in summary["files"]["pictures"] and "pictures/top.png" in summary["files"]["pictures"]


def _files(out):
    return {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}


def test_overwrite_keeps_the_earlier_run_until_the_new_one_starts(tmp_path, monkeypatch):
    from femshell.scene import runner

    out = tmp_path / "run"
    assert run("default", out, overrides=["mesh.n_vertices=150", "solver.t_final=0.02"]) == 0
    before = _files(out)
    assert "series_000001.vtu" in before

    def late_bad_input(self):
        raise ValueError("k0 must be a finite number (simulated: found while building the model)")

    def no_initial_state(self):
        raise runner.StepFailure("the initial equilibrium diverged (simulated)")

    for initialise, code in ((late_bad_input, 2), (no_initial_state, 1)):
        monkeypatch.setattr(runner.TimeRunner, "initialise", initialise)
        assert run("default", out, extra=["--overwrite"], overrides=["mesh.n_vertices=150"]) == code
        assert _files(out) == before                  # every file of the earlier run, unchanged
        assert not (out / runner.REPLACED).exists()
    # --overwrite into a directory without an earlier run: the failure is recorded, nothing is "kept"
    fresh = tmp_path / "fresh"
    assert run("default", fresh, extra=["--overwrite"], overrides=["mesh.n_vertices=150"]) == 1
    assert json.loads((fresh / "summary.json").read_text())["status"] == "failed"
    monkeypatch.undo()
    # a run that starts replaces it
    assert run("default", out, extra=["--overwrite"], overrides=["mesh.n_vertices=150", "solver.t_final=0.01"]) == 0
    assert _files(out)["summary.json"] != before["summary.json"]
    assert not (out / runner.REPLACED).exists()


def test_run_directory_guards(tmp_path, capsys):
    tiny = ["mesh.n_vertices=150", "solver.t_final=0.02"]
    out = tmp_path / "run"
    assert run("default", out, overrides=tiny, extra=["--max-steps", "1"]) == 0
    # frames alone are femshell output: a new run does not overwrite them
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "series_000000.vtu").write_bytes((out / "series_000000.vtu").read_bytes())
    assert run("default", frames, overrides=tiny) == 2
    assert [p.name for p in frames.iterdir()] == ["series_000000.vtu"]
    # a file is not an output directory
    (tmp_path / "afile").write_text("mine")
    assert run("default", tmp_path / "afile", overrides=tiny) == 2
    assert (tmp_path / "afile").read_text() == "mine"
    # resuming on another mesh (the run's scene.toml deleted: the checkpoint's own scene is compared): refused,
    # untouched
    (out / "scene.toml").unlink()
    before = _files(out)
    capsys.readouterr()
    assert run("default", out, extra=["--resume"], overrides=["mesh.n_vertices=300", "solver.t_final=0.02"]) == 2
    err = capsys.readouterr().err
    assert "was made with another scene than the one given now" in err and "[mesh] n_vertices: " in err
    assert _files(out) == before
    # resuming without a checkpoint: refused (it used to start again from t = 0 over the frames)
    for f in out.glob("checkpoint.npz*"):
        f.unlink()
    before = _files(out)
    assert run("default", out, extra=["--resume"], overrides=tiny) == 2
    assert "no checkpoint.npz to resume from" in capsys.readouterr().err
    assert _files(out) == before


def test_continuation_resume(tmp_path):
    over = ["mesh.edge_length=0.4", "solver.stop=1.1e-4", "solver.max_steps=5", "solver.n_eigs=2",
            "solver.switch_branch=false"]
    out = tmp_path / "run"
    assert run("clamped-plate-buckling", out, extra=["--max-steps", "2"], overrides=over) == 0
    assert json.loads((out / "summary.json").read_text())["status"] == "paused"
    assert run("clamped-plate-buckling", out, extra=["--resume"], overrides=over) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "done" and s["final"]["final_value"] == pytest.approx(1.1e-4)
    steps = [r for r in s["final"]["special_points"]]
    assert all(p["kind"] in ("branch", "fold", "possible_branch") for p in steps)
    entries, _ = check_series(out, min_frames=3)
    assert [t for t, _ in entries] == list(range(len(entries)))


def test_a_thick_shell_is_warned_once_and_runs(tmp_path, capsys):
    # sphere-small has R = 15: h = 10 is two thirds of the radius; h = 2 (the paper's) is not warned
    assert run("sphere-small", tmp_path / "thick", overrides=SPHERE_TINY + ["shell.thickness=10"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: the shell is thick") == 1 and "thickness 10 against a surface of size" in err
    assert run("sphere-small", tmp_path / "thin", overrides=SPHERE_TINY) == 0
    assert "thick" not in capsys.readouterr().err


def test_a_fold_finer_than_the_mesh_is_warned(tmp_path, capsys):
    # a plate just past buckling is smooth: no warning; the tiny sphere's spot (edges of 4 against a spot of
    # radius 2) folds by tens of degrees per edge: the warning, and the summary's count checked against the
    # last frame's shape
    from femshell.geometry import fold_angles
    from femshell.scene import runner

    assert run("clamped-plate-buckling", tmp_path / "a", overrides=TINY["clamped-plate-buckling"]) == 0
    assert "neighbouring faces" not in capsys.readouterr().err
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["final"]["max_fold_change_deg"] < 1
    assert run("default", tmp_path / "b", overrides=SPHERE_TINY) == 0
    err = capsys.readouterr().err
    fin = json.loads((tmp_path / "b" / "summary.json").read_text())["final"]
    _, last = check_series(tmp_path / "b")
    rest = last.points - last.point_data["displacement"]
    tri = [c for c in last.cells if c.type == "triangle"][0].data
    ef = SurfaceMesh(rest, tri).topology.edge_faces
    turn = np.abs(fold_angles(last.points, tri, ef) - fold_angles(rest, tri, ef))
    assert fin["max_fold_change_deg"] == pytest.approx(turn.max(), rel=1e-6)
    assert fin["edges_folded_over_limit"] == np.count_nonzero(turn > runner.FOLD_WARNING_DEG) > 0
    assert f"warning: neighbouring faces turn by up to {turn.max():.0f}°" in err


def test_a_step_switch_names_the_steepness(tmp_path, capsys):
    # b = 1e30 makes Λ(c) a step: where c crosses c*, no dt keeps |Δs| under ds_max
    over = ["mesh.n_vertices=300", "growth.b=1e30", "solver.t_final=1", "solver.dt_min=1e-4"]
    assert run("sphere-small", tmp_path / "run", overrides=over) == 1
    err = capsys.readouterr().err
    assert "fell below dt_min" in err and "a change of c of about 8/b = 8e-30 (b = 1e+30)" in err
    assert "growth.b" in err and "solver.ds_max" in err


def test_continuation_resumed_on_the_switched_branch_ends_where_the_uninterrupted_one_does(tmp_path):
    # paused after the first step of the switched branch (6), and exactly at the primary's stop value (2 + 3):
    # the resumes went back down the branch (first) or could not start (second)
    over = TINY["clamped-plate-buckling"]
    assert run("clamped-plate-buckling", tmp_path / "u", overrides=over) == 0
    ref = json.loads((tmp_path / "u" / "summary.json").read_text())["final"]
    assert ref["amplitude"] > 1e-3                                   # buckled: on the switched branch
    for name, pauses in (("a", [6]), ("b", [2, 3])):
        out = tmp_path / name
        assert run("clamped-plate-buckling", out, extra=["--max-steps", str(pauses[0])], overrides=over) == 0
        for k in pauses[1:]:
            assert run("clamped-plate-buckling", out, extra=["--resume", "--max-steps", str(k)], overrides=over) == 0
        assert run("clamped-plate-buckling", out, extra=["--resume"], overrides=over) == 0
        s = json.loads((out / "summary.json").read_text())
        assert s["status"] == "done", (name, s["message"])
        assert s["final"]["final_value"] == pytest.approx(ref["final_value"], rel=1e-9)
        assert s["final"]["amplitude"] == pytest.approx(ref["amplitude"], rel=1e-6)
        # the table's step numbers go on across the resumes (they restarted at 1)
        with open(out / "branch.csv") as f:
            table = list(csv.DictReader(f))
        for branch in ("primary", "switched"):
            steps = [int(r["step"]) for r in table if r["branch"] == branch and not r.get("special")]
            assert steps == list(range(steps[0], steps[0] + len(steps))), (name, branch, steps)


def test_continuation_short_of_its_stop_says_so(tmp_path):
    # 2 steps of ds 1e-6 cannot reach a stop at strain 1e-3: the run is not "done"
    over = ["mesh.edge_length=0.4", "solver.stop=1e-3", "solver.max_steps=2", "solver.n_eigs=0",
            "solver.switch_branch=false", "solver.ds=1e-6"]
    out = tmp_path / "run"
    assert run("clamped-plate-buckling", out, overrides=over) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "max_steps_branch", s["status"]
    assert "primary branch: stopped at solver.max_steps = 2 before its stop value 0.001" in s["message"]
    assert s["final"]["final_value"] < 1e-3


def test_continuation_reaches_a_stop_below_its_start(tmp_path):
    # the branch set off upward whatever the stop, ran away from a stop below the start and ended at max_steps
    over = ["mesh.edge_length=0.4", "solver.stop=-1e-4", "solver.max_steps=6", "solver.n_eigs=0",
            "solver.switch_branch=false", "solver.stop_at=[]"]
    out = tmp_path / "run"
    assert run("clamped-plate-buckling", out, overrides=over) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "done", (s["status"], s["message"])
    assert s["final"]["final_value"] == pytest.approx(-1e-4, rel=1e-12)


def test_continuation_leaving_the_parameter_range_is_named(tmp_path, capsys):
    # strain -0.9999999 is a valid start (stretch > 0) but the parameter's difference step crosses -1
    over = ["mesh.edge_length=0.4", "solver.start=-0.9999999", "solver.max_steps=2", "solver.n_eigs=0"]
    assert run("clamped-plate-buckling", tmp_path / "run", overrides=over) == 1     # a failed run, reported
    out = capsys.readouterr()
    assert "continuation in growth.strain reached -1.0000009, outside its range" in out.out + out.err
    assert "Traceback" not in out.out + out.err


def test_a_loaded_scene_runs_and_a_wrong_type_is_named(tmp_path):
    sc = load_scene("clamped-plate-buckling", ["mesh.edge_length=0.4", "solver.stop=1e-4", "solver.max_steps=2",
                                               "solver.n_eigs=0", "solver.switch_branch=false"])
    assert run_scene(sc, tmp_path / "run", quiet=True, overrides=()) == 0
    with pytest.raises(SceneError, match="already loaded"):
        run_scene(sc, tmp_path / "run2", overrides=["solver.stop=2e-4"])
    with pytest.raises(SceneError, match="got int"):
        load_scene(3)


def test_scene_step_limits_and_newton_iterations_reach_the_solver(tmp_path, monkeypatch):
    # a time scene's solver.max_steps stops one invocation like --max-steps (it was ignored)
    out = tmp_path / "time"
    assert run("default", out, overrides=RESUME + ["solver.max_steps=2"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "paused" and s["steps"] == 2 and "(solver.max_steps)" in s["message"]
    # --max-steps 0 takes no continuation step (it took one)
    over = ["mesh.edge_length=0.4", "solver.stop=1.1e-4", "solver.max_steps=5", "solver.n_eigs=0",
            "solver.switch_branch=false", "solver.newton_max_iter=5"]
    out = tmp_path / "cont"
    assert run("clamped-plate-buckling", out, extra=["--max-steps", "0"], overrides=over) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "paused" and s["steps"] == 0
    # solver.newton_max_iter limits the continuation's corrector (it was not passed on)
    import femshell.solvers.continuation as cont

    seen, real = [], cont.continuation

    def recording(*a, **k):
        seen.append(k.get("max_corrector_iterations"))
        return real(*a, **k)

    monkeypatch.setattr(cont, "continuation", recording)
    assert run("clamped-plate-buckling", tmp_path / "cont2", overrides=over) == 0
    assert seen == [5]


def test_an_unexpected_error_mid_run_is_a_failed_run_with_its_state(tmp_path, monkeypatch, capsys):
    _second_step_raises(monkeypatch, IndexError("index 7 is out of bounds (simulated bug)"))
    out = tmp_path / "run"
    assert run("default", out, overrides=RESUME) == 1           # a failed run (was exit 2, "bad input")
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and s["steps"] == 1
    assert "internal error after step 1 (IndexError: index 7 is out of bounds (simulated bug))" in s["message"]
    assert load_checkpoint(out / "checkpoint.npz")[1]["step"] == 1
    assert "Traceback" in capsys.readouterr().err                   # for the report


def test_a_stationary_run_is_not_sent_round_in_circles(tmp_path, capsys):
    scene = tmp_path / "still.toml"      # no seed, no diffusion: nothing happens, stationary at once
    scene.write_text('description = "a sphere without a seed"\n[mesh]\nkind = "sphere"\nradius = 5.0\n'
                     'n_vertices = 150\n[shell]\nthickness = 1.0\n[growth]\nlaw = "contractility"\n'
                     '[chemistry]\nD = 0.0\n[initial]\nkind = "none"\n[solver]\nkind = "time"\nt_final = 10.0\n')
    out = tmp_path / "run"
    assert run(str(scene), out) == 0
    assert json.loads((out / "summary.json").read_text())["status"] == "stationary"
    capsys.readouterr()
    assert run(str(scene), out, extra=["--resume"], overrides=["solver.t_final=20"]) == 0
    msg = capsys.readouterr().out
    assert "nothing to do" in msg and "stationary" in msg and "extend it with --set solver.t_final" not in msg


def test_spots_take_the_elongation_direction():
    from femshell.mesh import sphere
    from femshell.scene.build import coupled_parameters, initial_concentration

    mesh = sphere(15.0, n_vertices=300)
    c = []
    for d in ("[1.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]"):
        sc = load_scene("default", ["initial.kind=spots", "initial.layout=icosahedron", "initial.elongation=3.0",
                                    f"initial.direction={d}"])
        c.append(initial_concentration(sc, mesh, coupled_parameters(sc)[0]))
    assert np.abs(c[0] - c[1]).max() > 0.1 * c[0].max()


# ----------------------------------------------------------------------------- kill -9

def test_kill_9_loses_no_finished_step(uninterrupted, tmp_path):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "femshell.cli", "run", "default", "--out", str(out), "-q",
           "--set", "output.pictures=false", *sets(RESUME)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    step = -1
    deadline = time.time() + 600
    try:
        while time.time() < deadline and proc.poll() is None:
            try:
                step = load_checkpoint(out / "checkpoint.npz")[1]["step"]
            except Exception:
                step = -1
            if step >= 2:
                os.kill(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.05)
    finally:
        if proc.poll() is None and step < 2:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert step >= 2, proc.stderr.read().decode()[-2000:]
    killed_at = load_checkpoint(out / "checkpoint.npz")[1]["step"]
    assert killed_at >= step                 # the checkpoint seen before the kill is still there
    assert run("default", out, extra=["--resume"], overrides=RESUME) == 0
    assert_same_run(uninterrupted, out)


def _tree(path):
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


def test_an_overwrite_stopped_while_it_starts_keeps_the_earlier_run(tmp_path):
    """SIGTERM during the new run's initial equilibrium puts the earlier run back; a leftover of a
    kill -9 at that moment (.femshell-replaced) is put back by the next command, not deleted."""
    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY) == 0
    before = _tree(out)
    # 4 000 vertices: an initial equilibrium of several seconds to stop
    cmd = [sys.executable, "-m", "femshell.cli", "run", "default", "--out", str(out), "--overwrite",
           "--set", "mesh.n_vertices=4000", "--set", "output.pictures=false"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        for line in proc.stdout:
            if line.startswith("initial equilibrium"):
                time.sleep(1.0)
                os.kill(proc.pid, signal.SIGTERM)
                break
    finally:
        if proc.poll() is None:
            try:
                proc.wait(timeout=120)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    assert proc.returncode == 130
    assert _tree(out) == before
    # what a kill -9 at that moment leaves: the earlier run set aside, a frame of the new one
    from femshell.scene.runner import RunDir

    RunDir(out).set_aside()
    (out / "series_000000.vtu").write_text("half a frame")
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY) == 0     # finished: nothing to do
    assert _tree(out) == before


def test_an_overwrite_killed_while_it_starts_is_put_back_by_any_command(tmp_path, capsys):
    """After a kill -9 in an --overwrite's start-up, `run --out X --resume` said "no scene.toml to resume
    from" and `render X` found no series (issue 65, item 1): without the scene named, each puts the
    earlier run back; a set-aside cut short (some files moved) and a deletion cut short are finished."""
    from femshell.scene.runner import DROPPED, REPLACED, RunDir

    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY) == 0        # finished: a --resume writes nothing
    before = _tree(out)
    rd = RunDir(out)
    for command in (["run", "--out", str(out), "--resume", "-q"],
                    ["render", str(out), "--no-movie"]):
        rd.set_aside()
        (out / "series_000000.vtu").write_text("half a frame of the new run")
        assert main(command) == 0, capsys.readouterr().err
        assert "put back the run" in capsys.readouterr().err
        for p in (out / "pictures").glob("*"):
            p.unlink()
        with contextlib.suppress(FileNotFoundError):
            (out / "pictures").rmdir()
        assert _tree(out) == before
    # killed while it moved the earlier run's files: those moved come back, those left stay
    (out / REPLACED).mkdir()
    (out / "summary.json").rename(out / REPLACED / "summary.json")
    (out / "checkpoint.npz").rename(out / REPLACED / "checkpoint.npz")
    assert run("default", out, overrides=SPHERE_TINY, extra=["--resume"]) == 0
    assert _tree(out) == before
    # killed while it deleted the replaced run: the deletion is finished, the new run kept
    (out / DROPPED).mkdir()
    (out / DROPPED / "summary.json").write_text("{}")
    assert run("default", out, overrides=SPHERE_TINY, extra=["--resume"]) == 0
    assert not (out / DROPPED).exists() and _tree(out) == before


def _sigterm_in_a_finalizer():
    """A SIGTERM whose handler runs inside a garbage-collector callback, where Python drops its exception."""
    import weakref

    class Held:
        pass

    held = Held()
    weakref.finalize(held, signal.raise_signal, signal.SIGTERM)
    del held


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")   # the point: Python drops it
def test_a_stop_dropped_in_a_finalizer_still_stops_the_run(tmp_path, monkeypatch):
    """A SIGTERM raised inside a finalizer (a PARDISO factor being freed) is printed and dropped by
    Python; the run still stops, at the next step boundary, and an overwrite keeps the earlier run."""
    from femshell.scene.runner import TimeRunner

    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY) == 0
    before = _tree(out)
    initialise = TimeRunner.initialise

    def stopped_while_starting(self):
        initialise(self)
        _sigterm_in_a_finalizer()

    monkeypatch.setattr(TimeRunner, "initialise", stopped_while_starting)
    assert run("default", out, extra=["--overwrite"], overrides=SPHERE_TINY) == 130
    assert _tree(out) == before
    # once started: dropped in a step before it commits (then the signal is not held), the run stops
    # before its next step, or, in the last step of this invocation, after it; resumable either way
    monkeypatch.setattr(TimeRunner, "initialise", initialise)
    advance = TimeRunner.advance

    def stopped_in_step(k):
        def advance_and_stop(self):
            if self.step == k:
                _sigterm_in_a_finalizer()
            return advance(self)
        return advance_and_stop

    for k, extra in ((0, ["--overwrite"]), (1, ["--resume", "--max-steps", "1"])):
        monkeypatch.setattr(TimeRunner, "advance", stopped_in_step(k))
        assert run("default", out, extra=extra, overrides=SPHERE_TINY) == 130
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "interrupted" and summary["steps"] == k + 1
    monkeypatch.setattr(TimeRunner, "advance", advance)
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY) == 0


def test_resume_with_another_set_names_the_command_that_resumes(tmp_path, capsys):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "1"], overrides=SPHERE_TINY) == 0
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY + ["shell.thickness=1.0"]) == 2
    err = capsys.readouterr().err
    assert "cannot be resumed" in err and f"femshell run --out {out} --resume, without a scene or --set" in err
    assert main(["run", "--out", str(out), "--resume", "-q"]) == 0
    # another scene altogether: the first differences and a count, not a 40-line listing
    assert run("sphere-propagation", out, extra=["--resume"], overrides=SPHERE_TINY) == 2
    err = capsys.readouterr().err
    listed = [line for line in err.splitlines() if " in the run, " in line]
    assert len(listed) == 8 and "more" in err


def test_resume_after_scene_toml_was_edited_is_refused(tmp_path, capsys):
    # the run's scene.toml edited (thickness 1.5 -> 1): resuming from it would continue another shell
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "1"], overrides=SPHERE_TINY) == 0
    text = (out / "scene.toml").read_text()
    assert "thickness = 1.5" in text
    (out / "scene.toml").write_text(text.replace("thickness = 1.5", "thickness = 1.0"))
    before = _tree(out)
    assert main(["run", "--out", str(out), "--resume", "-q"]) == 2
    err = capsys.readouterr().err
    assert "was made with another scene than the one given now" in err and "[shell] thickness: 1.5 in the run" in err
    assert _tree(out) == before


def test_resume_without_the_series_index_keeps_the_frames(tmp_path, capsys):
    out = tmp_path / "run"
    assert run("default", out, extra=["--max-steps", "1"], overrides=SPHERE_TINY) == 0
    (out / "series.pvd").unlink()
    before = _tree(out)
    assert run("default", out, extra=["--resume"], overrides=SPHERE_TINY) == 2
    assert "series.pvd is missing but 2 frames series_*.vtu are there" in capsys.readouterr().err
    assert _tree(out) == before


def test_overwrite_replaces_femshells_files_only(tmp_path):
    out = tmp_path / "run"
    assert run("default", out, overrides=SPHERE_TINY, pictures=True) == 0
    mine = {"pictures/my_figure.png": b"mine", "series_final_by_hand.vtu": b"mine too", "notes.txt": b"notes"}
    for name, data in mine.items():
        (out / name).write_bytes(data)
    assert run("default", out, extra=["--overwrite"], overrides=SPHERE_TINY) == 0
    assert {k: v for k, v in _tree(out).items() if k in mine} == mine
    assert not (out / "pictures" / "top.png").exists()          # the earlier run's picture went with it


def test_unresolved_seed_is_warned_and_negative_c_star_refused(tmp_path, capsys):
    over = ["mesh.n_vertices=150", "solver.t_final=0.02", "initial.width=1e-3"]
    assert run("default", tmp_path / "thin", overrides=over) == 0
    assert "narrower than the mesh resolves" in capsys.readouterr().err
    assert run("default", tmp_path / "neg", overrides=["mesh.n_vertices=150", "growth.c_star=-0.1"]) == 2
    assert "c_star" in capsys.readouterr().err


def test_a_static_run_stopped_by_an_error_reports_its_accepted_state(tmp_path, monkeypatch):
    """The error comes in the second load increment, after the model was set to the trial load:
    the summary's energy is that of the accepted state at its own load, not at the trial one."""
    import femshell.solvers.newton as newton
    from femshell.scene import make_mesh
    from femshell.scene.build import shell_parts

    real, calls = newton.minimize, {"n": 0}

    def failing(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise IndexError("simulated bug")
        return real(*a, **k)

    monkeypatch.setattr(newton, "minimize", failing)
    over = ["mesh.edge_length=0.5", "solver.steps=8"]
    out = tmp_path / "run"
    assert run("cantilever-roll-up", out, overrides=over) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and s["final"]["load_factor"] == pytest.approx(0.125)
    state, _ = load_checkpoint(out / "checkpoint.npz")
    sc = load_scene("cantilever-roll-up", over)
    model = shell_parts(sc, make_mesh(sc)).model
    model.load_factor = float(state["mu"])
    assert s["final"]["energy"] == pytest.approx(model.energy(np.asarray(state["u"])), rel=1e-9)


def test_resume_of_a_checkpoint_with_edge_angles_is_refused(tmp_path, capsys):
    # a continuation checkpoint written before the edge unknown became the tangent of the normal's angle
    # holds bare angles, which the shell would read as other normals: refused, the run left as it was
    over = ["mesh.edge_length=0.4", "solver.stop=1.1e-4", "solver.max_steps=5", "solver.n_eigs=2",
            "solver.switch_branch=false"]
    out = tmp_path / "run"
    assert run("clamped-plate-buckling", out, extra=["--max-steps", "2"], overrides=over) == 0
    state, meta = load_checkpoint(out / "checkpoint.npz")
    assert meta.pop("edge_unknown") == "tangent"
    save_checkpoint(out / "checkpoint.npz", state, meta)
    before = _tree(out)
    assert run("clamped-plate-buckling", out, extra=["--resume"], overrides=over) == 2
    assert "took the tangent of the mid-edge normal's angle" in capsys.readouterr().err
    assert _tree(out) == before
