"""Host driver for an actuator box speaking protocol v1 or v2 over a serial line (or pty, socket).

Usage::

    with ActuatorDriver("/dev/ttyACM0", params=RobotParams()) as box:
        box.ping()                             # negotiates the protocol version (below)
        box.enable()
        state = box.set_target(actuators)      # the arm's m actuators [rad or m each]
        psi = box.measured_psi()

Version negotiation (docs/protocol.md): the host speaks first with PING, whose PONG (u8
version, u8 n) is the same two bytes in both versions. A device answering version 1 carries 6
actuators: the host speaks v1 and refuses an arm with another count in one line naming both. A
device answering version 2 carries n actuators: the host speaks v2 if n is its arm's actuator
count, else refuses in one line naming both. Nothing is enabled or moved before that check.
Until a PONG arrives the driver frames SET_TARGET and STATE with its arm's count.

Every request carries a fresh sequence number (1..255) and waits for the reply that echoes it;
a request unanswered within ``timeout`` seconds is re-sent up to ``retries`` times before
:class:`ActuatorTimeout`. Device errors become typed exceptions. Leaving the ``with`` block,
normally, on an exception or on Ctrl-C, sends DISABLE (best effort) and closes the port.
Keep the box fed: an enabled device disables itself after 250 ms without SET_TARGET or
GET_STATE (watchdog).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from types import TracebackType

import numpy as np
import serial
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm, ArmSpec, actuator_names, actuator_units, arm_size
from wristmark.models.errors import ConfigError, LimitError, WristmarkError
from wristmark.models.limits import actuator_bounds
from wristmark.models.robot_params import RobotParams
from wristmark.models.units import MICRO
from wristmark.rig.link import protocol as P

try:  # pyserial's POSIX port: flush (tcdrain) and the buffer resets raise termios.error, not OSError
    import termios

    PORT_ERRORS: tuple[type[Exception], ...] = (serial.SerialException, OSError, termios.error)
except ImportError:  # pragma: no cover - not POSIX
    PORT_ERRORS = (serial.SerialException, OSError)

Array = NDArray[np.float64]


class ActuatorError(WristmarkError):
    """Base of every failure talking to the actuator box."""


class ActuatorTimeout(ActuatorError):
    """No valid reply within the timeout after all retries."""


class ActuatorRejected(ActuatorError):
    """The device refused a target outside its limits (ERROR 5, flag bit3); nothing moved."""


class ActuatorNotEnabled(ActuatorError):
    """SET_TARGET while disabled (ERROR 4), e.g. after a watchdog trip; call enable()."""


class ActuatorEStopped(ActuatorError):
    """The device is emergency-stopped (ERROR 6); call reset() then enable()."""


class ActuatorDisconnected(ActuatorError):
    """The serial port could not be opened, or closed / failed while in use."""


class ActuatorProtocolError(ActuatorError):
    """The device answered with something the protocol does not allow, or speaks a protocol
    version / actuator count that does not fit this host's arm."""


@dataclass(frozen=True)
class DeviceState:
    """A STATE reply decoded: positions of the arm's actuators [rad or m each; the reference
    arm's rad, m, m, m, m, m], flags, device clock [ms]."""

    positions: Array
    flags: int
    clock_ms: int

    @property
    def enabled(self) -> bool:
        """bit0: SET_TARGET is obeyed."""
        return bool(self.flags & P.FLAG_ENABLED)

    @property
    def estopped(self) -> bool:
        """bit1: emergency stop active."""
        return bool(self.flags & P.FLAG_ESTOPPED)

    @property
    def watchdog_tripped(self) -> bool:
        """bit2: the watchdog disabled the device (until the next ENABLE)."""
        return bool(self.flags & P.FLAG_WATCHDOG)

    @property
    def target_rejected(self) -> bool:
        """bit3: the last target was outside the limits."""
        return bool(self.flags & P.FLAG_REJECTED)

    @property
    def fault(self) -> bool:
        """bit4: device fault."""
        return bool(self.flags & P.FLAG_FAULT)

    @property
    def clock_s(self) -> float:
        """Device clock [s]."""
        return self.clock_ms / 1000.0

    @classmethod
    def from_packet(cls, s: P.State) -> DeviceState:
        """Convert a STATE packet to SI."""
        return cls(P.si_from_micro(s.positions_micro, len(s.positions_micro)), s.flags, s.clock_ms)


