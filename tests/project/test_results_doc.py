"""docs/results.md stays current and short, and the README's results table agrees with it
(issue "The front door"). Reads the files only: no benchmark runs here."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results.md"
README = ROOT / "README.md"
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?")
BLOCK = re.compile(r"<!-- generated:([a-z_0-9]+):start -->\n(.*?)\n<!-- generated:\1:end -->", re.S)


def _results_script() -> ModuleType:
    """bench/results.py (standard library only: importing it runs nothing)."""
    spec = importlib.util.spec_from_file_location("bench_results", ROOT / "bench" / "results.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _readme_block() -> str:
    text = README.read_text()
    m = re.search(r"<!-- results-table:start -->\n(.*?)<!-- results-table:end -->", text, re.S)
    assert m is not None, "README.md has no <!-- results-table:start --> ... <!-- results-table:end --> block"
    return m.group(1)


def _numbers(text: str) -> set[float]:
    return {float(x) for x in NUMBER.findall(text)}


def test_results_doc_is_at_most_30_kb() -> None:
    assert RESULTS.stat().st_size <= 30_000, f"docs/results.md is {RESULTS.stat().st_size} bytes (limit 30 000)"


def test_every_number_of_the_readme_table_is_in_results_doc_with_the_same_value() -> None:
    block = _readme_block()
    rows = [ln for ln in block.splitlines() if ln.startswith("|")]
    assert len(rows) >= 3, "the README's results table has no rows"
    assert len(rows) - 2 <= 6, f"the README's results table has {len(rows) - 2} rows (at most 6)"
    assert "paper" in rows[0], "the README's results table compares with the paper"
    in_results = _numbers(RESULTS.read_text())
    missing = sorted(x for x in NUMBER.findall(block) if float(x) not in in_results)
    assert not missing, f"numbers of README's results table not in docs/results.md: {missing}"


def test_number_parsing() -> None:
    assert NUMBER.findall("| 3.37 / 6.10 | 4.2 % | `--pairs 20` | -0.5 |") == ["3.37", "6.10", "4.2", "20", "-0.5"]
    assert NUMBER.findall("1080p, x2, v0.3") == ["1080"]
    assert 6.1 in _numbers("max 6.10 mm")


def test_every_generated_block_names_its_command() -> None:
    script = _results_script()
    blocks = BLOCK.findall(RESULTS.read_text())
    assert blocks, "docs/results.md has no generated block"
    names = [n for n, _ in blocks]
    assert len(names) == len(set(names)), f"a generated block appears twice: {names}"
    opened = re.findall(r"<!-- generated:([a-z_0-9]+):start -->", RESULTS.read_text())
    assert sorted(opened) == sorted(names), "a generated block is not closed by its end marker"
    for name, body in blocks:
        first = body.strip().splitlines()[0] if body.strip() else ""
        m = re.fullmatch(r"Command: `(.+)`", first)
        assert m, f"block {name!r} does not start with its command (Command: `...`)"
        assert name in script.BY_NAME, f"block {name!r} is not a result of bench/results.py"
        assert m.group(1) == script.BY_NAME[name].command, f"block {name!r} names another command than bench/results.py"


def test_the_script_rewrites_only_the_blocks() -> None:
    script = _results_script()
    text = ("intro 1.5\n<!-- generated:cube:start -->\nold 9.9\n<!-- generated:cube:end -->\nmiddle\n"
            "<!-- generated:tracking:start -->\nkept 7\n<!-- generated:tracking:end -->\n")
    new, done = script.rewrite_blocks(text, {"cube": "Command: `x`\n\nnew 2.5", "other": "y"})
    assert done == ["cube"]
    assert new == text.replace("old 9.9", "Command: `x`\n\nnew 2.5")
    readme = "a\n<!-- results-table:start -->\n| old |\n<!-- results-table:end -->\nb\n"
    assert script.rewrite_readme(readme, ["| new |"]) == readme.replace("| old |", "| new |")


def test_the_readme_table_keeps_the_rows_it_has_no_new_result_for() -> None:
    script = _results_script()
    readme = ("a\n<!-- results-table:start -->\n| | paper | wristmark | command |\n|---|---|---|---|\n"
              "| cube, closed loop | 0.82 | 0.141 | `make run` |\n| tip accuracy | 0.67 | 0.096 | `x` |\n"
              "<!-- results-table:end -->\nb\n")
    cube = "| cube, closed loop | 0.82 | 0.140 | `make run` |"
    table = ["| | paper | wristmark | command |", "|---|---|---|---|", cube, "| new row | - | 1 | `y` |"]
    assert script.merged_table(readme, table) == [*table[:2], cube, "| tip accuracy | 0.67 | 0.096 | `x` |",
                                                  "| new row | - | 1 | `y` |"]


def test_only_the_results_run_are_written(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    script = _results_script()
    results, readme = tmp_path / "results.md", tmp_path / "README.md"
    results.write_text("<!-- generated:cube:start -->\nold cube\n<!-- generated:cube:end -->\n"
                       "<!-- generated:tracking:start -->\nold tracking\n<!-- generated:tracking:end -->\n")
    readme.write_text("<!-- results-table:start -->\n<!-- results-table:end -->\n")
    monkeypatch.setattr(script, "RESULTS_MD", results)
    monkeypatch.setattr(script, "README", readme)
    monkeypatch.setattr(script, "_stored", lambda name: ({"n": name}, {}))  # every result kept
    monkeypatch.setattr(script, "block_text", lambda e, data, meta: f"new {data['n']}")
    monkeypatch.setattr(script, "readme_table", lambda stored: None)
    script.write_docs(["tracking"])
    assert "old cube" in results.read_text() and "new tracking" in results.read_text()
    script.write_docs(None)
    assert "new cube" in results.read_text()


def test_a_command_runs_under_its_time_limit_and_keeps_its_json(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    script = _results_script()
    monkeypatch.setattr(script, "OUT", tmp_path)  # ROOT / an absolute path is that path
    fast = script.Entry("fast", "t", (sys.executable, "-c", "print('{\"x\": 1.5}')"), 30, lambda d: [str(d["x"])])
    assert script.run_entry(fast)
    assert (tmp_path / "fast.json").read_text().replace(" ", "").replace("\n", "") == '{"x":1.5}'
    meta = (tmp_path / "fast.meta.json").read_text()
    assert '"command"' in meta and '"wall_s"' in meta and '"commit"' in meta
    slow = script.Entry("slow", "t", (sys.executable, "-c", "import time; time.sleep(60)"), 0.5, lambda d: [])
    assert not script.run_entry(slow)
    assert not (tmp_path / "slow.json").exists()
