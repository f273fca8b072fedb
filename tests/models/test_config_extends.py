"""`extends` (docs/configuration.md): a configuration file states only what differs from the file
it is laid on. The shipped variants, rewritten as overlays, load to exactly what their old full
files gave (the old files' contents below, as they were at commit 4c350e2); the merge, its
refusals, every kind of file and the sweep's dotted keys."""
# ruff: noqa: E501  (the old files' long comment lines, kept as they were)

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tests.old_defaults import OLD_CONTROLLER
from wristmark.cvs.calibration.load import load_calibration
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.models.config_io import extends_chain, from_mapping, load_layered, merge_mappings
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams, load_robot
from wristmark.rig.loop.loop_setup import load_loop_setup
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.render.settings import RenderSettings
from wristmark.solvers.controller import ControllerConfig, flat_controller_mapping

OLD_FILES = {
    "controller_plain.yaml": """\
# The qp without dead-band inversion or tip-error integral: the default configs/controller.yaml
# before the play probe (docs/results.md). kind: paper (eq. 17-21) | qp (velocity-bounded QP). SI units.
controller:
  kind: qp
  # the servo cycle is the loop's: rig.yaml control_dt (a dt here must agree with it)
  # paper
  v_xlim: 0.020              # constant tip speed of eq. 18 [m/s]
  gamma: 1.0e-6              # damping of eq. 20 [(m/s)^2-scale, J J^T units]
  xi: 1.0e-3                 # damp when the smallest singular value is below this
  saturate_near_target: false  # true: speed min(v_xlim, |dp|/dt) (not in the paper)
  lock_saturated_joints: true  # re-solve without a joint the step would push through its limit (not in the paper)
  # qp
  kp: 8.0                    # proportional gain on the tip error [1/s]
  max_correction_speed: 0.02 # cap of the feedback velocity [m/s]
  feed_forward: true         # add the desired path velocity
  damping: 1.0e-3            # weight of ||S psi_dot||^2 [-]
  lever: 0.05                # S: tip metres per joint radian [m/rad]
  orientation_weight: 1.0e-3 # keep the tip frame's orientation [m^2/rad^2]
  qp_solver: daqp            # daqp | qpoases
  # integral of the tip error in the qp's task (solvers/tip_integral.py); 0 = off
  ki: 0.0                    # [1/s^2]
  integral_speed_limit: 0.003  # cap of the integral's velocity [m/s]
  # dead-band (backlash) inversion, both kinds (solvers/backlash_compensation.py)
  backlash_compensation: false  # on: configs/controller.yaml (the default), controller_encoders.yaml, controller_backlash.yaml
  backlash_play_max: [0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00016]  # largest play assumed [rad, m x5]
  backlash_start: 0.25       # initial estimate / play_max
  backlash_fraction: 0.5     # share of the estimate inverted (the feedback covers the rest; the estimate errs high)
  backlash_hysteresis: 0.1   # the command must come back this x play_max to count as reversed
  backlash_learning: true    # learn the play at every reversal from the feedback's share of the command
  backlash_window: 0.4       # [s] either side of a reversal
  backlash_learning_rate: 0.3  # step towards each reversal's estimate
  backlash_lead: 0.0         # [s] lead on the offset (configs/controller_backlash.yaml: 0.03)
  backlash_method: schmitt   # schmitt | encoders (the play tracked from the encoders: configs/controller_encoders.yaml)
  backlash_margin: 0.02      # encoders: the command must leave the tracked band by this x play_max to change side
  backlash_kinds: [paper, qp]  # the controller kinds the inversion applies to
""",
    "controller_encoders.yaml": """\
# As controller.yaml (the default) without the play probe: the play tracked from the encoders
# (solvers/play_observer.py) is learnt online at the reversals only (docs/results.md, "the play
# tracked from the encoders"). SI units.
controller:
  kind: qp
  # the servo cycle is the loop's: rig.yaml control_dt (a dt here must agree with it)
  # paper
  v_xlim: 0.020              # constant tip speed of eq. 18 [m/s]
  gamma: 1.0e-6              # damping of eq. 20 [(m/s)^2-scale, J J^T units]
  xi: 1.0e-3                 # damp when the smallest singular value is below this
  saturate_near_target: false  # true: speed min(v_xlim, |dp|/dt) (not in the paper)
  lock_saturated_joints: true  # re-solve without a joint the step would push through its limit (not in the paper)
  # qp
  kp: 8.0                    # proportional gain on the tip error [1/s]
  max_correction_speed: 0.02 # cap of the feedback velocity [m/s]
  feed_forward: true         # add the desired path velocity
  damping: 1.0e-3            # weight of ||S psi_dot||^2 [-]
  lever: 0.2                 # S: tip metres per joint radian [m/rad] (0.2: fewer stem/bend reversals through their play)
  orientation_weight: 1.0e-3 # keep the tip frame's orientation [m^2/rad^2]
  qp_solver: daqp            # daqp | qpoases
  # integral of the tip error in the qp's task (solvers/tip_integral.py); 0 = off
  ki: 4.0                    # [1/s^2] (lowers the mean on an arm with gain errors; docs/results.md, "encoders")
  integral_speed_limit: 0.003  # cap of the integral's velocity [m/s]
  # dead-band (backlash) inversion, both kinds (solvers/backlash_compensation.py)
  backlash_compensation: true
  backlash_play_max: [0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00016]  # largest play assumed [rad, m x5]
  backlash_start: 0.15       # initial estimate / play_max (low: an arm with little play is not over-compensated while it learns)
  backlash_fraction: 0.75    # share of the estimate inverted (the feedback covers the rest; the estimate errs high)
  backlash_hysteresis: 0.1   # schmitt: the command must come back this x play_max to count as reversed
  backlash_learning: true    # learn the play at every reversal from the feedback's share of the command
  backlash_window: 0.4       # [s] either side of a reversal
  backlash_learning_rate: 0.3  # step towards each reversal's estimate
  backlash_lead: 0.03        # [s] lead on the offset: a reversal crosses the play in a one-cycle burst (0 = none)
  # encoders: the play's output tracked from the encoders (solvers/play_observer.py); schmitt: a
  # Schmitt trigger on the command (configs/controller_backlash.yaml)
  backlash_method: encoders
  backlash_margin: 0.01      # encoders: the command must leave the tracked band by this x play_max to change side
  backlash_kinds: [qp]       # the kinds it applies to (the paper controller is not helped: docs/results.md)
  play_probe: false          # the play learnt online only (configs/controller.yaml probes it first)
  backlash_freeze: 0.0       # (controller.yaml: 0.5 s)
""",
    "controller_backlash.yaml": """\
# The Schmitt-trigger dead-band inversion (docs/results.md, "Unseen arms"); the default
# configs/controller.yaml tracks the play from the encoders instead (and probes it first). SI units.
controller:
  kind: qp
  # the servo cycle is the loop's: rig.yaml control_dt (a dt here must agree with it)
  # paper
  v_xlim: 0.020              # constant tip speed of eq. 18 [m/s]
  gamma: 1.0e-6              # damping of eq. 20 [(m/s)^2-scale, J J^T units]
  xi: 1.0e-3                 # damp when the smallest singular value is below this
  saturate_near_target: false  # true: speed min(v_xlim, |dp|/dt) (not in the paper)
  lock_saturated_joints: true  # re-solve without a joint the step would push through its limit (not in the paper)
  # qp
  kp: 8.0                    # proportional gain on the tip error [1/s]
  max_correction_speed: 0.02 # cap of the feedback velocity [m/s]
  feed_forward: true         # add the desired path velocity
  damping: 1.0e-3            # weight of ||S psi_dot||^2 [-]
  lever: 0.2                 # S: tip metres per joint radian [m/rad] (0.2: fewer stem/bend reversals through their play)
  orientation_weight: 1.0e-3 # keep the tip frame's orientation [m^2/rad^2]
  qp_solver: daqp            # daqp | qpoases
  # integral of the tip error in the qp's task (solvers/tip_integral.py); 0 = off
  ki: 0.0                    # [1/s^2]
  integral_speed_limit: 0.003  # cap of the integral's velocity [m/s]
  # dead-band (backlash) inversion, both kinds (solvers/backlash_compensation.py)
  backlash_compensation: true
  backlash_play_max: [0.012, 0.0002, 0.00016, 0.00016, 0.00016, 0.00016]  # largest play assumed [rad, m x5]
  backlash_start: 0.15       # initial estimate / play_max (low: an arm with little play is not over-compensated while it learns)
  backlash_fraction: 0.75    # share of the estimate inverted (the feedback covers the rest; the estimate errs high)
  backlash_hysteresis: 0.1   # the command must come back this x play_max to count as reversed
  backlash_learning: true    # learn the play at every reversal from the feedback's share of the command
  backlash_window: 0.4       # [s] either side of a reversal
  backlash_learning_rate: 0.3  # step towards each reversal's estimate
  backlash_lead: 0.03        # [s] lead on the offset: a reversal crosses the play in a one-cycle burst (0 = none)
  backlash_method: schmitt   # a Schmitt trigger on the command (configs/controller_encoders.yaml: encoders)
""",
    "plant_misplaced_camera.yaml": """\
# The default simulated arm (configs/plant.yaml) with the endoscope not where the calibration
# says: the true camera sits at world_T_left @ T(camera_offset), offset in {ll}
# [x, y, z (m), rotation vector (rad)]: 5.8 mm and 3.2 deg. The closed loop then converges to
# the wrong place until `wristmark register --plant configs/plant_misplaced_camera.yaml`
# finds the camera (docs/calibration.md: segment 1's plane offset o1 = 0.01 rad below is not
# observable by a camera registration and stays in it as a 0.57 deg turn about z_w).
bend_gain: [0.98, 0.945]
plane_offset: [0.01, -0.02]
stem_coupling: 0.038
backlash: [0.008, 0.0001, 0.00003, 0.00003, 0.00003, 0.00003]
actuator_tau: 0.04
tip_force: [0.0, 0.0, -0.03]
segment_stiffness: [0.40, 0.15]
camera_offset: [0.004, 0.003, -0.003, -0.03, 0.035, 0.03]
""",
}

