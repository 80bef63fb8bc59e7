"""[solver] kind = "linear-buckling": a scene's linear buckling through the command line."""

import csv
import json

import meshio
import numpy as np
import pytest

from femshell.cli import main

SCENE = """
description = "clamped disk grown uniformly: linear buckling at the rest shape"
[mesh]
kind = "disk"
radius = 1.0
edge_length = 0.12
[material]
nu = 0.3
[shell]
thickness = 0.01
thickness_mode = "uniform"
[growth]
law = "uniform"
strain = 1e-4
[[boundary]]
type = "clamped"
curve = "outer"
[solver]
kind = "linear-buckling"
modes = 3
"""


def test_linear_buckling_scene(tmp_path, capsys):
    scene = tmp_path / "disk.toml"
    scene.write_text(SCENE)
    out = tmp_path / "run"
    assert main(["run", str(scene), "--out", str(out), "-q", "--set", "output.pictures=false"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["solver"] == "linear-buckling" and summary["status"] == "done"
    factors = summary["final"]["critical_factors"]
    assert len(factors) == 3 and factors == sorted(factors)
    # the factor times the growth strain is the critical strain: k² = 14.682 of the clamped disk (coarse mesh)
    assert factors[0] * 1e-4 * 12 * 1.3 / 0.01 ** 2 == pytest.approx(14.682, rel=3e-2)
    rows = list(csv.DictReader(open(out / "buckling.csv")))
    assert [float(r["parameter"]) for r in rows] == pytest.approx(factors, rel=1e-12)
    modes = meshio.read(out / "modes.vtu")
    assert set(modes.point_data) == {"mode_1", "mode_2", "mode_3"}
    assert np.linalg.norm(modes.point_data["mode_1"], axis=1).max() == pytest.approx(1.0)
    assert summary["files"]["modes"] == "modes.vtu"


@pytest.mark.parametrize("change, message", [
    ("solver.modes=0", "modes"),
    ("solver.modes=51", "modes"),
    ("solver.at=-1", "at"),
    ("solver.target=0", "target"),
])
def test_linear_buckling_scene_bad_input(tmp_path, capsys, change, message):
    scene = tmp_path / "disk.toml"
    scene.write_text(SCENE)
    assert main(["run", str(scene), "--out", str(tmp_path / "run"), "-q", "--set", change]) == 2
    err = capsys.readouterr().err
    assert f"[solver] {message}" in err or f"solver.{message}" in err, err
