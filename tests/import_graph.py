"""botstage's import graph read from the source (ast): which module imports which at run time.

Every import that can run counts: top-level statements (in `try`/`if` blocks too), imports inside
functions (run when first used) and `importlib.import_module("literal")`; only those under
`if TYPE_CHECKING:` (type-only) do not. The layering and cycle tests walk this graph.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("behaviors", "skills", "robots", "missions")


def modules() -> dict[str, Path]:
    """Every botstage module by its import name."""
    found = {}
    for layer in LAYERS:
        for path in sorted((ROOT / layer).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found["botstage." + ".".join(parts)] = path
    return found


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _runtime_nodes(node: ast.AST) -> Iterator[ast.AST]:
    """Every node below ``node`` except those under ``if TYPE_CHECKING:``."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.If) and _is_type_checking(child.test):
            for other in child.orelse:
                yield other
                yield from _runtime_nodes(other)
            continue
        yield child
        yield from _runtime_nodes(child)


def imported_names(module: str, path: Path, known: dict[str, Path]) -> Iterator[str]:
    """The absolute names of the modules a module imports: ``from a import b`` names ``a.b`` where
    that is a module, else ``a``."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    for node in _runtime_nodes(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            yield node.args[0].value
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                source = ".".join([*base, *([node.module] if node.module else [])])
            else:
                source = node.module or ""
            for alias in node.names:
                yield f"{source}.{alias.name}" if f"{source}.{alias.name}" in known else source


def graph() -> dict[str, set[str]]:
    """Module -> the botstage modules and the outside top-level packages it imports at run time.

    A parent package imported on the way to its submodule is not an edge: a package's
    ``__init__`` that re-exports its submodules would otherwise make a cycle of every submodule
    that imports a sibling."""
    known = modules()
    edges: dict[str, set[str]] = {}
    for module, path in known.items():
        targets: set[str] = set()
        for name in imported_names(module, path, known):
            if name.startswith("botstage."):
                if name in known and name != module:
                    targets.add(name)
            elif name and not name.startswith("."):
                targets.add(name.split(".")[0])
        edges[module] = targets
    return edges


def reach(edges: dict[str, set[str]], start: str) -> dict[str, str]:
    """Everything importing ``start`` imports, each with the module that brought it in."""
    seen: dict[str, str] = {start: ""}
    todo = [start]
    while todo:
        module = todo.pop()
        for target in edges.get(module, ()):
            if target not in seen:
                seen[target] = module
                todo.append(target)
        parent = module.rpartition(".")[0]
        if parent.startswith("botstage.") and parent not in seen and parent in edges:
            seen[parent] = module
            todo.append(parent)
    return seen


def chain(seen: dict[str, str], target: str) -> list[str]:
    out = [target]
    while seen.get(out[-1]):
        out.append(seen[out[-1]])
    return out[::-1]


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of botstage modules that import each other at run time
    (Tarjan's algorithm); a package's `__init__` importing its own submodules is not counted as
    the submodule importing the package back unless the submodule really does."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(node: str) -> None:
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on.add(node)
        for target in edges.get(node, ()):
            if target not in edges:
                continue
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            group = []
            while True:
                item = stack.pop()
                on.discard(item)
                group.append(item)
                if item == node:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    import sys

    sys.setrecursionlimit(10000)
    for node in sorted(edges):
        if node not in index:
            visit(node)
    return out
