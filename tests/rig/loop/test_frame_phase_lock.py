"""The servo loop's cycle locked to a free-running camera's capture phase (rig frame_phase_lock):
the phase-locked loop on its own, and the servo loop on the wall clock with a camera whose frame
clock starts at an arbitrary phase of the loop's cycle."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from tests import old_defaults
from tests.rig.loop.test_camera_cycle import IMG, PSI0, P, _line, _ModelSensor, _WallLink
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.errors import ConfigError
from wristmark.rig.loop.frame_phase_lock import MAX_STEP, FramePhaseLock
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.recording.run_log import RunLog
from wristmark.solvers.controller_registry import make_controller

DT = 0.06  # [s] the loop's cycle and the camera's period
TRANSPORT = 0.012  # [s] capture -> arrival of every frame


def test_the_lock_converges_to_the_target_phase_in_bounded_steps() -> None:
    lock = FramePhaseLock(0.004, DT)
    phase = 0.027  # the camera captures 27 ms after the unshifted grid's cycle starts
    shifts = [0.0]
    for _ in range(40):
        lock.observe(phase - lock.shift)
        shifts.append(lock.shift)
    assert np.all(np.abs(np.diff(shifts)) <= MAX_STEP + 1e-12)
    assert lock.shift == pytest.approx(phase - 0.004, abs=2e-4)  # captures now 4 ms after each start
    assert len(lock.offsets) == 40


def test_a_frame_handed_to_the_next_cycle_counts_as_a_small_phase_error() -> None:
    lock = FramePhaseLock(0.0, DT)
    lock.observe(-0.058)  # captured 2 ms after the previous cycle's start: a phase of +2 ms, not -58 ms
    assert lock.shift == pytest.approx(0.3 * 0.002)  # not a full MAX_STEP back
    lock.observe(math.nan)  # no capture stamp: ignored
    assert len(lock.offsets) == 1


def test_the_lock_keys_are_validated() -> None:
    with pytest.raises(ConfigError, match="frame_lock_phase"):
        RigConfig(frame_lock_phase=0.04).validate()  # not below frame_wait (0.04)
    with pytest.raises(ConfigError, match="frame_lock_phase"):
        RigConfig(frame_lock_phase=-0.06).validate()  # not a whole cycle before the start
    with pytest.raises(ConfigError, match="frame_phase_lock"):
        RigConfig(frame_phase_lock="yes").validate()
    RigConfig(frame_phase_lock="capture", frame_lock_phase=-0.03).validate()


class _FreeRunningCamera:
    """A live camera on ``time.monotonic()``: frame j is captured at c0 + j DT and arrives
    TRANSPORT later; take() follows rig.loop.frame_feed.LatestFrameFeed's rules (the newest unseen
    frame, waiting until ``wait_until`` for one that arrives after ``fresh_after``)."""

    name = "free-running test camera"

    def __init__(self, c0: float) -> None:
        self.c0 = c0
        self.taken = -1
        self.last_arrival = math.nan

    def _arrival(self, j: int) -> float:
        return self.c0 + j * DT + TRANSPORT

    def take(self, fresh_after: float = -math.inf, wait_until: float = -math.inf) -> StereoFrame | None:
        j = int(math.floor((time.monotonic() - self.c0 - TRANSPORT) / DT))  # the newest arrived
        if j <= self.taken or self._arrival(j) < fresh_after:
            if self._arrival(j + 1) <= wait_until:
                j += 1
            time.sleep(max(0.0, min(self._arrival(j), wait_until) - time.monotonic()))
        if j <= self.taken or self._arrival(j) > time.monotonic():
            return None
        self.taken = j
        self.last_arrival = self._arrival(j)
        return StereoFrame(IMG, IMG, self.c0 + j * DT, j)

    @property
    def dropped(self) -> int:
        return 0

    def close(self) -> None:
        pass


def _capture_offsets(lock: str, phase: float = 0.0) -> np.ndarray:
    """Capture instant - nominal cycle start [s] of every cycle's frame in a ~1.7 s run whose
    camera's clock starts 27 ms into the loop's cycle (rig frame_phase_lock ``lock`` at ``phase``)."""
    rig = old_defaults.rig(settle_time=0.0, control_dt=DT, frame_phase_lock=lock, frame_lock_phase=phase,
                           reuse_measurement_age=0.0)
    link = _WallLink()
    camera = _FreeRunningCamera(link.t + 0.027 - 10 * DT)
    sensor = _ModelSensor()
    loop = ServoLoop(P, rig, link, frames=camera, sensor=sensor,  # type: ignore[arg-type]
                     controller=make_controller(P, old_defaults.controller(kind="qp")), wall_clock=True,
                     frame_wait=rig.frame_wait)
    sensor.loop = loop
    loop.psi_cmd = PSI0.copy()
    log = RunLog()
    loop.run(_line(), "servo", True, log, settle=1.0)  # ~1.7 s in all
    recs = [r for r in log.records if math.isfinite(r.t_capture)]
    assert len(recs) > 15
    return np.array([r.t_capture - r.t for r in recs])


@pytest.mark.wallclock
def test_the_loop_locks_its_cycle_to_the_cameras_capture_phase() -> None:
    free = _capture_offsets("none")
    locked = _capture_offsets("capture")
    assert np.all(np.abs(free[-8:] - 0.027) < 0.003), free  # unlocked: wherever the clocks started
    assert np.all(np.abs(locked[-8:]) < 0.003), locked  # locked: captured at each cycle's start


@pytest.mark.wallclock
def test_locked_on_the_arrival_the_frames_arrive_at_the_chosen_phase() -> None:
    locked = _capture_offsets("arrival", 0.02)  # arriving 20 ms after each start: captured TRANSPORT before
    assert np.all(np.abs(locked[-8:] - (0.02 - TRANSPORT)) < 0.003), locked