def _arm_label(params: Arm) -> str:
    return f"this arm ({params.name})" if isinstance(params, ArmSpec) and params.name else "this arm"


def check_protocol_arm(params: Arm) -> None:
    """Raise ConfigError unless protocol v1 (a device answering version 1) can carry the arm's
    actuators: 6, the reference arm's layout. Protocol v2 carries any count from 1 to 16."""
    m = arm_size(params)[1]
    if m != P.ACTUATOR_COUNT:
        raise ConfigError(f"the actuator box speaks protocol v1, which carries 6 actuators; this arm has {m} "
                          "(a protocol-v2 box carries 1 to 16: firmware, or wristmark emulator --pty --robot FILE); "
                          "or, on the simulated bench, the in-process link (wristmark servo --direct)")


def check_device_arm(version: int, count: int, params: Arm) -> None:
    """Raise ActuatorProtocolError (one line naming both counts) unless a device that answered
    PONG ``version``, ``count`` can drive the arm ``params``: v1 with 6 actuators and a
    6-actuator arm, or v2 with exactly the arm's actuator count."""
    m = arm_size(params)[1]
    if version == P.PROTOCOL_VERSION:
        if count != P.ACTUATOR_COUNT:
            raise ActuatorProtocolError(f"device claims protocol v1 with {count} actuators; v1 carries exactly 6: "
                                        "nothing was moved")
        if m != P.ACTUATOR_COUNT:
            raise ActuatorProtocolError(f"device speaks protocol v1 with 6 actuators; {_arm_label(params)} has {m} "
                                        "(a protocol-v2 box carries any count): nothing was moved")
        return
    if version == P.PROTOCOL_V2:
        if count != m:
            raise ActuatorProtocolError(f"device speaks protocol v2 with {count} actuators; {_arm_label(params)} "
                                        f"has {m}: check --robot against the box; nothing was moved")
        return
    raise ActuatorProtocolError(f"device speaks protocol v{version} with {count} actuators; this host speaks "
                                "v1 (6 actuators) and v2 (1 to 16): nothing was moved")


