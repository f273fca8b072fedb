"""Layers only look down: every import in wristmark/ (module level, inside functions, under
TYPE_CHECKING, relative or absolute) goes to the same package or a lower one.

Layering, lowest first: models < cvs < solvers < rig < viz < sim < cli < sweep (a sweep's trial is
a command line; ``wristmark sweep`` is named in cli/main.py's COMMAND_MODULES). The package root
(wristmark/__init__.py, __main__.py) stands above them all; its private helper
wristmark/_lazy.py (the lazy public names of every package, standard library only) lies below them all.

And no two modules import each other, directly or round a longer loop (the same walk, as a graph of
modules: see :func:`module_graph`).
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import wristmark
from wristmark._lazy import public_names

LAYERS = ("models", "cvs", "solvers", "rig", "viz", "sim", "cli", "sweep")
BASE = ("wristmark._lazy",)  # below every layer: imports nothing of wristmark
PACKAGE = Path(wristmark.__file__).resolve().parent


@dataclass(frozen=True)
class Edge:
    """One import: the importing file (relative to the package), its line, the imported module."""

    file: str
    line: int
    module: str

    def __str__(self) -> str:
        return f"wristmark/{self.file}:{self.line} imports {self.module}"


def _module_name(rel: str) -> list[str]:
    parts = list(Path(rel).with_suffix("").parts)
    return parts[:-1] if parts[-1] == "__init__" else parts


def _is_package(module: str) -> bool:
    """Whether a dotted name is a package of wristmark (a folder with an ``__init__.py``)."""
    parts = module.split(".")
    return parts[0] == "wristmark" and (PACKAGE.joinpath(*parts[1:]) / "__init__.py").is_file()


def imports_in(source: str, rel: str) -> list[Edge]:
    """Every wristmark module imported by ``source``, the text of wristmark/``rel``, wherever
    the import statement stands."""
    here = ["wristmark", *_module_name(rel)]
    package = here if rel.endswith("__init__.py") else here[:-1]
    edges = []
    for node in ast.walk(ast.parse(source, rel)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: resolve against the importing package
                base = package[: len(package) - (node.level - 1)]
                names = [".".join([*base, node.module] if node.module else base)]
            else:
                names = [node.module or ""]
            if _is_package(names[0]):  # from wristmark import sim, from wristmark.rig.link import protocol
                names = [f"{names[0]}.{a.name}" for a in node.names]
        else:
            continue
        edges += [Edge(rel, node.lineno, n) for n in names if n == "wristmark" or n.startswith("wristmark.")]
    return edges


def imports_of(path: Path) -> list[Edge]:
    """:func:`imports_in` of a file of the package."""
    return imports_in(path.read_text(), path.relative_to(PACKAGE).as_posix())


def layer_of(module: str) -> str | None:
    """The layer a dotted module name belongs to, None for the package root."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else None


def upward_edges() -> list[Edge]:
    """Imports from a layer to a higher one (or to the package root) anywhere in wristmark/."""
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        src = layer_of(".".join(["wristmark", *_module_name(path.relative_to(PACKAGE).as_posix())]))
        if src is None:
            continue  # the package root may import everything
        for e in imports_of(path):
            if e.module in BASE:
                continue
            dst = layer_of(e.module)
            if dst is None or LAYERS.index(dst) > LAYERS.index(src):
                bad.append(e)
    return bad


def module_of(path: Path) -> str:
    """The dotted module name of a file of the package (a package's ``__init__.py``: the package)."""
    return ".".join(["wristmark", *_module_name(path.relative_to(PACKAGE).as_posix())])


def file_of(module: str) -> Path | None:
    """The file of a dotted wristmark module (a package's ``__init__.py``), None when it is none."""
    parts = module.split(".")
    if parts[0] != "wristmark":
        return None
    base = PACKAGE.joinpath(*parts[1:])
    for path in (base / "__init__.py", base.parent / f"{base.name}.py"):
        if path.is_file():
            return path
    return None


def target_module(name: str) -> str:
    """The module an imported dotted name lands in: the name itself when it is a module; a package's
    public name (its lazy API, wristmark/_lazy.py) the module that defines it; any other attribute
    the module that holds it."""
    if file_of(name) is not None:
        return name
    parent, _, attr = name.rpartition(".")
    init = file_of(parent)
    if init is not None and init.name == "__init__.py":
        exported = public_names(init)
        if attr in exported:
            module, real = exported[attr]
            return target_module(f"{module}.{real}")
    return target_module(parent)


