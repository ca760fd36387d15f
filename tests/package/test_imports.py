"""The package's import graph: no cycle, and no module importing a layer above its own.

The graph is read from the source with ``ast`` (nothing is imported): every ``import`` and
``from … import`` anywhere in a module, at module level or inside a function, is an edge.
``from a import b`` is an edge to the module ``a.b`` when that is a module, else to ``a``.
Importing ``a.b`` is not counted as importing the package ``a``'s ``__init__`` too: a package
that re-exports its submodules would otherwise be in a cycle with each of them.

:data:`LAYERS` orders the top-level modules and packages, lowest first: a module may import
its own layer (without a cycle) and the layers below it. A module of a package may have a
layer of its own (``visualization.live_visualizer``, a system, sits with the systems).
:data:`SUBLAYERS` orders the modules inside a package the same way.
"""

import ast
import pkgutil
from collections.abc import Iterator
from pathlib import Path

PACKAGE = "drake_uuv"
SOURCE = Path(__file__).resolve().parents[2] / PACKAGE
ROOT = "__init__"  # the package's own __init__: the public facade

# Top-level modules and packages, lowest layer first.
LAYERS: list[set[str]] = [
    {"scenario", "io", "models", "kernel_cache"},  # configuration, files, plain numpy math
    {  # one Drake system per module (and their helpers)
        "primitives",
        "plants",
        "navigation",
        "sensors",
        "estimators",
        "attitude",
        "tracking",
        "testing",
        "visualization.scene",
        "visualization.scene_content",
        "visualization.live_visualizer",
    },
    {"diagram", "monitor", "signals"},  # the closed loop
    {
        "simulation",
        "metrics",
        "run_bounds",
        "batch_logs",
        "diagnostics",
        ROOT,
    },  # runs of it (the facade exports ClosedLoopSimulation)
    # Many runs, pictures; field data (ROS bags replayed, the loop's halves over LCM).
    {"analysis", "studies", "visualization", "recordings", "hardware"},
    {"cli"},  # the command line, on top of everything
]

# Inside a package: its modules, lowest layer first (every module must be listed).
SUBLAYERS: dict[str, list[set[str]]] = {
    "studies": [
        {"study"},
        {"runner"},
        {"storage"},
        {"statistics"},
        {"report"},
        {"execution"},
        {"comparison", "estimate"},
        {"groups"},
        {ROOT},
    ],
    "cli": [
        {"options"},
        {"run", "diagram", "animate", "montecarlo", "compare", "variants", "scenarios"},
        {"replay", "onboard", "vehicle"},
        {ROOT},
        {"__main__"},
    ],
}


def _modules(directory: Path, prefix: str) -> Iterator[tuple[str, Path, bool]]:
    """``(dotted name, file, is package)`` of every module under ``directory``, recursively.

    ``pkgutil.iter_modules`` lists a folder without importing anything (unlike
    ``pkgutil.walk_packages``, which imports each package to read its ``__path__``).
    """
    for info in pkgutil.iter_modules([str(directory)]):
        name = f"{prefix}.{info.name}"
        if info.ispkg:
            yield name, directory / info.name / "__init__.py", True
            yield from _modules(directory / info.name, name)
        else:
            yield name, directory / f"{info.name}.py", False


MODULES: dict[str, tuple[Path, bool]] = {
    PACKAGE: (SOURCE / "__init__.py", True),
    **{name: (path, ispkg) for name, path, ispkg in _modules(SOURCE, PACKAGE)},
}


def _imports(module: str) -> set[str]:
    """The package's modules that ``module`` imports, anywhere in its source."""
    path, ispkg = MODULES[module]
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if ispkg else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: up (level − 1) packages from this module's package
                parts = package.split(".")
                anchor = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{anchor}.{base}" if base else anchor
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            # "import drake_uuv.a.b" names the module a.b; the longest known prefix otherwise.
            while target and target not in MODULES:
                target = target.rpartition(".")[0]
            if target and target != module:
                found.add(target)
    return found


GRAPH: dict[str, set[str]] = {module: _imports(module) for module in MODULES}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
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
    return [_one_cycle(graph, set(component)) for component in components]


