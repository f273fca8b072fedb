"""The actuator box, emulated: protocol v1 / v2 device side driving any :class:`ActuatedArm`.

Protocol version: v1 (6 actuators) for the reference arm's flat robot file (:class:`RobotParams`),
so today's behaviour is unchanged byte for byte; v2 with n = the arm's actuator count (1..16) for
a format-2 robot file (:class:`ArmSpec`), even when n = 6. ``protocol_version`` overrides.

Bytes in, bytes out (:meth:`ActuatorEmulator.receive`), or served on a fresh pseudo-terminal
(:meth:`ActuatorEmulator.serve_pty`) in a background thread. The arm is advanced in the
emulator's clock (wall clock by default; pass a simulated clock to share time with a loop)
before every answer and every ~10 ms while serving, so the watchdog fires on time.

Safety (docs/design.md): SET_TARGET only when enabled and not emergency-stopped; a target outside
:func:`models.limits.actuator_bounds` is rejected whole (ERROR 5, flag bit3, the arm holds);
enabled and silent (no SET_TARGET / GET_STATE) for more than ``watchdog_s`` -> hold, disable,
watchdog flag until the next ENABLE; ESTOP holds at once and leaves only GET_STATE, PING,
RESET (and ESTOP) served; RESET clears the stop and stays disabled. Bad bytes never raise.
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty
from collections.abc import Callable

import numpy as np

from wristmark.models.arm_shape import ArmShape
from wristmark.models.arm_spec import Arm, arm_size
from wristmark.models.errors import ConfigError, WristmarkError
from wristmark.models.limits import actuator_bounds
from wristmark.models.plant_interface import ActuatedArm
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import check_protocol_arm

_POLL_S = 0.01  # serve loop wake-up period [s]: watchdog and arm advance resolution


class ActuatorEmulator:
    """Device side of protocol v1 / v2 around an arm. Thread-safe: one lock guards the state.

    protocol_version: 1 or 2; None: 1 for the flat reference arm (RobotParams), else 2. The
    actuator count on the wire is the arm's (v1: must be 6)."""

    def __init__(self, arm: ActuatedArm, params: Arm, watchdog_s: float = 0.25,
                 clock: Callable[[], float] = time.monotonic, protocol_version: int | None = None) -> None:
        if watchdog_s <= 0:
            raise WristmarkError(f"watchdog_s must be > 0 s, got {watchdog_s}")
        self.arm = arm
        self.params = params
        if protocol_version is None:
            protocol_version = P.PROTOCOL_VERSION if isinstance(params, RobotParams) else P.PROTOCOL_V2
        if protocol_version == P.PROTOCOL_VERSION:
            check_protocol_arm(params)
        elif protocol_version != P.PROTOCOL_V2:
            raise ConfigError(f"the emulator speaks protocol v1 or v2, not v{protocol_version}")
        self.protocol_version = int(protocol_version)
        self.count = arm_size(params)[1]
        if not 1 <= self.count <= P.MAX_ACTUATORS:
            raise ConfigError(f"protocol v2 carries 1 to {P.MAX_ACTUATORS} actuators; this arm has {self.count}")
        self.watchdog_s = float(watchdog_s)
        self.clock = clock
        self.lo, self.hi = actuator_bounds(params)
        self.enabled = False
        self.estopped = False
        self.watchdog_tripped = False
        self.target_rejected = False
        self.fault = False
        self.counters = {"packets": 0, "errors": 0}
        self._parser = P.StreamParser(count=self.count)
        self._lock = threading.RLock()
        self._t0 = clock()
        self._t_last = self._t0
        self._t_fed = self._t0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._fds: tuple[int, int] | None = None
        self.arm.hold()

    # -- state ----------------------------------------------------------------------------------
    @property
    def flags(self) -> int:
        """STATE flag word."""
        return ((P.FLAG_ENABLED if self.enabled else 0) | (P.FLAG_ESTOPPED if self.estopped else 0)
                | (P.FLAG_WATCHDOG if self.watchdog_tripped else 0)
                | (P.FLAG_REJECTED if self.target_rejected else 0) | (P.FLAG_FAULT if self.fault else 0))

    def clock_ms(self) -> int:
        """Device clock [ms] since start, wrapping at 2^32."""
        return int((self.clock() - self._t0) * 1000.0) & 0xFFFFFFFF

    def poll(self) -> None:
        """Advance the arm to now and run the watchdog (holding exactly at the trip time)."""
        with self._lock:
            now = self.clock()
            if self.enabled and now - self._t_fed > self.watchdog_s:
                t_trip = self._t_fed + self.watchdog_s
                self._advance(t_trip - self._t_last)
                self._t_last = max(self._t_last, t_trip)
                self._safe_hold()
                self.enabled = False
                self.watchdog_tripped = True
            self._advance(now - self._t_last)
            self._t_last = max(self._t_last, now)

    def sample_arm(self) -> tuple[float, ArmShape]:
        """Advance the arm to now (the watchdog runs) and return (now on the emulator's clock [s],
        the arm's true shape then), atomically: what a camera sees at that instant."""
        with self._lock:
            self.poll()
            return self._t_last, self.arm.true_shape()

    def _advance(self, dt: float) -> None:
        if dt > 0 and not self.fault:
            try:
                self.arm.advance(dt)
            except WristmarkError:
                self.fault = True

    def _safe_hold(self) -> None:
        try:
            self.arm.hold()
        except WristmarkError:
            self.fault = True

    # -- bytes ----------------------------------------------------------------------------------
    def receive(self, data: bytes) -> bytes:
        """Process incoming bytes; return the reply bytes (possibly empty). Never raises."""
        with self._lock:
            self.poll()
            out = bytearray()
            for item in self._parser.feed(data):
                reply = self._handle(item)
                if isinstance(reply, P.Error):
                    self.counters["errors"] += 1
                out += P.encode(reply)
            return bytes(out)

    def _state(self, seq: int) -> P.State:
        a = self.arm.measured_actuators()
        try:
            micro = P.micro_from_si(a, self.count)
        except WristmarkError:
            self.fault = True
            micro = (0,) * self.count
        return P.State(micro, self.flags, self.clock_ms(), seq=seq)

    def _handle(self, item: P.Packet | P.ParseError) -> P.Packet:
        if isinstance(item, P.ParseError):
            seq = item.seq if item.seq is not None and item.code != P.ERR_BAD_CRC else 0
            return P.Error(item.code, seq=seq)
        self.counters["packets"] += 1
        seq = item.seq
        if isinstance(item, P.Ping):
            return P.Pong(self.protocol_version, self.count, seq=seq)
        if isinstance(item, P.GetState):
            self._t_fed = self.clock()
            return self._state(seq)
        if isinstance(item, P.EStop):
            self._safe_hold()
            self.enabled = False
            self.estopped = True
            return self._state(seq)
        if isinstance(item, P.Reset):
            self._safe_hold()
            self.estopped = False
            self.enabled = False
            self.target_rejected = False
            return self._state(seq)
        if not isinstance(item, P.Enable | P.Disable | P.SetTarget):
            return P.Error(P.ERR_UNKNOWN_TYPE, seq=seq)  # a device -> host type sent to the device
        if self.estopped:
            return P.Error(P.ERR_ESTOPPED, seq=seq)
        if isinstance(item, P.Enable):
            self._safe_hold()
            self.enabled = True
            self.watchdog_tripped = False
            self._t_fed = self.clock()
            return self._state(seq)
        if isinstance(item, P.Disable):
            self._safe_hold()
            self.enabled = False
            return self._state(seq)
        return self._set_target(item)

    def _set_target(self, item: P.SetTarget) -> P.Packet:
        if not self.enabled:
            return P.Error(P.ERR_NOT_ENABLED, seq=item.seq)
        self._t_fed = self.clock()
        a = P.si_from_micro(item.targets_micro, self.count)
        if np.any(a < self.lo) or np.any(a > self.hi):
            self.target_rejected = True
            self._safe_hold()
            return P.Error(P.ERR_OUT_OF_LIMITS, seq=item.seq)
        self.target_rejected = False
        try:
            self.arm.command(a)
        except WristmarkError:
            self.fault = True
            self._safe_hold()
        return self._state(item.seq)

    # -- pty server -----------------------------------------------------------------------------
    def serve_pty(self) -> str:
        """Open a raw pty pair, serve on the master end in a daemon thread; return the slave path."""
        if self._thread is not None:
            raise WristmarkError("emulator is already serving; call stop() first")
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        self._fds = (master, slave)
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, args=(master,), name="actuator-emulator", daemon=True)
        self._thread.start()
        return os.ttyname(slave)

    def _serve(self, master: int) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([master], [], [], _POLL_S)
                if not ready:
                    self.poll()
                    continue
                data = os.read(master, 4096)
            except (OSError, ValueError):
                return  # master closed by stop()
            if not data:
                return
            reply = self.receive(data)
            try:
                if reply:
                    os.write(master, reply)
            except OSError:
                return

    def stop(self) -> None:
        """Stop serving and close both ends of the pty (clients see the device vanish)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(1.0)
        self._thread = None
        if self._fds is not None:
            for fd in self._fds:
                try:
                    os.close(fd)
                except OSError:
                    pass
            self._fds = None

    def __enter__(self) -> ActuatorEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
