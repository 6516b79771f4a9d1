"""Sphinx configuration of the mpfem-fenicsx documentation (``make docs``).

Markdown pages (MyST), the furo theme (no web access at build time), autodoc / autosummary for
the API reference, and the local extension ``docs/_ext/mpfem_docs.py`` that generates the
case-file reference, the demo pages and the validation summaries before the sources are read.
"""

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "mpfem-fenicsx"
author = "the mpfem-fenicsx developers"
copyright = "mpfem-fenicsx developers, MIT licence"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax served from the site itself: equations render offline
    "sphinx.ext.viewcode",
    "mpfem_docs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_generated", "figures"]

# MyST: $...$ and $$...$$ math, ::: fences, definition lists, heading anchors for links
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# pages generated from files written for other readers (READMEs, demos in cells) may skip a
# heading level; that is no error in a page
suppress_warnings = ["myst.header"]

# API reference: one page per public module (docs/api.md lists them), members documented
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
add_module_names = False

html_theme = "furo"
html_title = "mpfem-fenicsx"
html_static_path = []

# docstrings and demo texts are plain ASCII on purpose: keep "--option" and quotes as written,
# and show their indented blocks (formulas, command lines) without guessing a language
smartquotes = False
highlight_language = "none"