def old_controller(path: Path) -> ControllerConfig:
    """An old full controller file as it loaded at 4c350e2: a key it does not state (one added
    after it was written) took the dataclass default of then (tests/old_defaults.py)."""
    data = load_layered(path, "controller", flat_controller_mapping)
    return from_mapping(ControllerConfig, {**OLD_CONTROLLER, **data}, str(path))


# the old full file's loader (as of 4c350e2) and the overlay's loader (today's)
LOADERS: dict[str, tuple[Callable[[Path], Any], Callable[[Path], Any]]] = {
    "controller_plain.yaml": (old_controller, ControllerConfig.load),
    "controller_encoders.yaml": (old_controller, ControllerConfig.load),
    "controller_backlash.yaml": (old_controller, ControllerConfig.load),
    "plant_misplaced_camera.yaml": (PlantParams.load, PlantParams.load),
}


def differences(expected: Any, got: Any) -> list[str]:
    return [f"{f.name}: {getattr(expected, f.name)!r} != {getattr(got, f.name)!r}"
            for f in dataclasses.fields(expected) if getattr(expected, f.name) != getattr(got, f.name)]


@pytest.mark.parametrize("name", sorted(OLD_FILES))
def test_each_shipped_overlay_loads_to_what_its_old_full_file_gave(name: str, tmp_path: Path) -> None:
    old = tmp_path / name
    old.write_text(OLD_FILES[name])
    assert "extends" not in yaml.safe_load(OLD_FILES[name])
    assert "extends" in (CONFIG_DIR / name).read_text()
    load_old, load_new = LOADERS[name]
    diff = differences(load_old(old), load_new(default_config(name)))
    assert not diff, f"configs/{name} no longer means its old full file: " + "; ".join(diff)


