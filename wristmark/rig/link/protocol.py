"""Actuator serial protocol v1 and v2 (docs/protocol.md): packets and framing.

On the wire every packet is ``COBS(type u8 | seq u8 | payload | crc u16 LE) + 0x00`` with
crc = CRC-16/CCITT-FALSE over type, seq and payload; integers are little-endian. Actuator
values travel as i32 micro-units (µrad for a rotation, µm for a length). Protocol v1 carries
exactly 6 actuators (phi, d, s1a, s1b, s2a, s2b); protocol v2 is byte for byte the same with n
actuators (1 to 16, the robot file's actuator order), so SET_TARGET and STATE are sized by n and
v1 is v2 with n = 6. PONG (u8 version, u8 n) has the same two bytes in both, which is how a host
learns n. :func:`micro_from_si` / :func:`si_from_micro` convert.

:class:`StreamParser` turns an arbitrary byte stream into packets and :class:`ParseError`
records; it never raises, bounds its buffer and yields a packet only if its frame decodes,
its CRC matches and its payload has exactly the length its type requires for its ``count``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum
from typing import ClassVar, TypeAlias

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import LimitError
from wristmark.models.units import MICRO
from wristmark.rig.link.cobs import CobsError, cobs_decode, cobs_encode
from wristmark.rig.link.crc16 import crc16_ccitt_false

Array = NDArray[np.float64]

PROTOCOL_VERSION = 1  # protocol v1: exactly ACTUATOR_COUNT actuators
ACTUATOR_COUNT = 6
PROTOCOL_V2 = 2  # protocol v2: n actuators, 1 <= n <= MAX_ACTUATORS
MAX_ACTUATORS = 16
I32_MIN, I32_MAX = -(2**31), 2**31 - 1
MAX_FRAME = 64  # longest accepted COBS frame [bytes]; the longest v1 packet (STATE) encodes to 35


def check_count(count: int) -> int:
    """``count`` as an int if it is a valid actuator count (1..16), else LimitError."""
    if not 1 <= int(count) <= MAX_ACTUATORS:
        raise LimitError(f"the actuator count must be in 1..{MAX_ACTUATORS}, got {count}")
    return int(count)


def max_frame_for(count: int) -> int:
    """Longest accepted COBS frame [bytes] for ``count`` actuators: 64 up to 6 (v1's bound),
    else the n-actuator STATE's encoded size (4 n + 11 bytes) plus 5 bytes of slack."""
    return max(MAX_FRAME, 4 * check_count(count) + 16)


class MsgType(IntEnum):
    """Packet types: host -> device below 0x80, device -> host above."""

    PING = 0x01
    ENABLE = 0x02
    DISABLE = 0x03
    SET_TARGET = 0x04
    GET_STATE = 0x05
    ESTOP = 0x06
    RESET = 0x07
    PONG = 0x81
    STATE = 0x84
    ERROR = 0xEE


# STATE flag bits.
FLAG_ENABLED = 1 << 0
FLAG_ESTOPPED = 1 << 1
FLAG_WATCHDOG = 1 << 2
FLAG_REJECTED = 1 << 3
FLAG_FAULT = 1 << 4

# ERROR codes.
ERR_BAD_CRC = 1
ERR_BAD_LENGTH = 2
ERR_UNKNOWN_TYPE = 3
ERR_NOT_ENABLED = 4
ERR_OUT_OF_LIMITS = 5
ERR_ESTOPPED = 6

ERROR_NAMES = {
    ERR_BAD_CRC: "bad CRC / framing",
    ERR_BAD_LENGTH: "bad length",
    ERR_UNKNOWN_TYPE: "unknown type",
    ERR_NOT_ENABLED: "not enabled",
    ERR_OUT_OF_LIMITS: "target outside limits",
    ERR_ESTOPPED: "emergency-stopped",
}

_STATE_TAIL = struct.Struct("<HI")  # STATE's flags u16 and clock u32 after the n positions


@dataclass(frozen=True)
class Ping:
    """Host -> device: are you there? Answered by :class:`Pong`."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.PING


@dataclass(frozen=True)
class Enable:
    """Host -> device: accept SET_TARGET from now on (clears the watchdog flag)."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.ENABLE


@dataclass(frozen=True)
class Disable:
    """Host -> device: hold position and ignore SET_TARGET."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.DISABLE


@dataclass(frozen=True)
class GetState:
    """Host -> device: report positions, flags and clock (also feeds the watchdog)."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.GET_STATE


@dataclass(frozen=True)
class EStop:
    """Host -> device: hold at once; ignore all but GET_STATE, PING and RESET."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.ESTOP


@dataclass(frozen=True)
class Reset:
    """Host -> device: clear an emergency stop; the device stays disabled."""

    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.RESET


@dataclass(frozen=True)
class SetTarget:
    """Host -> device: n i32 targets in micro-units, the arm's actuator order (v1: six, phi, d,
    s1a, s1b, s2a, s2b)."""

    targets_micro: tuple[int, ...]
    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.SET_TARGET


@dataclass(frozen=True)
class Pong:
    """Device -> host: protocol version and actuator count."""

    version: int
    count: int
    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.PONG


@dataclass(frozen=True)
class State:
    """Device -> host: n i32 measured positions [micro-units] (v1: six), u16 flags, u32 clock [ms]."""

    positions_micro: tuple[int, ...]
    flags: int
    clock_ms: int
    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.STATE


@dataclass(frozen=True)
class Error:
    """Device -> host: error code (ERR_*)."""

    code: int
    seq: int = 0
    TYPE: ClassVar[MsgType] = MsgType.ERROR


Packet: TypeAlias = Ping | Enable | Disable | GetState | EStop | Reset | SetTarget | Pong | State | Error
COMMANDS = (Ping, Enable, Disable, GetState, EStop, Reset, SetTarget)  # host -> device


@dataclass(frozen=True)
class ParseError:
    """A frame the parser dropped. ``code`` is the ERROR code a device answers with (1, 2, 3);
    ``seq`` is known only when the CRC matched; ``reason`` is human-readable."""

    code: int
    reason: str
    seq: int | None = None
    frame: bytes = field(default=b"", repr=False)


_FIXED_LEN = {
    MsgType.PING: 0,
    MsgType.ENABLE: 0,
    MsgType.DISABLE: 0,
    MsgType.GET_STATE: 0,
    MsgType.ESTOP: 0,
    MsgType.RESET: 0,
    MsgType.PONG: 2,
    MsgType.ERROR: 1,
}


def payload_len(mtype: MsgType, count: int = ACTUATOR_COUNT) -> int:
    """Payload bytes of a packet of type ``mtype`` with ``count`` actuators (v1: 6)."""
    if mtype is MsgType.SET_TARGET:
        return 4 * count
    if mtype is MsgType.STATE:
        return 4 * count + _STATE_TAIL.size
    return _FIXED_LEN[mtype]

_EMPTY: dict[MsgType, type[Ping | Enable | Disable | GetState | EStop | Reset]] = {
    MsgType.PING: Ping,
    MsgType.ENABLE: Enable,
    MsgType.DISABLE: Disable,
    MsgType.GET_STATE: GetState,
    MsgType.ESTOP: EStop,
    MsgType.RESET: Reset,
}


def _check_u8(name: str, v: int) -> int:
    if not 0 <= int(v) <= 0xFF:
        raise LimitError(f"{name} must be in 0..255, got {v}")
    return int(v)


def payload_of(packet: Packet) -> bytes:
    """The payload bytes of ``packet`` (no type, seq or CRC)."""
    if isinstance(packet, SetTarget):
        v = _check_i32s(packet.targets_micro, None)
        return struct.pack(f"<{len(v)}i", *v)
    if isinstance(packet, Pong):
        return bytes((_check_u8("version", packet.version), _check_u8("count", packet.count)))
    if isinstance(packet, State):
        if not 0 <= packet.flags <= 0xFFFF or not 0 <= packet.clock_ms <= 0xFFFFFFFF:
            raise LimitError("STATE flags must fit u16 and clock_ms u32")
        v = _check_i32s(packet.positions_micro, None)
        return struct.pack(f"<{len(v)}i", *v) + _STATE_TAIL.pack(packet.flags, packet.clock_ms)
    if isinstance(packet, Error):
        return bytes((_check_u8("error code", packet.code),))
    return b""


def encode_packet(type: int, seq: int, payload: bytes = b"") -> bytes:
    """Wire bytes of one packet: COBS(type | seq | payload | crc16 LE) followed by 0x00."""
    body = bytes((_check_u8("type", type), _check_u8("seq", seq))) + bytes(payload)
    body += struct.pack("<H", crc16_ccitt_false(body))
    return cobs_encode(body) + b"\x00"


def encode(packet: Packet) -> bytes:
    """Wire bytes of a packet dataclass (its ``seq`` field is used)."""
    return encode_packet(packet.TYPE, packet.seq, payload_of(packet))


def decode_frame(frame: bytes, count: int = ACTUATOR_COUNT) -> Packet | ParseError:
    """Decode one COBS frame (without the 0x00 delimiter) of a link carrying ``count``
    actuators (v1: 6); never raises."""
    try:
        body = cobs_decode(frame)
    except CobsError as e:
        return ParseError(ERR_BAD_CRC, f"COBS: {e}", None, bytes(frame))
    if len(body) < 4:
        return ParseError(ERR_BAD_CRC, f"frame too short ({len(body)} bytes decoded)", None, bytes(frame))
    (crc,) = struct.unpack_from("<H", body, len(body) - 2)
    if crc16_ccitt_false(body[:-2]) != crc:
        return ParseError(ERR_BAD_CRC, "CRC mismatch", None, bytes(frame))
    t, seq, payload = body[0], body[1], body[2:-2]
    try:
        mtype = MsgType(t)
    except ValueError:
        return ParseError(ERR_UNKNOWN_TYPE, f"unknown type 0x{t:02X}", seq, bytes(frame))
    need = payload_len(mtype, count)
    if len(payload) != need:
        return ParseError(ERR_BAD_LENGTH, f"{mtype.name} needs {need} payload bytes, got {len(payload)}",
                          seq, bytes(frame))
    if mtype in _EMPTY:
        return _EMPTY[mtype](seq=seq)
    if mtype is MsgType.SET_TARGET:
        return SetTarget(struct.unpack(f"<{count}i", payload), seq=seq)
    if mtype is MsgType.PONG:
        return Pong(payload[0], payload[1], seq=seq)
    if mtype is MsgType.STATE:
        flags, clock_ms = _STATE_TAIL.unpack_from(payload, 4 * count)
        return State(struct.unpack_from(f"<{count}i", payload), flags, clock_ms, seq=seq)
    return Error(payload[0], seq=seq)


class StreamParser:
    """Incremental frame splitter and decoder over an untrusted byte stream.

    Bytes up to each 0x00 form a frame; empty frames are skipped. A frame longer than
    ``max_frame`` bytes is discarded (one ParseError, code 2) and bytes are skipped up to the
    next 0x00, so memory stays bounded whatever arrives. ``count``: the link's actuator count
    (v1: 6), which sizes SET_TARGET and STATE; :meth:`set_count` changes it (after a PONG), and
    with it ``max_frame`` unless that was given.
    """

    def __init__(self, max_frame: int | None = None, count: int = ACTUATOR_COUNT) -> None:
        self.count = check_count(count)
        self._fixed_max = max_frame is not None
        self.max_frame = int(max_frame) if max_frame is not None else max_frame_for(self.count)
        self._buf = bytearray()
        self._overflow = False

    def set_count(self, count: int) -> None:
        """Decode SET_TARGET and STATE with ``count`` actuators from now on."""
        self.count = check_count(count)
        if not self._fixed_max:
            self.max_frame = max_frame_for(self.count)

    def feed(self, data: bytes) -> list[Packet | ParseError]:
        """Consume ``data``; return the packets and errors completed by it, in order."""
        out: list[Packet | ParseError] = []
        start = 0
        mv = bytes(data)
        while start < len(mv):
            end = mv.find(0, start)
            chunk = mv[start:] if end < 0 else mv[start:end]
            if not self._overflow:
                self._buf += chunk
                if len(self._buf) > self.max_frame:
                    self._overflow = True
                    self._buf.clear()
                    out.append(ParseError(ERR_BAD_LENGTH, f"frame longer than {self.max_frame} bytes"))
            if end < 0:
                break
            if not self._overflow and self._buf:
                out.append(decode_frame(bytes(self._buf), self.count))
            self._buf.clear()
            self._overflow = False
            start = end + 1
        return out

    def reset(self) -> None:
        """Forget any partial frame."""
        self._buf.clear()
        self._overflow = False


# -- units -------------------------------------------------------------------------------------
def _check_i32s(values: object, count: int | None = ACTUATOR_COUNT) -> tuple[int, ...]:
    """Values as ints that fit i32; exactly ``count`` of them (None: any count 1..16)."""
    v = tuple(int(x) for x in values)  # type: ignore[attr-defined]
    if count is None:
        if not 1 <= len(v) <= MAX_ACTUATORS:
            raise LimitError(f"expected 1 to {MAX_ACTUATORS} actuator values, got {len(v)}")
    elif len(v) != count:
        raise LimitError(f"expected {count} actuator values, got {len(v)}")
    for i, x in enumerate(v):
        if not I32_MIN <= x <= I32_MAX:
            raise LimitError(f"actuator {i} value {x} does not fit an i32 micro-unit")
    return v


def micro_from_si(actuators: object, count: int = ACTUATOR_COUNT) -> tuple[int, ...]:
    """``count`` actuators in SI [rad or m each] -> i32 micro-units (µrad or µm), rounded to
    nearest (v1: 6, [rad, m, m, m, m, m]).

    Raises LimitError if a value is not finite or does not fit an i32 (|x| > 2147 rad or m).
    """
    a = np.asarray(actuators, dtype=float)
    if a.shape != (count,):
        raise LimitError(f"expected {count} actuator values, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise LimitError(f"actuator values must be finite, got {a.tolist()}")
    m = np.rint(a * MICRO)
    if np.any(m < I32_MIN) or np.any(m > I32_MAX):
        raise LimitError(f"actuator values {a.tolist()} do not fit i32 micro-units (|x| <= 2147)")
    return tuple(int(x) for x in m)


def si_from_micro(values: object, count: int = ACTUATOR_COUNT) -> Array:
    """``count`` i32 micro-units (µrad or µm) -> actuators in SI [rad or m] (v1: 6)."""
    return np.array(_check_i32s(values, count), dtype=float) / MICRO
