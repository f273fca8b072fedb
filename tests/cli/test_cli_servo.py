"""`wristmark servo`: the closed loop through protocol-v1 bytes on a real pty, end to end (as a
subprocess and in process), its accuracy against the in-process loop, and its safe stops; the
hardware path (`--serial PORT --camera URL`) against a virtual lab served from this process."""

from __future__ import annotations

import dataclasses
import json
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.rig.link.test_serial_link import PARAMS, PLANT, RecordingEmulator
from wristmark.cli import servo as S
from wristmark.models.errors import InputError
from wristmark.models.robot_params import HOME_PSI
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.loop.realtime_priority import realtime_priority_allowed
from wristmark.rig.loop.servo_summary import summarize
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.sim.servo_bench import open_sim_session
from wristmark.sim.setup import SimSetup, load_setup
from wristmark.sim.virtual_lab import LabCamera, VirtualLab

ROOT = Path(__file__).resolve().parents[2]
HOME = np.asarray(HOME_PSI, float)


def wristmark(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "wristmark", *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )


def popen_wristmark(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "wristmark", *args], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


@pytest.fixture(scope="module")
def setup() -> SimSetup:
    s = load_setup()
    return s.with_changes(rig=dataclasses.replace(s.rig, sensor="truth-noise"))


LAB_SCALE = 0.25  # the virtual lab's image scale in these tests (fast)
RT_HOST = ["--rt-priority", "20"] if realtime_priority_allowed(20) else []  # see test_virtual_lab


def started_lab(setup: SimSetup) -> Iterator[VirtualLab]:
    """A virtual lab (actuator box on a pty, endoscope on an MJPEG stream, wall clock) served
    from this process, for `--serial PTY --camera URL` subprocesses (like hardware)."""
    vl = VirtualLab(PARAMS, PLANT, setup.camera, setup.marker, LabCamera(fps=30.0, image_scale=LAB_SCALE),
                    rt_priority=10 if RT_HOST else None, emulator_factory=RecordingEmulator)
    vl.start()
    yield vl
    vl.stop()


@pytest.fixture
def lab(setup: SimSetup) -> Iterator[VirtualLab]:
    """A virtual lab of the test's own."""
    yield from started_lab(setup)


@pytest.fixture(scope="module")
def untouched_lab(setup: SimSetup) -> Iterator[VirtualLab]:
    """One virtual lab for the tests whose command must never open its box (each checks that)."""
    yield from started_lab(setup)


def hardware_args(lab: VirtualLab) -> list[str]:
    return ["--serial", lab.pty_path, "--camera", lab.url, "--image-scale", str(LAB_SCALE), "--no-progress", *RT_HOST]


def run_in_process(
    setup: SimSetup,
    kind: str = "emulator",
    duration: float = 3.0,
    settle: float = 1.5,
    on_cycle: Any = None,
    sensor: Any = None,
) -> tuple[S.ServoOutcome, S.ServoSession, dict]:
    """``sensor``: None (the bench's own) or ``session -> TipSensor``."""
    traj = S.build_trajectory(setup, "cube", None, duration)
    psi0 = S.start_configuration(setup, traj)
    session = open_sim_session(setup, psi0, S.LinkOptions(kind=kind), emulator_factory=RecordingEmulator)
    hook = (lambda rec: on_cycle(session, rec)) if on_cycle is not None else None
    out = S.run_servo(setup, traj, session, psi0, settle=settle, on_cycle=hook,
                      sensor=sensor(session) if sensor is not None else None)
    return out, session, summarize(setup, traj, session, out)


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    return lines[0]


# -- end to end --------------------------------------------------------------------------------
@pytest.mark.slow
def test_servo_subprocess_tracks_the_cube_through_the_pty(tmp_path: Path) -> None:
    r = wristmark(
        "servo",
        "--sensor",
        "truth-noise",
        "--duration",
        "3",
        "--no-progress",
        "--out",
        str(tmp_path / "run"),
        "--json",
        str(tmp_path / "res.json"),
    )
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "res.json").read_text())
    c = res["closed_loop"]
    assert c["mean_mm"] < 0.5 and c["cycles"] >= 50
    assert res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    link = res["link"]
    assert link["kind"] == "emulator" and link["port"].startswith("/dev/")
    assert link["sent"] > 3 * c["cycles"] and link["retries"] == 0  # every cycle crossed the pty
    assert link["device"]["enabled"] is False  # disabled at the end
    for name in ("config.json", "log.csv", "result.json"):
        assert (tmp_path / "run" / name).is_file()
    assert "mean" in r.stdout and "max" in r.stdout


class RoundingDirectLink(DirectLink):
    """DirectLink that rounds every target to protocol micro-units, as the wire does."""

    def send_target(self, actuators: np.ndarray) -> None:
        super().send_target(P.si_from_micro(P.micro_from_si(actuators)))


