"""Consistent Overhead Byte Stuffing (COBS): frames without 0x00 bytes, delimited by 0x00.

``cobs_encode`` never emits a zero byte and does not append the delimiter; ``cobs_decode``
takes one frame without its delimiter and raises :class:`CobsError` on any malformed input.
"""

from __future__ import annotations

from wristmark.models.errors import WristmarkError


class CobsError(WristmarkError, ValueError):
    """A byte string is not a valid COBS frame (corrupted on the wire)."""


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode ``data``; the result contains no 0x00 and is at most len/254 + 1 longer."""
    out = bytearray()
    code_at = 0
    out.append(0)  # placeholder for the first code byte
    code = 1
    for b in data:
        if b == 0:
            out[code_at] = code
            code_at = len(out)
            out.append(0)
            code = 1
            continue
        out.append(b)
        code += 1
        if code == 0xFF:
            out[code_at] = code
            code_at = len(out)
            out.append(0)
            code = 1
    out[code_at] = code
    return bytes(out)


def cobs_decode(frame: bytes) -> bytes:
    """Decode one COBS frame (no trailing 0x00). Raises CobsError if it is malformed."""
    out = bytearray()
    i, n = 0, len(frame)
    if n == 0:
        raise CobsError("empty COBS frame")
    while i < n:
        code = frame[i]
        if code == 0:
            raise CobsError(f"zero byte inside a COBS frame at offset {i}")
        end = i + code
        if end > n:
            raise CobsError(f"COBS block at offset {i} runs past the end of the frame")
        block = frame[i + 1 : end]
        if 0 in block:
            raise CobsError("zero byte inside a COBS block")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)
