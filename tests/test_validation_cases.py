"""Every validation case at quick level (the contract of design.md section 4): each row compares
with an independent reference (plate theory, the elastica, the classical benchmark values, series
solutions, l(l+1), the fold theory of a shallow arch) or is reported; the case passes when every
toleranced row does. The full levels are run by hand (validation/results)."""

import json
import math

import pytest

from femshell.validation import run_case
from femshell.validation.framework import CASES


@pytest.mark.parametrize("name", list(CASES))
def test_case_quick(name, tmp_path):
    assert run_case(name, "quick", tmp_path, log=lambda *a: None)
    doc = json.loads((tmp_path / f"{name}.json").read_text())
    assert doc["case"] == name and doc["level"] == "quick" and doc["source"]
    assert (tmp_path / f"{name}.png").stat().st_size > 0
    assert any(row["tolerance"] is not None for row in doc["rows"])      # something is checked
    for row in doc["rows"]:
        assert set(row) >= {"quantity", "value", "reference", "rel_error", "tolerance", "passed", "n_vertices",
                            "wall_s"}
        assert row["value"] is not None and math.isfinite(row["value"])
