"""The emulator plays any arm: protocol v2 with the arm's n actuators for a format-2 robot file
(in process and `wristmark emulator --pty --robot FILE`), v1 for the reference arm's flat file."""

from __future__ import annotations

import signal
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import serial

from tests.sim.test_actuator_emulator import _transact
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import home_psi, load_loop_arm
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorRejected
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams

TENDON3_FILE = CONFIG_DIR / "robots" / "tendon3.yaml"
TENDON3 = load_loop_arm(TENDON3_FILE, MarkerModel.load(default_config("marker.yaml")))
EXE = Path(sys.executable).parent / "wristmark"


def _tendon3_plant() -> TruePlant:
    return TruePlant(TENDON3, PlantParams.load(CONFIG_DIR / "robots" / "tendon3_plant.yaml"), psi0=home_psi(TENDON3))


def test_in_process_v2_emulator_drives_the_tendon_arm_through_the_driver() -> None:
    emu = ActuatorEmulator(_tendon3_plant(), TENDON3)
    assert (emu.protocol_version, emu.count) == (2, 10)
    path = emu.serve_pty()
    try:
        with ActuatorDriver(path, timeout=0.5, retries=1, params=TENDON3) as drv:
            assert drv.ping() == P.Pong(2, 10, seq=1)
            drv.enable()
            a = actuators_from_psi(TENDON3, home_psi(TENDON3)) + 1e-4
            st = drv.set_target(a)
            assert st.enabled and st.positions.shape == (10,)
            with pytest.raises(ActuatorRejected, match=r"s1a=.* m not in"):
                drv.set_target(a + np.r_[0.0, 1.0, np.zeros(8)])  # a tendon pulled 1 m: refused whole
            assert np.allclose(drv.get_state().positions, st.positions, atol=1e-4)
    finally:
        emu.stop()


def test_flat_reference_arm_stays_v1_and_v1_refuses_another_count() -> None:
    assert ActuatorEmulator(_tendon3_plant(), TENDON3, protocol_version=2).protocol_version == 2
    from tests.sim.test_actuator_emulator import A_HOME, IdealArm

    assert ActuatorEmulator(IdealArm(A_HOME), RobotParams()).protocol_version == 1
    with pytest.raises(ConfigError, match="protocol v1, which carries 6 actuators; this arm has 10"):
        ActuatorEmulator(_tendon3_plant(), TENDON3, protocol_version=1)


