"""cvs.sources.newest_frame: the newest frame wins, replaced frames are counted, the end and stalls."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame
from wristmark.cvs.sources.newest_frame import NewestFrame


def _frame(k: int) -> StereoFrame:
    img = np.zeros((2, 2), np.uint8)
    return StereoFrame(img, img, float(k), k)


def test_newest_wins_and_drops_are_counted() -> None:
    slot = NewestFrame()
    for k in range(3):
        slot.put(_frame(k))
    got = slot.take(0.1, "stalled")
    assert got is not None and got.index == 2 and slot.dropped == 2 and slot.captured == 3
    slot.skip()
    assert slot.dropped == 3 and slot.captured == 4
    with pytest.raises(FrameSourceError, match="stalled"):
        slot.take(0.05, "stalled")  # nothing new since the last take


def test_take_waits_for_a_frame_and_the_first_finish_decides() -> None:
    slot = NewestFrame()
    threading.Timer(0.05, slot.put, args=(_frame(7),)).start()
    t0 = time.monotonic()
    f = slot.take(2.0, "stalled")
    assert f is not None and f.index == 7 and time.monotonic() - t0 < 1.0
    slot.put(_frame(8))
    slot.finish("cam: the stream ended")
    slot.finish()  # ignored: the first call decides
    assert slot.take(0.1, "stalled").index == 8  # type: ignore[union-attr]  # the last frame first
    with pytest.raises(FrameSourceError, match="the stream ended"):
        slot.take(0.1, "stalled")
    done = NewestFrame()
    done.finish()
    assert done.take(0.1, "stalled") is None
