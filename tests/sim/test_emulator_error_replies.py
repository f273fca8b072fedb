"""docs/protocol.md's error replies are what the emulator sends, byte for byte (issue 17, item 5).

In particular the ERROR 2 for an over-long frame: seq 0 (the frame is discarded before a CRC
could vouch for its seq), as the document says.
"""

from __future__ import annotations

import re
from pathlib import Path

from wristmark.models.robot_params import RobotParams
from wristmark.rig.link import protocol as P
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams

DOC = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def _hex(text: str) -> bytes:
    """Hex bytes with ``XX*N`` for N repeats."""
    out = bytearray()
    for tok in text.split():
        value, _, n = tok.partition("*")
        out += bytes([int(value, 16)]) * (int(n) if n else 1)
    return bytes(out)


def _replies() -> list[tuple[bytes, bytes]]:
    block = re.search(r"```device-replies\n(.*?)```", DOC.read_text(), re.S)
    assert block is not None, "docs/protocol.md has no device-replies block"
    pairs = [ln.split("->") for ln in block.group(1).splitlines() if ln.strip()]
    return [(_hex(a), _hex(b)) for a, b in pairs]


def _emulator() -> ActuatorEmulator:
    params = RobotParams()
    return ActuatorEmulator(TruePlant(params, PlantParams()), params)


def test_documented_error_replies_are_the_emulators() -> None:
    pairs = _replies()
    assert any(len(req) > P.MAX_FRAME for req, _ in pairs), "the over-long frame is documented"
    for request, reply in pairs:
        assert _emulator().receive(request) == reply, request.hex(" ")


def test_over_long_frame_gets_error_2_with_seq_0_and_moves_nothing() -> None:
    emu = _emulator()
    assert emu.receive(P.encode(P.Enable(seq=3)))  # enabled
    before = emu.arm.measured_actuators().copy()
    frame = P.encode(P.SetTarget((1, 2, 3, 4, 5, 6), seq=42))[:-1] * 3 + b"\x00"  # delimiters lost: 3 in one
    assert len(frame) > P.MAX_FRAME
    (err,) = P.StreamParser().feed(emu.receive(frame))
    assert isinstance(err, P.Error) and (err.code, err.seq) == (P.ERR_BAD_LENGTH, 0)
    assert (emu.arm.measured_actuators() == before).all()
    assert "longer than 64 bytes" in DOC.read_text() and "ERROR 2 with seq 0" in DOC.read_text()
