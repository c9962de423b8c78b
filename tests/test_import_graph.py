"""The package's import graph, read from its source files with ``ast``: no circle, kernels a leaf.

Every ``import`` and ``from ... import`` of a module of ``sk_hamiltonian``
(relative or absolute) is an arrow from the importing module to the imported
one. Importing ``a.b.c`` also runs the ``__init__`` of the package ``a.b``,
so it is an arrow to that package too, unless the importer lives inside it
(a package is already running when one of its modules is imported). An
import inside a function runs when the function is first called; it is
collected separately, so that a circle closed only by such an import is
named as such.
"""

import ast
import sys
from pathlib import Path

import pytest

PACKAGE = "sk_hamiltonian"
ROOT = Path(__file__).resolve().parent.parent / PACKAGE
# What the compiled kernels may import besides themselves (and the standard
# library): they take arrays and return arrays.
KERNEL_DEPENDENCIES = {"numpy", "scipy", "numba"}


def _module_name(path):
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _sources():
    """``{module name: (path, is_package)}`` of every source file of the package."""
    return {
        _module_name(path): (path, path.name == "__init__.py")
        for path in sorted(ROOT.rglob("*.py"))
    }


MODULES = _sources()


class _Imports(ast.NodeVisitor):
    """Every import of one file: ``(imported name, line, enclosing function or None)``."""

    def __init__(self, module, is_package):
        self.package = module if is_package else module.rpartition(".")[0]
        self.found = []
        self._functions = []

    def visit_FunctionDef(self, node):
        self._functions.append(node.name)
        self.generic_visit(node)
        self._functions.pop()

    visit_AsyncFunctionDef = visit_FunctionDef

    def _add(self, name, node):
        self.found.append((name, node.lineno, self._functions[-1] if self._functions else None))

    def visit_Import(self, node):
        for alias in node.names:
            self._add(alias.name, node)

    def visit_ImportFrom(self, node):
        if node.level:
            base = self.package.split(".")
            base = base[: len(base) - (node.level - 1)]
            prefix = ".".join(base + ([node.module] if node.module else []))
        else:
            prefix = node.module
        for alias in node.names:
            # ``from package import module`` imports the module; ``from
            # module import name`` the module that holds the name.
            candidate = f"{prefix}.{alias.name}"
            self._add(candidate if candidate in MODULES else prefix, node)


def _imports(module):
    path, is_package = MODULES[module]
    visitor = _Imports(module, is_package)
    visitor.visit(ast.parse(path.read_text(), filename=str(path)))
    return visitor.found


def _arrows(module):
    """Arrows ``(target, how)`` out of ``module`` to modules of the package."""
    arrows = []
    for name, line, function in _imports(module):
        if name != PACKAGE and not name.startswith(PACKAGE + "."):
            continue
        where = f"line {line}" + (f", inside {function}()" if function else "")
        parts = name.split(".")
        for k in range(2, len(parts) + 1):
            target = ".".join(parts[:k])
            if target not in MODULES or target == module:
                continue
            if k < len(parts) and (module + ".").startswith(target + "."):
                continue  # a package the importer lives in: already running
            implied = "" if k == len(parts) else f" (the package of {name})"
            arrows.append((target, function is not None, f"{where}{implied}"))
    return arrows


ARROWS = {module: _arrows(module) for module in MODULES}


def _graph(with_functions):
    graph = {module: {} for module in MODULES}
    for module, arrows in ARROWS.items():
        for target, in_function, how in arrows:
            if in_function and not with_functions:
                continue
            graph[module].setdefault(target, how)
    return graph


def find_circles(graph):
    """One circle per strongly connected component (Tarjan), each as a list of modules."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def connect(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in graph[node]:
            if target not in index:
                connect(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1 or node in graph[node]:
                components.append(set(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph)))
    try:
        for node in sorted(graph):
            if node not in index:
                connect(node)
    finally:
        sys.setrecursionlimit(limit)
    return [_circle_in(graph, component) for component in components]


def _circle_in(graph, component):
    """The shortest circle through the component's first module (breadth first)."""
    start = min(component)
    previous, frontier = {start: None}, [start]
    while frontier:
        following = []
        for node in frontier:
            for target in sorted(graph[node]):
                if target == start:
                    path = [node]
                    while previous[path[-1]] is not None:
                        path.append(previous[path[-1]])
                    return path[::-1] + [start]
                if target in component and target not in previous:
                    previous[target] = node
                    following.append(target)
        frontier = following
    raise AssertionError(f"no circle found in the component {sorted(component)}")


def describe(graph, circle):
    arrows = [f"  {a} -> {b}  [{graph[a][b]}]" for a, b in zip(circle, circle[1:])]
    return " -> ".join(circle) + "\n" + "\n".join(arrows)


def test_the_walk_sees_the_package():
    # Guards the test itself: an import the walk cannot resolve would hide
    # arrows, and then circles.
    assert "sk_hamiltonian._base" in MODULES and "sk_hamiltonian._kernels" in MODULES
    targets = {t for t, _, _ in ARROWS["sk_hamiltonian._hamiltonian"]}
    assert "sk_hamiltonian._base" in targets
    assert sum(len(a) for a in ARROWS.values()) > 100


def test_find_circles_names_a_circle():
    graph = {"a": {"b": "line 1"}, "b": {"c": "line 2"}, "c": {"a": "line 3"}, "d": {"a": "x"}}
    assert find_circles(graph) == [["a", "b", "c", "a"]]
    assert find_circles({"a": {"b": "line 1"}, "b": {}}) == []


@pytest.mark.parametrize("with_functions", [False, True], ids=["module level", "with function-level imports"])
def test_no_import_circle(with_functions):
    graph = _graph(with_functions)
    circles = find_circles(graph)
    what = "imports, counting those inside functions," if with_functions else "module-level imports"
    assert not circles, f"{len(circles)} circle(s) of {what} in {PACKAGE}:\n" + "\n".join(
        describe(graph, circle) for circle in circles
    )


def test_kernels_import_nothing_of_the_package_but_themselves():
    allowed = KERNEL_DEPENDENCIES | set(sys.stdlib_module_names)
    kernels = f"{PACKAGE}._kernels"
    offending = []
    for module in MODULES:
        if module != kernels and not module.startswith(kernels + "."):
            continue
        for name, line, function in _imports(module):
            inside = name == kernels or name.startswith(kernels + ".")
            if not inside and name.split(".")[0] not in allowed:
                offending.append(f"{module} line {line}: {name}")
    assert not offending, (
        "the kernels take arrays and return arrays; they import only numpy, scipy, numba, "
        "the standard library and each other:\n" + "\n".join(offending)
    )
