"""A capture time carried inside a JPEG: a COM segment ``wristmark t_capture=<seconds>`` right
after the SOI marker, with the sender's ``time.monotonic()`` [s].

CLOCK_MONOTONIC is one clock for every process of a machine, so a camera process on the same
host (the virtual lab's emulator) can stamp each frame with its true capture time and the
network source (cvs.sources.stream) reads it back; decoders ignore COM segments.
"""

from __future__ import annotations

import struct

_PREFIX = b"wristmark t_capture="
_SOI, _COM, _SOS = b"\xff\xd8", 0xFE, 0xDA
_MAX_SEGMENTS = 16  # segments looked at before giving up (the stamp is the first one)


def add_capture_stamp(jpeg: bytes, t_capture: float) -> bytes:
    """``jpeg`` with a COM segment holding ``t_capture`` [s] inserted after SOI."""
    if not jpeg.startswith(_SOI):
        raise ValueError("not a JPEG (no SOI marker)")
    text = _PREFIX + f"{float(t_capture):.6f}".encode("ascii")
    return jpeg[:2] + b"\xff\xfe" + struct.pack(">H", len(text) + 2) + text + jpeg[2:]


def read_capture_stamp(jpeg: bytes | memoryview) -> float | None:
    """The t_capture [s] of :func:`add_capture_stamp`, or None when the JPEG has none."""
    data = bytes(jpeg[:4096])
    if not data.startswith(_SOI):
        return None
    pos = 2
    for _ in range(_MAX_SEGMENTS):
        if pos + 4 > len(data) or data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == _SOS:
            return None
        (length,) = struct.unpack_from(">H", data, pos + 2)
        if marker == _COM:
            body = data[pos + 4 : pos + 2 + length]
            if body.startswith(_PREFIX):
                try:
                    return float(body[len(_PREFIX) :].decode("ascii"))
                except ValueError:
                    return None
        pos += 2 + length
    return None
