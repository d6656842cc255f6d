"""Sphinx configuration of lpvid's documentation.

Build with ``sphinx-build -W --keep-going -b html docs docs/_build/html``
from the repository root (the requirements are in ``docs/requirements.txt``,
mirrored by the ``docs`` extra of pyproject.toml).
"""

from __future__ import annotations

import os
import sys

# lpvid is installed editable in CI; from a checkout, import the tree's own
# Python sources (the compiled core must be built or copied beside them).
sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "python")))

import lpvid  # noqa: E402

project = "lpvid"
author = "the lpvid authors"
copyright = "the lpvid authors"  # noqa: A001
release = lpvid.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "requirements.txt"]
templates_path = ["_templates"]

# The API pages are generated from the docstrings at every build (and not
# committed): docs/api/ is written by autosummary.
autosummary_generate = True
autosummary_imported_members = True
autosummary_ignore_module_all = False
# Names of the top-level namespace: a module page links to them rather than
# documenting them a second time (see _templates/autosummary/module.rst).
autosummary_context = {"toplevel": sorted(set(lpvid.__all__) - {"__version__"})}
autodoc_typehints = "none"
autodoc_member_order = "bysource"

# numpydoc renders the sections; the members of a class are listed by the
# autosummary template, not again by numpydoc.
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# The method document's formulas: $...$ and $$...$$ rendered by MathJax.
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

html_theme = "alabaster"
html_title = f"lpvid {release}"
html_static_path: list[str] = []

# The doctest builder runs the ``{doctest}`` blocks of the pages only: the
# docstrings' examples already run with pytest (--doctest-modules).
doctest_test_doctest_blocks = ""
