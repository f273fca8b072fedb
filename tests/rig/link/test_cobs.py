"""COBS framing: known vectors, round trips, and rejection of malformed frames."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.rig.link.cobs import CobsError, cobs_decode, cobs_encode

# Vectors from the COBS paper / Wikipedia table.
VECTORS = [
    (b"\x00", b"\x01\x01"),
    (b"\x00\x00", b"\x01\x01\x01"),
    (b"\x00\x11\x00", b"\x01\x02\x11\x01"),
    (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"),
    (b"\x11\x22\x33\x44", b"\x05\x11\x22\x33\x44"),
    (b"\x11\x00\x00\x00", b"\x02\x11\x01\x01\x01"),
]


@pytest.mark.parametrize("raw,enc", VECTORS)
def test_known_vectors(raw: bytes, enc: bytes) -> None:
    assert cobs_encode(raw) == enc
    assert cobs_decode(enc) == raw


def test_long_runs_without_zero() -> None:
    data = bytes(range(1, 256))  # 255 non-zero bytes: needs a 0xFF block
    enc = cobs_encode(data)
    assert enc[0] == 0xFF and 0 not in enc
    assert cobs_decode(enc) == data


@settings(max_examples=300, derandomize=True)
@given(st.binary(max_size=600))
def test_round_trip_and_no_zero(data: bytes) -> None:
    enc = cobs_encode(data)
    assert 0 not in enc
    assert len(enc) <= len(data) + len(data) // 254 + 1
    assert cobs_decode(enc) == data


@pytest.mark.parametrize("bad", [b"", b"\x00", b"\x05\x11\x22", b"\x03\x11\x00"])
def test_malformed_frames_raise_cobs_error(bad: bytes) -> None:
    with pytest.raises(CobsError):
        cobs_decode(bad)