@pytest.mark.slow
def test_serial_link_is_the_direct_loop_with_micro_unit_targets(setup: SimSetup) -> None:
    """Same trajectory, seed and noise. Through the pty the loop is *exactly* the in-process loop
    with every target rounded to micro-units (chunked simulated time changes nothing), so the
    serial path adds no error of its own. Against the unrounded loop, the rounding (<= 0.5 µm of
    backbone, <= ~50 µm at the tip, see test_serial_link) is corrected from cycle to cycle; the
    arm's redundancy (6 joints for a 3-D tip) lets a rounding difference move the solution along
    near-null directions for a few cycles, so single cycles may differ by up to ~0.1 mm on a short
    run (0.3 mm once on the full cube) while the error statistics agree to within 0.01 mm."""
    serial_out, _, serial_res = run_in_process(setup, "emulator")
    traj = S.build_trajectory(setup, "cube", None, 3.0)
    psi0 = S.start_configuration(setup, traj)
    rounded = open_sim_session(setup, psi0, S.LinkOptions(kind="direct"))
    rounded.link = RoundingDirectLink(rounded.arm)
    rounded_out = S.run_servo(setup, traj, rounded, psi0, settle=1.5)
    direct_out, _, direct_res = run_in_process(setup, "direct")
    tips = [np.array([r.p_true for r in o.log.records]) for o in (serial_out, rounded_out, direct_out)]
    assert tips[0].shape == tips[1].shape == tips[2].shape
    np.testing.assert_allclose(tips[0], tips[1], rtol=0, atol=1e-12)
    assert np.linalg.norm(tips[0] - tips[2], axis=1).max() < 0.1e-3
    s, d = serial_res["closed_loop"], direct_res["closed_loop"]
    assert abs(s["mean_mm"] - d["mean_mm"]) < 0.01
    assert abs(s["max_mm"] - d["max_mm"]) < 0.05


@pytest.mark.slow
def test_vision_sensor_default_path(tmp_path: Path) -> None:
    r = wristmark(
        "servo",
        "--duration",
        "0.6",
        "--settle",
        "0.6",
        "--image-scale",
        "0.5",
        "--no-progress",
        "--json",
        str(tmp_path / "res.json"),
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "res.json").read_text())
    c = res["closed_loop"]
    assert res["sensor"] == "vision" and c["lost"] == 0 and c["rejected"] == 0
    assert c["vision_vs_true"]["mean_mm"] < 0.3  # the tracker really ran on rendered pixels
    assert c["mean_mm"] < 1.0


# -- safe stops ------------------------------------------------------------------------------
def test_emergency_stop_mid_run_stops_safely(setup: SimSetup) -> None:
    state: dict[str, Any] = {}

    def press_estop(session: S.ServoSession, rec: Any) -> None:
        if len(state) == 0 and rec.t > 2.5:
            emu = session.emulator
            emu.receive(P.encode(P.EStop(seq=99)))  # the box's stop button
            state["at"] = len(emu.received)
            state["pos"] = emu.arm.measured_actuators()

    out, session, res = run_in_process(setup, on_cycle=press_estop)
    emu = session.emulator
    assert out.cause == "estop" and "emergency" in out.stopped
    assert res["safe_stop"]["held_and_disabled"]
    assert emu.estopped and not emu.enabled
    assert "SetTarget" not in emu.received[state["at"] :]  # nothing was commanded after the stop
    np.testing.assert_allclose(emu.arm.measured_actuators(), state["pos"], atol=1e-12)  # and nothing moved


class LosesMarker:
    """Truth + noise that goes blind after ``after`` measurements (marker occluded)."""

    def __init__(self, arm: Any, after: int) -> None:
        self.arm, self.after, self.n = arm, after, 0
        self.rng = np.random.default_rng(0)

    def measure(self, frame: Any, axis_hint_world: Any = None) -> TipMeasurement:
        self.n += 1
        if self.n > self.after:
            return TipMeasurement(False, None, "marker not found")
        return TipMeasurement(True, self.arm.true_shape().tip + self.rng.normal(0, 1e-4, 3))


def test_marker_lost_holds_then_disables_on_the_device(setup: SimSetup) -> None:
    out, session, res = run_in_process(setup, sensor=lambda session: LosesMarker(session.arm, after=40))
    emu = session.emulator
    assert out.cause == "marker-lost" and "marker lost" in out.stopped
    assert out.cycles >= 40 and res["safe_stop"]["held_and_disabled"]
    # the loop holds (GET_STATE + SET_TARGET at the measured position), then close holds and disables
    assert emu.received[-5:] == ["GetState", "SetTarget", "GetState", "SetTarget", "Disable"]
    assert not emu.enabled and not emu.watchdog_tripped
    held = emu.arm.measured_actuators()
    emu.arm.advance(1.0)  # the held targets are where the motors were: no further motion
    np.testing.assert_allclose(emu.arm.measured_actuators(), held, atol=1e-6)


