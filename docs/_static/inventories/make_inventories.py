"""Write the intersphinx inventories that the documentation build reads offline.

Why
---
``sphinx.ext.intersphinx`` turns references such as
:class:`~sklearn.model_selection.GridSearchCV` or a parameter type ``ndarray``
into links to the other project's documentation. It finds the target URLs in
that project's ``objects.inv``, normally downloaded at build time. The
documentation must build without network (CI has none), so ``conf.py`` points
intersphinx at the files in this directory instead::

    intersphinx_mapping = {"numpy": ("https://numpy.org/doc/stable/",
                                     "_static/inventories/numpy.inv"), ...}

The URL is only the base of the links; the inventory is read from disk.

What
----
This script writes ``python.inv``, ``numpy.inv``, ``scipy.inv``,
``sklearn.inv`` and ``matplotlib.inv`` next to itself. They are valid Sphinx
inventories, version 2 (four header lines, then zlib-compressed lines
``name domain:role priority uri dispname``), but list only the objects that
these docs reference (or that sphinx-gallery may link in the examples' code),
not the projects' whole APIs. Each URI is the object's page in the project's
current documentation, relative to the base URL in ``conf.py``, following the
project's page layout (for instance
``modules/generated/sklearn.pipeline.Pipeline.html#sklearn.pipeline.Pipeline``
for scikit-learn, ``reference/generated/numpy.mean.html#numpy.mean`` for NumPy).

Adding a name
-------------
1. Build nitpicky; an unresolved reference is reported::

       python -m sphinx -n -b html docs docs/_build/html
       ... WARNING: py:class reference target not found: sklearn.base.clone

2. Add it to the list of its project below (for the usual page layout one of
   the helper functions gives the URI), rerun this script from anywhere::

       python docs/_static/inventories/make_inventories.py

   and commit the changed ``.inv`` files with the script. Check the URL in a
   browser when you can: intersphinx cannot tell a wrong URI from a right one.

The output is deterministic (sorted entries, fixed zlib level), so an unchanged
list rewrites identical files.
"""

import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent


# URI helpers: the page layouts of each project's documentation.


def _autosummary(prefix, name):
    """``prefix/<name>.html#<name>``: one page per object (autosummary)."""
    return f"{prefix}/{name}.html#{name}"


def sklearn_api(name):
    return _autosummary("modules/generated", name)


def numpy_api(name):
    return _autosummary("reference/generated", name)


def scipy_api(name):
    return _autosummary("reference/generated", name)


def matplotlib_api(name):
    return _autosummary("api/_as_gen", name)


def python_builtin(name, page="functions"):
    return f"library/{page}.html#{name}"


# (name, "domain:role", uri, display name or "-" for the name itself)

PYTHON = [
    # Built-in types and functions (numpydoc's default type aliases).
    ("int", "py:class", python_builtin("int"), "-"),
    ("float", "py:class", python_builtin("float"), "-"),
    ("bool", "py:class", python_builtin("bool"), "-"),
    ("complex", "py:class", python_builtin("complex"), "-"),
    ("str", "py:class", python_builtin("str", "stdtypes"), "-"),
    ("list", "py:class", python_builtin("list", "stdtypes"), "-"),
    ("tuple", "py:class", python_builtin("tuple", "stdtypes"), "-"),
    ("dict", "py:class", python_builtin("dict", "stdtypes"), "-"),
    ("set", "py:class", python_builtin("set", "stdtypes"), "-"),
    ("range", "py:class", python_builtin("range", "stdtypes"), "-"),
    ("slice", "py:class", python_builtin("slice"), "-"),
    ("object", "py:class", python_builtin("object"), "-"),
    ("callable", "py:function", python_builtin("callable"), "-"),
    ("isinstance", "py:function", python_builtin("isinstance"), "-"),
    ("len", "py:function", python_builtin("len"), "-"),
    ("None", "py:data", python_builtin("None", "constants"), "-"),
    ("True", "py:data", python_builtin("True", "constants"), "-"),
    ("False", "py:data", python_builtin("False", "constants"), "-"),
    ("NotImplemented", "py:data", python_builtin("NotImplemented", "constants"), "-"),
    ("Ellipsis", "py:data", python_builtin("Ellipsis", "constants"), "-"),
    # Exceptions and warnings.
    ("Exception", "py:exception", python_builtin("Exception", "exceptions"), "-"),
    ("ArithmeticError", "py:exception", python_builtin("ArithmeticError", "exceptions"), "-"),
    ("FloatingPointError", "py:exception", python_builtin("FloatingPointError", "exceptions"), "-"),
    ("OverflowError", "py:exception", python_builtin("OverflowError", "exceptions"), "-"),
    ("RuntimeError", "py:exception", python_builtin("RuntimeError", "exceptions"), "-"),
    ("TypeError", "py:exception", python_builtin("TypeError", "exceptions"), "-"),
    ("ValueError", "py:exception", python_builtin("ValueError", "exceptions"), "-"),
    ("KeyError", "py:exception", python_builtin("KeyError", "exceptions"), "-"),
    ("Warning", "py:exception", python_builtin("Warning", "exceptions"), "-"),
    ("UserWarning", "py:exception", python_builtin("UserWarning", "exceptions"), "-"),
    ("RuntimeWarning", "py:exception", python_builtin("RuntimeWarning", "exceptions"), "-"),
    # Standard library.
    ("warnings", "py:module", "library/warnings.html#module-warnings", "-"),
    ("warnings.warn", "py:function", "library/warnings.html#warnings.warn", "-"),
    ("warnings.filterwarnings", "py:function", "library/warnings.html#warnings.filterwarnings", "-"),
    ("warnings.catch_warnings", "py:class", "library/warnings.html#warnings.catch_warnings", "-"),
    ("collections.namedtuple", "py:function", "library/collections.html#collections.namedtuple", "-"),
    ("contextlib.contextmanager", "py:function", "library/contextlib.html#contextlib.contextmanager", "-"),
    ("functools.partial", "py:function", "library/functools.html#functools.partial", "-"),
    # Glossary terms and labels used by numpydoc's default type aliases
    # ("bool" -> :ref:`python:bltin-boolean-values`, "iterable", ...).
    ("iterable", "std:term", "glossary.html#term-iterable", "-"),
    ("sequence", "std:term", "glossary.html#term-sequence", "-"),
    ("mapping", "std:term", "glossary.html#term-mapping", "-"),
    ("generator", "std:term", "glossary.html#term-generator", "-"),
    ("bltin-boolean-values", "std:label", "library/stdtypes.html#bltin-boolean-values", "Boolean Type - bool"),
]

