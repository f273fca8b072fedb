"""``wristmark register --serial PORT --camera URL`` against a virtual lab started here in a
process of its own: the actuator emulator on a real pty around the simulated true arm
(wall-clock time) and its stereo endoscope rendered through the misplaced true camera and
served as a side-by-side HTTP MJPEG stream on 127.0.0.1."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.cvs.calibration.load import save_calibration
from wristmark.cvs.calibration.registration_file import load_registration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.config_files import CONFIG_DIR
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.setup import load_setup
from wristmark.solvers.registration import transform_error

ROOT = Path(__file__).resolve().parents[2]
SCALE = 0.4
OFFSET = (0.003, 0.002, -0.002, -0.02, 0.025, 0.02)  # [m, m, m, rad, rad, rad]

LAB = r"""
import sys, threading, time
import cv2, numpy as np
cv2.setNumThreads(1)
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.robot_params import HOME_PSI
from wristmark.cvs.sources.mjpeg_server import MjpegServer
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.plant_params import PlantParams
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.setup import load_setup, make_plant

scale, offset = float(sys.argv[1]), tuple(float(v) for v in sys.argv[2:8])
setup = load_setup(plant=sys.argv[8]).with_changes(plant=PlantParams(camera_offset=offset))
renderer = StereoRenderer(scaled_stereo_camera(setup.true_camera, scale), setup.marker, noise_preset("default"), seed=1)
emu = ActuatorEmulator(make_plant(setup, np.asarray(HOME_PSI, float)), setup.params)
port = emu.serve_pty()
server = MjpegServer()
print(port, flush=True)
print(server.url, flush=True)
done = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
while not done.is_set():
    with emu._lock:  # the emulator's thread advances the same arm
        emu.poll()
        flags, shape, t = emu.flags, emu.arm.true_shape(), time.monotonic()
    frame = renderer.render(shape)
    server.publish_image(np.hstack([frame.left, frame.right]), quality=95, t_capture=t)
    print(f"flags {flags}", file=sys.stderr, flush=True)
    time.sleep(0.1)
with emu._lock:
    print(f"flags {emu.flags}", file=sys.stderr, flush=True)
emu.stop()
server.close()
"""


@pytest.mark.slow
@pytest.mark.network
def test_register_through_serial_and_stream(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    setup = load_setup(plant=CONFIG_DIR / "plant_ideal.yaml")
    setup = setup.with_changes(plant=PlantParams(camera_offset=OFFSET))
    true_cam = scaled_stereo_camera(setup.true_camera, SCALE)
    save_calibration(tmp_path / "calib.yaml", scaled_stereo_camera(setup.camera, SCALE))
    err = (tmp_path / "lab.err").open("w")
    lab = subprocess.Popen([sys.executable, "-c", LAB, str(SCALE), *map(str, OFFSET),
                            str(CONFIG_DIR / "plant_ideal.yaml")], cwd=ROOT, stdin=subprocess.PIPE,
                           stdout=subprocess.PIPE, stderr=err, text=True)
    try:
        assert lab.stdout is not None
        port, url = lab.stdout.readline().strip(), lab.stdout.readline().strip()
        assert port.startswith("/dev/") and url.startswith("http://127.0.0.1:"), (port, url)
        capsys.readouterr()
        rc = main(["register", "--serial", port, "--camera", url, "--calib", str(tmp_path / "calib.yaml"),
                   "--poses", "4", "--rigid-arm", "--speed", "1", "--out", str(tmp_path / "reg.yaml"),
                   "--log", str(tmp_path / "log"), "--json", "--no-progress"])
        out = capsys.readouterr()
    finally:
        try:
            lab.communicate("", timeout=20)
        except subprocess.TimeoutExpired:
            lab.kill()
            lab.wait()
        err.close()
    assert rc == 0, out.err
    res = json.loads(out.out)
    assert res["simulated"] is False and res["poses"] == 4 and len(res["per_pose"]) == 8
    t, r = transform_error(true_cam.T_world_left, load_registration(tmp_path / "reg.yaml").world_T_left)
    assert t < 5e-4 and np.degrees(r) < 0.3, (1000 * t, np.degrees(r))
    assert (tmp_path / "log" / "registration_log.csv").read_text().count("\n") == 9
    # the box was left disabled (flag bit 0), not emergency-stopped (bit 1); a watchdog trip (bit 2)
    # on a loaded machine is recovered from and noted on stderr
    flags = [int(line.split()[1]) for line in (tmp_path / "lab.err").read_text().splitlines()
             if line.startswith("flags ")]
    assert flags and flags[-1] & 3 == 0
    if any(f & 4 for f in flags):
        assert "watchdog fired" in out.err


def test_a_move_resumes_after_the_watchdog_fired() -> None:
    """A host that is late once mid-ramp (0.4 s > the 250 ms watchdog): the box holds, the rig
    ENABLEs again and finishes the move from the encoders; it ends DISABLEd. The box and the rig
    share a simulated clock that only the rig's sleeps move (the late one included), so the
    watchdog fires exactly once however loaded the machine is."""
    from wristmark.models.robot_params import HOME_PSI, RobotParams
    from wristmark.rig.link.actuator_driver import ActuatorDriver
    from wristmark.rig.link.serial_link import SimClock
    from wristmark.rig.registration.hardware import HardwareRegistrationRig
    from wristmark.sim.actuator_emulator import ActuatorEmulator
    from wristmark.sim.plant import TruePlant

    params = RobotParams()
    home = np.asarray(HOME_PSI, float)
    clock = SimClock()
    emu = ActuatorEmulator(TruePlant(params, PlantParams(), psi0=home), params, clock=clock)
    port = emu.serve_pty()
    calls = []

    def sleep(s: float) -> None:
        calls.append(s)
        clock.set(clock() + (0.4 if len(calls) == 3 else s))

    try:
        with ActuatorDriver(port, timeout=0.2, retries=3, params=params) as driver:
            rig = HardwareRegistrationRig(driver, None, params, speed=1.0, clock=clock,  # type: ignore[arg-type]
                                          sleep=sleep)
            target = home + np.array([0.3, 0.002, 0.1, 0.0, 0.1, 0.0])  # 6 ramp steps of 50 ms
            rig.move_to(target)
            assert len(rig.notes) == 1 and "watchdog fired" in rig.notes[0]
            np.testing.assert_allclose(driver.measured_psi(), target, atol=1e-5)
            assert not emu.enabled and not emu.estopped
            rig.close()
            assert not emu.enabled
    finally:
        emu.stop()
