"""The marker chain stepping over a corner washed out by a highlight (DetectorSettings.max_gaps)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.corners.detector import MarkerCornerDetector
from wristmark.cvs.corners.xcorners import DetectorSettings


def _strip(washed: bool) -> np.ndarray:
    """A two-row checker strip of 6 columns (5 X-corners 30 px apart on a vertical line at
    x = 69.5), optionally under a clipped stripe across its middle corner."""
    img = np.full((200, 300), 120, np.uint8)
    s = 30
    for c in range(6):
        for r in range(2):
            img[40 + r * s : 40 + (r + 1) * s, 60 + c * s : 60 + (c + 1) * s] = 230 if (c + r) % 2 else 25
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    if washed:
        cv2.rectangle(img, (143, 20), (157, 120), 255, -1)
        img = cv2.GaussianBlur(img, (0, 0), 0.8)
    return np.ascontiguousarray(img.T)


def test_an_intact_chain_is_the_same_with_or_without_gaps() -> None:
    det = MarkerCornerDetector()
    a = det.detect(_strip(False))
    b = det.retry_with_gaps()
    assert a.corners.shape == (5, 2)
    np.testing.assert_array_equal(a.corners, b.corners)
    np.testing.assert_array_equal(a.polarity, b.polarity)


@pytest.mark.parametrize("gaps", [0, 1])
def test_a_washed_out_corner_breaks_the_chain_unless_it_may_step_over_it(gaps: int) -> None:
    det = MarkerCornerDetector(DetectorSettings(max_gaps=gaps))
    assert det.detect(_strip(True)).corners.shape[0] == 0  # 2 + 2 corners: no chain of 3
    c = det.retry_with_gaps()  # on the same search's candidates
    if gaps == 0:
        assert c.corners.shape[0] == 0
        return
    want = np.array([[69.5, 89.5], [69.5, 119.5], [69.5, 179.5], [69.5, 209.5]])
    np.testing.assert_allclose(c.corners, want, atol=0.2)
    # the step over the gap repeats the polarity: the stereo match indexes it two on
    assert c.polarity.tolist() == [-1, 1, 1, -1]
    assert det.previous_roi((300, 200)) is not None  # the next search follows it


def test_no_search_no_retry() -> None:
    assert MarkerCornerDetector().retry_with_gaps().corners.shape[0] == 0
