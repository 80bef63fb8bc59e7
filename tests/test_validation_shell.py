"""The shell validation cases at quick level: each compares with an independent reference
(plate theory, the elastica, the exact roll-up circle, the classical benchmark values)."""

import json
import math

import pytest

from femshell.validation import run_case

SHELL_CASES = ["patch-tests", "clamped-plate-pressure", "cantilever-end-shear", "cantilever-end-moment",
               "scordelis-lo", "pinched-cylinder", "shallow-arch-snap", "disk-wrinkles"]


@pytest.mark.parametrize("name", SHELL_CASES)
def test_shell_case_quick(name, tmp_path):
    assert run_case(name, "quick", tmp_path, log=lambda *a: None)
    doc = json.loads((tmp_path / f"{name}.json").read_text())
    assert doc["case"] == name and doc["level"] == "quick" and doc["source"]
    assert (tmp_path / f"{name}.png").stat().st_size > 0
    for row in doc["rows"]:
        assert set(row) >= {"quantity", "value", "reference", "rel_error", "tolerance", "passed", "n_vertices",
                            "wall_s"}
        assert row["value"] is not None and math.isfinite(row["value"])