def test_the_overlays_state_only_what_differs() -> None:
    """controller_encoders.yaml: a handful of keys, not a copy of controller.yaml."""
    raw = yaml.safe_load((CONFIG_DIR / "controller_encoders.yaml").read_text())
    own = {k: v for section in raw["controller"].values() for k, v in section.items()}
    assert len(own) <= 6
    assert ControllerConfig.load(CONFIG_DIR / "controller_encoders.yaml") == dataclasses.replace(ControllerConfig(), **own)


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_mappings_merge_and_everything_else_replaces() -> None:
    base = {"a": 1, "m": {"x": 1, "y": [1, 2], "n": {"p": 1}}, "l": [1, 2, 3]}
    over = {"m": {"y": [3], "n": {"q": 2}}, "l": [9], "b": 2}
    assert merge_mappings(base, over) == {"a": 1, "m": {"x": 1, "y": [3], "n": {"p": 1, "q": 2}}, "l": [9], "b": 2}
    assert base["m"]["n"] == {"p": 1}  # the base is not changed


def test_extends_a_file_next_to_it_and_the_base_extends_on(tmp_path: Path) -> None:
    write(tmp_path / "a.yaml", "controller:\n  kind: paper\n  v_xlim: 0.01\n  extends: controller.yaml\n")
    write(tmp_path / "b.yaml", "extends: a.yaml\ncontroller:\n  v_xlim: 0.03\n")
    got = ControllerConfig.load(tmp_path / "b.yaml")
    assert got == dataclasses.replace(ControllerConfig(), kind="paper", v_xlim=0.03)
    assert extends_chain(tmp_path / "b.yaml") == [tmp_path / "b.yaml", tmp_path / "a.yaml", CONFIG_DIR / "controller.yaml"]