def test_pty_closing_mid_run_stops_with_a_clear_error(setup: SimSetup) -> None:
    def unplug(session: S.ServoSession, rec: Any) -> None:
        if rec.t > 2.5:
            session.emulator.stop()

    out, session, res = run_in_process(setup, on_cycle=unplug)
    assert out.cause == "device" and session.port in out.stopped and "\n" not in out.stopped
    assert "unreachable" in out.close_error and not res["safe_stop"]["held_and_disabled"]


@pytest.mark.network
@pytest.mark.wallclock
def test_serial_port_vanishing_mid_run_exits_non_zero_with_one_line(lab: VirtualLab) -> None:
    emu, path = lab.emulator, lab.pty_path
    proc = popen_wristmark("servo", *hardware_args(lab))
    deadline = time.monotonic() + 20
    while "SetTarget" not in emu.received and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    emu.stop()  # cable pulled
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 3, err
    line = one_line(err)
    assert line.startswith("wristmark servo: error: stopped safely") and path in line


@pytest.mark.network
@pytest.mark.wallclock
def test_ctrl_c_holds_and_disables_the_device(lab: VirtualLab) -> None:
    emu = lab.emulator
    proc = popen_wristmark("servo", *hardware_args(lab))
    deadline = time.monotonic() + 20
    while "SetTarget" not in emu.received and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 130, err
    assert "interrupted" in one_line(err)
    assert emu.received[-3:] == ["GetState", "SetTarget", "Disable"]
    assert not emu.enabled and not emu.watchdog_tripped  # disabled by the host, not by silence


# -- bad input -------------------------------------------------------------------------------
@pytest.mark.network
@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--duration", "-1"], ["--duration", "(0, 3600]"]),
        (["--controller", "nope"], ["nope"]),
        (["--dt", "0"], ["--dt", "[0.001, 1]"]),
        (["--trajectory", "point", "--point", "1", "1", "1"], ["out of reach"]),
        (["--point", "0", "0", "0.15"], ["--trajectory point"]),
        (["--timeout", "0"], ["--timeout"]),
        (["--sensor", "truth-noise"], ["--sensor", "only for the simulated bench"]),
        (["--plant", "configs/plant.yaml"], ["--plant", "only for the simulated bench"]),
        (["--realtime"], ["--realtime", "always real time"]),
        (["--camera-timeout", "0"], ["--camera-timeout"]),
    ],
)
def test_bad_options_fail_before_any_motion(untouched_lab: VirtualLab, args: list[str], words: list[str]) -> None:
    lab = untouched_lab
    assert lab.emulator.received == []  # no earlier command opened it either
    r = wristmark("servo", *hardware_args(lab), *args)
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert line.startswith("wristmark servo: error:")
    for w in words:
        assert w in line
    assert lab.emulator.received == []  # not even opened


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--serial", "/dev/null"], ["--serial needs --camera SPEC"]),
        (["--camera", "http://127.0.0.1:1/x"], ["--camera SPEC needs --serial PORT"]),
        (["--camera", "configs/camera.yaml"], ["--camera SPEC needs --serial PORT"]),  # the old --camera YAML
        (["--rt-priority", "5"], ["--rt-priority is for the hardware path"]),
    ],
)
def test_serial_and_camera_go_together(args: list[str], words: list[str]) -> None:
    r = wristmark("servo", "--no-progress", *args)
    assert r.returncode == 2
    line = one_line(r.stderr)
    for w in words:
        assert w in line


def test_missing_port_is_one_line() -> None:
    r = wristmark("servo", "--serial", "/dev/does-not-exist", "--camera", "http://127.0.0.1:1/none")
    assert r.returncode == 2
    assert "cannot open actuator port" in one_line(r.stderr)


@pytest.mark.network
def test_wrong_image_size_fails_before_any_motion(lab: VirtualLab) -> None:
    """The stream is 0.25 x the calibration; without --image-scale the sizes differ."""
    args = [a for a in hardware_args(lab) if a not in ("--image-scale", str(LAB_SCALE))]
    r = wristmark("servo", *args)
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert "480x270" in line and "1920x1080" in line and lab.url in line
    assert "Enable" not in lab.emulator.received and "SetTarget" not in lab.emulator.received


def test_view_without_the_live_view_module_is_one_clear_error(setup: SimSetup,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "wristmark.viz.live", None)  # as if viz/live.py were missing
    with pytest.raises(InputError, match="--view needs the Meshcat live view"):
        S.live_view(setup)
