"""Sphinx configuration of the drake_uuv site: ``sphinx-build -W -b html docs docs/_build/html``.

Everything the build uses is installed by pip (the ``docs`` extra): the theme, MyST and
MyST-NB. Nothing is fetched while it builds: no intersphinx inventory, no web font, no
remote image; MathJax is not used.
"""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
# This checkout's package, for autodoc here and for the notebooks' kernels (which inherit
# the environment), whichever checkout the environment has installed.
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))

project = "drake_uuv"
author = "drake_uuv contributors"
copyright = "drake_uuv contributors, BSD-3-Clause"

extensions = [
    "myst_nb",  # Markdown pages (MyST) and notebooks executed at build time
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # the docstrings' Args:/Returns: sections (Google style)
    "sphinx.ext.viewcode",  # the source of each documented object, on the site itself
    "uuv_sphinx",  # docs/_ext: port blocks, field tables, the generated reference pages
]

root_doc = "index"
# results.md: the old single results page, now a pointer to results/ for links from the code.
exclude_patterns = ["_build", "results.md", "**/.ipynb_checkpoints"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

# MyST: heading anchors, so that a page's `[text](page.md#a-heading)` links resolve (and a
# broken one is a warning, so an error).
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]

# MyST-NB: run every notebook while building, through jupyter-cache (docs/_ext/uuv_sphinx.py
# empties the cache when the package, its scenarios or the notebooks change), and fail the
# build on an error in a cell.
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True

autodoc_member_order = "bysource"
autodoc_typehints = "description"
# Types for the parameters a docstring documents (a dataclass's fields are in its table).
autodoc_typehints_description_target = "documented"
autodoc_typehints_format = "short"
autodoc_default_options = {"show-inheritance": True}
autoclass_content = "class"

html_theme = "furo"
html_title = "drake_uuv"
html_static_path = ["_static"]
html_theme_options = {"navigation_with_keys": True}
html_copy_source = False
html_show_sourcelink = False
# Furo links Google Fonts nowhere; the pages load only files of the site.

napoleon_google_docstring = True
napoleon_numpy_docstring = False
