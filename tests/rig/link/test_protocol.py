"""Protocol v1 packets: round trips, hostile byte streams, single-bit errors, units."""

import re
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.models.errors import LimitError
from wristmark.rig.link import protocol as P
from wristmark.rig.link.cobs import cobs_decode
from wristmark.rig.link.crc16 import crc16_ccitt_false

i32 = st.integers(P.I32_MIN, P.I32_MAX)
u8 = st.integers(0, 255)
six = st.tuples(i32, i32, i32, i32, i32, i32)
packets = st.one_of(
    st.builds(P.Ping, seq=u8), st.builds(P.Enable, seq=u8), st.builds(P.Disable, seq=u8),
    st.builds(P.GetState, seq=u8), st.builds(P.EStop, seq=u8), st.builds(P.Reset, seq=u8),
    st.builds(P.SetTarget, six, seq=u8), st.builds(P.Pong, u8, u8, seq=u8),
    st.builds(P.State, six, st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF), seq=u8),
    st.builds(P.Error, u8, seq=u8),
)

EXAMPLES = [
    P.Ping(seq=1), P.Enable(seq=2), P.Disable(seq=3), P.GetState(seq=0), P.EStop(seq=255), P.Reset(seq=7),
    P.SetTarget((1, -2, 0, 2**31 - 1, -(2**31), 0), seq=9), P.Pong(1, 6, seq=4),
    P.State((0, 40000, 1750, 0, -2430, 5), 0x1F, 123456, seq=200), P.Error(5, seq=0),
]


def test_wire_layout_by_hand() -> None:
    wire = P.encode(P.SetTarget((1, 2, 3, 4, 5, 6), seq=0x42))
    assert wire[-1] == 0 and 0 not in wire[:-1]
    body = cobs_decode(wire[:-1])
    assert body[:2] == b"\x04\x42"
    assert struct.unpack("<6i", body[2:26]) == (1, 2, 3, 4, 5, 6)
    assert struct.unpack("<H", body[26:]) == (crc16_ccitt_false(body[:26]),)
    assert len(P.encode(P.State((0,) * 6, 0, 0))) - 1 <= P.MAX_FRAME


@settings(max_examples=300, derandomize=True)
@given(packets)
def test_round_trip(pkt: P.Packet) -> None:
    assert P.StreamParser().feed(P.encode(pkt)) == [pkt]


@settings(max_examples=100, derandomize=True)
@given(st.lists(packets, min_size=1, max_size=8), st.integers(1, 40))
def test_stream_split_anywhere(pkts: list, chunk: int) -> None:
    wire = b"".join(P.encode(p) for p in pkts)
    parser, out = P.StreamParser(), []
    for i in range(0, len(wire), chunk):
        out += parser.feed(wire[i : i + chunk])
    assert out == pkts


@settings(max_examples=400, derandomize=True)
@given(st.binary(max_size=400))
def test_random_bytes_never_raise_nor_yield_commands(data: bytes) -> None:
    parser = P.StreamParser()
    out = parser.feed(data) + parser.feed(b"\x00")
    assert all(isinstance(x, P.ParseError) for x in out)
    assert len(parser._buf) == 0


def test_oversized_frame_is_bounded_and_resyncs() -> None:
    parser = P.StreamParser(max_frame=64)
    out = parser.feed(b"\x07" * 10_000)
    assert [x.code for x in out] == [P.ERR_BAD_LENGTH]
    assert len(parser._buf) == 0
    assert parser.feed(b"\x07" * 10 + b"\x00" + P.encode(P.Ping(seq=5))) == [P.Ping(seq=5)]


def test_bad_length_and_unknown_type_keep_seq() -> None:
    bad_len = P.encode_packet(P.MsgType.SET_TARGET, 17, b"\x01\x02")
    unknown = P.encode_packet(0x42, 18, b"")
    out = P.StreamParser().feed(bad_len + unknown)
    assert [(e.code, e.seq) for e in out] == [(P.ERR_BAD_LENGTH, 17), (P.ERR_UNKNOWN_TYPE, 18)]


def _flip_all_bits(wire: bytes) -> None:
    for pos in range(len(wire)):
        for bit in range(8):
            bad = bytearray(wire)
            bad[pos] ^= 1 << bit
            out = P.StreamParser().feed(bytes(bad) + b"\x00")
            assert all(isinstance(x, P.ParseError) for x in out), (pos, bit, out)


@pytest.mark.parametrize("pkt", EXAMPLES, ids=lambda p: type(p).__name__)
def test_every_single_bit_error_is_caught(pkt: P.Packet) -> None:
    _flip_all_bits(P.encode(pkt))  # includes the delimiter: merged / split frames too


@settings(max_examples=40, derandomize=True)
@given(packets)
def test_every_single_bit_error_is_caught_random(pkt: P.Packet) -> None:
    _flip_all_bits(P.encode(pkt)[:-1])


def test_units_round_trip_and_ranges() -> None:
    a = np.array([0.5, 0.04, 0.00175, -0.001, 0.0024, -1e-7])
    m = P.micro_from_si(a)
    assert m == (500000, 40000, 1750, -1000, 2400, 0)
    assert np.allclose(P.si_from_micro(m), a, atol=0.5e-6)
    with pytest.raises(LimitError, match="i32"):
        P.micro_from_si([3000.0, 0, 0, 0, 0, 0])
    with pytest.raises(LimitError, match="finite"):
        P.micro_from_si([np.nan, 0, 0, 0, 0, 0])
    with pytest.raises(LimitError, match="6 actuator"):
        P.micro_from_si([0.0] * 5)
    with pytest.raises(LimitError, match="seq"):
        P.encode_packet(P.MsgType.PING, 256)


DOC = Path(__file__).resolve().parents[3] / "docs" / "protocol.md"


def _examples() -> list[str]:
    text = DOC.read_text()
    block = re.search(r"```wire-examples\n(.*?)```", text, re.S)
    assert block is not None
    return [ln for ln in block.group(1).splitlines() if ln.strip()]


def test_doc_examples_decode_as_documented() -> None:
    lines = _examples()
    assert {ln.split()[0] for ln in lines} == {t.name for t in P.MsgType}
    for line in lines:
        left, hexbytes = line.split("->")
        name, *fields = left.split()
        out = P.StreamParser().feed(bytes.fromhex(hexbytes))
        assert len(out) == 1 and not isinstance(out[0], P.ParseError), line
        pkt = out[0]
        assert pkt.TYPE.name == name
        for f in fields:
            key, value = f.split("=")
            want = tuple(int(v) for v in value.split(",")) if "," in value else int(value)
            assert getattr(pkt, key) == want, (line, key)
        assert P.encode(pkt) == bytes.fromhex(hexbytes)


def test_doc_error_examples() -> None:
    text = DOC.read_text()
    assert "07 04 09 01 02 d3 c3 00" in text and "03 04 0f 00" in text
    bad_len = P.StreamParser().feed(bytes.fromhex("07 04 09 01 02 d3 c3 00"))
    assert [(e.code, e.seq) for e in bad_len] == [(P.ERR_BAD_LENGTH, 9)]
    short = P.StreamParser().feed(bytes.fromhex("03 04 0f 00"))
    assert [(e.code, e.seq) for e in short] == [(P.ERR_BAD_CRC, None)]