def test_a_flat_overlay_on_a_sectioned_base_and_back(tmp_path: Path) -> None:
    write(tmp_path / "flat.yaml", "extends: controller.yaml\nki: 1.0\n")
    write(tmp_path / "sectioned.yaml", "extends: flat.yaml\ncontroller:\n  kp: 5.0\n")
    assert ControllerConfig.load(tmp_path / "sectioned.yaml") == dataclasses.replace(ControllerConfig(), ki=1.0, kp=5.0)


def test_a_shipped_name_with_or_without_configs_and_a_file_named_like_it(tmp_path: Path) -> None:
    for name in ("plant.yaml", "configs/plant.yaml"):
        f = write(tmp_path / "p.yaml", f"extends: {name}\nactuator_tau: 0.05\n")
        assert PlantParams.load(f) == dataclasses.replace(PlantParams.load(default_config("plant.yaml")),
                                                          actuator_tau=0.05)
    own = write(tmp_path / "mine" / "controller.yaml", "extends: controller.yaml\ncontroller:\n  play_probe: false\n")
    assert ControllerConfig.load(own) == dataclasses.replace(ControllerConfig(), play_probe=False)


def test_a_file_next_to_it_wins_over_a_shipped_one(tmp_path: Path) -> None:
    write(tmp_path / "plant.yaml", "actuator_tau: 0.01\n")
    f = write(tmp_path / "p.yaml", "extends: plant.yaml\nstem_coupling: 0.1\n")
    assert PlantParams.load(f) == PlantParams(actuator_tau=0.01, stem_coupling=0.1)


@pytest.mark.parametrize("files, words", [
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "extends: a.yaml\n"}, ["a.yaml", "circle", "b.yaml"]),
    ({"a.yaml": "extends: a.yaml\nkind: qp\n"}, ["a.yaml", "circle"]),
    ({"a.yaml": "extends: nowhere.yaml\n"}, ["a.yaml", "nowhere.yaml", "names no file"]),
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "extends: nowhere.yaml\n"}, ["b.yaml", "nowhere.yaml"]),
    ({"a.yaml": "extends: [controller.yaml]\n"}, ["a.yaml", "'extends' must name"]),
    ({"a.yaml": "extends: controller.yaml\ncontroller:\n  extends: controller.yaml\n"}, ["a.yaml", "twice"]),
    ({"a.yaml": "extends: b.yaml\n", "b.yaml": "controller: [\n"}, ["b.yaml", "not valid YAML"]),
    ({"a.yaml": "extends: controller.yaml\ncontroller:\n  bogus: 1\n"}, ["a.yaml", "unknown key 'bogus'"]),
])
def test_a_bad_chain_is_one_line_naming_the_file(tmp_path: Path, files: dict[str, str], words: list[str]) -> None:
    for name, text in files.items():
        write(tmp_path / name, text)
    with pytest.raises(ConfigError) as e:
        ControllerConfig.load(tmp_path / "a.yaml")
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_a_chain_too_long_is_refused(tmp_path: Path) -> None:
    for i in range(20):
        write(tmp_path / f"c{i}.yaml", f"extends: c{i + 1}.yaml\n" if i < 19 else "kind: qp\n")
    with pytest.raises(ConfigError, match="more than 16 files"):
        ControllerConfig.load(tmp_path / "c0.yaml")


