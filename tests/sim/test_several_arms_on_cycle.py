"""walk_scene's ``on_cycle(arm, record)`` hook (sim.several_arms): every logged cycle of every
arm, named, in order (what the live view of several arms draws)."""

from __future__ import annotations

from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.sim.scene_experiments import scene_trajectories
from wristmark.sim.scene_setup import load_scene_setup
from wristmark.sim.several_arms import walk_scene


def test_on_cycle_gets_every_logged_cycle_of_every_arm() -> None:
    setup = load_scene_setup(CONFIG_DIR / "scenes" / "two_arms.yaml",
                             controller=CONFIG_DIR / "controller_encoders.yaml")
    seen: list[tuple[str, CycleRecord]] = []
    walk = walk_scene(setup, scene_trajectories(setup, duration=0.3), False, "open_loop",
                      on_cycle=lambda name, rec: seen.append((name, rec)))
    for name in ("a", "b"):
        got = [rec for n, rec in seen if n == name]
        logged = walk.arms[name].log.records
        assert got and len(got) == len(logged) and all(a is b for a, b in zip(got, logged))
    assert [n for n, _ in seen[:4]] == ["a", "b", "a", "b"]  # lockstep, in the scene's order