NUMPY = [
    ("numpy.ndarray", "py:class", numpy_api("numpy.ndarray"), "-"),
    ("numpy.ndarray.shape", "py:attribute", numpy_api("numpy.ndarray.shape"), "-"),
    ("numpy.dtype", "py:class", numpy_api("numpy.dtype"), "-"),
    ("numpy.random.Generator", "py:class", "reference/random/generator.html#numpy.random.Generator", "-"),
    ("numpy.random.RandomState", "py:class", "reference/random/legacy.html#numpy.random.RandomState", "-"),
    ("numpy.random.default_rng", "py:function", "reference/random/generator.html#numpy.random.default_rng", "-"),
    ("numpy.inf", "py:data", "reference/constants.html#numpy.inf", "-"),
    ("numpy.nan", "py:data", "reference/constants.html#numpy.nan", "-"),
    ("numpy.pi", "py:data", "reference/constants.html#numpy.pi", "-"),
    ("numpy.linalg.norm", "py:function", numpy_api("numpy.linalg.norm"), "-"),
    ("numpy.linalg.lstsq", "py:function", numpy_api("numpy.linalg.lstsq"), "-"),
    ("numpy.errstate", "py:class", numpy_api("numpy.errstate"), "-"),
    # Glossary and labels (numpydoc's "array-like" and "scalar" aliases).
    ("array_like", "std:term", "glossary.html#term-array_like", "-"),
    ("arrays.scalars", "std:label", "reference/arrays.scalars.html#arrays-scalars", "Scalars"),
] + [
    (f"numpy.{name}", "py:function", numpy_api(f"numpy.{name}"), "-")
    for name in (
        "abs", "all", "any", "arange", "argmax", "argmin", "array", "asarray",
        "concatenate", "cos", "diff", "empty", "exp", "full", "isfinite",
        "linspace", "log", "max", "maximum", "mean", "median", "min", "minimum",
        "ones", "ptp", "sin", "sqrt", "stack", "std", "sum", "where", "zeros",
    )
]

SCIPY = [
    ("scipy.integrate.solve_ivp", "py:function", scipy_api("scipy.integrate.solve_ivp"), "-"),
    ("scipy.integrate.trapezoid", "py:function", scipy_api("scipy.integrate.trapezoid"), "-"),
    ("scipy.linalg.lstsq", "py:function", scipy_api("scipy.linalg.lstsq"), "-"),
    ("scipy.linalg.solve", "py:function", scipy_api("scipy.linalg.solve"), "-"),
    ("scipy.linalg.cho_factor", "py:function", scipy_api("scipy.linalg.cho_factor"), "-"),
    ("scipy.optimize.fsolve", "py:function", scipy_api("scipy.optimize.fsolve"), "-"),
    ("scipy.special.comb", "py:function", scipy_api("scipy.special.comb"), "-"),
]

