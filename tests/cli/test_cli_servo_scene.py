"""`wristmark servo --scene SCENE --serial NAME=PORT ...` (or `--actuator NAME=ros2:NS ...`): bad
input is refused in one line (exit 2) before any motion command: options that mean nothing with a
scene, a missing, unknown or repeated arm, a port or namespace given twice, serial and ROS 2 boxes
mixed, an --actuator namespace that --ros2 would publish on, a box that does not answer, a bad
--target NAME=SPEC (unknown or repeated arm, stdin for two arms, not loopback, a port taken), a
--record that is not a new .mcap file, a --model that is not NAME=MODEL.yaml of an arm."""

from __future__ import annotations

import os
import socket
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.rig.link.test_serial_link import PARAMS, PLANT, RecordingEmulator
from wristmark.cli.main import main
from wristmark.models.robot_params import HOME_PSI
from wristmark.sim.plant import TruePlant

SCENE = "configs/scenes/two_arms.yaml"
CAMERA = ["--camera", "http://127.0.0.1:9/stream.mjpg", "--calib", "configs/camera.yaml"]


@pytest.fixture
def box_a() -> Iterator[tuple[RecordingEmulator, str]]:
    """A real actuator box on a pty, for arm a: it records every packet it gets."""
    em = RecordingEmulator(TruePlant(PARAMS, PLANT, psi0=np.asarray(HOME_PSI, float)), PARAMS)
    path = em.serve_pty()
    yield em, path
    em.stop()


