"""Sphinx configuration of the ea-gym documentation: furo, MyST Markdown pages, autodoc with napoleon.

Build: ``.venv/bin/sphinx-build -W --keep-going -b html docs out/docs`` (scripts/test.sh runs it).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # ea_gym and agents from the checkout
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import ea_gym  # noqa: E402

project = "ea-gym"
author = "ea-gym contributors"
copyright = "ea-gym contributors"
release = ea_gym.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
    "ea_docs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_generated/*.md", "Thumbs.db", ".DS_Store"]  # _generated: included by the pages
templates_path = ["_templates"]  # autosummary's module page: the module's automodule and its submodules

# MyST: $...$ maths, ::: fences, heading anchors for links such as page.md#section
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# autodoc: members in source order, type hints in the description, Google-style docstrings (napoleon)
# members defined in each module (a package's re-exports are documented once, where they are defined)
autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": True, "ignore-module-all": True}
autodoc_inherit_docstrings = False  # gymnasium's and SB3's own docstrings stay in their documentation
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
autodoc_mock_imports = ["ray", "torchrl", "rl_zoo3", "progpy"]
autosummary_generate = True
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True
napoleon_custom_sections = [("Keys", "params_style")]  # the keys of a returned dict, documented like arguments


html_theme = "furo"
html_title = f"ea-gym {release}"
html_static_path: list[str] = []
