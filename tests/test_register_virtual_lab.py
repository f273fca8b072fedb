"""``wristmark register --serial PORT --camera URL`` against a virtual lab made here: the actuator
emulator on a real pty around the simulated true arm (wall-clock time) and its stereo endoscope
rendered through the misplaced true camera and served as an HTTP MJPEG stream on 127.0.0.1."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

from cvs.calibration_io import save_calibration
from cvs.camera import scaled_stereo_camera
from cvs.registration_io import load_registration
from models.robot_params import HOME_PSI
from rig.cli import main
from rig.mjpeg_server import MjpegServer
from sim.actuator_emulator import ActuatorEmulator
from sim.render import StereoRenderer
from sim.render_settings import noise_preset
from sim.setup import load_setup, make_plant
from solvers.registration import transform_error

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
SCALE = 0.4


class VirtualCamera:
    """Renders the emulator's arm through the true camera and publishes side-by-side JPEGs."""

    def __init__(self, emu: ActuatorEmulator, renderer: StereoRenderer, server: MjpegServer) -> None:
        self.emu, self.renderer, self.server = emu, renderer, server
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            with self.emu._lock:  # the emulator's thread advances the same arm
                self.emu.poll()
                shape = self.emu.arm.true_shape()
            frame = self.renderer.render(shape)
            self.server.publish_image(np.hstack([frame.left, frame.right]), quality=95)
            self.stop.wait(0.05)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)


def test_register_through_serial_and_stream(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cv2.setNumThreads(1)
    setup = load_setup(plant=CONFIGS / "plant_ideal.yaml")
    offset = (0.003, 0.002, -0.002, -0.02, 0.025, 0.02)
    setup = setup.with_changes(plant=setup.plant.__class__(camera_offset=offset))
    true_cam = scaled_stereo_camera(setup.true_camera, SCALE)
    host = scaled_stereo_camera(setup.camera, SCALE)
    save_calibration(tmp_path / "calib.yaml", host)
    plant = make_plant(setup, np.asarray(HOME_PSI, float))
    emu = ActuatorEmulator(plant, setup.params)
    port = emu.serve_pty()
    server = MjpegServer()
    camera = VirtualCamera(emu, StereoRenderer(true_cam, setup.marker, noise_preset("default"), seed=1), server)
    try:
        capsys.readouterr()
        rc = main(["register", "--serial", port, "--camera", server.url, "--calib", str(tmp_path / "calib.yaml"),
                   "--poses", "4", "--rigid-arm", "--speed", "1", "--out", str(tmp_path / "reg.yaml"),
                   "--log", str(tmp_path / "log"), "--json", "--no-progress"])
        out = capsys.readouterr()
    finally:
        camera.close()
        server.close()
    try:
        assert rc == 0, out.err
        res = json.loads(out.out)
        assert res["simulated"] is False and res["poses"] == 4 and len(res["per_pose"]) == 8
        assert not emu.enabled and not emu.watchdog_tripped and not emu.estopped  # DISABLE at the end
    finally:
        emu.stop()
    t, r = transform_error(true_cam.T_world_left, load_registration(tmp_path / "reg.yaml").world_T_left)
    assert t < 5e-4 and np.degrees(r) < 0.3, (1000 * t, np.degrees(r))
    assert (tmp_path / "log" / "registration_log.csv").read_text().count("\n") == 9
