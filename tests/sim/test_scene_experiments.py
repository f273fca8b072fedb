"""``experiment cube --scene`` (sim.scene_experiments.run_scene_cube) with ``--orientation``: every
arm's path asks for its tip frame's orientation and every arm's loop holds it from its own
sleeve's pose; the result and the table report it per arm."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError
from wristmark.sim.scene_experiments import run_scene_cube, scene_trajectories
from wristmark.sim.scene_setup import load_scene_setup

SCENE = CONFIG_DIR / "scenes" / "two_arms.yaml"
FAST = CONFIG_DIR / "controller_encoders.yaml"  # the default controller without its play probe (faster)


@pytest.mark.slow
def test_every_arm_holds_its_tip_orientation_from_its_own_sleeve(tmp_path: Path) -> None:
    setup = load_scene_setup(SCENE, controller=FAST)
    res = run_scene_cube(setup, tmp_path / "run", duration=1.0, orientation="hold")
    assert res["orientation"] == "hold"
    for n in ("a", "b"):
        o, c = res["arms"][n]["open_loop"], res["arms"][n]["closed_loop"]
        assert not c["stopped"] and c["lost"] == 0
        # 2 s cube (2026-12-05): open loop ~1.07 deg, closed ~0.2 deg (noise-free 0.14-0.18) per arm
        assert c["orientation_true_mean_deg"] < 0.5 * o["orientation_true_mean_deg"]
        assert c["orientation_true_max_deg"] < 1.0
        assert c["noise_free"]["mean_mm"] < 0.3  # the position loop as without the orientation task
    table = (tmp_path / "run" / "results.md").read_text()
    assert "Orientation (hold)" in table and "a mean" in table and "b mean" in table


def test_a_position_only_controller_is_refused_naming_the_arm(tmp_path: Path) -> None:
    paper = tmp_path / "paper.yaml"
    paper.write_text(f"extends: {CONFIG_DIR / 'controller.yaml'}\ncontroller:\n  kind: paper\n")
    setup = load_scene_setup(SCENE, controller=paper)
    assert {s.controller.kind for s in setup.arms.values()} == {"paper"}
    with pytest.raises(ConfigError, match="arm 'a': --orientation follow needs --controller qp"):
        scene_trajectories(setup, 1.0, (), "follow")
    assert set(scene_trajectories(setup, 1.0)) == {"a", "b"}  # position only: every arm's path


@pytest.mark.slow
def test_the_arms_tracked_in_worker_processes_walk_exactly_as_in_one(tmp_path: Path) -> None:
    """``processes=True`` (`experiment cube --scene --arm-processes`): arm b's sleeve tracked in a
    worker process of its own; every logged cycle of both arms the same as with the arms in one
    process, but for the wall-clock timings, and the worker stopped at the end."""
    import multiprocessing

    setup = load_scene_setup(SCENE, controller=FAST)
    for procs in (False, True):
        run_scene_cube(setup, tmp_path / f"run_{procs}", duration=1.0, processes=procs)
    assert not multiprocessing.active_children()
    timing = {"t_wall", "ctrl_us", "vision_ms"}
    for n in ("a", "b"):
        rows = [list(csv.DictReader((tmp_path / f"run_{p}" / f"log_{n}.csv").open())) for p in (False, True)]
        assert len(rows[0]) == len(rows[1]) > 30
        for one, two in zip(*rows):
            assert {k for k in one if one[k] != two[k]} <= timing
