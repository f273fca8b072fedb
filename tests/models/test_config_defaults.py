"""One default, stated once (issue "The front door", item 4): every configuration dataclass
constructed with no arguments equals the shipped file that states its default, field by field;
and a key that no file states takes that one default (there is no second table of defaults)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from wristmark.models.config_files import default_config
from wristmark.models.config_io import from_mapping
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams, load_robot
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.sim.plant_params import PlantParams
from wristmark.solvers.controller import ControllerConfig

# ControllerConfig() and RigConfig() before their defaults became controller.yaml's and rig.yaml's
# (written out from the dataclasses at commit 4c350e2): what a key a file leaves out has always meant.
OLD_CONTROLLER_DEFAULTS: dict[str, Any] = {
    "kind": "qp", "dt": 0.06, "v_xlim": 0.02, "gamma": 1e-06, "xi": 0.001, "saturate_near_target": False,
    "lock_saturated_joints": True, "kp": 8.0, "max_correction_speed": 0.02, "feed_forward": True, "damping": 0.001,
    "lever": 0.05, "orientation_weight": 0.001, "position_weight": 1.0, "pose_orientation_weight": 0.001, "kr": 8.0,
    "max_angular_speed": 0.5, "qp_solver": "daqp", "ki": 0.0, "integral_speed_limit": 0.003, "integral_mode": "plain",
    "backlash_compensation": False, "backlash_play_max": [0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00016],
    "backlash_start": 0.25, "backlash_fraction": 0.5, "backlash_hysteresis": 0.1, "backlash_learning": True,
    "backlash_window": 0.4, "backlash_learning_rate": 0.3, "backlash_lead": 0.0, "backlash_method": "schmitt",
    "backlash_margin": 0.02, "backlash_freeze": 0.0, "backlash_motor_burst": False, "backlash_kinds": ["paper", "qp"],
    "play_probe": False, "play_probe_amplitude": 2.0, "play_probe_time": 0.6, "play_probe_settle": 0.6,
    "play_probe_learning": True,
}
OLD_RIG_DEFAULTS: dict[str, Any] = {
    "control_dt": 0.06, "vision_latency": 0.045, "plant_dt": 0.001, "sensor": "vision", "truth_noise_rms": 0.0002,
    "image_scale": 1.0, "render_noise": "default", "tracker_rms": 0.00012, "gate": 0.004, "model_gate": 0.025,
    "max_lost_cycles": 25, "settle_time": 1.5, "feedforward_preview": 0.035, "feedforward_lead": 0.06, "seed": 0,
    "realtime": False, "frame_wait": 0.04, "delay_compensation": True, "delay_compensation_tau": 0.0,
    "delay_compensation_learn_window": 5.0, "tracking_budget": 0.15, "command_phase": 0.0,
    "reuse_measurement_age": 0.0, "frame_phase_lock": "none", "frame_lock_phase": 0.0, "frame_age": 0.0,
}


def differences(expected: Any, got: Any) -> list[str]:
    """The fields where two configurations of one dataclass differ, one line each."""
    return [f"{f.name}: {getattr(expected, f.name)!r} != {getattr(got, f.name)!r}"
            for f in dataclasses.fields(expected) if getattr(expected, f.name) != getattr(got, f.name)]


def _marker() -> MarkerModel:
    return MarkerModel.load(default_config("marker.yaml"))


# (dataclass, its default file, how the command line loads that file)
DEFAULT_FILES = {
    "controller": (ControllerConfig, "controller.yaml", ControllerConfig.load),
    "rig": (RigConfig, "rig.yaml", RigConfig.load),
    "robot": (RobotParams, "robot.yaml", lambda p: load_robot(p, _marker())),
    "marker": (MarkerModel, "marker.yaml", MarkerModel.load),
    # the plant's default is the ideal arm (every error zero, docs/configuration.md); the command
    # line's default plant.yaml is the reference simulated arm, a deliberate set of errors
    "plant": (PlantParams, "plant_ideal.yaml", PlantParams.load),
}


@pytest.mark.parametrize("kind", sorted(DEFAULT_FILES))
def test_the_dataclass_default_is_its_shipped_file(kind: str) -> None:
    cls, name, load = DEFAULT_FILES[kind]
    diff = differences(cls(), load(default_config(name)))
    assert not diff, f"{cls.__name__}() (left) differs from configs/{name} (right) in: " + "; ".join(diff)


def test_the_default_controller_runs_at_the_default_loops_cycle() -> None:
    assert ControllerConfig().dt == RigConfig().control_dt


def test_the_default_plant_file_states_every_error() -> None:
    """plant.yaml (the command line's default arm) states each error it has; only the camera is
    where the calibration says."""
    plant = PlantParams.load(default_config("plant.yaml"))
    ideal = PlantParams()
    same = [f.name for f in dataclasses.fields(PlantParams) if getattr(plant, f.name) == getattr(ideal, f.name)]
    assert same == ["segment_stiffness", "camera_offset"]


@pytest.mark.parametrize("cls", [ControllerConfig, RigConfig])
def test_a_file_that_states_nothing_means_the_defaults(tmp_path: Path, cls: Any) -> None:
    f = tmp_path / "empty.yaml"
    f.write_text("{}\n")
    diff = differences(cls(), cls.load(f))
    assert not diff, f"an empty {cls.__name__} file is not the default: " + "; ".join(diff)


@pytest.mark.parametrize("cls", [ControllerConfig, RigConfig])
def test_the_old_defaults_are_no_longer_the_defaults(cls: Any) -> None:
    """The defaults did change when they became the shipped files' (CHANGELOG): a test that
    cannot fail if the old table came back would prove nothing above."""
    old = OLD_CONTROLLER_DEFAULTS if cls is ControllerConfig else OLD_RIG_DEFAULTS
    assert differences(from_mapping(cls, old), cls())


def test_a_partial_flat_controller_file_takes_the_defaults_for_the_rest(tmp_path: Path) -> None:
    """A user's file of the flat format stating a few keys: the rest are controller.yaml's."""
    f = tmp_path / "mine.yaml"
    f.write_text("controller:\n  kind: qp\n  backlash_compensation: true\n  backlash_method: encoders\n  ki: 2.0\n")
    expected = dataclasses.replace(ControllerConfig.load(default_config("controller.yaml")), backlash_compensation=True,
                                   backlash_method="encoders", ki=2.0)
    diff = differences(expected, ControllerConfig.load(f))
    assert not diff, "; ".join(diff)


def test_a_partial_flat_rig_file_takes_the_defaults_for_the_rest(tmp_path: Path) -> None:
    f = tmp_path / "rig.yaml"
    f.write_text("sensor: truth-noise\ncontrol_dt: 0.05\nvision_latency: 0.03\n")
    expected = dataclasses.replace(RigConfig.load(default_config("rig.yaml")), sensor="truth-noise", control_dt=0.05,
                                   vision_latency=0.03)
    diff = differences(expected, RigConfig.load(f))
    assert not diff, "; ".join(diff)
