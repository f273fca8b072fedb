"""Outputs are never overwritten by accident (issue 17, item 2).

A non-empty output folder or an existing output file is refused with one line (exit 2) and every
byte stays as it was; ``--force`` empties the folder first, so no stale file survives; a run
without ``--out`` writes a new folder each time and links it as runs/latest.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import subprocess
from pathlib import Path

import pytest

from wristmark.cli import main as cli
from wristmark.rig.recording.output_dir import OutputExistsError, claim_outputs, link_latest, new_run_dir

ROOT = Path(__file__).resolve().parents[3]
QUICK_CUBE = ["experiment", "cube", "--sensor", "truth-noise", "--duration", "0.12", "--no-progress"]


def tree_digest(root: Path) -> dict[str, str]:
    """Every file and link below ``root`` with the hash of its bytes (or its link target)."""
    out: dict[str, str] = {}
    for p in sorted(root.rglob("*")):
        key = str(p.relative_to(root))
        if p.is_symlink():
            out[key] = "link:" + os.readlink(p)
        elif p.is_file():
            out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[key] = "dir"
    return out


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


def assert_refused(code: int, err: str, *words: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]


def test_render_refuses_a_dataset_folder_and_force_leaves_no_stale_pair(tmp_path: Path) -> None:
    ds = tmp_path / "ds"
    base = ["render", "--out", str(ds), "--scale", "0.25", "--noise", "none"]
    assert run([*base, "--pairs", "2", "--seed", "1"])[0] == 0
    before = tree_digest(tmp_path)
    assert "ds/pair_01_left.png" in before
    code, _, err = run([*base, "--pairs", "1", "--seed", "2"])
    assert_refused(code, err, str(ds), "not empty", "--force")
    assert tree_digest(tmp_path) == before  # nothing touched
    (ds / "notes.txt").write_text("an earlier file")
    assert run([*base, "--pairs", "1", "--seed", "2", "--force"])[0] == 0
    names = sorted(p.name for p in ds.iterdir())
    assert names == ["calib.yaml", "marker.yaml", "pair_00_left.png", "pair_00_right.png", "truth.json"]
    assert len(json.loads((ds / "truth.json").read_text())) == 1


def test_experiment_refuses_a_run_folder_and_a_result_file(tmp_path: Path) -> None:
    run_dir, result = tmp_path / "run", tmp_path / "result.json"
    assert run([*QUICK_CUBE, "--out", str(run_dir), "--json", str(result)])[0] == 0
    (run_dir / "stale.csv").write_text("from another run\n")
    before = tree_digest(tmp_path)
    code, _, err = run([*QUICK_CUBE, "--out", str(run_dir)])
    assert_refused(code, err, "not empty")
    code, _, err = run([*QUICK_CUBE, "--out", str(tmp_path / "other"), "--json", str(result)])
    assert_refused(code, err, "result.json", "exists", "--force")
    assert tree_digest(tmp_path) == before  # neither the folder nor the file, nor a new folder
    assert run([*QUICK_CUBE, "--out", str(run_dir), "--json", str(result), "--force"])[0] == 0
    assert not (run_dir / "stale.csv").exists()
    assert {"config.json", "log.csv", "result.json"} <= {p.name for p in run_dir.iterdir()}


def test_load_refuses_its_folder(tmp_path: Path) -> None:
    run_dir = tmp_path / "load"
    run_dir.mkdir()
    (run_dir / "results.md").write_text("earlier sweep\n")
    before = tree_digest(tmp_path)
    code, _, err = run(["experiment", "load", "--forces", "0", "--sensor", "truth-noise", "--duration", "0.12",
                        "--no-progress", "--out", str(run_dir)])
    assert_refused(code, err, "not empty")
    assert tree_digest(tmp_path) == before


def test_urdf_snapshot_and_servo_outputs_are_refused(tmp_path: Path) -> None:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("<robot/>")
    page = tmp_path / "view.html"
    page.write_text("<html/>")
    servo_dir = tmp_path / "servo"
    servo_dir.mkdir()
    (servo_dir / "log.csv").write_text("t\n")
    before = tree_digest(tmp_path)
    assert_refused(*run(["urdf", "--out", str(urdf)])[::2], "exists")
    assert_refused(*run(["view", "--snapshot", str(page)])[::2], "exists")
    assert_refused(*run(["servo", "--direct", "--sensor", "truth-noise", "--trajectory", "point", "--duration", "0.1",
                         "--no-progress", "--out", str(servo_dir)])[::2], "not empty")
    assert tree_digest(tmp_path) == before
    assert run(["urdf", "--out", str(urdf), "--force"])[0] == 0
    assert "<joint" in urdf.read_text()


@pytest.mark.slow
def test_runs_without_out_get_a_new_folder_and_a_latest_link(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert run(QUICK_CUBE)[0] == 0
    assert run(QUICK_CUBE)[0] == 0
    folders = sorted(p for p in (tmp_path / "runs").iterdir() if not p.is_symlink())
    assert len(folders) == 2 and all(p.name.startswith("cube-") for p in folders)
    latest = tmp_path / "runs" / "latest"
    assert latest.is_symlink() and latest.resolve() == max(folders, key=lambda p: p.stat().st_mtime_ns).resolve()
    assert (latest / "result.json").is_file()


def test_make_run_writes_a_new_folder_each_time() -> None:
    recipe = subprocess.run(["make", "-n", "run"], cwd=ROOT, capture_output=True, text=True, timeout=60).stdout
    line = next(x for x in recipe.splitlines() if "wristmark experiment cube" in x)
    assert "--out" not in line and "--json" not in line  # the default: runs/cube-<time> and runs/latest


def test_force_refuses_to_empty_the_current_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "keep.txt").write_text("x")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputExistsError, match="refusing to empty"):
        claim_outputs(dirs=[tmp_path], force=True)
    with pytest.raises(OutputExistsError, match="refusing to empty"):
        claim_outputs(dirs=[".."], force=True)
    assert (tmp_path / "keep.txt").read_text() == "x"


def test_a_refused_file_leaves_the_folder_untouched(tmp_path: Path) -> None:
    """Every output is checked before any is emptied."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "a").write_text("a")
    f = tmp_path / "f.json"
    f.mkdir()  # a folder where a file should go
    with pytest.raises(OutputExistsError, match="is a folder"):
        claim_outputs(dirs=[d], files=[f], force=True)
    assert (d / "a").read_text() == "a"


def test_new_run_dir_never_reuses_a_folder(tmp_path: Path) -> None:
    first = new_run_dir(tmp_path, "cube")
    first.mkdir()
    second = new_run_dir(tmp_path, "cube")
    assert second != first and not second.exists()
    link = link_latest(second)
    assert os.readlink(link) == second.name
