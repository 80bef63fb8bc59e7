"""The manual builds with one command (docs/build.py) without a warning, and its pages hold.

The build runs Sphinx with -W into a temporary directory, running only the quick gallery
examples (docs/build.py QUICK_EXAMPLES; the others run in tests/test_tutorials.py). About
1.5-3 minutes on 2 shared cores, most of it autodoc importing every module.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: the pages a newcomer reads first, each under ~300 lines
FIRST_PAGES = ["index.md", "getting-started.md", "theory.md", "paper.md", "accuracy-and-cost.md", "validation-report.md",
               "guide/run-a-scene.md", "guide/write-a-scene.md", "guide/python-api.md",
               "guide/continuation.md", "guide/convergence.md"]


def test_docs_build(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("sphinx_gallery")
    r = subprocess.run([sys.executable, str(DOCS / "build.py"), "--out", str(tmp_path), "--gallery", "quick"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, (r.stdout[-3000:], r.stderr[-5000:])
    assert "WARNING" not in r.stderr and "ERROR" not in r.stderr, r.stderr[-5000:]
    for page in FIRST_PAGES + ["studies/index.md", "studies/benchmarks.md", "studies/disk-crosscheck.md",
                               "studies/sphere-patterns.md", "studies/accuracy-and-cost.md"]:
        assert (tmp_path / page.replace(".md", ".html")).exists(), page
    for module in ("mesh", "shell", "solvers", "geometry", "growth", "chemistry", "coupled", "scene"):
        assert (tmp_path / "api" / f"femshell.{module}.html").exists(), module
    for example in (DOCS / "examples").glob("plot_*.py"):
        assert (tmp_path / "gallery" / f"{example.stem}.html").exists(), example.name
    # the quick example ran: its pictures are on its page
    page = (tmp_path / "gallery" / "plot_plate_pressure.html").read_text(encoding="utf-8")
    assert page.count("sphx_glr_plot_plate_pressure_0") >= 2


@pytest.mark.parametrize("page", FIRST_PAGES)
def test_first_pages_are_short(page):
    assert len((DOCS / page).read_text(encoding="utf-8").splitlines()) < 300


def test_pages_do_not_cite_design_md():
    """design.md is outside the repository: users read docs/theory.md's sections instead."""
    for page in [ROOT / "README.md", *DOCS.rglob("*.md"), *(DOCS / "examples").glob("*.py")]:
        assert "design.md" not in page.read_text(encoding="utf-8"), page


def test_readme_quick_start_is_the_two_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    quick = readme.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    commands = re.findall(r"^```bash\n(.*?)^```", quick, flags=re.S | re.M)
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert len(commands) == 2 and commands[0].strip().endswith("femshell run default")
    assert commands[1].strip() in ci
    assert "docs/build.py" in readme


def test_scene_examples_in_the_guide_are_valid_scenes():
    """Every ```toml block of write-a-scene.md with a [mesh] is a scene the schema accepts."""
    from femshell.scene.schema import parse_scene, validate

    text = (DOCS / "guide" / "write-a-scene.md").read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"^```toml\n(.*?)^```", text, flags=re.S | re.M) if "[mesh]" in b]
    assert blocks
    for block in blocks:
        validate(parse_scene(block, "guide"), name="guide", label="write-a-scene.md")


def test_accuracy_page_takes_results_given_relative_to_the_repository(tmp_path, monkeypatch):
    """`validation/convergence.py --results validation/results` from the repository root (the
    convergence example's default --out is such a path): it failed in Path.relative_to."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("convergence_page", ROOT / "validation" / "convergence.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    monkeypatch.chdir(ROOT)
    assert page._rel("validation/results/scordelis-lo.json") == "validation/results/scordelis-lo.json"
    assert page._rel(str(ROOT / "validation" / "results" / "x.json")) == "validation/results/x.json"
    assert page._rel(str(tmp_path / "x.json")) == str(tmp_path / "x.json")


def test_validation_report_is_the_generated_one():
    """docs/validation-report.md is `docs/build.py --update-report`'s output from validation/results: a section
    written by hand would be dropped by the next update (and a case without a full-level JSON has none)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_build", DOCS / "build.py")
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    report = build.validation_report()
    assert (DOCS / "validation-report.md").read_text(encoding="utf-8") == report
    for f in (ROOT / "validation" / "results").glob("*.json"):
        assert f"\n## {f.stem}: " in report, f.name
