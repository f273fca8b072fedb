"""Fixed-size binary form of a servo cycle for the live view's pipe (one record = one write of
RECORD_SIZE bytes, below PIPE_BUF, so writes are atomic and never interleave).

Layout (little-endian): t [s], phase (24 bytes UTF-8, NUL-padded), n (the arm's configuration
variables, uint64), p_des, p_cmd, p_est (NaN: no estimate), p_true [m, {w}], psi_cmd, psi_true
[rad, m] (each MAX_PSI entries, the first n used: any arm of models.arm_spec up to MAX_PSI).
A scene of several arms prefixes each record with the arm's index (uint64, :func:`encode_arm`).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from wristmark.rig.recording.run_log import CycleRecord

Array = NDArray[np.float64]

MAX_PSI = 16  # configuration variables a record carries at most
_FORMAT = struct.Struct(f"<d24sQ{12 + 2 * MAX_PSI}d")
_HEAD = struct.Struct("<d24sQ")
RECORD_SIZE = _FORMAT.size
_NAN3 = (math.nan, math.nan, math.nan)


@dataclass
class WireRecord:
    """What the live view draws of one cycle; positions in {w} [m]."""

    t: float
    phase: str
    p_des: Array
    p_cmd: Array
    p_est: Array | None
    p_true: Array
    psi_cmd: Array
    psi_true: Array


def encode(rec: CycleRecord) -> bytes:
    """RECORD_SIZE bytes of one cycle (~3 us)."""
    est = _NAN3 if rec.p_est is None else rec.p_est
    n = np.size(rec.psi_cmd)
    if not 1 <= n <= MAX_PSI or np.size(rec.psi_true) != n:
        raise ValueError(f"cycle record has malformed psi ({n} and {np.size(rec.psi_true)} entries, "
                         f"expected equal and 1 to {MAX_PSI})")
    pad = np.full(MAX_PSI - n, math.nan)
    values = np.concatenate((rec.p_des, rec.p_cmd, est, rec.p_true, rec.psi_cmd, pad, rec.psi_true, pad),
                            dtype="<f8")
    if values.shape != (12 + 2 * MAX_PSI,):
        raise ValueError(f"cycle record has malformed vectors ({values.shape[0]} numbers, expected {12 + 2 * MAX_PSI})")
    return _HEAD.pack(float(rec.t), rec.phase.encode("utf-8")[:24], n) + values.tobytes()


def decode(data: bytes) -> WireRecord:
    """The record of RECORD_SIZE bytes written by :func:`encode`."""
    t, phase, n, *v = _FORMAT.unpack(data)
    a = np.array(v, float)
    c, r = 12, 12 + MAX_PSI
    est = a[6:9]
    return WireRecord(
        t=t, phase=phase.rstrip(b"\0").decode("utf-8", errors="replace"),
        p_des=a[0:3], p_cmd=a[3:6], p_est=est if np.all(np.isfinite(est)) else None,
        p_true=a[9:12], psi_cmd=a[c:c + n], psi_true=a[r:r + n],
    )


# Several arms in one view: each record is preceded by the arm's index in the scene (uint64).
_ARM = struct.Struct("<Q")
ARM_RECORD_SIZE = _ARM.size + RECORD_SIZE


def encode_arm(index: int, rec: CycleRecord) -> bytes:
    """ARM_RECORD_SIZE bytes of one cycle of the scene's arm number ``index``."""
    return _ARM.pack(index) + encode(rec)


def decode_arm(data: bytes) -> tuple[int, WireRecord]:
    """(arm index, record) of ARM_RECORD_SIZE bytes written by :func:`encode_arm`."""
    (index,) = _ARM.unpack_from(data)
    return int(index), decode(data[_ARM.size:])
