"""femshell sweep: the spec's validation, a tiny sweep on a 2-worker LocalCluster (a failing point among
them), Ctrl-C of the client, kill -9 of a worker mid-point and --resume.

The runs are tiny (150 vertices, a few steps) so that the whole module stays within a minute on 2 cores.
"""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from femshell.cli import main
from femshell.io import load_checkpoint
from femshell.sweep import load_spec, run_sweep

# every point: 150 vertices, t <= 0.05 (4 steps), no pictures (pyvista's start-up would dominate)
TINY_SET = {"mesh.n_vertices": 150, "solver.t_final": 0.05, "output.pictures": False}


def spec_text(vary: dict, mode="product", fixed=TINY_SET, extra=""):
    lines = ['scene = "default"', f'mode = "{mode}"', extra, "[set]"]
    lines += [f'"{k}" = {json.dumps(v)}' for k, v in fixed.items()]
    lines += ["[vary]"] + [f'"{k}" = {json.dumps(v)}' for k, v in vary.items()]
    return "\n".join(lines) + "\n"


def write_spec(tmp_path, text, name="spec.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, words", [
    (spec_text({"growth.c_star": [0.1]}, extra='colour = "red"'), ["unknown key 'colour'"]),
    (spec_text({"growth.c_star": []}), ['"growth.c_star" = [] is empty']),
    (spec_text({"growth.c_star": 0.1}), ['"growth.c_star" = 0.1 must be a list']),
    (spec_text({"growth.c_star": ["high", 0.1]}), ['"growth.c_star" = "high"', "c_star", "must be a number"]),
    (spec_text({"growth.c_star": [0.1, -0.2]}), ['"growth.c_star" = -0.2', "out of range"]),
    (spec_text({"growth.c_stra": [0.1]}), ['"growth.c_stra"', "unknown key 'c_stra'"]),
    (spec_text({"shape.radius": [1.0]}), ['"shape.radius"', "[shape] is not a section"]),
    (spec_text({"growth.c_star": [0.1, 0.2], "shell.thickness": [1.0]}, mode="zip"), ["one length"]),
    (spec_text({"growth.c_star": [0.1]}, mode="grid"), ['mode = "grid"']),
    (spec_text({"growth.c_star": [0.1, 0.1]}), ["points 0 and 1 have the same values"]),
    (spec_text({"growth.c_star": [0.1]}, extra='measures = ["regime", "colour"]'), ["unknown measure \"colour\""]),
])
def test_bad_spec_exits_2_naming_it_and_starts_nothing(tmp_path, capsys, text, words):
    out = tmp_path / "out"
    assert main(["sweep", str(write_spec(tmp_path, text)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err
    assert "Traceback" not in err and not out.exists()


def test_spec_points_product_and_zip(tmp_path):
    prod = load_spec(write_spec(tmp_path, spec_text({"growth.c_star": [0.1, 0.2], "shell.thickness": [1, 2, 3]})))
    assert [p.values for p in prod.points][:4] == [{"growth.c_star": 0.1, "shell.thickness": t} for t in (1, 2, 3)] + [
        {"growth.c_star": 0.2, "shell.thickness": 1}]
    assert len(prod.points) == 6 and len({p.key for p in prod.points}) == 6
    assert prod.points[4].key == "004_c_star=0.2_thickness=2" and prod.plot_axes == ("growth.c_star", "shell.thickness")
    zipped = load_spec(write_spec(tmp_path, spec_text({"growth.c_star": [0.1, 0.2], "shell.thickness": [1, 2]},
                                                      mode="zip")))
    assert [p.values for p in zipped.points] == [{"growth.c_star": 0.1, "shell.thickness": 1},
                                                 {"growth.c_star": 0.2, "shell.thickness": 2}]


def read_results(out):
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_tiny_sweep_two_workers_with_a_failing_point(tmp_path):
    # one Newton iteration without cuts cannot reach the grown initial equilibrium at c* = 0.1: that point fails
    zipped = {"growth.c_star": [0.1, 0.3, 0.35, 0.35], "solver.newton_max_iter": [1, 40, 40, 30],
              "solver.max_cuts": [0, 8, 8, 8]}
    spec = load_spec(write_spec(tmp_path, spec_text(zipped, mode="zip")))
    out = tmp_path / "sw"
    assert run_sweep(spec, out, workers=2) == 1                 # one point failed
    rows = {r["key"]: r for r in read_results(out)}
    assert len(rows) == 4
    failed = "000_c_star=0.1_newton_max_iter=1_max_cuts=0"
    assert rows[failed]["status"] == "failed" and "Newton" in rows[failed]["message"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert [manifest["state"][k]["status"] for k in sorted(rows)] == ["failed", "finished", "finished", "finished"]
    for key, row in rows.items():
        d = out / "points" / key
        summ = json.loads((d / "summary.json").read_text())
        scene = (d / "scene.toml").read_text() if key != failed else None
        if key == failed:
            continue
        # an ordinary run directory of the point's own scene, and the table reads its summary
        assert {"series.pvd", "checkpoint.npz", "scene.toml", "summary.json"} <= {p.name for p in d.iterdir()}
        assert f"c_star = {float(row['c_star'])!r}" in scene and "n_vertices = 150" in scene
        assert row["status"] == summ["status"] == "t_final"
        assert float(row["t"]) == summ["final"]["t"] == pytest.approx(0.05)
        assert int(row["n_spots"]) == summ["final"]["pattern"]["n_spots"]
        assert float(row["max_c"]) == summ["final"]["max_c"] and row["worker"].startswith("tcp://127.0.0.1:")
    assert (out / "phase_diagram.png").stat().st_size > 0 and (out / "contact_sheet.png").stat().st_size > 0
    # --plot DIR draws them again from the run directories alone
    for name in ("phase_diagram.png", "contact_sheet.png", "results.csv"):
        (out / name).unlink()
    assert main(["sweep", "--plot", str(out)]) == 0
    assert (out / "phase_diagram.png").exists() and read_results(out) == list(rows.values())
    # a resume has nothing to run: the failed point is skipped (without --retry-failed), no cluster starts
    t0 = time.perf_counter()
    assert main(["sweep", str(tmp_path / "spec.toml"), "--out", str(out), "--resume", "--no-plot"]) == 1
    assert time.perf_counter() - t0 < 20
    # another spec cannot resume it, and no resume starts over a sweep
    other = write_spec(tmp_path, spec_text({"growth.c_star": [0.2]}), "other.toml")
    assert main(["sweep", str(other), "--out", str(out), "--resume"]) == 2
    assert main(["sweep", str(tmp_path / "spec.toml"), "--out", str(out)]) == 2


def _wait(cond, what, timeout=120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = cond()
        if got:
            return got
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def _checkpoint_step(d):
    try:
        return load_checkpoint(d / "checkpoint.npz")[1]["step"]
    except Exception:
        return -1


def _sweep_process(spec, out, *extra):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[1]), env.get("PYTHONPATH", "")])
    return subprocess.Popen([sys.executable, "-m", "femshell.cli", "sweep", str(spec), "--out", str(out), "--workers",
                             "1", "--no-plot", *extra], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)


def test_ctrl_c_then_resume_through_a_killed_worker(tmp_path):
    # one point of 60 small steps (30 finished before an idle client handled its Ctrl-C): Ctrl-C of the client stops it at a step with a checkpoint; the resume
    # continues from there, its worker is killed (-9) mid-point, and Dask's next worker finishes it
    slow = {**TINY_SET, "solver.t_final": 0.24, "solver.dt_max": 0.004, "solver.dt_initial": 0.004}
    spec = write_spec(tmp_path, spec_text({"growth.c_star": [0.35]}, fixed=slow))
    out = tmp_path / "sw"
    d = out / "points" / "000_c_star=0.35"
    proc = _sweep_process(spec, out)
    _wait(lambda: _checkpoint_step(d) >= 2, "step 2's checkpoint")
    proc.send_signal(signal.SIGINT)
    text = proc.communicate(timeout=120)[0]
    assert proc.returncode == 130, text
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["state"]["000_c_star=0.35"]["status"] == "interrupted"
    summ = json.loads((d / "summary.json").read_text())
    assert summ["status"] == "interrupted" and summ["steps"] == _checkpoint_step(d) >= 2
    assert not (d / ".femshell.lock").exists()         # the worker's run ended, not killed
    stopped_at = summ["steps"]

    proc = _sweep_process(spec, out, "--resume")
    lock = d / ".femshell.lock"
    _wait(lambda: _checkpoint_step(d) >= stopped_at + 2 and lock.exists(), "two resumed steps")
    os.kill(int(lock.read_text()), signal.SIGKILL)      # the worker process running the point
    text = proc.communicate(timeout=180)[0]
    assert proc.returncode == 0, text
    summ = json.loads((d / "summary.json").read_text())
    assert summ["status"] == "t_final" and summ["final"]["t"] == pytest.approx(0.24) and summ["resumes"] >= 2
    assert read_results(out)[0]["status"] == "t_final"
    assert json.loads((out / "manifest.json").read_text())["state"]["000_c_star=0.35"]["status"] == "finished"


STUDY_SPECS = Path(__file__).resolve().parents[1] / "validation" / "regimes"


@pytest.mark.parametrize("path", sorted(STUDY_SPECS.glob("*.toml")), ids=lambda p: p.stem)
def test_the_shipped_study_specs_are_valid(path):
    # every point's scene is validated as `femshell sweep` would before starting; each study has three
    # points or more, on the R = 15 sphere at edge 1.1 to t <= 100 (docs/regimes.md)
    spec = load_spec(path)
    assert len(spec.points) >= 3 and spec.fixed["mesh.edge_length"] == 1.1
    assert 0 < spec.fixed["solver.t_final"] <= 100.0 and spec.description
