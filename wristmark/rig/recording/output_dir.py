"""Output folders and files that a command never overwrites by accident.

A command that writes a folder (``render --out``, ``experiment --out``, ``servo --out``) or a
result file (``--json OUT``, ``urdf --out``, ``view --snapshot``) claims its outputs with
:func:`claim_outputs` before it writes anything: a non-empty folder or an existing file is
refused with one line (exit 2) and nothing is touched, unless ``--force``, which empties the
folder (no stale file of an earlier run survives) and removes the file first. Every output is
checked before any is changed, so a refusal of one leaves all as they were.

``new_run_dir`` names a fresh run folder (``runs/<name>-YYYYmmdd-HHMMSS``) and ``link_latest``
points ``runs/latest`` at it.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Iterable
from pathlib import Path

from wristmark.models.errors import InputError

LATEST = "latest"  # name of the link to the newest run folder


class OutputExistsError(InputError):
    """An output folder is not empty or an output file exists, and --force was not given."""


def _shown(names: list[str]) -> str:
    head = ", ".join(sorted(names)[:3])
    return head + (f", ... ({len(names)} entries)" if len(names) > 3 else "")


def _check_dir(path: Path, force: bool) -> None:
    if not path.exists() and not path.is_symlink():
        return
    if not path.is_dir():
        raise OutputExistsError(f"{path}: exists and is not a folder; choose another output folder")
    names = [p.name for p in path.iterdir()]
    if not names:
        return
    if not force:
        raise OutputExistsError(f"{path}: output folder is not empty ({_shown(names)}); "
                                "pass --force to empty it first, or choose another folder")
    real = path.resolve()
    cwd = Path.cwd().resolve()
    if real == Path(real.anchor) or real == Path.home().resolve() or cwd == real or real in cwd.parents:
        raise OutputExistsError(f"{path}: refusing to empty it with --force (it is the root, the home folder "
                                "or holds the current folder); choose a folder of its own")
    if (real / ".git").exists():
        raise OutputExistsError(f"{path}: refusing to empty a git checkout with --force; choose a folder of its own")


def _check_file(path: Path, force: bool) -> None:
    if path.is_dir() and not path.is_symlink():
        raise OutputExistsError(f"{path}: is a folder, expected an output file name")
    if (path.exists() or path.is_symlink()) and not force:
        raise OutputExistsError(f"{path}: output file exists; pass --force to replace it, or choose another name")


def _empty(path: Path) -> None:
    for child in path.iterdir():
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()


def claim_outputs(dirs: Iterable[str | Path | None] = (), files: Iterable[str | Path | None] = (),
                  force: bool = False) -> None:
    """Check every output folder and file (None entries are skipped), then, with ``force``,
    empty the folders and remove the files; raise OutputExistsError before touching anything."""
    dir_paths = [Path(d) for d in dirs if d is not None]
    file_paths = [Path(f) for f in files if f is not None]
    for d in dir_paths:
        _check_dir(d, force)
    for f in file_paths:
        _check_file(f, force)
    for d in dir_paths:
        if d.is_dir():
            _empty(d)
    for f in file_paths:
        if f.exists() or f.is_symlink():
            f.unlink()


def new_run_dir(root: str | Path, name: str) -> Path:
    """A run folder that does not exist yet: ``root/<name>-YYYYmmdd-HHMMSS`` (``-2``, ``-3``, ...
    appended when that second is taken)."""
    base = Path(root) / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    path, n = base, 1
    while path.exists() or path.is_symlink():
        n += 1
        path = base.with_name(f"{base.name}-{n}")
    return path


def link_latest(run_dir: str | Path) -> Path:
    """Point ``<parent>/latest`` at ``run_dir`` (a relative symbolic link, replaced atomically)."""
    run = Path(run_dir)
    link = run.parent / LATEST
    if link.exists() and not link.is_symlink():
        raise OutputExistsError(f"{link}: exists and is not a link; remove it to keep a link to the latest run")
    tmp = run.parent / f".{LATEST}.{os.getpid()}"
    if tmp.is_symlink():
        tmp.unlink()
    os.symlink(run.name, tmp)
    os.replace(tmp, link)
    return link