def refused(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run ``wristmark servo ARGV``: it must exit 2 with one line on stderr, which is returned."""
    code = main(["servo", *argv])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert err and "\n" not in err, err
    return err


@pytest.mark.parametrize(("extra", "cause"), [
    (["--serial", "a={A}"], "no box for arm 'b'"),
    (["--serial", "a={A}", "--serial", "c=/dev/pts/99"], "no arm 'c' in the scene"),
    (["--serial", "a={A}", "--serial", "b={A}"], "given for both 'a' and 'b'"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--robot", "configs/robot.yaml"], "--robot"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "stdin"], "each arm's targets are NAME=SPEC"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "c=stdin"], "no arm 'c' in the scene"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=stdin", "--target", "a=tcp:0"],
     "arm 'a' given twice"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=stdin", "--target", "b=stdin"],
     "stdin given for both 'a' and 'b'"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=tcp:10.0.0.1:5000"], "loopback only"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=tcp:127.0.0.1:http"], "PORT must be"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=cube"],
     "stdin, tcp:127.0.0.1:PORT or ros2"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=ros2"], "--target a=ros2 needs --ros2"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--ros2", "9bad"], "--ros2: ROS 2 namespace"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--ros2", "x", "--target", "c=ros2"],
     "no arm 'c' in the scene"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--ros2", "x", "--target", "a=ros2", "--target", "a=ros2"],
     "arm 'a' given twice"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--target", "a=tcp:0", "--hold", "a"], "also in --hold"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--view-hold", "2"], "--view-hold"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--orientation", "hold", "--controller", "paper"],
     "arm 'a': --orientation hold needs --controller qp"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--orientation", "follow", "--target", "a=tcp:127.0.0.1:0"],
     "live targets take --orientation none or hold"),
    (["--actuator", "ros2:/lab"], "with --scene each arm is NAME=ros2:NS"),
    (["--actuator", "a=ros2:/lab/a"], "no arm driver for arm 'b'"),
    (["--actuator", "a=ros2:/lab/a", "--actuator", "c=ros2:/lab/c"], "no arm 'c' in the scene"),
    (["--actuator", "a=ros2:/lab/a", "--actuator", "a=ros2:/lab/b"], "--actuator: arm 'a' given twice"),
    (["--actuator", "a=ros2:/lab/x", "--actuator", "b=ros2:/lab/x"], "namespace /lab/x given for both 'a' and 'b'"),
    (["--actuator", "a={A}", "--actuator", "b=ros2:/lab/b"], "each arm is NAME=ros2:NS"),
    (["--actuator", "a=ros2:9bad", "--actuator", "b=ros2:/lab/b"], "--actuator a=ros2:9bad:"),
    (["--actuator", "a=ros2:/lab/a", "--actuator", "b=ros2:/lab/b", "--ros2", "lab"],
     "arm 'a' would publish on /lab/a, arm 'a''s --actuator namespace"),
    (["--actuator", "a=ros2:/lab/a", "--actuator", "b=ros2:/lab/b", "--no-operating-state"],
     "--no-operating-state: not with --scene"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--no-operating-state"],
     "--no-operating-state: not with --scene"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--hold", "c"], "--hold c: no such arm"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--record", "run_dir"], "must be an .mcap file"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--record", "/no/such/dir/run.mcap"], "does not exist"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--record-jpeg"], "--record-jpeg needs --record"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--host", "0.0.0.0"], "--host serves the live view"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--model", "m.yaml"], "each model is NAME=MODEL.yaml"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--model", "c=m.yaml"], "no arm 'c' in the scene"),
    (["--serial", "a={A}", "--serial", "b=/dev/pts/99", "--model", "a=configs/plant.yaml"],
     "--model a=configs/plant.yaml: configs/plant.yaml: not a model file"),
])
def test_bad_scene_input_is_refused_in_one_line_and_nothing_reaches_the_box(
        capsys: pytest.CaptureFixture[str], box_a: tuple[RecordingEmulator, str], extra: list[str],
        cause: str) -> None:
    em, path = box_a
    err = refused(capsys, "--scene", SCENE, *[x.replace("{A}", path) for x in extra], *CAMERA)
    assert cause in err
    assert em.received == []  # refused before any port was opened


def test_a_target_port_already_taken_is_refused_naming_its_arm_before_any_box_opens(
        capsys: pytest.CaptureFixture[str], box_a: tuple[RecordingEmulator, str], tmp_path: Path) -> None:
    em, path = box_a
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        err = refused(capsys, "--scene", SCENE, "--serial", f"a={path}", "--serial", "b=/dev/pts/99", *CAMERA,
                      "--target", f"b=tcp:127.0.0.1:{port}", "--out", str(tmp_path / "run"))
    assert f"tcp:127.0.0.1:{port}: cannot listen" in err
    assert em.received == []


def test_without_a_camera_or_a_calibration_the_scene_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, "--scene", SCENE, "--serial", "a=/dev/pts/98", "--serial", "b=/dev/pts/99",
                  "--camera", "http://127.0.0.1:9/x")
    assert "--calib" in err


def test_several_boxes_or_hold_need_a_scene(capsys: pytest.CaptureFixture[str]) -> None:
    assert "need --scene" in refused(capsys, "--serial", "/dev/pts/98", "--serial", "/dev/pts/99", *CAMERA)
    assert "--model given 2 times" in refused(capsys, "--model", "a.yaml", "--model", "b.yaml")
    assert "--hold needs --scene" in refused(capsys, "--hold", "a")
    assert "--arm-processes needs --scene" in refused(capsys, "--arm-processes")
    assert "targets need --scene" in refused(capsys, "--target", "stdin", "--target", "tcp:127.0.0.1:0")
    assert "--actuator given 2 times: several arms need --scene" in refused(
        capsys, "--actuator", "ros2:/lab/a", "--actuator", "ros2:/lab/b", *CAMERA)


def test_serial_and_ros2_boxes_in_one_scene_are_refused_in_one_line(
        capsys: pytest.CaptureFixture[str], box_a: tuple[RecordingEmulator, str]) -> None:
    em, path = box_a
    with pytest.raises(SystemExit) as e:  # argparse's one line: --serial and --actuator are exclusive
        main(["servo", "--scene", SCENE, "--serial", f"a={path}", "--actuator", "b=ros2:/lab/b", *CAMERA])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "\n" not in err, err
    assert "argument --actuator: not allowed with argument --serial" in err
    assert em.received == []


def test_a_box_that_does_not_answer_is_refused_naming_its_arm_and_no_box_is_enabled(
        capsys: pytest.CaptureFixture[str], box_a: tuple[RecordingEmulator, str], tmp_path: Path) -> None:
    em, path = box_a
    master, slave = os.openpty()  # a device that never answers
    try:
        err = refused(capsys, "--scene", SCENE, "--serial", f"a={path}", "--serial", f"b={os.ttyname(slave)}",
                      *CAMERA, "--out", str(tmp_path / "run"))
    finally:
        os.close(master)
        os.close(slave)
    assert "arm 'b'" in err and "no valid reply" in err
    assert "Ping" in em.received  # a was asked who it is ...
    assert "Enable" not in em.received and "SetTarget" not in em.received  # ... and never enabled nor moved
    assert not em.enabled


def test_an_arm_name_that_cannot_be_a_ros2_namespace_is_refused_in_one_line() -> None:
    from wristmark.cli.servo_scene import scene_namespaces
    from wristmark.models.errors import InputError

    assert scene_namespaces("/lab/", ["a", "b"]) == {"a": "/lab/a", "b": "/lab/b"}
    with pytest.raises(InputError) as e:
        scene_namespaces("lab", ["a", "9b"])
    assert "arm '9b' cannot name a ROS 2 namespace" in str(e.value) and "\n" not in str(e.value)