def test_cli_emulator_robot_speaks_v2_with_n_10_to_an_independent_client() -> None:
    proc = subprocess.Popen([str(EXE), "emulator", "--pty", "--robot", str(TENDON3_FILE)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/")
        port = serial.Serial(path, 115200, timeout=0.1)
        try:
            assert _transact(port, 0x01, 11) == (0x81, 11, b"\x02\x0a")
            t, seq, payload = _transact(port, 0x02, 12)  # ENABLE
            assert (t, seq, len(payload)) == (0x84, 12, 4 * 10 + 6)
            pos = struct.unpack("<10iHI", payload)
            assert pos[10] & 1
            assert _transact(port, 0x04, 13, struct.pack("<10i", *pos[:10]))[:2] == (0x84, 13)
            assert _transact(port, 0x04, 14, struct.pack("<6i", *pos[:6])) == (0xEE, 14, b"\x02")  # v1-sized
        finally:
            port.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=10)
        err = proc.stderr.read() if proc.stderr else ""
    assert rc == 0 and "protocol v2, 10 actuators" in err


def test_cli_emulator_psi0_of_the_wrong_size_is_one_line() -> None:
    r = subprocess.run([str(EXE), "emulator", "--pty", "--robot", str(TENDON3_FILE), "--psi0", "0", "0", "0"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and r.stdout == ""
    assert r.stderr.strip().count("\n") == 0 and "--psi0 needs 7 values" in r.stderr


def test_cli_calib_out_without_the_lab_is_refused_in_one_line(tmp_path: Path) -> None:
    """--calib-out belongs to the virtual lab (--camera-port or --ros2); nothing is served or written."""
    out = tmp_path / "lab_calib.yaml"
    r = subprocess.run([str(EXE), "emulator", "--pty", "--robot", str(TENDON3_FILE), "--calib-out", str(out)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stdout == "" and not out.exists()
    assert r.stderr.strip().count("\n") == 0 and "--calib-out need --camera-port PORT" in r.stderr


def test_cli_loads_from_stdin_without_the_lab_is_refused_in_one_line() -> None:
    r = subprocess.run([str(EXE), "emulator", "--pty", "--loads-from-stdin"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().count("\n") == 0 and "--loads-from-stdin need --camera-port PORT" in r.stderr


def test_the_labs_load_lines_hang_forces_and_bad_lines_change_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    """identify --load's weight on the virtual lab: 'load FX FY FZ' [N] in {w} on the lab's stdin."""
    from wristmark.cli.emulator import _read_loads

    hung: list[list[float]] = []
    _read_loads(["load 0 0 -0.15\n", "\n", "lod 1 2 3\n", "load 1 2\n", "load nan 0 0\n", "load 0 0 -20\n",
                 "load 0 0 0\n"], lambda f: hung.append(f.tolist()))
    assert hung == [[0.0, 0.0, -0.15], [0.0, 0.0, 0.0]]
    err = capsys.readouterr().err
    assert err.count("ignored") == 4 and "a tip load of 0.15 N hangs" in err


def test_the_labs_calibration_frames_a_format2_arm_and_is_written_for_the_host(tmp_path: Path) -> None:
    """Without --calib the lab's endoscope stands where the simulated bench frames the arm
    (sim.setup.camera_for_arm), which --calib-out writes; the reference arm keeps configs/camera.yaml."""
    import argparse

    from wristmark.cli.emulator import lab_calibration
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.sim.setup import load_setup

    marker = MarkerModel()
    out = tmp_path / "lab_calib.yaml"
    args = argparse.Namespace(calib=None, calib_out=str(out))
    cam = lab_calibration(args, load_loop_arm(TENDON3_FILE, marker), marker)
    bench = load_setup(robot=TENDON3_FILE).camera  # the simulated bench's framing of tendon3
    np.testing.assert_allclose(cam.T_world_left, bench.T_world_left, atol=1e-12)
    np.testing.assert_allclose(load_calibration(out).T_world_left, cam.T_world_left, atol=1e-9)
    shipped = load_calibration(default_config("camera.yaml"))
    assert np.abs(np.asarray(cam.T_world_left) - shipped.T_world_left).max() > 1e-3
    reference = lab_calibration(argparse.Namespace(calib=None, calib_out=None), RobotParams(), marker)
    np.testing.assert_array_equal(reference.T_world_left, shipped.T_world_left)


def test_a_target_at_a_limit_stays_within_it_on_the_wire() -> None:
    """phi = pi, the end of single_tendon's phi range, rounded to the nearest micro-unit would be
    3141593 urad > pi: the device rejected the whole target and the lab's cube stopped at 24 s
    (the loop drove phi to its limit). The driver rounds a target within the limits inwards; one
    beyond them is still rejected."""
    from wristmark.models.limits import actuator_bounds

    arm = load_loop_arm(CONFIG_DIR / "robots" / "single_tendon.yaml", MarkerModel())
    q = home_psi(arm)
    emu = ActuatorEmulator(TruePlant(arm, PlantParams(), psi0=q), arm)
    path = emu.serve_pty()
    try:
        with ActuatorDriver(path, timeout=0.5, retries=1, params=arm) as drv:
            drv.ping()
            drv.enable()
            lo, hi = actuator_bounds(arm)
            a = actuators_from_psi(arm, q)
            for phi in (hi[0], lo[0]):
                st = drv.set_target(np.r_[phi, a[1:]])
                assert st.enabled and not st.target_rejected
            with pytest.raises(ActuatorRejected, match=r"phi=.* rad not in"):
                drv.set_target(np.r_[hi[0] + 1e-5, a[1:]])
    finally:
        emu.stop()
