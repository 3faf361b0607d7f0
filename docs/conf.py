"""Sphinx configuration of the pumpsim documentation (`make docs`)."""
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))  # this checkout's pumpsim, also without an install

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

import pumpsim  # noqa: E402

project = "pumpsim"
author = "the pumpsim developers"
copyright = "the pumpsim developers"
release = version = pumpsim.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "sphinxarg.ext",
    "pumpsim_config_keys",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "gallery/README.rst", "tutorials/*.ipynb", "tutorials/*.py",
                    "tutorials/*.zip", "tutorials/*.md5", "tutorials/*.codeobj.json"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# API reference: numpydoc sections; the public names' docstrings are the source
autodoc_member_order = "bysource"
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

sphinx_gallery_conf = {
    "examples_dirs": ["gallery"],
    "gallery_dirs": ["tutorials"],
    "filename_pattern": r"/plot_",  # every tutorial runs; its figures are the page's
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "min_reported_time": 0,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
    "run_stale_examples": True,  # every build runs them: their output is the code's of this build
}

WIDE_PAGES = ["tutorials/plot_1_first_fit", "tutorials/plot_2_diagnosis", "tutorials/plot_3_tolerance_study",
              "tutorials/plot_4_pumpdown", "reference/config"]
html_theme = "pydata_sphinx_theme"
html_title = f"pumpsim {release}"
html_static_path = ["_static"]
html_css_files = ["pumpsim.css"]
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "navbar_align": "left",
    # the tutorials' code and the config tables need the width more than a page outline
    "secondary_sidebar_items": {"**": ["page-toc"], **{page: [] for page in WIDE_PAGES}},
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "getting-started": [], **{page: [] for page in WIDE_PAGES}}
html_show_sourcelink = False
