"""The marker chain past a corner whose edge along the chain a highlight bends (cvs.corners.chain)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.corners.detector import MarkerCornerDetector
from wristmark.cvs.corners.xcorners import DetectorSettings


def _strip_bent_at_middle(slope: float) -> np.ndarray:
    """A two-row checker strip of 6 columns (5 X-corners 30 px apart on a line at x = 69.5) whose
    row boundary is bent through the middle corner only (slope ``slope`` there, back to straight
    within ~10 px): that corner stays on the line, but its edge along the chain leans ~20 deg at
    slope 0.5, as under a highlight stripe on a path-traced sleeve (seed 606 pair 25 of
    bench/pbr_tracking.py: 75.7 deg against its neighbours' 91-93)."""
    yy, xx = np.mgrid[0:200, 0:300].astype(float) + 0.5
    s, u0, vb = 30.0, 60.0, 70.0
    xk = u0 + 2 * s
    bend = slope * (xx - xk) * np.exp(-(((xx - xk) / 8.0) ** 2))
    col, row = np.floor((xx - u0 + s) / s), (yy > vb + bend).astype(int)
    inside = (xx >= u0 - s) & (xx < u0 + 5 * s) & (yy > vb - s) & (yy < vb + s)
    img = np.where(inside, np.where((col + row) % 2 == 1, 230.0, 25.0), 120.0).astype(np.float32)
    return np.ascontiguousarray(np.clip(cv2.GaussianBlur(img, (0, 0), 1.0), 0, 255).astype(np.uint8).T)


@pytest.mark.parametrize("slope", [0.0, 0.5])
def test_the_chain_goes_on_straight_where_a_bent_edge_turns_its_search_off_the_line(slope: float) -> None:
    """From the bent corner the edge turn extrapolated along the chain points ~20 deg off it and
    its window misses the next corner: the straight continuation of the last step is searched
    too, and the paper's chain (no gaps) keeps all five corners."""
    det = MarkerCornerDetector(DetectorSettings(max_gaps=0))
    c = det.detect(_strip_bent_at_middle(slope))
    if slope:
        assert abs(np.degrees(c.edges[2, 0]) - 90.0) > 15.0  # the bent corner's edge leans as intended
    np.testing.assert_allclose(c.corners, [[69.5, y] for y in (59.5, 89.5, 119.5, 149.5, 179.5)], atol=0.1)
