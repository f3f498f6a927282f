"""Sphinx configuration of the documentation site: `make docs` builds it into docs/_build/html.

The Markdown pages are read by myst-parser as they are (GitHub shows the same files); the
command-line reference and the gallery are generated at build time by docs/_ext/counterpoise_docs.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import counterpoise  # noqa: E402

project = "counterpoise"
author = "the counterpoise developers"
copyright = "the counterpoise developers"  # noqa: A001 - Sphinx's name
release = version = counterpoise.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "counterpoise_docs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
# _generated/ holds pages included by others (cli.md); the scripts and images beside the pages are not pages
exclude_patterns = ["_build", "_generated", "Thumbs.db", ".DS_Store"]

# Markdown: GitHub's heading anchors (links such as `loops.md#the-home`), fenced directives
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence"]

# autodoc: the type hints in the signatures, one parameter a line when a signature is long
autodoc_typehints = "signature"
python_maximum_signature_line_length = 88
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_preserve_defaults = True

# "--set" stays two hyphens (not an en dash) wherever a page writes an option outside code
smartquotes = False

html_theme = "furo"
html_title = f"counterpoise {release}"
html_static_path = ["_static"]
html_css_files = ["counterpoise.css"]
html_show_sourcelink = False
