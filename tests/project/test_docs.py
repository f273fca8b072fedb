"""What a newcomer reads points to what exists, and the quick tour writes only ignored files
(issue 17, item 5)."""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
from pathlib import Path

from wristmark.cli import main as cli
from wristmark.models.config_files import CONFIG_DIR

ROOT = Path(__file__).resolve().parents[2]
USER_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
              *sorted(p for p in (CONFIG_DIR).rglob("*") if p.is_file())]
WRITES = ("--out", "--json", "--snapshot")  # options whose value is a written path


def _help_texts() -> dict[str, str]:
    out = {}
    for name in cli.COMMANDS:
        parser = cli.build_parser(name)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        out[name] = sub.choices[name].format_help()
    return out


def test_nothing_points_to_a_file_outside_the_repository() -> None:
    """docs/design.md is not shipped: README, docs, configs and --help must not send users there."""
    hits = [str(p.relative_to(ROOT)) for p in USER_FILES if "docs/design.md" in p.read_text()]
    hits += [f"wristmark {name} --help" for name, text in _help_texts().items() if "docs/design.md" in text]
    assert not hits, "docs/design.md is mentioned in: " + ", ".join(hits)


def test_every_link_and_docs_path_exists() -> None:
    missing = []
    for p in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        text = p.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" not in target and not (p.parent / target).exists():
                missing.append(f"{p.relative_to(ROOT)} -> {target}")
        for path in re.findall(r"\b(docs/[\w./-]+\.md)\b", text):
            if not (ROOT / path).exists():
                missing.append(f"{p.relative_to(ROOT)} mentions {path}")
    for c in sorted((CONFIG_DIR).rglob("*.yaml")):
        for path in re.findall(r"\b(docs/[\w./-]+\.md)\b", c.read_text()):
            if not (ROOT / path).exists():
                missing.append(f"{c.relative_to(ROOT)} mentions {path}")
    assert not missing, missing
    assert (ROOT / "docs" / "formats.md").is_file() and (ROOT / "docs" / "command-line.md").is_file()


def _tour_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## Quick tour\n+```sh\n(.*?)```", text, re.S)
    assert block is not None
    return [shlex.split(ln.split("#", 1)[0]) for ln in block.group(1).splitlines() if ln.startswith("wristmark ")]


def test_quick_tour_writes_only_under_runs_and_git_ignores_it() -> None:
    written = []
    for argv in _tour_commands():
        for opt, value in zip(argv, argv[1:]):
            if opt in WRITES and not value.startswith("-"):
                written.append(value)
    assert len(written) >= 6, written  # urdf, render, experiments, snapshot
    outside = [w for w in written if not (w.startswith("runs/") or w.startswith("/tmp/"))]
    assert not outside, f"the tour writes into the repository: {outside}"
    for w in written:
        if w.startswith("runs/"):
            r = subprocess.run(["git", "check-ignore", "-q", w], cwd=ROOT)
            assert r.returncode == 0, f"{w} is not ignored by git"


def test_old_tour_outputs_are_ignored() -> None:
    for w in ("arm.urdf", "data/demo/pair_00_left.png", "view.html"):
        assert subprocess.run(["git", "check-ignore", "-q", w], cwd=ROOT).returncode == 0, w
