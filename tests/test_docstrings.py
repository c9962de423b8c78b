"""Every public object has a valid numpydoc docstring."""

import importlib
import inspect

import pytest

validate = pytest.importorskip("numpydoc.validate").validate

PUBLIC_MODULES = [
    "sk_hamiltonian",
    "sk_hamiltonian.datasets",
    "sk_hamiltonian.inspection",
    "sk_hamiltonian.io",
    "sk_hamiltonian.metrics",
    "sk_hamiltonian.model_selection",
    "sk_hamiltonian.plotting",
]

# Checks not enforced: extended summaries (ES01), See Also (SA01) and Examples
# (EX01) are written where they help, not on every method; GL08 is for objects
# without docstrings, which the other checks report more precisely; RT02 forbids
# named returns such as ``self : object``, scikit-learn's own convention.
IGNORED = {"ES01", "SA01", "EX01", "GL08", "RT02"}


def public_names():
    names = []
    for module_name in PUBLIC_MODULES:
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            continue
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)):
                continue
            qualified = f"{obj.__module__}.{obj.__qualname__}"
            names.append(qualified)
            if inspect.isclass(obj) and not issubclass(obj, BaseException):
                for method, member in vars(obj).items():
                    if inspect.isfunction(member) and not method.startswith("_"):
                        names.append(f"{qualified}.{method}")
                # Public methods defined on a private base class.
                for base in obj.__mro__[1:]:
                    if base.__module__.startswith("sk_hamiltonian"):
                        for method, member in vars(base).items():
                            if inspect.isfunction(member) and not method.startswith("_"):
                                names.append(f"{base.__module__}.{base.__qualname__}.{method}")
    return sorted(set(names))


@pytest.mark.parametrize("name", public_names())
def test_numpydoc(name):
    result = validate(name)
    errors = [f"{code}: {message}" for code, message in result["errors"] if code not in IGNORED]
    assert not errors, "\n".join([name] + errors)
