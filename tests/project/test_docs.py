"""What a newcomer reads points to what exists, and the quick tour writes only ignored files
(issue 17, item 5); the front door is short, and what the code cites of docs/design.md is there
(issue "The front door")."""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
from pathlib import Path

from wristmark.cli import main as cli
from wristmark.models.config_files import CONFIG_DIR

ROOT = Path(__file__).resolve().parents[2]
WRITES = ("--out", "--json", "--snapshot")  # options whose value is a written path


def _help_texts() -> dict[str, str]:
    out = {}
    for name in cli.COMMANDS:
        parser = cli.build_parser(name)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        out[name] = sub.choices[name].format_help()
    return out


# Spelled in two parts so that this file does not name them itself.
OUTSIDE = ("../" + "shared", "/wo" + "rk/")  # the design folder beside the checkout; the machine's checkouts
CODE_DIRS = ("wristmark", "wristmark_testing", "tests", "bench", "examples")
# `docs/design.md "Recording"`, `docs/design.md, "The manipulator"`, `docs/design.md ("Stereo dataset format"`,
# `docs/design.md's "Stereo dataset format"`: the title in quotes right after the path.
DESIGN_CITATION = re.compile(r"docs/design\.md(?:'s)?`?,?\s*\(?\s*\"([^\"\n]+)\"")


def _repository_files() -> list[Path]:
    """The files of the repository: tracked by git, or new and not ignored."""
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                         cwd=ROOT, capture_output=True, check=True).stdout
    return [ROOT / name for name in sorted(set(out.decode().split("\0"))) if name and (ROOT / name).is_file()]


def _text(p: Path) -> str | None:
    try:
        return p.read_text(encoding="utf-8")
    except (UnicodeDecodeError, IsADirectoryError):
        return None


def test_readme_is_a_front_door() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines (at most 200: details belong in docs/)"
    text = "\n".join(lines)
    start, end = "<!-- results-table:start -->", "<!-- results-table:end -->"
    assert text.count(start) == 1 and text.count(end) == 1 and text.index(start) < text.index(end)
    rows = [ln for ln in text[text.index(start):text.index(end)].splitlines() if ln.startswith("|")]
    assert 3 <= len(rows) <= 2 + 6, f"the results table has {len(rows) - 2} rows (at most six)"
    assert (ROOT / "LICENSE").is_file() and (ROOT / "CHANGELOG.md").is_file()


def test_nothing_points_to_a_file_outside_the_repository() -> None:
    """Users have the repository only: no tracked file and no --help names the folders beside it."""
    hits = []
    for p in _repository_files():
        text = _text(p)
        if text is None:
            continue
        for n, line in enumerate(text.splitlines(), 1):
            if any(o in line for o in OUTSIDE):
                hits.append(f"{p.relative_to(ROOT)}:{n}: {line.strip()[:100]}")
    hits += [f"wristmark {name} --help" for name, text in _help_texts().items() if any(o in text for o in OUTSIDE)]
    assert not hits, "paths outside the repository:\n" + "\n".join(hits)


def test_every_design_citation_names_a_heading() -> None:
    """Every section of docs/design.md that the code, the tests, the benchmarks or the examples
    cite by its quoted title is a heading there, so that a reader finds the section meant."""
    design = (ROOT / "docs" / "design.md").read_text()
    headings = {m.group(1).strip() for m in re.finditer(r"^#{1,6}\s+(.+?)\s*$", design, re.M)}
    cited: dict[str, list[str]] = {}
    for d in CODE_DIRS:
        for p in sorted((ROOT / d).rglob("*")):
            if p.suffix not in (".py", ".md", ".yaml", ".txt") or "__pycache__" in p.parts:
                continue
            text = _text(p)
            for m in DESIGN_CITATION.finditer(text or ""):
                cited.setdefault(m.group(1), []).append(str(p.relative_to(ROOT)))
    assert len(cited) >= 10, f"the pattern found too few citations to be right: {sorted(cited)}"
    missing = {title: where for title, where in cited.items() if title not in headings}
    assert not missing, f"cited titles that are no heading of docs/design.md: {missing}"


def test_every_link_and_docs_path_exists() -> None:
    """Every relative link of README.md and docs/ resolves to a file of the repository (or a folder
    holding some), and every docs/*.md path they or the configs mention exists."""
    files = set(_repository_files())
    missing = []
    for p in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        text = p.read_text()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" in target or target.startswith("mailto:"):
                continue
            dest = (p.parent / target).resolve()
            if not (dest in files or any(dest in f.parents for f in files)):
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


def test_the_index_lists_every_page() -> None:
    """docs/index.md links every page of docs/ (sub-folders have their own index page)."""
    index = (ROOT / "docs" / "index.md").read_text()
    linked = set(re.findall(r"\]\(([^)#\s]+)", index))
    unlisted = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p.name not in linked]
    assert not unlisted, f"docs/index.md does not list: {unlisted}"


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
    assert len(written) >= 6, written  # experiment, servo, calibrate, register, snapshot, sweep
    outside = [w for w in written if not (w.startswith("runs/") or w.startswith("/tmp/"))]
    assert not outside, f"the tour writes into the repository: {outside}"
    for w in written:
        if w.startswith("runs/"):
            r = subprocess.run(["git", "check-ignore", "-q", w], cwd=ROOT)
            assert r.returncode == 0, f"{w} is not ignored by git"


def test_old_tour_outputs_are_ignored() -> None:
    for w in ("arm.urdf", "data/demo/pair_00_left.png", "view.html"):
        assert subprocess.run(["git", "check-ignore", "-q", w], cwd=ROOT).returncode == 0, w
