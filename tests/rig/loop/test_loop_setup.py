"""rig/loop/loop_setup.py: one source of truth per parameter when the loop's files are loaded together:
the cycle time is the rig file's ``control_dt`` (a controller file's ``dt`` must agree), the tip
offset the marker file's (a robot file's must agree); a mismatch names the file to fix."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from wristmark.models.errors import ConfigError
from wristmark.rig.loop.loop_setup import load_loop_setup

ROOT = Path(__file__).resolve().parents[3]


def _file(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def test_the_shipped_files_define_the_cycle_once() -> None:
    from wristmark.models.config_files import default_config
    from wristmark.models.config_io import load_yaml

    assert "control_dt" in load_yaml(default_config("rig.yaml"))["loop"]
    for name in ("controller.yaml", "controller_backlash.yaml"):
        assert "dt" not in load_yaml(default_config(name))["controller"], name
    setup = load_loop_setup()
    assert setup.controller.dt == setup.rig.control_dt
    assert setup.params.tip_offset == setup.marker.tip_offset


def test_the_controller_runs_at_the_loops_cycle(tmp_path: Path) -> None:
    rig = _file(tmp_path, "rig.yaml", "control_dt: 0.05\nvision_latency: 0.03\nframe_wait: 0.02\n")
    ctrl = _file(tmp_path, "ctrl.yaml", "controller:\n  kind: paper\n")
    setup = load_loop_setup(rig=rig, controller=ctrl)
    assert setup.rig.control_dt == 0.05 and setup.controller.dt == 0.05 and setup.controller.kind == "paper"


def test_a_controller_dt_that_disagrees_is_refused_naming_the_file(tmp_path: Path) -> None:
    rig = _file(tmp_path, "rig.yaml", "control_dt: 0.05\nvision_latency: 0.03\nframe_wait: 0.02\n")
    ctrl = _file(tmp_path, "my_controller.yaml", "controller:\n  dt: 0.06\n")
    with pytest.raises(ConfigError) as e:
        load_loop_setup(rig=rig, controller=ctrl)
    msg = str(e.value)
    assert msg.startswith(str(ctrl)) and str(rig) in msg and "'dt'" in msg and "control_dt" in msg


def test_the_loop_carries_the_markers_tip_offset(tmp_path: Path) -> None:
    marker = _file(tmp_path, "marker.yaml", "radius: 0.00455\ncolumns: 12\nrow_height: 0.0025\ntip_offset: 0.02\n")
    setup = load_loop_setup(marker=marker)
    assert setup.marker.tip_offset == 0.02 and setup.params.tip_offset == 0.02


def test_a_robot_tip_offset_that_disagrees_is_refused_naming_the_file(tmp_path: Path) -> None:
    robot = _file(tmp_path, "robot_old.yaml", "tip_offset: 0.012\n")
    with pytest.raises(ConfigError, match="robot_old.yaml: 'tip_offset'"):
        load_loop_setup(robot=robot)


def test_the_experiment_command_refuses_a_cycle_mismatch_in_one_line(tmp_path: Path) -> None:
    rig = _file(tmp_path, "rig_fast.yaml", "control_dt: 0.04\nvision_latency: 0.03\nframe_wait: 0.02\n")
    ctrl = _file(tmp_path, "ctrl_60ms.yaml", "controller:\n  kind: qp\n  dt: 0.06\n")
    r = subprocess.run([sys.executable, "-m", "wristmark", "experiment", "cube", "--rig", str(rig),
                        "--controller-config", str(ctrl), "--out", str(tmp_path / "run")], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{ctrl}: 'dt'" in err[-1] and str(rig) in err[-1]
    assert not (tmp_path / "run" / "log.csv").exists()


def test_the_run_record_camera_is_the_calibration_mapping_and_reads_back() -> None:
    """config.json's camera is written and read by the calibration's own mapping functions."""
    import numpy as np

    from wristmark.cvs.calibration.load import calibration_from_mapping, calibration_mapping

    setup = load_loop_setup()
    recorded = setup.describe()["camera"]
    assert recorded == calibration_mapping(setup.camera)
    back = calibration_from_mapping(recorded, "config.json")
    assert back.image_size == setup.camera.image_size
    for a, b in ((back.left.K, setup.camera.left.K), (back.right.dist, setup.camera.right.dist),
                 (back.R, setup.camera.R), (back.T, setup.camera.T), (back.T_world_left, setup.camera.T_world_left)):
        np.testing.assert_array_equal(a, b)
