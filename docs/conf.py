"""Sphinx configuration: the user guide (MyST Markdown), the API reference from the docstrings
(autodoc + napoleon: the package's docstrings are Google style with Sphinx cross-references)
and results pages generated from the committed ``summary.csv`` files at every build."""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(DOCS))

project = "gp-pseudospectral-mpc"
author = "the gp-pseudospectral-mpc developers"
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "myst_parser",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
napoleon_google_docstring = True
napoleon_numpy_docstring = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
html_theme = "furo"
html_title = "gp-pseudospectral-mpc"
suppress_warnings = ["myst.xref_missing"]


def _generate(app) -> None:
    from results_pages import write_results_pages

    write_results_pages(REPO / "benchmarks" / "results", DOCS / "results")


def setup(app) -> None:
    app.connect("builder-inited", _generate)
