"""Sphinx configuration of the agrihil documentation site (MyST Markdown, furo theme).

Built by ``bash scripts/docs.sh`` (``sphinx-build -W``) and by the test run
(``tests/test_docs_build.py``): a broken reference, link or directive fails the build.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

from hil import __version__  # noqa: E402

project = "agrihil"
author = "the agrihil authors"
copyright = "2026, the agrihil authors"
release = __version__
version = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
    "agrihil_docs",
    "rig_quantities",
]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_mock_imports: list[str] = []
napoleon_numpy_docstring = True
napoleon_google_docstring = False

html_theme = "furo"
html_title = f"agrihil {release}"
html_static_path: list[str] = []
# the repository is the link target for source files named in the pages
suppress_warnings = ["myst.header"]