SKLEARN = [
    ("sklearn.base.BaseEstimator", "py:class", sklearn_api("sklearn.base.BaseEstimator"), "-"),
    ("sklearn.base.RegressorMixin", "py:class", sklearn_api("sklearn.base.RegressorMixin"), "-"),
    ("sklearn.base.TransformerMixin", "py:class", sklearn_api("sklearn.base.TransformerMixin"), "-"),
    ("sklearn.base.clone", "py:function", sklearn_api("sklearn.base.clone"), "-"),
    ("sklearn.pipeline.Pipeline", "py:class", sklearn_api("sklearn.pipeline.Pipeline"), "-"),
    ("sklearn.pipeline.make_pipeline", "py:function", sklearn_api("sklearn.pipeline.make_pipeline"), "-"),
    ("sklearn.model_selection.GridSearchCV", "py:class", sklearn_api("sklearn.model_selection.GridSearchCV"), "-"),
    ("sklearn.model_selection.RandomizedSearchCV", "py:class", sklearn_api("sklearn.model_selection.RandomizedSearchCV"), "-"),
    ("sklearn.model_selection.KFold", "py:class", sklearn_api("sklearn.model_selection.KFold"), "-"),
    ("sklearn.model_selection.GroupKFold", "py:class", sklearn_api("sklearn.model_selection.GroupKFold"), "-"),
    ("sklearn.set_config", "py:function", sklearn_api("sklearn.set_config"), "-"),
    ("sklearn.model_selection.cross_val_score", "py:function", sklearn_api("sklearn.model_selection.cross_val_score"), "-"),
    ("sklearn.model_selection.cross_validate", "py:function", sklearn_api("sklearn.model_selection.cross_validate"), "-"),
    ("sklearn.metrics.r2_score", "py:function", sklearn_api("sklearn.metrics.r2_score"), "-"),
    ("sklearn.metrics.make_scorer", "py:function", sklearn_api("sklearn.metrics.make_scorer"), "-"),
    ("sklearn.utils.check_random_state", "py:function", sklearn_api("sklearn.utils.check_random_state"), "-"),
    # Glossary.
    ("estimator", "std:term", "glossary.html#term-estimator", "-"),
    ("estimators", "std:term", "glossary.html#term-estimators", "-"),
    ("random_state", "std:term", "glossary.html#term-random_state", "-"),
    ("meta-estimator", "std:term", "glossary.html#term-meta-estimator", "-"),
    # The set_*_request methods that metadata routing adds to estimators with
    # sample_weight link to the routing guide.
    ("metadata_routing", "std:label", "metadata_routing.html#metadata-routing", "Metadata Routing"),
]

MATPLOTLIB = [
    ("matplotlib.axes.Axes", "py:class", matplotlib_api("matplotlib.axes.Axes"), "-"),
    ("matplotlib.figure.Figure", "py:class", matplotlib_api("matplotlib.figure.Figure"), "-"),
    ("matplotlib.figure.Figure.tight_layout", "py:method", matplotlib_api("matplotlib.figure.Figure.tight_layout"), "-"),
    ("matplotlib.figure.Figure.savefig", "py:method", matplotlib_api("matplotlib.figure.Figure.savefig"), "-"),
    ("matplotlib.pyplot.subplots", "py:function", matplotlib_api("matplotlib.pyplot.subplots"), "-"),
    ("matplotlib.pyplot.show", "py:function", matplotlib_api("matplotlib.pyplot.show"), "-"),
] + [
    (f"matplotlib.axes.Axes.{name}", "py:method", matplotlib_api(f"matplotlib.axes.Axes.{name}"), "-")
    for name in (
        "plot", "semilogy", "loglog", "legend", "set", "set_title", "set_xlabel",
        "set_ylabel", "set_xlim", "set_ylim", "axhline", "scatter",
    )
]

PROJECTS = {
    # file: (project name shown in link titles, entries)
    "python.inv": ("Python", PYTHON),
    "numpy.inv": ("NumPy", NUMPY),
    "scipy.inv": ("SciPy", SCIPY),
    "sklearn.inv": ("scikit-learn", SKLEARN),
    "matplotlib.inv": ("Matplotlib", MATPLOTLIB),
}


def inventory_bytes(project, entries):
    """The bytes of a Sphinx v2 inventory listing ``entries``."""
    names = [(name, role) for name, role, _, _ in entries]
    duplicates = {key for key in names if names.count(key) > 1}
    if duplicates:
        raise ValueError(f"{project}: duplicate entries {sorted(duplicates)}")
    lines = []
    for name, role, uri, dispname in sorted(entries):
        if " " in name or " " in uri:
            raise ValueError(f"{project}: no spaces allowed in {name!r} or {uri!r}")
        # Priority 1 for objects, -1 (not in search) for terms and labels, as
        # Sphinx writes them.
        priority = 1 if role.startswith("py:") else -1
        lines.append(f"{name} {role} {priority} {uri} {dispname}\n")
    # No version: the links show "(in NumPy)", since the inventory follows the
    # "stable" documentation rather than one release.
    header = (
        "# Sphinx inventory version 2\n"
        f"# Project: {project}\n"
        "# Version: \n"
        "# The remainder of this file is compressed using zlib.\n"
    )
    return header.encode() + zlib.compress("".join(lines).encode(), 9)


def main():
    for filename, (project, entries) in PROJECTS.items():
        path = HERE / filename
        path.write_bytes(inventory_bytes(project, entries))
        print(f"{path}: {len(entries)} entries")


if __name__ == "__main__":
    main()
