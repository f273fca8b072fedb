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


def _strip_dim_beyond(washed_corner: int) -> np.ndarray:
    """A two-row checker strip of 7 columns (6 X-corners 30 px apart on a vertical line at
    x = 69.5), clipped over corner ``washed_corner``, the corners beyond it of less contrast."""
    img = np.full((200, 360), 120, np.uint8)
    s = 30
    for c in range(7):
        lo, hi = (25, 230) if c <= washed_corner else (65, 190)
        for r in range(2):
            img[40 + r * s : 40 + (r + 1) * s, 30 + c * s : 30 + (c + 1) * s] = hi if (c + r) % 2 else lo
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    x = 60 + washed_corner * s
    cv2.rectangle(img, (x - 7, 20), (x + 7, 120), 255, -1)
    return np.ascontiguousarray(cv2.GaussianBlur(img, (0, 0), 0.8).T)


def test_a_step_over_that_finds_nothing_at_one_end_leaves_the_other_end_its_own() -> None:
    """The chain seeded beside the gap grows away from it first: the step over nothing at that
    end must not use up the one step over the washed-out corner at the other."""
    det = MarkerCornerDetector(DetectorSettings(max_gaps=1))
    assert det.detect(_strip_dim_beyond(2)).corners.shape[0] == 3  # the paper's chain: one side only
    c = det.retry_with_gaps()
    want = np.array([[69.5, y] for y in (59.5, 89.5, 149.5, 179.5, 209.5)])
    np.testing.assert_allclose(c.corners, want, atol=0.2)


def _strip_turned_before_gap() -> np.ndarray:
    """A two-row checker strip of 5 columns (4 X-corners 30 px apart on a line at x = 69.5),
    clipped over the third corner; the row boundary wiggles through the first two (1.5 px sine):
    their edges along the chain lean 10 deg either way, the corners stay on the line (as a limb
    corner's edge leans beside the stripe on a path-traced sleeve)."""
    yy, xx = np.mgrid[0:200, 0:300].astype(float) + 0.5
    s, u0, vb = 30.0, 60.0, 70.0
    b = np.where((xx > u0 - 15) & (xx < u0 + s + 15), 1.5 * np.sin(np.pi * (xx - u0) / s), 0.0)
    col, row = np.floor((xx - u0 + s) / s), (yy > vb + b).astype(int)
    inside = (xx >= u0 - s) & (xx < u0 + 4 * s) & (yy > vb - s) & (yy < vb + s)
    img = cv2.GaussianBlur(np.where(inside, np.where((col + row) % 2 == 1, 230.0, 25.0), 120.0).astype(np.float32),
                           (0, 0), 1.0)
    cv2.rectangle(img, (int(u0 + 2 * s) - 7, 50), (int(u0 + 2 * s) + 7, 90), 255, -1)
    return np.ascontiguousarray(np.clip(cv2.GaussianBlur(img, (0, 0), 0.8), 0, 255).astype(np.uint8).T)


def test_a_step_over_also_goes_straight_where_the_extrapolated_turn_misses() -> None:
    """The edge turn from the first corner to the second, extrapolated over two spacings, points
    20 deg off the line: the step over the gap is searched along the last step too."""
    det = MarkerCornerDetector(DetectorSettings(max_gaps=1))
    assert det.detect(_strip_turned_before_gap()).corners.shape[0] == 0
    c = det.retry_with_gaps()
    np.testing.assert_allclose(c.corners, [[69.5, 59.5], [69.5, 89.5], [69.5, 149.5]], atol=0.2)


def test_a_box_searched_with_a_lower_cl_threshold_finds_the_chain_the_whole_frame_missed() -> None:
    """Path-traced 2323/57's left view (tests/data/pbr/coded_stripe_row): beside the stripe a
    plain corner's normalised CL is 0.057, under the threshold of 0.06, so neither the whole-frame
    search nor its gap retry finds a chain; in the box of those rows, with the threshold halved,
    the chain steps over the corner under the stripe: 4 corners, on the truth's corner row."""
    from tests.cvs.tracking.pbr_pairs import load_pbr_pair

    left, _, _ = load_pbr_pair("coded_stripe_row")
    det = MarkerCornerDetector()
    assert det.detect(left).corners.shape[0] == 0 and det.retry_with_gaps().corners.shape[0] == 0
    box = (500, 20, 250, 230)
    assert det.retry_in_box(left, box, 1.0).corners.shape[0] == 0  # the same threshold: nothing
    found = det.retry_in_box(left, box, 0.5).corners
    assert found.shape[0] == 4
    np.testing.assert_allclose(found[[0, -1]], [[602, 55], [662, 207]], atol=1.5)
    with pytest.raises(ValueError, match="cl_scale"):
        det.retry_in_box(left, box, 0.0)
