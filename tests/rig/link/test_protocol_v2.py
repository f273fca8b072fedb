"""Protocol v2 packets: SET_TARGET and STATE sized by the actuator count n (1..16); v1 is n = 6."""

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.models.errors import LimitError
from wristmark.rig.link import protocol as P
from wristmark.rig.link.cobs import cobs_decode

i32 = st.integers(P.I32_MIN, P.I32_MAX)


@st.composite
def sized_packets(draw: st.DrawFn) -> tuple[int, P.Packet]:
    n = draw(st.integers(1, P.MAX_ACTUATORS))
    values = tuple(draw(st.lists(i32, min_size=n, max_size=n)))
    seq = draw(st.integers(0, 255))
    pkt = draw(st.sampled_from([
        P.SetTarget(values, seq=seq),
        P.State(values, draw(st.integers(0, 0xFFFF)), draw(st.integers(0, 0xFFFFFFFF)), seq=seq),
        P.Pong(P.PROTOCOL_V2, n, seq=seq), P.GetState(seq=seq), P.Error(5, seq=seq),
    ]))
    return n, pkt


@settings(max_examples=300, derandomize=True)
@given(sized_packets())
def test_v2_round_trip_for_every_count(case: tuple[int, P.Packet]) -> None:
    n, pkt = case
    wire = P.encode(pkt)
    assert len(wire) - 1 <= P.max_frame_for(n)
    assert P.StreamParser(count=n).feed(wire) == [pkt]


def test_v2_layout_by_hand_n10() -> None:
    values = tuple(range(-5, 5))
    body = cobs_decode(P.encode(P.SetTarget(values, seq=3))[:-1])
    assert body[:2] == b"\x04\x03" and len(body) == 2 + 40 + 2
    assert struct.unpack("<10i", body[2:42]) == values
    body = cobs_decode(P.encode(P.State(values, 0x11, 77, seq=4))[:-1])
    assert body[:2] == b"\x84\x04" and len(body) == 2 + 40 + 6 + 2
    assert struct.unpack("<10iHI", body[2:-2]) == (*values, 0x11, 77)
    assert P.encode(P.Pong(2, 10, seq=1)) == P.encode_packet(0x81, 1, bytes((2, 10)))


def test_v2_with_six_actuators_is_v1_byte_for_byte() -> None:
    v = (100000, 40000, 1750, 0, 2430, -100)
    wire = P.encode(P.SetTarget(v, seq=7))
    assert wire.hex(" ") == ("06 04 07 a0 86 01 03 40 9c 01 03 d6 06 01 01 01 01 01 03 7e 09 01 07 9c ff ff "
                             "ff c0 53 00")
    assert P.StreamParser(count=6).feed(wire) == P.StreamParser().feed(wire) == [P.SetTarget(v, seq=7)]
    assert P.StreamParser().max_frame == P.MAX_FRAME == 64


def test_a_packet_sized_for_another_count_is_error_2_with_its_seq() -> None:
    wire = P.encode(P.SetTarget((1,) * 10, seq=9))
    (err,) = P.StreamParser().feed(wire)  # a v1 (n = 6) parser
    assert isinstance(err, P.ParseError) and err.code == P.ERR_BAD_LENGTH and err.seq == 9
    (err,) = P.StreamParser(count=10).feed(P.encode(P.State((0,) * 6, 0, 0, seq=4)))
    assert isinstance(err, P.ParseError) and err.code == P.ERR_BAD_LENGTH and err.seq == 4


def test_set_count_switches_sizes_and_frame_bound() -> None:
    parser = P.StreamParser()
    parser.set_count(16)
    assert parser.max_frame == P.max_frame_for(16) == 80
    pkt = P.State(tuple(range(16)), 1, 2, seq=5)
    assert parser.feed(P.encode(pkt)) == [pkt]
    assert parser.feed(b"\x07" * 81 + b"\x00")[0].code == P.ERR_BAD_LENGTH  # still bounded


@pytest.mark.parametrize("n", [0, 17, -1])
def test_counts_outside_1_to_16_are_refused(n: int) -> None:
    with pytest.raises(LimitError, match="1..16"):
        P.StreamParser(count=n)
    with pytest.raises(LimitError, match="1 to 16"):
        P.encode(P.SetTarget((0,) * max(n, 0), seq=1))


def test_units_for_any_count() -> None:
    a = np.linspace(-0.5, 0.5, 10)
    m = P.micro_from_si(a, 10)
    assert len(m) == 10 and np.allclose(P.si_from_micro(m, 10), a, atol=0.5e-6)
    with pytest.raises(LimitError, match="expected 10 actuator values"):
        P.micro_from_si(a[:6], 10)


def test_doc_v2_examples_decode_as_documented() -> None:
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "protocol.md").read_text()
    block = re.search(r"```wire-examples-v2\n(.*?)```", text, re.S)
    assert block is not None
    lines = [ln for ln in block.group(1).splitlines() if ln.strip()]
    assert {ln.split()[0] for ln in lines} == {"PONG", "SET_TARGET", "STATE"}
    for line in lines:
        left, hexbytes = line.split("->")
        name, n_field, *fields = left.split()
        n = int(n_field.removeprefix("n="))
        out = P.StreamParser(count=n).feed(bytes.fromhex(hexbytes))
        assert len(out) == 1 and not isinstance(out[0], P.ParseError), line
        pkt = out[0]
        assert pkt.TYPE.name == name
        for f in fields:
            key, value = f.split("=")
            want = tuple(int(v) for v in value.split(",")) if "," in value else int(value)
            assert getattr(pkt, key) == want, (line, key)
        assert P.encode(pkt) == bytes.fromhex(hexbytes)
