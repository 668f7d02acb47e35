"""Sphinx configuration for the merge-irl documentation site.

Build (warnings are errors, as CI does)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

import shutil
import sys
import types
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _dist_version
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # document this checkout, not whatever else is installed

# `python -m analysis` runs the CLI on import; autosummary imports every submodule it walks,
# so a stand-in marked as a Sphinx mock keeps it (and only it) out of the walk.
_cli_entry = types.ModuleType("analysis.__main__")
_cli_entry.__sphinx_mock__ = True  # type: ignore[attr-defined]
sys.modules.setdefault("analysis.__main__", _cli_entry)

project = "merge-irl"
author = "merge-irl authors"
try:
    release = _dist_version("merge-irl")
except PackageNotFoundError:
    release = "0.1.0"
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# MyST: `$...$` maths, definition lists, anchors for `##`/`###` headings (cross-page links).
myst_enable_extensions = ["dollarmath", "deflist", "colon_fence"]
myst_heading_anchors = 3

# API pages: generated at build time from the docstrings (docs/api/generated is not committed).
# Start from an empty folder every build, so a module renamed or moved elsewhere leaves no stale
# page behind (a stale page outside every toctree is a warning, hence an error under -W).
shutil.rmtree(Path(__file__).resolve().parent / "api" / "generated", ignore_errors=True)
autosummary_generate = True
autosummary_imported_members = False
# Each object is documented once, in the module that defines it: a package's `__all__`
# re-exports (irl.IRLConfig = irl.config.IRLConfig) would otherwise be a second target.
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_mock_imports: list[str] = []

# Google-style docstrings (Args / Returns / Raises), as the code base writes them.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_attr_annotations = True

# Type names in signatures are not all resolvable (numpy aliases, pandas); links are a bonus,
# not a build failure.
nitpicky = False

html_theme = "alabaster"
html_title = f"merge-irl {release}"
html_static_path: list[str] = []
