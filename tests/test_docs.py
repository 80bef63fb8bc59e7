"""The documentation builds with one command (docs/build.py) and covers every module."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_docs_build(tmp_path):
    pytest.importorskip("pdoc")
    r = subprocess.run([sys.executable, str(ROOT / "docs" / "build.py"), "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    api = tmp_path / "api" / "femshell"
    for module in ("mesh", "shell", "solvers", "geometry", "growth", "chemistry"):
        assert (api / f"{module}.html").exists() or (api / module).is_dir(), module
    assert (tmp_path / "theory.md").exists()
    assert (tmp_path / "validation-report.md").read_text().startswith("# Validation report")
    index = (tmp_path / "index.md").read_text()
    for name in ("buckling", "mechanochemistry", "convergence"):     # the tutorials, page and script
        assert (tmp_path / "tutorials" / f"{name}.md").exists() and (tmp_path / "tutorials" / f"{name}.py").exists()
        assert f"tutorials/{name}.md" in index


def test_accuracy_page_takes_results_given_relative_to_the_repository(tmp_path, monkeypatch):
    """`validation/convergence.py --results validation/results` from the repository root (the
    convergence tutorial's default --out is such a path): it failed in Path.relative_to."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("convergence_page", ROOT / "validation" / "convergence.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    monkeypatch.chdir(ROOT)
    assert page._rel("validation/results/scordelis-lo.json") == "validation/results/scordelis-lo.json"
    assert page._rel(str(ROOT / "validation" / "results" / "x.json")) == "validation/results/x.json"
    assert page._rel(str(tmp_path / "x.json")) == str(tmp_path / "x.json")
