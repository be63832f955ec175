"""Sphinx configuration of the wearbench documentation (MyST Markdown, PyData theme).

Built with warnings as errors: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``
(``.ci/run`` does, then checks every internal link with ``docs/tools/check_links.py``). Three
pages are generated from the code and data, never typed: the CLI reference from the argparse
parsers (sphinx-argparse, ``_ext/wearbench_cli.py``), the Python API from ``wearbench.__all__``
(``_ext/wearbench_api.py``) and one results page per JSON file under ``results/data/``
(``_ext/wearbench_results.py``).
"""

from __future__ import annotations

import sys
from importlib.metadata import version as _version
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "wearbench"
author = "the wearbench authors"
copyright = "the wearbench authors, MIT licence"
release = _version("wearbench")
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinxarg.ext",
    "sphinx_design",
    "wearbench_api",
    "wearbench_cli",
    "wearbench_results",
]

source_suffix = {".md": "markdown"}  # results/data/*.json are added by wearbench_results
root_doc = "index"
exclude_patterns = ["_build", "results/schema.json", "tools", "figures/README.md"]
myst_enable_extensions = ["colon_fence", "deflist"]
smartquotes = False  # option names stay as typed: "--force", never an en dash
myst_heading_anchors = 3  # [text](page.md#a-heading) links are checked like any other reference

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"show-inheritance": False}
autosummary_generate = False  # the API page lists the objects itself (wearbench_api)

html_theme = "pydata_sphinx_theme"
html_title = f"wearbench {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 7,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "changelog": []}
html_context = {"default_mode": "light"}  # a first visit has no stored mode: no "invalid theme mode" error
html_static_path = ["_static"]
html_favicon = "_static/wearbench.svg"  # also spares the browser a request for /favicon.ico
html_show_sourcelink = False
