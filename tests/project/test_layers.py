"""Layers only look down: every import in wristmark/ (module level, inside functions, under
TYPE_CHECKING, relative or absolute) goes to the same package or a lower one.

Layering, lowest first: models < cvs < solvers < rig < viz < sim < cli < sweep (a sweep's trial is
a command line; ``wristmark sweep`` is named in cli/main.py's COMMAND_MODULES). The package root
(wristmark/__init__.py, __main__.py) stands above them all; its private helper
wristmark/_lazy.py (the lazy public names of every package, standard library only) lies below them all.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import wristmark

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
            if names[0] in ("wristmark", *(f"wristmark.{x}" for x in LAYERS)):  # from wristmark import sim
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
