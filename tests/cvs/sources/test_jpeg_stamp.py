"""cvs.sources.jpeg_stamp: a capture time in a JPEG COM segment, invisible to decoders."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.sources.jpeg_stamp import add_capture_stamp, read_capture_stamp


def test_round_trip_and_decoders_ignore_it() -> None:
    img = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    jpeg = cv2.imencode(".jpg", img)[1].tobytes()
    stamped = add_capture_stamp(jpeg, 12345.678901)
    assert read_capture_stamp(stamped) == pytest.approx(12345.678901, abs=1e-6)
    assert read_capture_stamp(jpeg) is None  # a JFIF APP0 segment, no stamp
    a = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    b = cv2.imdecode(np.frombuffer(stamped, np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(a, b)


def test_not_a_jpeg() -> None:
    assert read_capture_stamp(b"\x89PNG\r\n") is None
    assert read_capture_stamp(b"\xff\xd8\xff\xfe\x00\x05abc") is None  # a COM segment that is not ours, cut short
    with pytest.raises(ValueError, match="SOI"):
        add_capture_stamp(b"GIF89a", 1.0)
