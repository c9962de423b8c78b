"""Sphinx configuration of the sk_hamiltonian documentation.

Build (quick mode, as in CI)::

    SK_HAMILTONIAN_QUICK=1 python -m sphinx -n -W --keep-going -b html docs docs/_build/html
"""

from importlib import import_module
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
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]
# Optional extras of the docs extra; a bare Sphinx still builds without them.
if find_spec("sphinx-mathjax-offline") is not None:
    # Copies MathJax into the built site (_static/mathjax/), so that equations
    # render without network; without it they load MathJax from a CDN.
    extensions.append("sphinx-mathjax-offline")
if find_spec("sphinx_copybutton") is not None:
    extensions.append("sphinx_copybutton")  # a "copy" button on code blocks

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

# Types in numpydoc "Parameters"/"Returns" sections link to their documentation
# ("ndarray of shape (n, m)" links "ndarray"). Only the words below (and
# numpydoc's defaults: int, float, str, dict, None, array-like, ndarray, ...)
# are links; every other word of a type ("of", "shape", "n_states", ...) stays
# plain text, so new docstrings cannot break the nitpicky build.
numpydoc_xref_param_type = True
numpydoc_xref_ignore = "all"
numpydoc_xref_aliases = {
    # numpydoc's default shows NumPy's spelling "array_like"; keep ours.
    "array-like": ":term:`array-like <numpy:array_like>`",
    "Axes": "matplotlib.axes.Axes",
    "Figure": "matplotlib.figure.Figure",
    "Pipeline": "sklearn.pipeline.Pipeline",
    "estimator": ":term:`estimator <sklearn:estimator>`",
    "Generator": "numpy.random.Generator",
}
# The package's public names link to their API pages.
for _module_name in ("sk_hamiltonian", "sk_hamiltonian.datasets",
                     "sk_hamiltonian.model_selection", "sk_hamiltonian.plotting"):
    _module = import_module(_module_name)
    for _name in getattr(_module, "__all__", ()):
        if isinstance(getattr(_module, _name), type):  # classes only
            numpydoc_xref_aliases[_name] = f"{_module_name}.{_name}"

# Links to other projects' documentation. The build has no network: each
# inventory is read from docs/_static/inventories/, written by
# make_inventories.py there with the objects these docs reference; the URLs
# are used for the links only. Run `python -m sphinx -n ...` to see a
# reference that is missing ("reference target not found"), add it to
# make_inventories.py and rerun it.
_INVENTORIES = "_static/inventories"
intersphinx_mapping = {
    "python": ("https://docs.python.org/3/", f"{_INVENTORIES}/python.inv"),
    "numpy": ("https://numpy.org/doc/stable/", f"{_INVENTORIES}/numpy.inv"),
    "scipy": ("https://docs.scipy.org/doc/scipy/", f"{_INVENTORIES}/scipy.inv"),
    "sklearn": ("https://scikit-learn.org/stable/", f"{_INVENTORIES}/sklearn.inv"),
    "matplotlib": ("https://matplotlib.org/stable/", f"{_INVENTORIES}/matplotlib.inv"),
}

# One gallery in sections: the scripts directly in examples/ (getting started),
# then one section per subfolder that has a GALLERY_HEADER.rst, in alphabetical
# order: paper/ (the paper's examples), scenes/ (model spaces for other
# scenes). A section without scripts shows its header only. Each script writes
# its figures to a figures/ folder next to itself (results.rst includes them).
# The paths are relative to this directory: sphinx-gallery writes them into the
# toctree of the sections, where absolute paths do not resolve.
sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "auto_examples",
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
        # The navigation bar starts next to the title rather than above the
        # article, and search is an icon (the search box took a third row), so
        # that the six long section titles fit in two rows at 1400 px or less.
        "navbar_align": "left",
        "header_links_before_dropdown": 6,
        "navbar_persistent": [],
        "navbar_end": ["search-button", "theme-switcher", "navbar-icon-links"],
    }
else:  # the docs extra installs it; the fallback keeps a bare Sphinx working.
    html_theme = "alabaster"
# Only the site's own CSS and JavaScript are copied to the built _static/; the
# rest of docs/_static (benchmark figures, intersphinx inventories) is read at
# build time.
html_static_path = ["_static/site"]
html_css_files = ["custom.css"]  # full-width article, scrolling tables
html_js_files = ["figure-zoom.js"]  # click-to-enlarge figures
# Method entries of the page TOC read "fit()", not "HamiltonianRegressor.fit()".
toc_object_entries_show_parents = "hide"

_SECTION_NAVIGATION = {"sidebar-collapse.html", "sidebar-nav-bs.html"}


def _hide_empty_primary_sidebar(app, pagename, templatename, context, doctree):
    """Drop the primary sidebar on pages whose section has no sub-pages.

    The pydata theme shows its "Section Navigation" sidebar on every page below
    the root whose section contains a toctree, hidden ones included, and leaves
    it empty on single-page sections (user guide, results, ...), squeezing the
    article. Here a page keeps it only if its top-level section (the ancestor
    just below the root document) includes other documents, as the API
    reference and the gallery do.
    """
    if "sidebars" not in context or pagename == app.config.root_doc:
        return
    includes = app.env.toctree_includes
    parents = {}
    for parent, children in includes.items():
        for child in children:
            parents.setdefault(child, parent)
    if pagename not in parents:
        return  # genindex, search, orphans: the theme already drops it
    top, seen = pagename, {pagename}
    while parents.get(top, app.config.root_doc) != app.config.root_doc:
        top = parents[top]
        if top in seen:  # a toctree cycle; leave the page alone
            return
        seen.add(top)
    if not includes.get(top):
        # Names come from theme.conf with or without their ".html".
        context["sidebars"] = [
            name
            for name in context["sidebars"]
            if name not in _SECTION_NAVIGATION and f"{name}.html" not in _SECTION_NAVIGATION
        ]


def setup(app):
    app.connect("html-page-context", _hide_empty_primary_sidebar)
