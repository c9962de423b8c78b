"""Sphinx configuration of the sk_hamiltonian documentation.

Build (quick mode, as in CI)::

    SK_HAMILTONIAN_QUICK=1 python -m sphinx -W --keep-going -b html docs docs/_build/html
"""

from importlib.util import find_spec
from pathlib import Path

import sk_hamiltonian

DOCS = Path(__file__).resolve().parent

project = "sk_hamiltonian"
author = "sk_hamiltonian developers"
copyright = "2026, sk_hamiltonian developers"
release = version = sk_hamiltonian.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

# sphinx-gallery writes a summary of all galleries' run times at the top level;
# the gallery's own one is linked from the gallery.
exclude_patterns = ["_build", "sg_execution_times.rst"]
templates_path = ["_templates"]
default_role = "literal"

autosummary_generate = True
# No default members: the class template (_templates/class.rst) lists the
# members of the generated class pages itself, and a default "members" would
# also expand the ``automodule:: ... :no-members:`` blocks of api.rst, printing
# every function of datasets, model_selection and plotting a second time.
autodoc_default_options = {}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

sphinx_gallery_conf = {
    "examples_dirs": str(DOCS.parent / "examples"),
    "gallery_dirs": str(DOCS / "auto_examples"),
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"/_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "plot_gallery": "True",
    "reference_url": {"sk_hamiltonian": None},
    "doc_module": ("sk_hamiltonian",),
    # Mini-galleries of the examples using each object, included by the
    # autosummary templates.
    "backreferences_dir": str(DOCS / "generated"),
}

html_title = f"sk_hamiltonian {release}"
if find_spec("pydata_sphinx_theme") is not None:
    html_theme = "pydata_sphinx_theme"
    html_theme_options = {
        "navigation_with_keys": False,
        "show_toc_level": 2,
    }
else:  # the docs extra installs it; the fallback keeps a bare Sphinx working.
    html_theme = "alabaster"
html_static_path = []
