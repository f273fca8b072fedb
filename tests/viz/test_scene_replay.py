"""Replay of a run folder of several arms (viz.scene_replay, ``wristmark view``) on the committed
two-arm run tests/data/scene_run (``python -m tests.viz.scene_run_data`` writes it): every arm
with its estimated, desired and true tips, on one clock; one-line errors for broken folders."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.viz.test_arms_scene import node, transform_of
from tests.viz.test_viz_scene import make_fake_run
from wristmark.cli.main import main
from wristmark.rig.recording.run_log import read_log_csv
from wristmark.viz.arms_scene import arm_root
from wristmark.viz.scene_replay import _common_times, build_scene_replay, is_scene_run, load_scene_run
from wristmark.viz.snapshot import recording_visualizer
from wristmark.viz.style import ARM_TIP_KINDS

SCENE_RUN = Path(__file__).resolve().parents[1] / "data" / "scene_run"


def test_the_test_data_is_small() -> None:
    size = sum(p.stat().st_size for p in SCENE_RUN.iterdir())
    assert size < 200_000 and sorted(p.name for p in SCENE_RUN.glob("log_*.csv")) == ["log_a.csv", "log_b.csv"]


def test_scene_run_is_told_from_a_one_arm_run(tmp_path: Path) -> None:
    assert is_scene_run(SCENE_RUN)
    assert not is_scene_run(make_fake_run(tmp_path / "one", cycles=2))
    assert not is_scene_run(tmp_path / "missing")


def test_every_arm_is_loaded_at_its_base_on_one_clock() -> None:
    rep = load_scene_run(SCENE_RUN)
    cfg = json.loads((SCENE_RUN / "config.json").read_text())
    assert rep.config.names == ["a", "b"]
    for name in ("a", "b"):
        np.testing.assert_allclose(rep.config.bases[name], cfg["arms"][name]["base"])
        log = read_log_csv(SCENE_RUN / f"log_{name}.csv")
        arm = rep.arms[name]
        assert len(arm.states) == len(log["t"]) > 20
        assert np.all(np.diff(arm.times) > 0)
        last = arm.states[-1]  # closed loop: every tip known
        np.testing.assert_allclose(last.tips["estimated"], [log[f"p_est_{a}"][-1] for a in "xyz"])
        np.testing.assert_allclose(last.tips["desired"], [log[f"p_des_{a}"][-1] for a in "xyz"])
        np.testing.assert_allclose(last.tips["true"], [log[f"p_true_{a}"][-1] for a in "xyz"])
    # lockstep: the same cycle of both arms is at the same replay time
    np.testing.assert_allclose(rep.arms["a"].times, rep.arms["b"].times)
    # the scene camera is back in the scene's {w}: the left lens between the two arms' bases
    assert rep.config.camera is not None and 0.0 < rep.config.camera.T_world_left[0, 3] < 0.2
    assert rep.summary["a: closed loop"].startswith("mean ") and rep.summary["b: closed loop"].startswith("mean ")
    assert rep.summary["clearance"].endswith("kept")


def test_replay_tree_has_both_arms_with_their_tips_and_paths() -> None:
    rep = load_scene_run(SCENE_RUN)
    vis, window = recording_visualizer()
    build_scene_replay(vis, rep, max_frames=20, play=False)
    anim = [a for c in window.commands() if b"set_animation" in c for a in _animation_of(c)]
    paths = {a["path"] for a in anim}
    for name in ("a", "b"):
        root = arm_root(name)
        np.testing.assert_allclose(transform_of(window, root), rep.config.bases[name], atol=1e-12)
        assert node(window, f"{root}/arm/visuals").keys()  # type: ignore[attr-defined]
        for kind in ARM_TIP_KINDS:
            assert node(window, f"{root}/tips/{kind}").object is not None  # type: ignore[attr-defined]
            assert f"/meshcat/{root}/tips/{kind}" in paths  # it moves with the replay
            for phase in ("open_loop", "closed_loop"):
                if kind == "estimated" and phase == "open_loop":
                    continue  # no vision estimate in the open loop
                assert node(window, f"{root}/trails/{kind}/{phase}").object is not None  # type: ignore[attr-defined]
        assert any(p.startswith(f"/meshcat/{root}/arm/visuals/seg1_link_") for p in paths)
        # the last key of the estimated tip is the last logged estimate, in the arm's own {w}
        est = next(a for a in anim if a["path"] == f"/meshcat/{root}/tips/estimated")
        pos = next(t for t in est["clip"]["tracks"] if t["name"] == ".position")
        np.testing.assert_allclose(pos["keys"][-1]["value"], rep.arms[name].states[-1].tips["estimated"])
        assert len(pos["keys"]) == 20
    assert not any("/ghost/" in p for p in paths)


def _animation_of(command: bytes) -> list[dict]:
    import umsgpack

    return list(umsgpack.unpackb(command)["animations"])


def test_view_writes_a_snapshot_of_a_scene_run_with_every_arm_in_the_legend(tmp_path: Path) -> None:
    out = tmp_path / "scene.html"
    assert main(["view", str(SCENE_RUN), "--snapshot", str(out), "--max-frames", "10"]) == 0
    text = out.read_text()
    assert "arm a: desired / estimated / true tip" in text and "arm b: desired / estimated / true tip" in text
    assert "b: closed loop: mean" in text and "wmCommands" in text
    assert "commanded tip" not in text  # the one-arm legend is not used


def test_one_arm_runs_still_replay_alone(tmp_path: Path) -> None:
    run = make_fake_run(tmp_path / "run", cycles=3)
    out = tmp_path / "one.html"
    assert main(["view", str(run), "--snapshot", str(out)]) == 0
    text = out.read_text()
    assert "commanded tip" in text and "arm a:" not in text


def _copy(tmp_path: Path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(SCENE_RUN, run)
    return run


@pytest.mark.parametrize("case, message", [
    ("no_log", "no log_b.csv for arm 'b'"),
    ("bad_base", "'arms.a'.base: expected a 4x4 rigid pose"),
    ("corrupt_log", "log_a.csv: corrupt log, missing column 'psi_cmd_2'"),
    ("bad_arm", "'arms.x/y': expected an arm name"),
])
def test_broken_scene_run_folder_is_a_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                     case: str, message: str) -> None:
    run = _copy(tmp_path)
    cfg = json.loads((run / "config.json").read_text())
    if case == "no_log":
        (run / "log_b.csv").unlink()
    elif case == "bad_base":
        cfg["arms"]["a"]["base"] = [[1, 0, 0], [0, 1, 0]]
    elif case == "corrupt_log":
        log = run / "log_a.csv"
        log.write_text(log.read_text().replace("psi_cmd_2", "psi_cmd_x"))
    else:
        cfg["arms"]["x/y"] = cfg["arms"]["a"]
    (run / "config.json").write_text(json.dumps(cfg))
    out = tmp_path / "x.html"
    assert main(["view", str(run), "--snapshot", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


def test_common_clock_lays_the_phases_end_to_end() -> None:
    """Two arms, two phases each restarting the clock at 2 s; arm b stopped early in phase 1."""
    a = np.array([2.0, 2.1, 2.2, 2.0, 2.1, 2.2])
    b = np.array([2.0, 2.1, 2.2, 2.0, 2.1])
    t = _common_times({"a": a, "b": b})
    np.testing.assert_allclose(t["a"], [0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_allclose(t["b"], t["a"][:5])
