"""Sphinx configuration of the dea-opt documentation site.

Build it (warnings are errors, every cross-reference checked):

    .venv/bin/pip install -e ".[docs]" && .venv/bin/sphinx-build -W -n -b html docs docs/_build/html

The site loads nothing from the network: equations are MathML made here (``dea_docs.mathml``),
the theme's scripts and icons are its own files, search reads ``searchindex.js`` beside it.
The API reference, the command line, the scenario keys and the formulations' options are made
from the code at each build (``dea_docs.api``, ``dea_docs.reference``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

from dea_docs import api, gallery  # noqa: E402

import dea_opt  # noqa: E402

project = "dea-opt"
author = "dea-opt developers"
copyright = "dea-opt developers, MIT licence"
release = version = dea_opt.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "dea_docs",
]

# --- sources -------------------------------------------------------------------------------------
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "**/GALLERY_HEADER.rst", "_tutorials/*.py", "_ext", "_templates"]
templates_path = ["_templates"]

# Made at every build, so that they cannot drift from the code: the API pages (one per public
# module and one per documented object) and the math pages (each includes formulations/<name>.md).
api.write_api_pages(DOCS / "reference" / "api")
MATH = DOCS / "math" / "pages"
MATH.mkdir(parents=True, exist_ok=True)
for stale in MATH.glob("*.md"):
    stale.unlink()
for page in sorted((ROOT / "formulations").glob("*.md")):
    (MATH / page.name).write_text(f"```{{include}} ../../../formulations/{page.name}\n```\n")

# --- Markdown -------------------------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 4
myst_dmath_double_inline = True

# --- API: autodoc and numpydoc --------------------------------------------------------------------
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # numpydoc's Parameters sections give the types, with shapes and units
autodoc_inherit_docstrings = True
autosummary_generate = False  # dea_docs.api writes the pages itself
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# --- cross-references: every one must resolve (nitpicky, -n) ----------------------------------------
nitpicky = True
# Types named in docstrings and signatures that belong to other projects: the site links to no
# other site (nothing is fetched), so these stay plain text.
nitpick_ignore_regex = [
    # private names a docstring mentions (they have no page by design)
    (r"py:.*", r"(.*\.)?_[A-Za-z]\w*(\..*)?"),
    (
        r"py:.*",
        r"(numpy|np|scipy|pandas|pd|trimesh|pydantic|typer|click|casadi|cvxpy|dask|distributed|matplotlib)(\..*)?",
    ),
    (r"py:mod", r"(csv|json|io|os|sys|tomllib|xml)(\..*)?"),
    (r"py:func", r"(open|print|repr|isinstance)"),
    (r"py:.*", r"(pathlib|typing|collections|dataclasses|enum|os|io|concurrent|contextlib|types|abc)(\..*)?"),
    (r"py:class", r"(ndarray|DataFrame|Path|PathLike|Trimesh|ArrayLike|BaseModel|Enum|StrEnum|array_like|optional)"),
    (r"py:class", r"(int|float|str|bool|dict|list|tuple|set|frozenset|callable|object|bytes|type|None|Any)"),
]

# --- the gallery: examples/ run as they stand, their figures and timings on the pages ---------------
sphinx_gallery_conf = gallery.configuration(ROOT, DOCS)

# --- HTML -------------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = "dea-opt"
html_static_path = ["_static"]
html_css_files = ["dea.css"]
html_math_renderer = "mathml"
html_last_updated_fmt = None
html_copy_source = False
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "navbar_end": ["navbar-icon-links"],
    "icon_links": [],
    "footer_start": ["copyright"],
    "footer_end": [],
    "secondary_sidebar_items": ["page-toc"],
    "collapse_navigation": True,
}
html_sidebars = {"**": ["sidebar-nav-bs"]}
# The theme's light/dark switch reads this; left empty it logs an error in the console on the
# first page a fresh browser opens.
html_context = {"default_mode": "light"}
