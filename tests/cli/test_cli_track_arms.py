"""``wristmark track --marker A.yaml --marker B.yaml``: one object per marker file and pair with "arm";
the sleeve in view under its own arm, ``ok: false`` for the other (docs/design.md "Several arms in one
view"); marker sets that could be confused are refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from wristmark.cli.main import main


@pytest.mark.slow
def test_one_sleeve_in_view_is_reported_under_its_arm_only(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fam = tmp_path / "fam"
    assert main(["marker", "family", "--arms", "2", "--out", str(fam), "--bands-per-side", "3", "--sheet", "svg"]) == 0
    a, b = str(fam / "arm0.yaml"), str(fam / "arm1.yaml")
    scene = tmp_path / "scene"
    assert main(["render", "--out", str(scene), "--pairs", "3", "--marker", b]) == 0
    capsys.readouterr()
    pairs = [str(scene / f"pair_{i:02d}_{s}.png") for i in range(3) for s in ("left", "right")]
    assert main(["track", "--calib", str(scene / "calib.yaml"), "--marker", a, "--marker", b, *pairs, "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert len(lines) == 6 and [x["arm"] for x in lines] == ["arm0", "arm1"] * 3
    assert all(not x["ok"] for x in lines if x["arm"] == "arm0")  # never read as the other arm's
    mine = [x for x in lines if x["arm"] == "arm1" and x["ok"]]
    assert len(mine) >= 2 and all(x["roll_known"] and x["axis_source"] == "code" for x in mine)
    assert all(x["reason"] == "not in view" for x in lines if x["arm"] == "arm0")


def test_two_sleeves_in_each_pair_are_both_reported_each_under_its_own_arm(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``render --scene`` (both arms in every pair, truth per arm) then ``track`` with both marker
    files: every pair gives each arm its own pose, at its own truth."""
    out = tmp_path / "two"
    assert main(["render", "--scene", "configs/scenes/two_arms.yaml", "--out", str(out), "--pairs", "3",
                 "--image-scale", "0.75", "--seed", "4"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert [sorted(e["arms"]) for e in truth] == [["a", "b"]] * 3
    capsys.readouterr()
    pairs = [str(out / f"pair_{i:02d}_{s}.png") for i in range(3) for s in ("left", "right")]
    assert main(["track", "--calib", str(out / "calib.yaml"), "--marker", str(out / "marker_a.yaml"),
                 "--marker", str(out / "marker_b.yaml"), *pairs, "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["arm"] for x in lines] == ["a", "b"] * 3
    for k, x in enumerate(lines):
        assert x["ok"], x
        tip = truth[k // 2]["arms"][x["arm"]]["tip"]
        other = truth[k // 2]["arms"]["b" if x["arm"] == "a" else "a"]["tip"]
        assert sum((p - q) ** 2 for p, q in zip(x["tip"], tip)) ** 0.5 < min(3e-4, 3 * x["tip_sigma_m"])
        assert sum((p - q) ** 2 for p, q in zip(x["tip"], other)) ** 0.5 > 5e-3


def test_render_scene_refuses_the_one_arm_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["render", "--scene", "configs/scenes/two_arms.yaml", "--out", str(tmp_path / "x"),
               "--marker", "configs/marker_coded.yaml"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "--marker: not with --scene" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("second, cause", [("same", "the same arm name 'arm0'"),
                                           ("coded", "name their arm")])
def test_confusable_marker_sets_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             second: str, cause: str) -> None:
    fam = tmp_path / "fam"
    assert main(["marker", "family", "--arms", "2", "--out", str(fam), "--sheet", "svg"]) == 0
    a = str(fam / "arm0.yaml")
    other = a if second == "same" else "configs/marker_coded.yaml"
    images = [tmp_path / "l.png", tmp_path / "r.png"]
    for im in images:
        im.write_bytes(b"")  # never read: the marker set is refused first
    capsys.readouterr()
    rc = main(["track", "--calib", "configs/camera.yaml", "--marker", a, "--marker", other, *map(str, images)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and cause in err and len(err.splitlines()) == 1


@pytest.mark.slow
def test_arm_processes_give_the_same_lines(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--arm-processes`` (arm b in a worker process of its own): every line the one of one
    process but the time."""
    out = tmp_path / "two"
    assert main(["render", "--scene", "configs/scenes/two_arms.yaml", "--out", str(out), "--pairs", "3",
                 "--image-scale", "0.75", "--seed", "4"]) == 0
    pairs = [str(out / f"pair_{i:02d}_{s}.png") for i in range(3) for s in ("left", "right")]
    base = ["track", "--calib", str(out / "calib.yaml"), "--marker", str(out / "marker_a.yaml"),
            "--marker", str(out / "marker_b.yaml"), *pairs, "--json"]
    lines = []
    for extra in ([], ["--arm-processes"]):
        capsys.readouterr()
        assert main(base + extra) == 0
        lines.append([json.loads(x) | {"time_ms": None} for x in capsys.readouterr().out.splitlines()])
    assert len(lines[0]) == 6 and all(x["ok"] for x in lines[0]) and lines[1] == lines[0]


def test_arm_processes_need_several_markers(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["track", "--calib", "configs/camera.yaml", "--arm-processes", "a.png", "b.png"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "--arm-processes needs several --marker files" in err and len(err.splitlines()) == 1
