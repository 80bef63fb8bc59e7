"""Local Sphinx helpers of femshell's manual (loaded by conf.py).

femshell's docstrings are plain text in numpy style, written to be read in a terminal:
``|x|`` is a norm, ``u_,a`` a derivative, and short tables of literals line up in two
columns. reStructuredText reads the first as a substitution, the second as a link target
and the third as an indentation error, so :func:`plain_text_to_rst` escapes the first two
and turns the two-column lists into definition lists before autodoc parses a docstring.
Literal text (````...````, roles, maths) is left as written.
"""

import os
import re
import shutil
import tempfile
import time
from pathlib import Path

#: when each example's pictures were last collected (its output directory: time)
_shown: dict[Path, float] = {}
#: most pictures shown after one code block of an example
MAX_PICTURES = 4
#: where the gallery's examples write their files (docs/build.py sets it inside its output)
EXAMPLES_OUT = Path(os.environ.get("FEMSHELL_EXAMPLES_OUT", Path(tempfile.gettempdir()) / "femshell-docs-examples"))

#: inline literals, roles (:func:`x`), interpreted text and maths, which are kept verbatim
_LITERAL = re.compile(r"(``.+?``|:[a-z:]+:`[^`]+`|`[^`]+`_?)")
#: a line of a two-column list: a literal, two or more spaces, its description
_COLUMN_ITEM = re.compile(r"^(\s*)(``.+?``)\s{2,}(\S.*)$")


def _escape(text: str) -> str:
    text = text.replace("|", r"\|")
    return re.sub(r"(\w)_(?=[\s,.;:)\]]|$)", r"\1\\_", text)


def escape_line(line: str) -> str:
    """``line`` with ``|`` and a trailing ``_`` of a word escaped outside literals and roles."""
    if line.lstrip().startswith((">>>", "...")):
        return line
    parts = _LITERAL.split(line)
    return "".join(p if i % 2 else _escape(p) for i, p in enumerate(parts))


def _column_lists(lines: list[str]) -> list[str]:
    """Two-column lists (a literal, then its description and indented continuation lines)
    as definition lists."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = _COLUMN_ITEM.match(lines[i])
        if not m:
            out.append(lines[i])
            i += 1
            continue
        indent, term, desc = m.groups()
        column = len(lines[i]) - len(desc)
        body = [desc]
        i += 1
        while i < len(lines) and lines[i].strip() and len(lines[i]) - len(lines[i].lstrip()) >= column - 2:
            body.append(lines[i].strip())
            i += 1
        out += [indent + term, indent + "    " + " ".join(body)]
    return out


def plain_text_to_rst(app, what, name, obj, options, lines):
    """autodoc-process-docstring: make a plain-text docstring parse as reStructuredText."""
    in_literal_block = False
    fixed = []
    for line in _column_lists(lines):
        stripped = line.strip()
        if in_literal_block and stripped and not line.startswith((" ", "\t")):
            in_literal_block = False
        if not in_literal_block:
            line = escape_line(line)
            if stripped.startswith(":") and re.match(r"\s*:[a-z]+:`", line) and fixed and fixed[-1].strip():
                line = line.replace(":", "\\ :", 1)       # a role opening a line is not a field list
        if stripped.endswith("::") or stripped.startswith(".. math::"):
            in_literal_block = True
        fixed.append(line)
    lines[:] = fixed


def example_argv(gallery_conf, script_vars):
    """sphinx-gallery's reset_argv: each example writes into its own directory, outside the source tree."""
    out = EXAMPLES_OUT / Path(script_vars["src_file"]).stem
    shutil.rmtree(out, ignore_errors=True)        # a fresh start: its pictures are this run's
    _shown[out] = time.time()
    return ["--out", str(out)]


def new_pictures(block, block_vars, gallery_conf):
    """sphinx-gallery image scraper: the PNG files an example wrote into its output directory
    during the code block just run (the pictures a user running the script would get), at
    most :data:`MAX_PICTURES` per block; frames of a movie are left out."""
    from sphinx_gallery.scrapers import figure_rst     # noqa: PLC0415 (only when the gallery runs)

    out = EXAMPLES_OUT / Path(block_vars["src_file"]).stem
    since = _shown.get(out, 0.0)
    pictures = sorted((p for p in out.rglob("*.png") if p.stat().st_mtime > since and "frames" not in p.parts),
                      key=lambda p: p.stat().st_mtime)[:MAX_PICTURES]
    _shown[out] = time.time()
    shown = []
    for picture, target in zip(pictures, block_vars["image_path_iterator"]):
        shutil.copyfile(picture, target)
        shown.append(target)
    return figure_rst(shown, gallery_conf["src_dir"])


def setup(app):
    app.connect("autodoc-process-docstring", plain_text_to_rst, priority=600)   # after napoleon
    return {"parallel_read_safe": True, "parallel_write_safe": True}
