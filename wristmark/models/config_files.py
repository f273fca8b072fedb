"""The configuration files shipped inside the package, and how a path given by a user finds them.

The defaults (robot, marker, camera, controller, rig and the simulated plants) are package data
under ``wristmark/configs`` and are found through :mod:`importlib.resources`, so they work from a
wheel as from a checkout. A user's own file always wins: a path that exists is used as given. A
path that does not exist and is named like a shipped file (``plant_unseen.yaml`` or
``configs/plant_unseen.yaml``) is the shipped file, so the commands of the README run from any
folder.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

__all__ = ["CONFIG_DIR", "default_config", "find_config", "shipped_configs"]

CONFIG_DIR = Path(str(files("wristmark") / "configs"))


def default_config(name: str) -> Path:
    """Path of a shipped configuration file, e.g. ``default_config("plant_unseen.yaml")``."""
    return CONFIG_DIR / name


def shipped_configs() -> list[str]:
    """Names of the shipped configuration files, relative to the configs folder (sorted)."""
    return sorted(str(p.relative_to(CONFIG_DIR)) for p in CONFIG_DIR.rglob("*.yaml"))


def find_config(path: str | Path) -> Path:
    """``path`` if it exists; else the shipped file it names (``NAME.yaml``, ``configs/NAME.yaml``
    or ``configs/sweeps/NAME.yaml``) if there is one; else ``path`` unchanged (so the caller
    reports it as missing)."""
    p = Path(path)
    if p.exists() or p.is_absolute():
        return p
    parts = p.parts
    if parts and parts[0] == "configs":
        parts = parts[1:]
    if parts:
        shipped = CONFIG_DIR.joinpath(*parts)
        if shipped.is_file():
            return shipped
    return p
