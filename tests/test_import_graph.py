"""The package's import graph has no circle at run time (issue 34). Every import counts,
at the top of a module or inside a function; `if TYPE_CHECKING:` blocks do not (they
never run)."""

from __future__ import annotations

import ast
from pathlib import Path

import qdframe

PACKAGE = Path(qdframe.__file__).parent


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        typing_only = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
                       and getattr(block.test, "id", "") == "TYPE_CHECKING" for node in ast.walk(block)}
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[: len(package.split(".")) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                targets = ([target] if node.module else []) + [f"{target}.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                continue
            graph[name] |= {target for target in targets if target in modules and target != name}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in graph[module]:
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = set()
            while True:
                other = stack.pop()
                component.add(other)
                if other == module:
                    break
            if len(component) > 1:
                circles.append(component)

    for module in graph:
        if module not in index:
            visit(module)
    return circles


def test_no_import_circle():
    assert _circles(_graph()) == []


def test_the_registry_imports_nothing_it_builds():
    assert _graph()["qdframe.registry"] <= {"qdframe.errors"}


def test_a_circle_is_found():
    assert _circles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [{"a", "b"}]


# the layers, bottom first: a module imports only from its own layer or those below it. Every
# module is named (a new one that is not fails test_every_module_has_a_layer): the engine (the
# model interface, the set language, the schemes, the functional, the directions and line
# searches, the result) < the certificates (the true motion and the estimates) < the built-in
# models (a reference may use the integrator) < one descent < the solve < the tools
LAYERS = [
    ("foundation", ("qdframe.errors", "qdframe.argtypes", "qdframe.status", "qdframe.registry", "qdframe.progress")),
    ("engine", ("qdframe.model", "qdframe.ready_pieces", "qdframe.sets", "qdframe.schemes", "qdframe.functional",
                "qdframe.directions", "qdframe.line_searches", "qdframe.unknowns", "qdframe.result",
                "qdframe.plotting")),
    ("certificates", ("qdframe.certificates", "qdframe.simulate")),
    ("models", ("qdframe.models",)),
    ("descent", ("qdframe.descent",)),
    ("solve", ("qdframe.solve",)),
    ("tools", ("qdframe.authoring", "qdframe.bench", "qdframe.cli", "qdframe.__main__")),
    ("package", ("qdframe",)),
]


def _layer(module: str) -> int:
    """The index in LAYERS of `module`'s layer: the longest prefix that names it."""
    best, length = None, -1
    for number, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            named = module == prefix or module.startswith(prefix if prefix.endswith(".") else prefix + ".")
            if named and len(prefix) > length:
                best, length = number, len(prefix)
    return best


def test_imports_point_down_the_layers():
    graph = _graph()
    upward = sorted(f"{module} ({LAYERS[_layer(module)][0]}) imports {other} ({LAYERS[_layer(other)][0]})"
                    for module, targets in graph.items() for other in targets if _layer(other) > _layer(module))
    assert upward == []


def test_every_module_has_a_layer():
    """No module falls into a catch-all: each is named by its layer (or its folder)."""
    unnamed = sorted(module for module in _modules() if module != "qdframe" and _layer(module) == len(LAYERS) - 1)
    assert unnamed == []


def test_an_upward_import_is_caught():
    assert _layer("qdframe.certificates.filippov") < _layer("qdframe.descent.loop") < _layer("qdframe.solve.solving")
    assert _layer("qdframe.functional.layout") < _layer("qdframe.certificates.estimates")
