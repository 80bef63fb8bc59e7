"""Build the documentation: ``python docs/build.py [--out docs/_build]``.

1. the validation report (``validation-report.md``; ``--update-report`` also refreshes the
   committed ``docs/validation-report.md``), made from the full-level
   results in ``validation/results/*.json`` (``femshell validate NAME --level full
   --out validation/results``): one table per case with every row;
2. the API reference from the docstrings, as HTML, with pdoc;
3. the markdown pages (theory, report, accuracy and cost) copied beside it, and the
   tutorials (``docs/tutorials/NAME.md`` with their runnable scripts ``NAME.py`` and
   images) into ``tutorials/``, with an index.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
PAGES = ["theory.md", "validation-report.md", "accuracy-and-cost.md", "disk-crosscheck.md", "sphere-patterns.md"]
#: tutorials, in reading order: docs/tutorials/NAME.md (the page) and NAME.py (its script)
TUTORIALS = ["buckling", "mechanochemistry", "convergence"]


def _fmt(v, spec=".4g"):
    return "" if v is None else (f"{v:{spec}}" if isinstance(v, float) else str(v))


def validation_report(results: Path = ROOT / "validation" / "results") -> str:
    """Markdown tables of every validation JSON in ``results``."""
    from femshell.validation.framework import verdict

    lines = ["# Validation report", "",
             "Made by `python docs/build.py --update-report` from `validation/results/*.json`, the output of",
             "`femshell validate NAME --level full --out validation/results`. Each row compares femshell with",
             "an independent reference; `passed` is empty where a row is reported without a tolerance.",
             "`rel. error` is |value − reference| / |reference|, and the absolute error where the reference is 0.",
             ""]
    files = sorted(results.glob("*.json"))
    if not files:
        lines.append("No results yet: run `femshell validate all --level full --out validation/results`.")
    for f in files:
        doc = json.loads(f.read_text())
        text = verdict(doc["rows"])
        head, _, rest = text.partition(" (")
        lines += [f"## {doc['case']} ({doc['level']}): {head}", "", f"Verdict: {head} ({rest}", "",
                  doc.get("description", ""), "", f"Reference: {doc['source']}", ""]
        png = f.with_suffix(".png")
        if png.exists():
            lines += [f"![{doc['case']}](../validation/results/{png.name})", ""]
        lines += ["| quantity | value | reference | rel. error | tolerance | passed | vertices | wall [s] |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in doc["rows"]:
            lines.append(f"| {r['quantity']} | {_fmt(r['value'])} | {_fmt(r['reference'])} | "
                         f"{_fmt(r['rel_error'], '.2e')} | {_fmt(r['tolerance'], '.2g')} | "
                         f"{'' if r['passed'] is None else ('yes' if r['passed'] else 'NO')} | "
                         f"{r['n_vertices'] or ''} | {r['wall_s']:.2f} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def build(out: Path) -> Path:
    import pdoc

    out.mkdir(parents=True, exist_ok=True)
    (out / "validation-report.md").write_text(validation_report())
    pdoc.render.configure(docformat="numpy", math=True, footer_text="femshell")
    pdoc.pdoc("femshell", "!femshell.validation.framework", output_directory=out / "api")
    index = ["# femshell documentation", "", "- [API reference](api/femshell.html)"]
    for page in PAGES:
        src = DOCS / page
        if src.exists() and page != "validation-report.md":
            shutil.copy(src, out / page)
        if (out / page).exists():         # the report was written above, from validation/results
            index.append(f"- [{page[:-3].replace('-', ' ')}]({page})")
    tut = DOCS / "tutorials"
    titles = []
    for name in TUTORIALS:
        page = tut / f"{name}.md"
        if page.exists():
            (out / "tutorials").mkdir(exist_ok=True)
            for src in (page, tut / f"{name}.py"):
                if src.exists():
                    shutil.copy(src, out / "tutorials" / src.name)
            title = page.read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip() or name
            titles.append(f"  - [{title}](tutorials/{name}.md) (script: [{name}.py](tutorials/{name}.py))")
    if titles:
        index += ["- tutorials (each page has a script that runs it: `python docs/tutorials/NAME.py --quick`)"]
        index += titles
    if (tut / "images").exists():
        shutil.copytree(tut / "images", out / "tutorials" / "images", dirs_exist_ok=True)
    if (DOCS / "images").exists():
        shutil.copytree(DOCS / "images", out / "images", dirs_exist_ok=True)
    (out / "index.md").write_text("\n".join(index) + "\n")
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description="Build femshell's documentation.")
    ap.add_argument("--out", type=Path, default=DOCS / "_build")
    ap.add_argument("--update-report", action="store_true",
                    help="also rewrite docs/validation-report.md (the committed copy) from validation/results")
    args = ap.parse_args()
    if args.update_report:
        (DOCS / "validation-report.md").write_text(validation_report())
    print(f"documentation in {build(args.out)}")
