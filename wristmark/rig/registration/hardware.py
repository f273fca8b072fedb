"""Registration on hardware or the virtual lab: the actuator box over serial (rig/link/actuator_driver.py,
protocol v1) and the stereo endoscope through a frame source (cvs.sources.open_source).

Each move ENABLEs the box, ramps in configuration space at ``speed`` x the velocity limits,
one SET_TARGET every ``period`` [s] (well inside the box's 250 ms watchdog), then polls the
encoders until they settle (every joint within SETTLE_TOL over ``settle_time``) and DISABLEs
the box: it holds still while the host waits for a frame and tracks the marker, for as long as
that takes, and the 250 ms watchdog never has to fire. ``grab`` reads frames until one was
captured after the move settled (a live source hands out the newest frame). ``close`` holds at
the encoders' position and sends DISABLE.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError, StereoSource
from wristmark.models.arm_spec import Arm
from wristmark.models.limits import check_limits, delta_indices, velocity_limits
from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorError, ActuatorNotEnabled
from wristmark.rig.registration.poses import per_kind

Array = NDArray[np.float64]
MAX_RESUMES = 5  # watchdog trips a run may recover from before it gives up
SETTLE_TOL = np.array([2e-4, 5e-6, 2e-4, 2e-3, 2e-4, 2e-3])  # [rad, m, rad, rad, rad, rad] per poll (any arm: per kind)


class HardwareRegistrationRig:
    """:class:`rig.registration.run.RegistrationRig` over an :class:`ActuatorDriver` and a source."""

    def __init__(self, driver: ActuatorDriver, source: StereoSource, params: Arm, speed: float = 0.5,
                 period: float = 0.05,
                 settle_time: float = 0.3, timeout: float = 20.0, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.driver, self.source, self.params = driver, source, params
        self.speed = float(speed)  # fraction of the velocity limits
        self.period, self.settle_time, self.timeout = float(period), float(settle_time), float(timeout)
        self.clock, self.sleep = clock, sleep
        self._settled_at = -np.inf
        self._enabled = False  # whether this rig enabled the box (and must disable it)
        self.notes: list[str] = []

    def start(self) -> None:
        """ENABLE the box (it holds where it is until the next SET_TARGET; move_to does this)."""
        self.driver.enable()
        self._enabled = True

    def move_to(self, psi: Array) -> None:
        """Ramp to ``psi`` within the velocity limits, then wait until the encoders settle.

        If the box's watchdog fired during the ramp (the host was late: the box then held where
        it was), it is ENABLEd again and the ramp restarts from the encoders, at most
        MAX_RESUMES times a run; each time is noted in ``notes``."""
        target = check_limits(self.params, psi)
        while True:
            if not self._enabled:
                self.start()
            try:
                self._ramp(target)
                break
            except ActuatorNotEnabled:
                self._enabled = False
                state = self.driver.get_state()
                if state.estopped or not state.watchdog_tripped or len(self.notes) >= MAX_RESUMES:
                    raise
                self.notes.append("the box's watchdog fired during a move (the host was late); it held, "
                                  "and the move resumed from the encoders")
        self._settle()

    def _ramp(self, target: Array) -> None:
        q = self.driver.measured_psi()
        diff = target - q
        planes = list(delta_indices(self.params))
        diff[planes] = (diff[planes] + np.pi) % (2 * np.pi) - np.pi  # bending planes: the short way round
        target = q + diff
        step = self.speed * velocity_limits(self.params) * self.period
        while np.any(np.abs(target - q) > 1e-12):
            q = q + np.clip(target - q, -step, step)
            self.driver.set_psi(q)
            self.sleep(self.period)

    def _settle(self) -> None:
        t0 = self.clock()
        last, since = self.driver.measured_psi(), self.clock()
        while self.clock() - since < self.settle_time:
            if self.clock() - t0 > self.timeout:
                raise ActuatorError(f"the arm did not settle within {self.timeout:.0f} s of reaching its target")
            self.sleep(self.period)
            now = self.driver.measured_psi()
            if np.any(np.abs(now - last) > per_kind(self.params, SETTLE_TOL)):
                since = self.clock()
            last = now
        self._settled_at = self.clock()
        self.driver.disable()  # hold still while the host grabs and tracks
        self._enabled = False

    def measured_psi(self) -> Array:
        """Configuration from the encoders (GET_STATE)."""
        return self.driver.measured_psi()

    def grab(self) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """The first frame captured after the last move settled."""
        t0 = self.clock()
        while True:
            frame = self.source.read()
            if frame is None:
                raise FrameSourceError(f"{self.source.name}: the camera stream ended during registration")
            if frame.t_capture >= self._settled_at:
                return frame.left, frame.right
            if self.clock() - t0 > self.timeout:
                raise FrameSourceError(f"{self.source.name}: no frame newer than the settled arm within "
                                       f"{self.timeout:.0f} s")

    def close(self) -> None:
        """Hold at the encoders' position and DISABLE (errors ignored: the box may be gone)."""
        if not self._enabled:
            try:
                self.driver.disable()
            except ActuatorError:
                pass
            return
        self._enabled = False
        try:
            self.driver.set_psi(self.driver.measured_psi())
        except ActuatorError:
            pass
        finally:
            try:
                self.driver.disable()
            except ActuatorError:
                pass
