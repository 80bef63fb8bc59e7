"""Sphinx configuration of femshell's manual (built by ``python docs/build.py``).

Markdown pages are read by myst-parser, the API reference comes from the docstrings
(autodoc + autosummary, numpy style through napoleon), and the gallery from the literate
scripts in ``docs/examples`` (sphinx-gallery, run at build time).

Environment (set by docs/build.py):

* ``FEMSHELL_GALLERY``: a regular expression of the example files to run (default: all);
  the others are rendered without their output.
* ``FEMSHELL_EXAMPLES_OUT``: where the examples write their files (default: a directory
  under the system's temporary directory).
"""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, os.environ.get("FEMSHELL_ROOT", str(DOCS.parent)))   # this checkout's femshell first
sys.path.insert(0, str(DOCS))             # sphinx_ext, the local helpers

project = "femshell"
author = "femshell contributors"
copyright = "femshell contributors"
release = version = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
    "sphinx_ext",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_templates", "examples", "gallery/*.md", "**/*.ipynb",
                    "gallery/sg_execution_times.rst"]
templates_path = ["_templates"]

html_theme = "furo"
html_title = "femshell"
html_static_path = []
html_show_sourcelink = False

# Markdown: $...$ maths, ::: fences, anchors for the headings that pages link to.
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

# The API reference: one page per module, from the docstrings (numpy style).
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "member-order": "bysource", "ignore-module-all": True}
autodoc_typehints = "description"
autodoc_typehints_format = "short"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True          # an Attributes section does not document a property twice

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "gallery",
    "filename_pattern": os.environ.get("FEMSHELL_GALLERY", ".*"),
    "reset_argv": "sphinx_ext.example_argv",
    "image_scrapers": ("matplotlib", "sphinx_ext.new_pictures"),
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
    "capture_repr": (),
    "show_memory": False,
    "default_thumb_file": str(DOCS / "images" / "default-top.png"),
}
