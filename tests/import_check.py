"""Whether the package's names that a script imports exist.

A fast check that code outside the package (examples, benchmark scripts, the
README's snippets) still finds what it imports, for the default test run,
where the slow tests that run that code are skipped. It catches a moved
module or a renamed function, not a changed signature or behaviour.
"""

import ast
import importlib

PACKAGE = "sk_hamiltonian"


def _import(name):
    try:
        return importlib.import_module(name), None
    except ImportError as error:
        return None, error


def unresolved_imports(source):
    """The package's modules and names imported by ``source`` that do not exist."""
    missing = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE and _import(alias.name)[1]:
                    missing.append(f"line {node.lineno}: import {alias.name}")
        elif (isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
              and node.module.split(".")[0] == PACKAGE):
            module, error = _import(node.module)
            if error:
                missing.append(f"line {node.lineno}: {node.module} ({error})")
                continue
            for alias in node.names:
                # A name is an attribute of the module, or a submodule of a package.
                if (alias.name != "*" and not hasattr(module, alias.name)
                        and _import(f"{node.module}.{alias.name}")[1]):
                    missing.append(f"line {node.lineno}: {alias.name} from {node.module}")
    return missing