def test_every_kind_of_file_extends(tmp_path: Path) -> None:
    marker = MarkerModel.load(default_config("marker.yaml"))
    robot = write(tmp_path / "robot.yaml", "extends: robot.yaml\nrobot:\n  rigid_length: 0.012\n")
    assert load_robot(robot, marker) == dataclasses.replace(RobotParams(), rigid_length=0.012)
    with pytest.raises(ConfigError, match="tip_offset"):  # the marker's, also through a base
        write(tmp_path / "tip.yaml", "tip_offset: 0.02\n")
        load_robot(write(tmp_path / "r2.yaml", "extends: tip.yaml\n"), marker)
    m = write(tmp_path / "m.yaml", "extends: marker_coded.yaml\ntip_offset: 0.02\n")
    coded = MarkerModel.load(default_config("marker_coded.yaml"))
    assert MarkerModel.load(m) == dataclasses.replace(coded, tip_offset=0.02)
    cam = write(tmp_path / "cam.yaml", "extends: camera.yaml\nworld_T_left:\n"
                "- [1, 0, 0, 0]\n- [0, 1, 0, 0]\n- [0, 0, 1, 0.1]\n- [0, 0, 0, 1]\n")
    got, shipped = load_calibration(cam), load_calibration(default_config("camera.yaml"))
    assert np.array_equal(got.left.K, shipped.left.K) and np.array_equal(got.R, shipped.R)
    assert got.T_world_left is not None and got.T_world_left[2][3] == 0.1
    rig = write(tmp_path / "rig.yaml", "extends: rig.yaml\nsensor: truth-noise\n")
    assert RigConfig.load(rig) == dataclasses.replace(RigConfig(), sensor="truth-noise")
    settings = write(tmp_path / "render.yaml", "read_noise: 0.5\n")
    assert RenderSettings.load(write(tmp_path / "r.yaml", "extends: render.yaml\ncolour: false\n")) == \
        dataclasses.replace(RenderSettings(), read_noise=0.5, colour=False)
    assert settings.is_file()


def test_a_controller_dt_in_a_base_file_is_checked_against_the_loops_cycle(tmp_path: Path) -> None:
    write(tmp_path / "base.yaml", "extends: controller.yaml\ncontroller:\n  dt: 0.05\n")
    c = write(tmp_path / "c.yaml", "extends: base.yaml\ncontroller:\n  kp: 6.0\n")
    with pytest.raises(ConfigError, match="'dt' .0.05 s. disagrees with 'control_dt'"):
        load_loop_setup(controller=c)


def test_a_sweeps_dotted_key_changes_the_resolved_file(tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec

    ctrl = write(tmp_path / "ctrl.yaml", "extends: controller_encoders.yaml\ncontroller:\n  kp: 6.0\n")
    spec = write(tmp_path / "s.yaml", yaml.safe_dump({
        "experiment": "cube", "set": {"sensor": "truth-noise", "controller_config": str(ctrl)},
        "grid": {"controller.ki": [1.0, 2.0], "plant.backlash.0": [0.01]}}))
    s = load_spec(spec)
    encoders = ControllerConfig.load(default_config("controller_encoders.yaml"))
    for t, ki in zip(s.trials, (1.0, 2.0)):
        assert ControllerConfig(**{**t.configs["controller"], "backlash_play_max": tuple(
            t.configs["controller"]["backlash_play_max"]), "backlash_kinds": tuple(t.configs["controller"]["backlash_kinds"])}) \
            == dataclasses.replace(encoders, kp=6.0, ki=ki)
        assert t.configs["plant"]["backlash"][0] == 0.01 and t.configs["plant"]["actuator_tau"] == 0.04


def test_the_sweeps_fingerprint_follows_a_base_file(tmp_path: Path) -> None:
    from wristmark.sweep.spec import load_spec

    base = write(tmp_path / "base.yaml", (CONFIG_DIR / "plant.yaml").read_text())
    plant = write(tmp_path / "plant_x.yaml", "extends: base.yaml\nstem_coupling: 0.04\n")
    spec = write(tmp_path / "s.yaml", yaml.safe_dump({
        "experiment": "cube", "set": {"sensor": "truth-noise", "plant": str(plant)}, "grid": {"latency": [0.03]}}))
    first = load_spec(spec).fingerprint()
    base.write_text(base.read_text().replace("actuator_tau: 0.04", "actuator_tau: 0.05"))
    assert load_spec(spec).fingerprint() != first
