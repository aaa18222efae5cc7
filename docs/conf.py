"""Sphinx configuration of the aeromag_env documentation site.

Build it with ``bash scripts/build-docs`` (warnings are errors; nitpicky cross-references). The
pages are Markdown (MyST); the environment pages, the command-line, flight-field and report.json
references are generated at the start of every build from the code (``docs/_ext/``), and the
gallery (``examples/plot_*.py``) is run by the build, which makes its figures.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # the checkout's package, not an installed copy
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import aeromag_env  # noqa: E402

project = "aeromag_env"
author = "the aeromag_env authors"
copyright = "the aeromag_env authors, MIT licence"
release = version = aeromag_env.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_design",
    "sphinx_gallery.gen_gallery",
    "aeromag_docs",  # docs/_ext: the generated pages (environments, CLI, fields, report.json)
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# docs/<data>/ hold results files and figures that pages include or show; they are not pages
exclude_patterns = [
    "_build",
    "Thumbs.db",
    ".DS_Store",
    "discovery/**",
    "paper/**",
    "ppo/**",
    "general/**",
    "learners/**",
    "auto_examples/*.ipynb",
    "auto_examples/*.py",
    "auto_examples/*.zip",
    "auto_examples/*.json",
    "auto_examples/*.md5",
]

# -- Cross-references: every one to our own code must resolve ---------------------------------
templates_path = ["_templates"]
nitpicky = True
# No network at build time, so no intersphinx: names of other projects (numpy, gymnasium, the
# standard library…) in signatures and docstrings are not links; everything else must resolve.
_EXTERNAL = (
    r"(np|numpy|gym|gymnasium|spaces|torch|ray|h5py|scipy|matplotlib|plt|sb3|"
    r"stable_baselines3|optuna|pydantic|pydantic_core|pathlib|os|collections|typing|"
    r"typing_extensions|dataclasses|argparse|concurrent|json|enum|re|io|datetime|numba|"
    r"threading)"
)
nitpick_ignore_regex = [
    (r"py:.*", _EXTERNAL + r"\..*"),
    # builtins and typing words that numpydoc and autodoc turn into references
    (
        r"py:(class|obj|data)",
        r"(Path|Any|Callable|Iterable|Iterator|Sequence|Mapping|MutableMapping|Literal|"
        r"NamedTuple|Protocol|Self|Generator|ndarray|array_like|array-like|ArrayLike|"
        r"NDArray|optional|default|None|True|False|int|float|str|bool|dict|list|tuple|"
        r"set|frozenset|bytes|object|type|callable|sequence|mapping|iterable|of|or|and|"
        r"shape|function|Env|VecEnv|ActType|ObsType|Generator\[.*|.*\[.*)",
    ),
    # the standard library's abstract base of BasePolicy (no intersphinx: no network)
    ("py:class", r"abc\.ABC"),
]

# -- API reference ----------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "inherited-members": False, "show-inheritance": True}
autodoc_inherit_docstrings = False  # gymnasium.Env's own texts are not ours
autodoc_typehints = "none"  # the numpydoc Parameters sections give the types, with units
autodoc_member_order = "bysource"
numpydoc_show_class_members = False  # autosummary lists them, once
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- Markdown ---------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "dollarmath", "deflist", "fieldlist", "attrs_inline"]
myst_heading_anchors = 3  # [text](page.md#a-heading) links resolve and are checked

# -- Gallery: examples/plot_*.py, run by every build ------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": str(DOCS / "auto_examples"),
    "filename_pattern": r"/plot_",
    "abort_on_example_error": True,  # an example that breaks fails the build
    "only_warn_on_example_error": False,
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "plot_gallery": "True",
}

# -- HTML -------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"aeromag_env {release}"
html_static_path = ["_static"]
html_favicon = "_static/favicon.svg"
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 5,  # one line of the navbar at 1280 px
    "navbar_align": "left",
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
    "use_edit_page_button": False,
    "search_bar_text": "Search the docs…",
}
html_sidebars = {"index": [], "changelog": []}
html_context = {"default_mode": "light"}
