"""Lazy public names for the package ``__init__`` modules (PEP 562 module ``__getattr__``).

Each package writes its public API once, as the imports of an ``if TYPE_CHECKING:`` block (what
mypy and editors read). :func:`attach` gives the package ``__getattr__`` and ``__dir__``; the
block is read from the package's own source the first time a public name, ``__all__`` or
``dir()`` is asked for, and a name's module is imported the first time the name is used, so
``import wristmark`` does not import OpenCV, CasADi, Meshcat, dask or the simulated bench.
"""

from __future__ import annotations

import importlib
import sys

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)
if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path
    from typing import Any


def public_names(init_file: str | Path) -> dict[str, tuple[str, str]]:
    """The names imported in the ``if TYPE_CHECKING:`` block of ``init_file``: public name ->
    (module, attribute in that module). Only absolute ``from MODULE import NAME [as ALIAS]``."""
    import ast  # here, not at the top: ``import wristmark`` does not need it

    with open(init_file, encoding="utf-8") as f:
        tree = ast.parse(f.read())
    names: dict[str, tuple[str, str]] = {}
    for node in tree.body:
        if not (isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"):
            continue
        for stmt in node.body:
            if not (isinstance(stmt, ast.ImportFrom) and stmt.module and stmt.level == 0):
                raise ImportError(f"{init_file}: the TYPE_CHECKING block holds only 'from wristmark.x import y'")
            for alias in stmt.names:
                names[alias.asname or alias.name] = (stmt.module, alias.name)
    return names


def attach(package: str, init_file: str | Path,
           extra: tuple[str, ...] = ()) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package``: its public names (and ``__all__``, sorted,
    with the module-level names in ``extra``) are found on first use.

    A public name is imported on first use and then kept on the package; a subpackage or module
    of ``package`` (``wristmark.sim``) is imported on first attribute access too."""
    found: dict[str, tuple[str, str]] = {}

    def exports() -> dict[str, tuple[str, str]]:
        if not found:
            found.update(public_names(init_file))
        return found

    def __getattr__(name: str) -> Any:
        module = sys.modules[package]
        if name == "__all__":
            value: Any = [*extra, *sorted(exports())]
            vars(module)["__all__"] = value
            return value
        if not name.startswith("__") and name in exports():
            source, attr = exports()[name]
            value = getattr(importlib.import_module(source), attr)
            setattr(module, name, value)
            return value
        if not name.startswith("__"):
            from importlib.util import find_spec

            if find_spec(f"{package}.{name}") is not None:
                return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(exports()))

    return __getattr__, __dir__
