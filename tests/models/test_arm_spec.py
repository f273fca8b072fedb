"""models.arm_spec: the format-2 robot file, its validation, and the flat file read as an ArmSpec."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from wristmark.models.arm_spec import ArmSpec, load_arm, robot_file_format, shipped_robot_files
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import ConfigError, WristmarkError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams

ROBOTS = CONFIG_DIR / "robots"
SHIPPED = [p.name for p in shipped_robot_files()]  # not their <name>_plant.yaml

BASE = {
    "format": 2,
    "name": "probe",
    "stem": [{"joint": "revolute_z", "name": "phi", "range": [-3.0, 3.0], "max_velocity": 1.0},
             {"joint": "prismatic_z", "name": "d", "range": [0.0, 0.1], "max_velocity": 0.02}],
    "segments": [
        {"length": 0.05, "theta_max": 1.5, "max_velocity": [1.0, 4.0],
         "actuation": {"type": "push_pull", "pitch_radius": 0.002, "angles": [0.0, 1.5707963267948966]}},
        {"spacer": 0.01, "length": 0.02, "theta_max": 2.0, "max_velocity": [2.0, 6.0],
         "actuation": {"type": "tendons", "pitch_radius": 0.0025, "angles": [0.0, 2.0944, 4.1888]}},
    ],
    "marker_offset": 0.005,
    "outer_diameter": 0.0074,
}


def _write(tmp_path: Path, data: dict) -> Path:  # type: ignore[type-arg]
    p = tmp_path / "arm.yaml"
    p.write_text(yaml.safe_dump(json.loads(json.dumps(data))))  # fresh objects: no YAML anchors
    return p


def test_the_flat_reference_file_reads_as_an_armspec() -> None:
    spec = load_arm(CONFIG_DIR / "robot.yaml")
    assert spec == ArmSpec.from_params(RobotParams())
    assert (spec.n, spec.m) == (6, 6)
    assert spec.names == ("phi", "d", "theta1", "delta1", "theta2", "delta2")
    assert spec.actuator_names == ("phi", "d", "s1a", "s1b", "s2a", "s2b")
    lo, hi = spec.bounds()
    p = RobotParams()
    np.testing.assert_array_equal(lo, [-math.pi, 0, 0, -np.inf, 0, -np.inf])
    np.testing.assert_array_equal(hi, [math.pi, 0.15, p.theta_max[0], np.inf, p.theta_max[1], np.inf])
    np.testing.assert_array_equal(spec.velocity_limits(), p.max_velocity)


def test_paper_yaml_is_the_reference_arm() -> None:
    assert replace(load_arm(ROBOTS / "paper.yaml"), name="reference") == ArmSpec.from_params(RobotParams())


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_arms_load(name: str) -> None:
    spec = load_arm(ROBOTS / name)
    assert 1 <= len(spec.segments) <= 4
    assert len(spec.names) == spec.n == len(spec.bounds()[0]) == len(spec.velocity_limits())
    assert len(spec.actuator_names) == spec.m
    assert 0.005 <= spec.outer_diameter <= 0.008  # a 5-8 mm arm


def test_shipped_set() -> None:
    assert {"paper.yaml", "tendon3.yaml", "single_tendon.yaml", "planar.yaml"} <= set(SHIPPED)


def test_marker_sets_the_tip_offset() -> None:
    assert load_arm(ROBOTS / "paper.yaml", MarkerModel(tip_offset=0.02)).tip_offset == 0.02


def test_sizes_of_a_planar_arm(tmp_path: Path) -> None:
    data = {**BASE, "stem": [], "segments": [
        {**BASE["segments"][0], "planar": 0.3, "max_velocity": [2.0]}, BASE["segments"][1],
        {**BASE["segments"][0], "spacer": 0.0, "planar": 1.0, "max_velocity": [3.0],
         "actuation": {"type": "direct"}}]}
    spec = load_arm(_write(tmp_path, data))
    assert spec.names == ("theta1", "theta2", "delta2", "theta3")
    assert (spec.n, spec.m) == (4, 2 + 3 + 1)
    assert spec.actuator_names == ("s1a", "s1b", "s2a", "s2b", "s2c", "theta3")
    assert spec.theta_index == (0, 1, 3) and spec.delta_index == (None, 2, None)
    lo, hi = spec.bounds()
    np.testing.assert_array_equal(lo, [-1.5, 0.0, -np.inf, -1.5])
    np.testing.assert_array_equal(hi, [1.5, 2.0, np.inf, 1.5])
    np.testing.assert_array_equal(spec.velocity_limits(), [2.0, 2.0, 6.0, 3.0])


def _seg(i: int, **kw: object) -> dict:  # type: ignore[type-arg]
    segs = [dict(s) for s in BASE["segments"]]
    segs[i].update(kw)
    return {**BASE, "segments": segs}


def _act(i: int, **kw: object) -> dict:  # type: ignore[type-arg]
    return _seg(i, actuation={**BASE["segments"][i]["actuation"], **kw})


def _stem(i: int, **kw: object) -> dict:  # type: ignore[type-arg]
    stem = [dict(j) for j in BASE["stem"]]
    stem[i].update(kw)
    return {**BASE, "stem": stem}


BAD = [
    ({**BASE, "segments": []}, "segments: expected 1 to 4 segments, got 0"),
    ({**BASE, "segments": BASE["segments"] * 2 + BASE["segments"][1:]}, "segments: expected 1 to 4 segments, got 5"),
    (_act(1, angles=[0.0, 2.0]), "segments[1].actuation.angles: tendons need 3 or more, got 2"),
    (_seg(0, length=-0.01), "segments[0].length: expected > 0"),
    (_seg(1, spacer=-0.01), "segments[1].spacer: expected >= 0"),
    (_seg(0, spacer=0.01), "segments[0].spacer"),
    (_seg(0, planar=0.0), "segments[0].max_velocity: expected 1 entry"),
    (_seg(1, max_velocity=[1.0]), "segments[1].max_velocity: expected 2 entries"),
    (_seg(1, max_velocity=[1.0, 0.0]), "segments[1].max_velocity[1]: expected > 0"),
    (_seg(0, theta_max=4.0), "segments[0].theta_max: expected in (0, pi]"),
    (_stem(0, joint="rotary_x"), "stem[0].joint: expected one of revolute_z, prismatic_z, got 'rotary_x'"),
    (_stem(1, name="phi"), "stem[1].name: 'phi' is given twice"),
    (_stem(1, name="theta1"), "stem[1].name: 'theta1' is given twice"),
    (_stem(1, range=[0.1, 0.0]), "stem[1].range: expected [low, high] with low < high"),
    (_stem(0, max_velocity=0), "stem[0].max_velocity: expected > 0"),
    (_act(0, type="cables"), "segments[0].actuation.type: expected one of push_pull, tendons, direct"),
    (_act(0, pitch_radius=0.0), "segments[0].actuation.pitch_radius: expected in (0, outer_diameter/2"),
    (_act(0, pitch_radius=0.01), "segments[0].actuation.pitch_radius"),
    (_act(0, angles=[0.0, 3.141592653589793]),
     "segments[0].actuation.angles: expected two angles that are not parallel"),
    (_seg(0, planar=0.0, max_velocity=[1.0], actuation={"type": "push_pull", "pitch_radius": 0.002,
                                                        "angles": [1.5707963267948966]}),
     "segments[0].actuation.angles: no actuator bends the segment in its plane"),
    (_seg(0, actuation={"type": "direct", "pitch_radius": 0.002}), "segments[0].actuation: direct actuation takes no"),
    (_seg(0, actuation={"pitch_radius": 0.002}), "segments[0].actuation.type: missing"),
    ({**BASE, "segments": [{"length": 0.05}]}, "segments[0].theta_max: missing"),
    ({**BASE, "stem": [{"joint": "revolute_z"}]}, "stem[0].name: missing"),
    (_seg(0, bend=1.0), "unknown key 'segments[0].bend'"),
    (_seg(0, length="long"), "'segments[0].length' must be a number"),
    ({**BASE, "format": 3}, "format: expected 2"),
    ({**BASE, "tip_offset": 0.015}, "tip_offset: belongs to the marker file"),
    ({**BASE, "outer_diameter": 0.0}, "outer_diameter: expected > 0"),
    ({**BASE, "marker_offset": -1.0}, "marker_offset: expected >= 0"),
    ({k: v for k, v in BASE.items() if k != "format"}, "format: expected 2"),
    ({k: v for k, v in BASE.items() if k != "segments"}, "segments: missing"),
]


@pytest.mark.parametrize("data, words", BAD, ids=[w.split(":")[0] + f"-{i}" for i, (_, w) in enumerate(BAD)])
def test_bad_files_are_one_line_errors_naming_the_key(tmp_path: Path, data: dict, words: str) -> None:  # type: ignore[type-arg]
    path = _write(tmp_path, data)
    with pytest.raises(ConfigError) as e:
        load_arm(path)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and isinstance(e.value, WristmarkError)
    assert words in msg, msg


def test_the_base_mapping_is_valid(tmp_path: Path) -> None:
    spec = load_arm(_write(tmp_path, BASE))
    assert (spec.n, spec.m, spec.name) == (6, 7, "probe")


def test_robot_file_format() -> None:
    assert robot_file_format(CONFIG_DIR / "robot.yaml") == 1
    assert all(robot_file_format(ROBOTS / name) == 2 for name in SHIPPED)


def test_built_in_code_is_validated_too() -> None:
    spec = ArmSpec.from_params(RobotParams())
    bad = replace(spec, segments=(replace(spec.segments[0], planar=math.nan, max_velocity=(1.0,)),))
    with pytest.raises(ConfigError, match=r"segments\[0\].planar: expected a finite angle"):
        bad.validate()
    with pytest.raises(ConfigError, match="segments: expected 1 to 4"):
        replace(spec, segments=()).validate()


def test_an_empty_stem_may_be_written_either_way(tmp_path: Path) -> None:
    for text in ("stem: []\n", "stem:\n"):
        path = tmp_path / "bare.yaml"
        body = yaml.safe_dump({k: v for k, v in json.loads(json.dumps(BASE)).items() if k != "stem"})
        path.write_text(text + body)
        spec = load_arm(path)
        assert spec.stem == () and spec.names == ("theta1", "delta1", "theta2", "delta2")
