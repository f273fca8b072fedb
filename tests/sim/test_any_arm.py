"""Every shipped arm (configs/robots/*.yaml) runs the cube on the simulated bench with its own
plant file: a short walk with fast settings (the truth-noise sensor) closes the loop
(closed-loop error below the open loop's), and the run's log and result name the arm's joints."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import pytest

from wristmark.models.arm_spec import ArmSpec, shipped_robot_files
from wristmark.models.errors import ConfigError
from wristmark.sim.experiments import run_cube
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.setup import load_setup

ARMS = shipped_robot_files()


@pytest.mark.slow
@pytest.mark.parametrize("robot", ARMS, ids=[p.stem for p in ARMS])
def test_a_short_cube_closes_the_loop(robot: Path, tmp_path: Path) -> None:
    setup = load_setup(robot=robot)
    assert isinstance(setup.params, ArmSpec)
    rig = dataclasses.replace(setup.rig, sensor="truth-noise", settle_time=0.5)
    res = run_cube(setup.with_changes(rig=rig), tmp_path, progress=False, duration=8.0)
    assert not res["closed_loop"]["stopped"]
    assert res["closed_loop"]["mean_mm"] < res["open_loop"]["mean_mm"]
    assert res["arm"]["configuration"] == list(setup.params.names)
    assert res["arm"]["actuators"] == list(setup.params.actuator_names)
    with open(tmp_path / "log.csv", newline="") as f:
        header = next(csv.reader(f))
    assert [c for c in header if c.startswith("psi_cmd_")] == [f"psi_cmd_{n}" for n in setup.params.names]


def test_each_shipped_arm_has_its_plant_file() -> None:
    for robot in ARMS:
        if robot.stem == "paper":
            continue  # the paper arm keeps configs/plant.yaml
        setup = load_setup(robot=robot)
        assert setup.sources["plant"].endswith(f"{robot.stem}_plant.yaml")


def test_a_plant_file_sized_for_another_arm_is_refused_naming_the_key(tmp_path: Path) -> None:
    bad = tmp_path / "plant.yaml"
    bad.write_text("bend_gain: [0.98, 0.95]\n")
    with pytest.raises(ConfigError, match=r"'bend_gain' must have 3 entries \(one per segment of the arm\), got 2"):
        load_setup(robot=[p for p in ARMS if p.stem == "tendon3"][0], plant=bad)
    with pytest.raises(ConfigError, match=r"'backlash' must have 10 entries \(one per actuator of the arm\)"):
        PlantParams(backlash=(0.0, 0.0)).for_arm(3, 10)


def test_the_v1_actuator_box_refuses_an_arm_of_another_actuator_count() -> None:
    from wristmark.rig.link.actuator_driver import check_protocol_arm

    setup = load_setup(robot=[p for p in ARMS if p.stem == "tendon3"][0])
    with pytest.raises(ConfigError, match=r"protocol v1, which carries 6 actuators; this arm has 10 .*servo --direct"):
        check_protocol_arm(setup.params)
