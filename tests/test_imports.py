"""Imports run one way: no module of ``jeanscv`` or of the CLI (``jeanscv_cli``) imports,
directly or through others, a module that imports it back.

The graph is read from the source with :mod:`ast`, so imports inside functions count as
much as those at the top: a cycle that only closes at run time is still a cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Package name -> its source folder.
PACKAGES = {"jeanscv": ROOT / "jeanscv", "jeanscv_cli": ROOT / "cli"}


def module_files() -> dict[str, Path]:
    """Dotted module name -> source file of every module of :data:`PACKAGES`."""
    modules = {}
    for package, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The absolute name a ``from ... import`` names (its relative dots resolved)."""
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def imported_modules(module: str, path: Path, known: set[str]) -> set[str]:
    """The modules of ``known`` that ``module`` imports anywhere in its source.

    ``from PACKAGE import NAME`` counts as importing ``PACKAGE.NAME`` where that is a
    module, else ``PACKAGE``. Importing ``a.b.c`` runs ``a`` and ``a.b`` first, so it
    counts as importing them too, except the packages that hold ``module`` itself (they
    ran before it: a package importing its own submodules is the one-way case).
    """
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, is_package, node)
            names = [f"{target}.{alias.name}" if f"{target}.{alias.name}" in known else target for alias in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            found.update(".".join(parts[:end]) for end in range(1, len(parts) + 1))
    holders = {".".join(module.split(".")[:end]) for end in range(1, module.count(".") + 1)}
    return (found & known) - holders - {module}


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of both packages it imports."""
    files = module_files()
    return {module: imported_modules(module, path, set(files)) for module, path in files.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly-connected components of more than one module, each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return components


def a_cycle(graph: dict[str, set[str]], members: list[str]) -> list[str]:
    """One closed path through a component: ``[a, b, ..., a]``, found breadth-first."""
    start, inside = members[0], set(members)
    paths = {start: [start]}
    queue = [start]
    while queue:
        node = queue.pop(0)
        for successor in sorted(graph[node] & inside):
            if successor == start:
                return [*paths[node], start]
            if successor not in paths:
                paths[successor] = [*paths[node], successor]
                queue.append(successor)
    return members


def test_the_graph_is_read():
    """The parser sees imports at the top, relative ones and those inside functions."""
    graph = import_graph()
    assert "jeanscv.errors" in graph["jeanscv.fitting.garments"]  # from .errors import ... at the top
    assert "jeanscv.pipeline" in graph["jeanscv_cli.worker"]  # from jeanscv import pipeline, in a function
    assert "jeanscv.fitting.garments" in graph["jeanscv.fitting.fitter"]


def test_the_cycle_finder():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert strongly_connected(graph) == [["a", "b", "c"]]
    assert a_cycle(graph, ["a", "b", "c"]) == ["a", "b", "c", "a"]


def test_no_import_cycles():
    graph = import_graph()
    cycles = [" -> ".join(a_cycle(graph, members)) for members in strongly_connected(graph)]
    assert not cycles, "import cycles (each module imports the next, counting imports inside functions):\n" + "\n".join(
        cycles
    )
