"""CRC-16/CCITT-FALSE against the catalogue check value and a bitwise reference."""

from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.rig.link.crc16 import crc16_ccitt_false


def _bitwise(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def test_check_value() -> None:
    assert crc16_ccitt_false(b"123456789") == 0x29B1


def test_empty_is_init() -> None:
    assert crc16_ccitt_false(b"") == 0xFFFF


@settings(max_examples=200, derandomize=True)
@given(st.binary(max_size=64), st.binary(max_size=64))
def test_table_matches_bitwise_and_continues(a: bytes, b: bytes) -> None:
    assert crc16_ccitt_false(a + b) == _bitwise(a + b)
    assert crc16_ccitt_false(b, crc16_ccitt_false(a)) == crc16_ccitt_false(a + b)