def _one_cycle(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A shortest cycle through the component's first module (breadth-first)."""
    start = min(component)
    parents: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for nxt in sorted(graph[node] & component):
                if nxt == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(parents[path[-1]])
                    return [start, *reversed(path[:-1]), start]
                if nxt not in parents:
                    parents[nxt] = node
                    following.append(nxt)
        frontier = following
    raise AssertionError(f"no cycle in {sorted(component)}")  # Tarjan said there is one


def _rank(name: str, layers: list[set[str]], where: str) -> int:
    for rank, members in enumerate(layers):
        if name in members:
            return rank
    raise AssertionError(f"{where}: {name!r} is in no layer: add it to the table in {__file__}")


_PLACED = set().union(*LAYERS)


def _top(module: str) -> str:
    """The entry of :data:`LAYERS` a module belongs to: its package's module if that has a
    layer of its own, else its top-level package or module."""
    parts = module.split(".")
    if len(parts) > 2 and f"{parts[1]}.{parts[2]}" in _PLACED:
        return f"{parts[1]}.{parts[2]}"
    return parts[1] if len(parts) > 1 else ROOT


def _violations(modules: dict[str, set[str]]) -> list[str]:
    """Every import of a higher layer, top level or within a package of SUBLAYERS."""
    found = []
    for module, targets in sorted(modules.items()):
        for target in sorted(targets):
            here, there = _top(module), _top(target)
            if here != there:
                low = _rank(here, LAYERS, module)
                high = _rank(there, LAYERS, target)
            elif here in SUBLAYERS and module != target:
                own, other = (
                    m.split(".")[2] if m.count(".") > 1 else ROOT for m in (module, target)
                )
                low = _rank(own, SUBLAYERS[here], module)
                high = _rank(other, SUBLAYERS[here], target)
            else:
                continue
            if high > low:
                found.append(f"{module} (layer {low}) imports {target} (layer {high})")
    return found


# -------------------------------------------------------------------------------- the graph


def test_the_walk_finds_every_module_and_reads_local_imports():
    assert f"{PACKAGE}.studies.runner" in MODULES and f"{PACKAGE}.cli.__main__" in MODULES
    assert MODULES[f"{PACKAGE}.studies"][1]  # a package
    # A function-local import (the run command imports the simulation inside its handler).
    assert f"{PACKAGE}.simulation" in GRAPH[f"{PACKAGE}.cli.run"]
    # "from drake_uuv.cli import main" is an edge to the package, "from … import run" to run.
    assert GRAPH[f"{PACKAGE}.cli.__main__"] == {f"{PACKAGE}.cli"}
    assert f"{PACKAGE}.cli.run" in GRAPH[f"{PACKAGE}.cli"]


def test_cycles_are_found_and_named():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}}
    assert _cycles(graph) == [["a", "b", "c", "a"]]  # a self-import is no cycle here


def test_upward_imports_are_found_and_named():
    graph = {
        f"{PACKAGE}.io": {f"{PACKAGE}.cli.options"},
        f"{PACKAGE}.studies.runner": {f"{PACKAGE}.studies.storage", f"{PACKAGE}.scenario"},
    }
    assert _violations(graph) == [
        f"{PACKAGE}.io (layer 0) imports {PACKAGE}.cli.options (layer 5)",
        f"{PACKAGE}.studies.runner (layer 1) imports {PACKAGE}.studies.storage (layer 2)",
    ]


# ------------------------------------------------------------------------------ the package


def test_no_import_cycle():
    cycles = _cycles(GRAPH)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_studies_and_cli_import_only_lower_modules_of_their_own_package():
    inside: dict[str, set[str]] = {}
    for module, targets in GRAPH.items():
        package = _top(module)
        if package in SUBLAYERS:
            inside[module] = {target for target in targets if _top(target) == package}
            if module.count(".") > 1:  # every module is in its package's table
                _rank(module.split(".")[2], SUBLAYERS[package], module)
    assert set(inside) >= {f"{PACKAGE}.studies.runner", f"{PACKAGE}.cli.options"}
    violations = _violations(inside)
    assert not violations, "upward imports:\n" + "\n".join(violations)


def test_nothing_below_the_command_line_imports_it():
    importers = sorted(
        m for m, t in GRAPH.items() if _top(m) != "cli" for x in t if _top(x) == "cli"
    )
    assert not importers


def test_no_module_imports_a_higher_layer():
    violations = _violations(GRAPH)
    assert not violations, "upward imports:\n" + "\n".join(violations)
