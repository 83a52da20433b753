"""The host package's imports point down: no import runs from a lower layer back up, no circle.

Reads every module of ``host/tsa_bench`` with :mod:`ast` (nothing is imported): module-level
imports, imports inside functions and ``if TYPE_CHECKING:`` blocks, ``from . import x`` and
other relative imports. A room is a top-level package or module of ``tsa_bench``
(``tsa_bench/__init__.py`` is the room ``__init__``). :data:`LAYERS` is the project's layer
map, bottom to top, written here once (docs/architecture.md describes it): a room may import
its own layer and the layers below, never one above; no circle may run across rooms, nor
between the modules of one room. Every room of the package must be placed in a layer.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "host" / "tsa_bench"

#: The layers, bottom to top; a room imports its own layer and those below.
LAYERS: tuple[tuple[str, ...], ...] = (
    # vocabulary, importing nothing of ours above it
    ("__init__", "units", "shipped", "userfiles", "rundocs", "rundata", "benchdata", "operator", "outputs"),
    # pure parts
    ("protocol", "motion", "models", "sim", "device"),
    # configuration and plans
    ("bench", "plan", "control"),
    # engines
    ("runner", "analysis", "transport"),
    # stores and emulators
    ("store", "simavr"),
    # capabilities
    ("importers", "reproduce", "report", "console", "rig", "lab", "catalogue", "web", "bluesky"),
    # studies
    ("sweep",),
    # the command line
    ("cli",),
)
LAYER_OF = {room: i for i, rooms in enumerate(LAYERS) for room in rooms}
#: Circles between the modules of one room that stay: each closes only through an import
#: inside a function or under TYPE_CHECKING (the engine and its tracking hook, the plant and
#: its fused kernel, the run-file writer and its reader), so none runs at import time. Any
#: other circle fails; a circle cut must leave this list.
CIRCLES_LEFT = [
    ["tsa_bench.runner.engine", "tsa_bench.runner.tracking"],
    ["tsa_bench.sim.fused", "tsa_bench.sim.plant"],
    ["tsa_bench.store.hdf5", "tsa_bench.store.inspect", "tsa_bench.store.reader"],
]


def module_name(path: Path, package: Path) -> str:
    """``tsa_bench.store.reader`` for host/tsa_bench/store/reader.py (a package: its __init__)."""
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(package: Path) -> dict[str, Path]:
    return {module_name(p, package): p for p in sorted(package.rglob("*.py"))}


def imports(name: str, path: Path, known: dict[str, Path]) -> list[tuple[str, int]]:
    """(imported module of ours, line) for every import in the file, at any depth."""
    is_package = path.name == "__init__.py"
    top = name.split(".")[0]
    found: list[tuple[str, int]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names if a.name.split(".")[0] == top]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != top:
                continue
            for alias in node.names:   # `from pkg import module` imports the module
                sub = f"{target}.{alias.name}"
                found.append((sub if sub in known else target, node.lineno))
    return found


def room_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def import_graph(package: Path) -> list[tuple[str, str, str]]:
    """(importing module, imported module, "file:line") over the whole package."""
    known = modules(package)
    edges = []
    for name, path in known.items():
        for target, line in imports(name, path, known):
            edges.append((name, target, f"{path.relative_to(package.parent)}:{line}"))
    return edges


def upward(edges: list[tuple[str, str, str]]) -> list[str]:
    """Every import from a lower layer to a higher one (and from or to a room in no layer)."""
    found = []
    for a, b, where in edges:
        ra, rb = room_of(a), room_of(b)
        if ra == rb:
            continue
        for room in (ra, rb):
            if room not in LAYER_OF:
                found.append(f"{where}: room '{room}' is in no layer of LAYERS")
        if ra in LAYER_OF and rb in LAYER_OF and LAYER_OF[rb] > LAYER_OF[ra]:
            found.append(f"{where}: {a} (layer {LAYER_OF[ra] + 1}, {ra}) imports {b} "
                         f"(layer {LAYER_OF[rb] + 1}, {rb})")
    return sorted(set(found))


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    nodes = sorted(set(graph) | {b for bs in graph.values() for b in bs})
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found)


def _graph(pairs) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = defaultdict(set)
    for a, b in pairs:
        if a != b:
            graph[a].add(b)
    return graph


@pytest.fixture(scope="module")
def edges() -> list[tuple[str, str, str]]:
    return import_graph(PACKAGE)


def test_every_room_has_a_layer(edges):
    rooms = {room_of(m) for m in modules(PACKAGE)}
    assert sorted(rooms - set(LAYER_OF)) == [], "place each new room in LAYERS (and docs/architecture.md)"


def test_no_import_runs_up(edges):
    found = upward(edges)
    assert not found, "imports running up the layers (LAYERS in this file):\n" + "\n".join(found)


def test_no_circle_across_rooms(edges):
    found = circles(_graph((room_of(a), room_of(b)) for a, b, _ in edges))
    assert not found, f"rooms importing each other in a circle: {found}"


def test_no_circle_between_modules(edges):
    found = circles(_graph((a, b) for a, b, _ in edges))
    assert found == CIRCLES_LEFT, f"circles between modules: {found}"


def test_the_check_sees_every_kind_of_import(tmp_path):
    """A backward import is found whether module-level, lazy, type-only or relative."""
    pkg = tmp_path / "tsa_bench"
    for room in ("units", "models", "cli"):
        (pkg / room).mkdir(parents=True)
        (pkg / room / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "cli" / "main.py").write_text("from tsa_bench.models import fit\n")
    (pkg / "models" / "fit.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "from . import helper\n"
        "def f():\n    from ..cli import main\n"
        "if TYPE_CHECKING:\n    import tsa_bench.cli.main\n")
    (pkg / "models" / "helper.py").write_text("from .fit import f\n")
    (pkg / "units" / "__init__.py").write_text("from tsa_bench import cli\n")
    found = import_graph(pkg)
    assert ("tsa_bench.models.fit", "tsa_bench.models.helper", "tsa_bench/models/fit.py:2") in found
    assert ("tsa_bench.cli.main", "tsa_bench.models.fit", "tsa_bench/cli/main.py:1") in found
    assert upward(found) == [
        "tsa_bench/models/fit.py:4: tsa_bench.models.fit (layer 2, models) imports tsa_bench.cli.main (layer 8, cli)",
        "tsa_bench/models/fit.py:6: tsa_bench.models.fit (layer 2, models) imports tsa_bench.cli.main (layer 8, cli)",
        "tsa_bench/units/__init__.py:1: tsa_bench.units (layer 1, units) imports tsa_bench.cli (layer 8, cli)",
    ]
    assert circles(_graph((room_of(a), room_of(b)) for a, b, _ in found)) == [["cli", "models"]]
    assert circles(_graph((a, b) for a, b, _ in found)) == [
        ["tsa_bench.cli.main", "tsa_bench.models.fit", "tsa_bench.models.helper"]]