def _shown(module: str) -> str:
    """A module of the graph as its file, wristmark/..."""
    path = file_of(module)
    return module if path is None else path.relative_to(PACKAGE.parent).as_posix()


def _api_block_lines(source: str) -> set[int]:
    """The lines of a package ``__init__``'s ``if TYPE_CHECKING:`` API block (not its ``else:``)."""
    lines: set[int] = set()
    for node in ast.parse(source).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            lines.update(range(node.body[0].lineno, (node.body[-1].end_lineno or node.body[-1].lineno) + 1))
    return lines


def module_graph() -> dict[str, dict[str, list[Edge]]]:
    """Every module of wristmark/ -> the modules it imports -> the import statements that do it.

    All of :func:`imports_in`'s imports count (module level, inside functions, under TYPE_CHECKING),
    each landing in :func:`target_module`, except a package ``__init__``'s TYPE_CHECKING API block:
    that block only lists the public names for mypy and the lazy ``__getattr__`` of
    wristmark/_lazy.py (which imports a name's module when the name is first used, and is no import
    of the package's); an importer of a public name gets an edge to the module that defines it."""
    graph: dict[str, dict[str, list[Edge]]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        source = path.read_text()
        skip = _api_block_lines(source) if path.name == "__init__.py" else set()
        here = graph.setdefault(module_of(path), {})
        for e in imports_in(source, path.relative_to(PACKAGE).as_posix()):
            if e.line not in skip:
                here.setdefault(target_module(e.module), []).append(e)
    return graph


def strongly_connected(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of a directed graph (node -> its successors), each
    sorted (Tarjan's algorithm, iterative: no recursion limit)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        work.append((v, iter(sorted(graph.get(v, ())))))

    for root in sorted(graph):
        if root in index:
            continue
        work: list[tuple[str, Iterable[str]]] = []
        visit(root)
        while work:
            v, successors = work[-1]
            for w in successors:
                if w not in index:
                    visit(w)
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:  # every successor done: v closes its component if it is the root of one
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    component: list[str] = []
                    while not component or component[-1] != v:
                        component.append(stack.pop())
                        on_stack.discard(component[-1])
                    found.append(sorted(component))
    return found


def import_cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The components of more than one node: each a set of modules that import each other round a loop."""
    return sorted(c for c in strongly_connected(graph) if len(c) > 1)


def test_every_subpackage_has_a_layer() -> None:
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    assert subpackages == set(LAYERS), f"packages without a layer: {sorted(subpackages - set(LAYERS))}"


def test_the_base_imports_nothing_of_wristmark() -> None:
    for module in BASE:
        path = PACKAGE / (module.split(".", 1)[1].replace(".", "/") + ".py")
        mine = [e for e in imports_of(path) if e.module == "wristmark" or e.module.startswith("wristmark.")]
        assert not mine, mine


def test_no_import_looks_up() -> None:
    bad = upward_edges()
    assert not bad, "imports that look up the layering " + " < ".join(LAYERS) + ":\n" + "\n".join(map(str, bad))


def test_the_walk_sees_function_level_relative_and_type_checking_imports() -> None:
    """The walker itself: imports inside a function, relative ones, ``from wristmark import x``
    and those under TYPE_CHECKING are all seen and resolved (so a clean tree means something)."""
    code = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
            "    from wristmark.rig.loop.loop_setup import LoopSetup\n"
            "def f():\n    import wristmark.sim.plant\n    from ..cli import main\n    from . import errors\n"
            "from wristmark import viz\n")
    edges = imports_in(code, "models/probe.py")
    assert sorted(e.module for e in edges) == ["wristmark.cli.main", "wristmark.models.errors",
                                               "wristmark.rig.loop.loop_setup", "wristmark.sim.plant", "wristmark.viz"]
    up = sorted(e.module for e in edges if LAYERS.index(layer_of(e.module) or "cli") > 0)
    assert up == ["wristmark.cli.main", "wristmark.rig.loop.loop_setup", "wristmark.sim.plant", "wristmark.viz"]


def test_the_known_edges_of_the_tree_are_found() -> None:
    """Real edges the walk must see: a function-level import (rig/loop/loop_setup.py loads the
    calibration lazily) and a TYPE_CHECKING one (viz/scene.py names rig's LoopSetup)."""
    loop = [e.module for e in imports_of(PACKAGE / "rig" / "loop" / "loop_setup.py")]
    assert "wristmark.cvs.calibration.load" in loop
    scene = [e.module for e in imports_of(PACKAGE / "viz" / "scene.py")]
    assert "wristmark.rig.loop.loop_setup" in scene


def test_the_independent_checkers_share_nothing_with_the_library() -> None:
    """wristmark_testing (written from docs/design.md only) imports no wristmark module, and the library
    never imports it."""
    import wristmark_testing

    checkers = Path(wristmark_testing.__file__).resolve().parent
    shared = []
    for path in sorted(checkers.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            shared += [f"wristmark_testing/{path.name}:{node.lineno} imports {n}" for n in names
                       if n.split(".")[0] == "wristmark"]
    shared += [f"wristmark/{path.relative_to(PACKAGE)} imports wristmark_testing"
               for path in sorted(PACKAGE.rglob("*.py")) if "wristmark_testing" in path.read_text()]
    assert not shared, "\n".join(shared)


def test_no_import_cycle_between_modules() -> None:
    """No two modules of wristmark/ import each other, directly or through others: the module graph
    (:func:`module_graph`: imports inside functions and under TYPE_CHECKING count) has no strongly
    connected component of more than one module. A package ``__init__``'s TYPE_CHECKING API block
    and the lazy public names of wristmark/_lazy.py are not edges of a cycle (the block only names
    the public API; an import of a public name is an edge to the module defining it)."""
    graph = module_graph()
    report = []
    for cycle in import_cycles(graph):
        report.append(f"{len(cycle)} modules import each other: "
                      + ", ".join(map(_shown, cycle)))
        report += [f"    {e}" for m in cycle for n in cycle for e in graph[m].get(n, [])]
    assert not report, "import cycles:\n" + "\n".join(report)


def test_the_cycle_finder_finds_a_planted_cycle() -> None:
    """The finder itself, on small graphs: a planted three-module loop and a two-module one are
    found (not the module that only imports into a loop, nor a chain); a graph without loops has none."""
    planted = {"a": ["b"], "b": ["c"], "c": ["a", "d"], "d": [], "e": ["a"], "f": ["g"], "g": ["f", "h"]}
    assert import_cycles(planted) == [["a", "b", "c"], ["f", "g"]]
    assert sorted(map(tuple, strongly_connected(planted))) == [("a", "b", "c"), ("d",), ("e",), ("f", "g"), ("h",)]
    assert import_cycles({"a": ["b", "c"], "b": ["c"], "c": [], "d": ["a"]}) == []
    chain = {f"m{i}": [f"m{i + 1}"] for i in range(5000)}  # deep: no recursion limit
    assert import_cycles(chain) == [] and import_cycles({**chain, "m5000": ["m0"]}) == [sorted([*chain, "m5000"])]


def test_the_graph_lands_imports_in_modules() -> None:
    """Imported names land in modules: a module, a package's public name (its defining module),
    another attribute (its module); ``from package import submodule`` is seen at any depth; a
    package's API block is no edge, and the real tree's known edges are there."""
    assert target_module("wristmark.rig.link.protocol") == "wristmark.rig.link.protocol"
    assert target_module("wristmark.solvers.make_controller") == "wristmark.solvers.controller_registry"
    assert target_module("wristmark.MarkerTracker") == "wristmark.cvs.tracking.tracker"
    assert target_module("wristmark.__version__") == "wristmark"
    assert target_module("wristmark.rig.loop.play_probe.NO_POSE") == "wristmark.rig.loop.play_probe"
    edges = imports_in("from wristmark.rig.link import protocol as P\n", "sim/x.py")
    assert [e.module for e in edges] == ["wristmark.rig.link.protocol"]
    graph = module_graph()
    assert set(graph["wristmark.solvers"]) == {"wristmark._lazy"}  # the API block is not an edge
    assert "wristmark.rig.link.protocol" in graph["wristmark.rig.link.actuator_driver"]
    assert "wristmark.solvers.controller" in graph["wristmark.solvers.paper_controller"]
    assert "wristmark.cvs.calibration.load" in graph["wristmark.rig.loop.loop_setup"]  # inside a function
