"""The servo loop's actuator link over protocol v1 / v2: :class:`SerialLink` and its helpers.

Two ways time moves:

* **simulated** (``clock=SimClock``, the in-process emulator on a pty): the loop and the
  emulator share one simulated clock that moves only in :meth:`SerialLink.advance_to`. Every
  step of at most ``keepalive_s`` (0.1 s, well inside the device's 250 ms watchdog) ends with a
  GET_STATE, which feeds the watchdog and makes the emulator integrate its arm up to the new
  time before it answers. While the host computes (rendering, tracking, control) simulated time
  stands still, so the watchdog cannot trip spuriously however slow the host is; it still runs
  in simulated time (a clock moved without feeding it trips it).
* **real time** (``clock=None``: hardware, ``--serial PORT``, or the emulator on the wall
  clock): ``advance_to(t)`` sleeps until ``t`` seconds after :meth:`SerialLink.connect`,
  sending a GET_STATE keep-alive every ``keepalive_s`` while it waits. No keep-alive runs in
  the background: if the host goes silent (hung, killed, a cycle slower than 250 ms) the device
  disables itself, and the next command raises :class:`ActuatorNotEnabled` naming the watchdog.

Every STATE read is checked: an emergency stop, a watchdog trip or a device fault raises at
once (:class:`ActuatorEStopped`, :class:`ActuatorNotEnabled`, :class:`ActuatorError`).
:meth:`SerialLink.close` holds, sends DISABLE and closes the port, and never raises.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.models.limits import actuator_bounds
from wristmark.rig.link.actuator_driver import (
    PORT_ERRORS,
    ActuatorDriver,
    ActuatorError,
    ActuatorEStopped,
    ActuatorNotEnabled,
    ActuatorProtocolError,
    DeviceState,
)

Array = NDArray[np.float64]
CLOSE_ERRORS: tuple[type[Exception], ...] = (ActuatorError, *PORT_ERRORS)  # what close() reports, never raises

KEEPALIVE_S = 0.1  # [s] longest host silence while time advances (device watchdog: 0.25 s)
_HOLD_MARGIN = 1e-6  # [m or rad] a held target stays this far inside the limits (micro-unit rounding)


class SimClock:
    """Simulated time [s] shared by a link and an in-process emulator; moves only when set."""

    def __init__(self, t0: float = 0.0) -> None:
        self._t = float(t0)

    def __call__(self) -> float:
        """Current simulated time [s]."""
        return self._t

    def set(self, t: float) -> None:
        """Move time forward to ``t`` [s] (never backwards)."""
        self._t = max(self._t, float(t))


@dataclass
class LinkStats:
    """Counters of a link: keep-alives sent, real-time cycles started late and by how much."""

    keepalives: int = 0
    overruns: int = 0
    max_late_s: float = 0.0


class SerialLink:
    """:class:`rig.link.actuator_link.ActuatorLink` over an :class:`ActuatorDriver` (protocol v1 or v2).

    driver: an open driver (the link closes it in :meth:`close`). clock: a :class:`SimClock`
    shared with an in-process emulator, or None for real time. keepalive_s: longest silence
    while time advances [s]. pace: with a simulated clock, never run ahead of the wall clock
    (for watching a run; a slower host just runs slower). Call :meth:`connect` first.
    """

    def __init__(self, driver: ActuatorDriver, clock: SimClock | None = None,
                 keepalive_s: float = KEEPALIVE_S, pace: bool = False) -> None:
        if not 0 < keepalive_s < 0.25:
            raise ValueError(f"keepalive_s must be in (0, 0.25) s (the device watchdog), got {keepalive_s}")
        self.driver = driver
        self.clock = clock
        self.keepalive_s = float(keepalive_s)
        self.pace = bool(pace)
        self.params: Arm = driver.params
        self.state: DeviceState | None = None
        self.last_target: Array | None = None  # the last SET_TARGET's actuators [rad or m each]
        self.stats = LinkStats()
        self.t = clock() if clock is not None else 0.0
        self.close_error = ""  # why close() could not hold / disable ("" when it could)
        self._wall0 = time.monotonic()
        self._t_origin = self.t
        self._last_io = self._wall0  # wall time of the last answered request [s]
        self._connected = False
        self._closed = False

    @property
    def time(self) -> float:
        """The link's time now [s]: the shared simulated clock's, or in real time the ``t_now``
        given to :meth:`connect` plus the wall-clock seconds since (never before the instant
        :meth:`advance_to` last reached: a command sent late in a cycle is sent at its own time)."""
        if self.clock is not None or not self._connected:
            return self.t
        return max(self.t, self._t_origin + (time.monotonic() - self._wall0))

    @property
    def simulated(self) -> bool:
        """True when time is the shared simulated clock."""
        return self.clock is not None

    # -- setup ------------------------------------------------------------------------------
    def probe(self) -> DeviceState:
        """PING (protocol v1 with six actuators, or v2 with the arm's count: the driver checks) and
        GET_STATE; refuse a stopped or faulty device. Enables nothing, moves nothing."""
        try:
            self.driver.ping()
        except ActuatorProtocolError as e:
            raise ActuatorProtocolError(f"no usable actuator box on {self.driver.url!r}: {e}") from e
        st = self.driver.get_state()
        self.state = st
        if st.estopped:
            raise ActuatorEStopped("the device is emergency-stopped: release the stop and send RESET "
                                   "before servoing")
        if st.fault:
            raise ActuatorError("the device reports a fault (STATE flag bit4): check the actuator box")
        return st

    def connect(self, t_now: float | None = None) -> DeviceState:
        """:meth:`probe`, then ENABLE: from now on the watchdog wants a command every 250 ms.

        t_now: the loop's time now [s] (default: the link's); in real time ``advance_to(t)``
        then waits until ``t - t_now`` seconds from now.
        """
        self.probe()
        self.state = self.driver.enable()
        self._wall0 = self._last_io = time.monotonic()
        if t_now is not None and self.clock is None:
            self.t = float(t_now)
        self._t_origin = self.t
        self._connected = True
        return self.state

    # -- ActuatorLink -------------------------------------------------------------------------
    def advance_to(self, t: float) -> None:
        """Let time run to ``t`` [s], feeding the watchdog every ``keepalive_s``; refresh the state."""
        self._require_connected()
        if self.clock is not None:
            if self.clock() >= t:
                self._poll()  # time stands: still read a fresh STATE
            while self.clock() < t:
                step_to = min(t, self.clock() + self.keepalive_s)
                if self.pace:
                    self._sleep_until(self._wall0 + (step_to - self._t_origin))
                self.clock.set(step_to)
                self._poll()
        else:
            deadline = self._wall0 + (t - self._t_origin)
            late = time.monotonic() - deadline
            if late > 0.5 * self.keepalive_s:
                self.stats.overruns += 1
                self.stats.max_late_s = max(self.stats.max_late_s, late)
            while (remaining := deadline - time.monotonic()) > 0:
                time.sleep(min(remaining, self.keepalive_s))
                if deadline - time.monotonic() > 0:
                    self._poll()
            self._poll()
        self.t = max(self.t, t)

    def send_target(self, actuators: Array) -> None:
        """SET_TARGET the arm's actuators [rad or m each]; the driver's typed errors propagate."""
        self._require_connected()
        silent = time.monotonic() - self._last_io
        try:
            self.state = self.driver.set_target(np.asarray(actuators, float))
            self.last_target = np.array(actuators, float)
        except ActuatorNotEnabled as e:
            raise self._why_disabled(silent_s=silent) or e from None
        self._last_io = time.monotonic()

    def hold(self) -> None:
        """Hold the current position: SET_TARGET the measured positions (a disabled or
        emergency-stopped device already holds)."""
        st = self.driver.get_state()
        self.state = st
        if st.enabled and not st.estopped:
            lo, hi = actuator_bounds(self.params)
            target = np.clip(st.positions, lo + _HOLD_MARGIN, hi - _HOLD_MARGIN)
            self.state = self.driver.set_target(target)
            self.last_target = target

    def measured_actuators(self) -> Array:
        """Encoder readings from a fresh GET_STATE [rad or m each]."""
        self.state = self.driver.get_state()
        return self.state.positions.copy()

    def close(self) -> None:
        """Hold, DISABLE, close the port. Always tries both commands; never raises."""
        if self._closed:
            return
        self._closed = True
        problems = []
        for name, step in (("hold", self.hold), ("DISABLE", self._disable)):
            if not self.driver.is_open:
                problems = ["the device is unreachable (port closed); its 250 ms watchdog holds and disables it"]
                break
            try:
                step()
            except CLOSE_ERRORS as e:
                problems.append(f"{name} failed: {e}")
        self.driver.close()
        self.close_error = "; ".join(problems)

    # -- internals ----------------------------------------------------------------------------
    def _disable(self) -> None:
        try:
            self.state = self.driver.disable()
        except ActuatorEStopped:
            pass  # an emergency stop already holds and disables; the device refuses DISABLE then

    def _require_connected(self) -> None:
        if not self._connected:
            raise ActuatorError("serial link not connected: call connect() first")
        if self._closed:
            raise ActuatorError("serial link is closed")

    def _sleep_until(self, wall: float) -> None:
        remaining = wall - time.monotonic()
        if remaining > 0:
            time.sleep(remaining)

    def _poll(self) -> None:
        silent = time.monotonic() - self._last_io
        st = self.driver.get_state()
        self._last_io = time.monotonic()
        self.stats.keepalives += 1
        self.state = st
        if st.estopped:
            raise ActuatorEStopped(f"the device was emergency-stopped (device clock {st.clock_s:.3f} s); "
                                   "it holds the arm; send RESET before the next run")
        if st.fault:
            raise ActuatorError(f"the device reports a fault (device clock {st.clock_s:.3f} s); it holds the arm")
        if not st.enabled:
            raise self._why_disabled(st, silent) or ActuatorNotEnabled("the device disabled itself")

    def _why_disabled(self, st: DeviceState | None = None, silent_s: float | None = None) -> ActuatorError | None:
        """A clear error for a device that stopped obeying (None if the state says nothing)."""
        if st is None:
            try:
                st = self.driver.get_state()
            except ActuatorError:
                return None
            self.state = st
        if st.estopped:
            return ActuatorEStopped("the device was emergency-stopped; it holds the arm; send RESET "
                                    "before the next run")
        if st.watchdog_tripped:
            gap = "" if self.clock is not None or silent_s is None else \
                f" (this host was silent for {1000 * silent_s:.0f} ms: a cycle took too long?)"
            return ActuatorNotEnabled("the device's watchdog tripped: the host sent nothing for more than "
                                      f"250 ms, so the device held the arm and disabled itself{gap}")
        if not st.enabled:
            return ActuatorNotEnabled("the device is disabled (DISABLE from elsewhere or a restart)")
        return None