class ActuatorDriver:
    """Request/response client of one actuator box (protocol v1 or v2, see :meth:`ping`).

    url_or_path: '/dev/ttyUSB0', a pty path, 'loop://' or 'socket://host:port'.
    timeout: wait per attempt [s]; retries: extra attempts after a timeout or a corrupted frame.
    params: robot used by set_psi / measured_psi, for the actuator count (1..16) and for error
    messages on rejected targets.
    """

    def __init__(self, url_or_path: str, baudrate: int = 115200, timeout: float = 0.05, retries: int = 2,
                 params: Arm | None = None) -> None:
        if timeout <= 0 or retries < 0:
            raise LimitError(f"timeout must be > 0 s and retries >= 0, got {timeout}, {retries}")
        self.url = url_or_path
        self.baudrate = int(baudrate)
        self.timeout = float(timeout)
        self.retries = int(retries)
        self.params: Arm = params if params is not None else RobotParams()
        m = arm_size(self.params)[1]
        if not 1 <= m <= P.MAX_ACTUATORS:
            raise ConfigError(f"the actuator box protocol carries 1 to {P.MAX_ACTUATORS} actuators; "
                              f"{_arm_label(self.params)} has {m}")
        self.count = m  # actuators on the wire: the arm's (confirmed by ping())
        lo, hi = actuator_bounds(self.params)  # in micro-units, rounded inwards: see set_target
        self._bounds_si = (lo, hi)
        self._bounds_micro = (np.ceil(np.round(lo * MICRO, 6)), np.floor(np.round(hi * MICRO, 6)))
        self.version: int | None = None  # the device's protocol version, once ping() answered
        self._parser = P.StreamParser(count=m)
        self._seq = 0
        self._psi_hint: Array | None = None
        self.stats = {"sent": 0, "retries": 0, "dropped": 0}
        self._port: serial.SerialBase | None = None
        self._open()

    # -- connection ---------------------------------------------------------------------------
    def _open(self) -> None:
        try:
            self._port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=self.timeout,
                                               write_timeout=max(1.0, self.timeout))
        except (serial.SerialException, OSError, ValueError) as e:
            raise ActuatorDisconnected(f"cannot open actuator port {self.url!r}: {e}; check the path / URL") from e
        self._parser.reset()

    def close(self) -> None:
        """Close the port (does not disable the device; see :meth:`__exit__`)."""
        if self._port is not None:
            try:
                self._port.close()
            except PORT_ERRORS:
                pass
            self._port = None

    def reconnect(self) -> None:
        """Close and reopen the port (after ActuatorDisconnected)."""
        self.close()
        self._open()

    @property
    def is_open(self) -> bool:
        """True while the port is open."""
        return self._port is not None and bool(self._port.is_open)

    def __enter__(self) -> ActuatorDriver:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if self.is_open:
                self.disable()
        except ActuatorError:
            pass
        finally:
            self.close()

    # -- transport ----------------------------------------------------------------------------
    def _next_seq(self) -> int:
        self._seq = self._seq % 255 + 1  # 1..255; seq 0 marks "unknown" in device errors
        return self._seq

    def _port_or_raise(self) -> serial.SerialBase:
        if self._port is None:
            raise ActuatorDisconnected(f"actuator port {self.url!r} is closed; call reconnect()")
        return self._port

    def _write(self, data: bytes) -> None:
        port = self._port_or_raise()
        try:
            port.write(data)
            port.flush()
        except PORT_ERRORS as e:  # e.g. the device's end closed between the write and the flush
            self.close()
            raise ActuatorDisconnected(f"actuator port {self.url!r} failed on write: {e}; reconnect") from e

    def _read_some(self) -> bytes:
        port = self._port_or_raise()
        try:
            return bytes(port.read(port.in_waiting or 1))
        except PORT_ERRORS as e:
            self.close()
            raise ActuatorDisconnected(f"actuator port {self.url!r} failed on read: {e}; reconnect") from e

    def request(self, packet_type: P.MsgType, payload: bytes = b"") -> P.Packet:
        """Send one request, return the reply echoing its seq (device errors are raised).

        Re-sent with a fresh seq after ``timeout`` without a reply (up to ``retries`` times) and
        at once when the device reports a corrupted frame (ERROR 1, seq 0); a reply to any of
        this request's attempts is accepted, so late replies are never lost.
        """
        last = "no reply"
        seqs: set[int] = set()
        fast_resends = 0
        for attempt in range(self.retries + 1):
            if attempt:
                self.stats["retries"] += 1
            seqs.add(self._send(packet_type, payload))
            deadline = time.monotonic() + self.timeout
            while time.monotonic() < deadline:
                for item in self._parser.feed(self._read_some()):
                    if isinstance(item, P.ParseError):
                        self.stats["dropped"] += 1
                        last = f"corrupted reply ({item.reason})"
                    elif item.seq in seqs:
                        if isinstance(item, P.Error):
                            self._raise_device_error(item.code, packet_type, payload)
                        return item
                    elif isinstance(item, P.Error) and item.seq == 0 and item.code == P.ERR_BAD_CRC:
                        last = "device saw a corrupted frame"
                        if fast_resends <= self.retries:  # our frame may have been damaged: resend now
                            fast_resends += 1
                            self.stats["retries"] += 1
                            seqs.add(self._send(packet_type, payload))
                            deadline = time.monotonic() + self.timeout
                    else:
                        self.stats["dropped"] += 1  # reply to an earlier, abandoned request
        raise ActuatorTimeout(
            f"actuator box on {self.url!r} gave no valid reply to {packet_type.name} after "
            f"{self.retries + 1} attempts of {self.timeout * 1000:.0f} ms ({last}); check cable and power"
        )

    def _send(self, packet_type: P.MsgType, payload: bytes) -> int:
        seq = self._next_seq()
        self._write(P.encode_packet(packet_type, seq, payload))
        self.stats["sent"] += 1
        return seq

    def _raise_device_error(self, code: int, packet_type: P.MsgType, payload: bytes) -> None:
        if code == P.ERR_OUT_OF_LIMITS:
            raise ActuatorRejected(f"target rejected by the device limits{self._limit_detail(payload)}; nothing moved")
        if code == P.ERR_NOT_ENABLED:
            raise ActuatorNotEnabled(
                "device is disabled (never enabled, disabled, or watchdog tripped after 250 ms without "
                "SET_TARGET/GET_STATE); call enable()"
            )
        if code == P.ERR_ESTOPPED:
            raise ActuatorEStopped(
                f"{packet_type.name} refused: device is emergency-stopped; call reset() then enable()"
            )
        name = P.ERROR_NAMES.get(code, f"unknown error code {code}")
        raise ActuatorProtocolError(f"device answered {packet_type.name} with ERROR {code} ({name}); "
                                    "check firmware protocol version")

    def _limit_detail(self, payload: bytes) -> str:
        if len(payload) != 4 * self.count:
            return ""
        a = P.si_from_micro(np.frombuffer(payload, "<i4").tolist(), self.count)
        lo, hi = actuator_bounds(self.params)
        names, units = actuator_names(self.params), actuator_units(self.params)
        bad = [f"{names[i]}={a[i]:.6g} {units[i]} not in [{lo[i]:.6g}, {hi[i]:.6g}]"
               for i in range(self.count) if not lo[i] <= a[i] <= hi[i]]
        return f" ({', '.join(bad)})" if bad else ""

    def _state_request(self, packet_type: P.MsgType, payload: bytes = b"") -> DeviceState:
        reply = self.request(packet_type, payload)
        if not isinstance(reply, P.State):
            raise ActuatorProtocolError(f"expected STATE in reply to {packet_type.name}, got {type(reply).__name__}")
        return DeviceState.from_packet(reply)

    # -- commands -----------------------------------------------------------------------------
    def ping(self) -> P.Pong:
        """PING; returns the PONG and speaks its version from now on. Raises ActuatorProtocolError
        (one line naming both counts) unless version 1 with 6 actuators and a 6-actuator arm, or
        version 2 with the arm's actuator count."""
        reply = self.request(P.MsgType.PING)
        if not isinstance(reply, P.Pong):
            raise ActuatorProtocolError(f"expected PONG, got {type(reply).__name__}")
        check_device_arm(reply.version, reply.count, self.params)
        self.version = reply.version
        self.count = reply.count
        self._parser.set_count(reply.count)
        return reply

    def enable(self) -> DeviceState:
        """ENABLE: the device obeys SET_TARGET from now on (clears the watchdog flag)."""
        return self._state_request(P.MsgType.ENABLE)

    def disable(self) -> DeviceState:
        """DISABLE: hold position and ignore targets."""
        return self._state_request(P.MsgType.DISABLE)

    def get_state(self) -> DeviceState:
        """GET_STATE: measured positions [rad or m each], flags, clock (feeds the watchdog)."""
        return self._state_request(P.MsgType.GET_STATE)

    def estop(self) -> DeviceState:
        """ESTOP: hold at once; only GET_STATE, PING and RESET are served afterwards."""
        return self._state_request(P.MsgType.ESTOP)

    def reset(self) -> DeviceState:
        """RESET: clear an emergency stop; the device stays disabled."""
        return self._state_request(P.MsgType.RESET)

    def set_target(self, actuators: object) -> DeviceState:
        """SET_TARGET the arm's actuators [rad or m each, :func:`actuator_units`]; returns the STATE reply.

        Raises ActuatorRejected (outside limits), ActuatorNotEnabled, ActuatorEStopped.
        """
        try:
            micro = P.micro_from_si(actuators, self.count)
        except LimitError as e:
            raise ActuatorRejected(f"target not sendable: {e}") from e
        # a target within the limits stays within them on the wire: rounded to the nearest
        # micro-unit, a value within half a unit of a limit (phi = pi at its range's end) would
        # land beyond it and the device would reject the whole target
        a = np.asarray(actuators, float)
        inside = (a >= self._bounds_si[0]) & (a <= self._bounds_si[1])
        clipped = np.where(inside, np.clip(micro, *self._bounds_micro), micro)
        micro = tuple(int(x) for x in clipped)
        return self._state_request(P.MsgType.SET_TARGET, P.payload_of(P.SetTarget(micro)))

    def set_psi(self, psi: object) -> DeviceState:
        """Command configuration psi [rad or m each] through the arm's actuation map."""
        q = np.asarray(psi, dtype=float)
        state = self.set_target(actuators_from_psi(self.params, q))
        self._psi_hint = q
        return state

    def measured_psi(self) -> Array:
        """Configuration psi from the measured actuator positions (GET_STATE)."""
        state = self.get_state()
        psi = psi_from_actuators(self.params, state.positions, self._psi_hint)
        self._psi_hint = psi
        return psi
