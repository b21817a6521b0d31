"""Imports run one way: no module of ``jeanscv`` or of the CLI (``jeanscv_cli``) imports,
directly or through others, a module that imports it back; and within ``jeanscv`` no
module imports one of a later stage of the data flow (:data:`STAGES`).

The graph is read from the source with :mod:`ast`, so imports inside functions count as
much as those at the top: a cycle that only closes at run time is still a cycle.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
#: Package name -> its source folder.
PACKAGES = {"jeanscv": ROOT / "jeanscv", "jeanscv_cli": ROOT / "cli"}


def module_files(packages: dict[str, Path] = PACKAGES) -> dict[str, Path]:
    """Dotted module name -> source file of every module of ``packages`` (name -> folder)."""
    modules = {}
    for package, folder in packages.items():
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


def _type_only(tree: ast.Module) -> set[int]:
    """The ids of the nodes inside ``if TYPE_CHECKING:`` blocks (imports that never run)."""
    nodes = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            nodes.update(id(inner) for statement in node.body for inner in ast.walk(statement))
    return nodes


def imported_modules(module: str, path: Path, known: set[str], run_time_only: bool = False) -> set[str]:
    """The modules of ``known`` that ``module`` imports anywhere in its source
    (``run_time_only``: leaving out those under ``if TYPE_CHECKING:``, for annotations only).

    ``from PACKAGE import NAME`` counts as importing ``PACKAGE.NAME`` where that is a
    module, else ``PACKAGE``. Importing ``a.b.c`` runs ``a`` and ``a.b`` first, so it
    counts as importing them too, except the packages that hold ``module`` itself (they
    ran before it: a package importing its own submodules is the one-way case).
    """
    is_package = path.name == "__init__.py"
    found = set()
    tree = ast.parse(path.read_text(), str(path))
    skipped = _type_only(tree) if run_time_only else set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
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


def import_graph(packages: dict[str, Path] = PACKAGES, run_time_only: bool = False) -> dict[str, set[str]]:
    """Module -> the modules of ``packages`` it imports."""
    files = module_files(packages)
    return {module: imported_modules(module, path, set(files), run_time_only) for module, path in files.items()}


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


#: The stages of the data flow, lowest first, each a list of modules and packages (a
#: package holds its submodules; ``jeanscv`` itself, the lazy namespace, only its
#: ``__init__``). A module may import modules of its own stage and of earlier ones only.
#: The base is what every stage shares; ``pipeline`` ties the stages together (``report``
#: sits beside it, as the pipeline makes the result; ``plugins`` looks up garments and
#: silhouette methods, the latter living in ``subject.plugins``); ``run`` runs many inputs
#: through the pipeline. The CLI (``jeanscv_cli``) stands on top of all of them.
STAGES: list[tuple[str, list[str]]] = [
    ("base", ["jeanscv.errors", "jeanscv.geometry", "jeanscv.device", "jeanscv.options"]),
    ("io", ["jeanscv.io"]),
    ("detect", ["jeanscv.detect"]),
    ("subject", ["jeanscv.subject"]),
    ("fitting", ["jeanscv.fitting"]),
    ("paint", ["jeanscv.paint"]),
    (
        "pipeline",
        [
            "jeanscv",
            "jeanscv.pipeline",
            "jeanscv.report",
            "jeanscv.plugins",
            "jeanscv.api",
            "jeanscv._command",
            "jeanscv.__main__",
        ],
    ),
    ("run", ["jeanscv.run"]),
]


def stage_of(module: str, stages: list[tuple[str, list[str]]] = STAGES) -> int | None:
    """The index in ``stages`` of the stage ``module`` belongs to (the longest entry that
    names it or a package holding it), or None."""
    best, best_length = None, -1
    for index, (_, members) in enumerate(stages):
        for member in members:
            holds = module == member or (member != "jeanscv" and module.startswith(member + "."))
            if holds and len(member) > best_length:
                best, best_length = index, len(member)
    return best


def upward_imports(graph: dict[str, set[str]], stages: list[tuple[str, list[str]]] = STAGES) -> list[str]:
    """Every import of ``graph`` from a module of ``jeanscv`` to one of a later stage, as
    ``"a (stage) -> b (stage)"`` lines."""
    found = []
    for module in sorted(graph):
        if not (module == "jeanscv" or module.startswith("jeanscv.")):
            continue
        low = stage_of(module, stages)
        for target in sorted(graph[module]):
            high = stage_of(target, stages)
            if low is not None and high is not None and high > low:
                found.append(f"{module} ({stages[low][0]}) -> {target} ({stages[high][0]})")
    return found


def test_every_import_names_a_module():
    """Every ``import jeanscv...`` and ``from jeanscv... import`` (relative ones resolved)
    names a module or package that exists: a path left behind by a move is found here,
    before the import runs."""
    files = module_files()
    missing = []
    for module, path in files.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                targets = [_resolve(module, path.name == "__init__.py", node)]
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                continue
            missing += [
                f"{module}:{node.lineno} {target}"
                for target in targets
                if target.split(".")[0] in PACKAGES and target not in files
            ]
    assert not missing, "imports of modules that do not exist:\n" + "\n".join(missing)


def test_every_module_has_a_stage():
    unplaced = [m for m in module_files() if m.startswith("jeanscv.") and stage_of(m) is None]
    assert not unplaced, f"modules in no stage (add them to STAGES): {unplaced}"


def test_imports_follow_the_stages():
    """No module imports one of a later stage (imports for annotations only do not count:
    ``options`` names the ``Garment`` and ``Clicks`` types, which never load at run time)."""
    upward = upward_imports(import_graph(run_time_only=True))
    assert not upward, "imports against the stage order (see STAGES):\n" + "\n".join(upward)


def test_the_stage_checker_fails_on_an_upward_import():
    graph = {"jeanscv.subject.masks": {"jeanscv.errors", "jeanscv.fitting.garments"}, "jeanscv.fitting.garments": set()}
    assert upward_imports(graph) == ["jeanscv.subject.masks (subject) -> jeanscv.fitting.garments (fitting)"]
    assert upward_imports({"jeanscv.paint.denim": {"jeanscv.fitting.garments", "jeanscv.io.write"}}) == []


def test_a_planted_upward_import_is_found(tmp_path):
    """A copy of the package with one upward import planted, inside a function."""
    copy = tmp_path / "jeanscv"
    shutil.copytree(PACKAGES["jeanscv"], copy, ignore=shutil.ignore_patterns("__pycache__"))
    masks = copy / "subject" / "masks.py"
    masks.write_text(masks.read_text() + "\n\ndef _planted():\n    from ..paint import denim  # noqa: F401\n")
    upward = upward_imports(import_graph({"jeanscv": copy}, run_time_only=True))
    assert upward == [
        "jeanscv.subject.masks (subject) -> jeanscv.paint (paint)",
        "jeanscv.subject.masks (subject) -> jeanscv.paint.denim (paint)",
    ]


def test_every_package_is_installed():
    """``pip install .`` installs the packages pyproject.toml lists: every folder of code,
    and folders of files without code (the page's), listed with their files."""
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed, data = set(setuptools["packages"]), set(setuptools["package-data"])
    folders = {m for m, path in module_files().items() if path.name == "__init__.py"}
    assert folders <= listed
    assert listed - folders <= data  # no code: installed for its files alone
    assert data <= listed


def test_old_paths_import_the_moved_modules():
    """The paths from before the stage folders that the docs showed, and that plugins use,
    import the module itself (one object: its state and its classes are the same)."""
    import importlib

    import jeanscv

    moved = {**jeanscv._MOVED, "jeanscv.silhouette.photo": "jeanscv.subject.photo"}
    moved["jeanscv.silhouette.interactive"] = "jeanscv.subject.interactive"
    moved["jeanscv.silhouette.scene"] = "jeanscv.subject.scene"  # a package's modules follow it
    for old, new in moved.items():
        module = importlib.import_module(old)
        assert module is importlib.import_module(new)
        assert module.__name__ == new and module.__spec__.name == new
    from jeanscv.fitting.garments import Garment as Moved
    from jeanscv.garments import Garment

    assert Garment is Moved
    assert jeanscv.fit.__module__ == "jeanscv.pipeline"  # the function, not the fitting package
