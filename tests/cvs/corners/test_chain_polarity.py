"""The chain's polarity taken along the chain (cvs.corners.chain.along_polarity): a steeply seen
sleeve, whose ring edge turns through 45 deg from one corner to the next."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.corners.chain import along_polarity
from wristmark.cvs.corners.detector import MarkerCornerDetector, detect_xcorners
from wristmark.cvs.corners.xcorners import DetectorSettings
from wristmark.models.errors import InputError

RADIUS, CENTRE = 150.0, (40.0, 40.0)


def _arc_strip(corners_deg: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Two rows of checker cells along a circular arc (radius 150 px about (40, 40)): X-corners
    at the polar angles ``corners_deg`` on the arc between the rows; the ring edge's direction is
    the angle + 90 deg, the cells' edges across it radial. Returns the image and the corners [px]."""
    yy, xx = np.mgrid[0:330, 0:330].astype(float)
    dx, dy = xx - CENTRE[0], yy - CENTRE[1]
    rho, phi = np.hypot(dx, dy), np.degrees(np.arctan2(dy, dx))
    b = np.asarray(corners_deg, float)
    step = b[1] - b[0]
    cell = np.floor((phi - (b[0] - step)) / step)
    inside = (np.abs(rho - RADIUS) < 22.0) & (cell >= 0) & (cell <= b.size)
    img = np.where(inside, np.where((cell + (rho > RADIUS)) % 2 == 1, 230, 25), 120).astype(np.uint8)
    img = np.asarray(cv2.GaussianBlur(img, (0, 0), 1.0), np.uint8)
    return img, np.c_[CENTRE[0] + RADIUS * np.cos(np.radians(b)), CENTRE[1] + RADIUS * np.sin(np.radians(b))]


# ring edge at 110, 122, 134, 146, 158 deg: the X-corner test's edge "closer to vertical" changes
# from the ring edge to the radial one between the third and the fourth corner
STEEP = [20.0, 32.0, 44.0, 56.0, 68.0]


def test_the_image_polarity_flips_where_the_ring_edge_passes_45_degrees() -> None:
    img, want = _arc_strip(STEEP)
    xc = detect_xcorners(img, DetectorSettings())
    assert xc.corners.shape[0] == 5
    order = [int(np.argmin(np.hypot(*(xc.corners - w).T))) for w in want]
    pol = xc.polarity[order]
    assert pol[2] == pol[3]  # the X-corner test's own polarity repeats across the flip
    ring = np.radians(np.asarray(STEEP) + 90.0)
    along = along_polarity(pol, xc.edges[order], np.c_[np.cos(ring), np.sin(ring)])
    assert np.all(along[1:] == -along[:-1])  # along the chain it alternates
    # either sense of the chain's direction gives the same
    np.testing.assert_array_equal(along, along_polarity(pol, xc.edges[order], -np.c_[np.cos(ring), np.sin(ring)]))


def test_the_chain_runs_through_the_flip_with_the_polarity_along_it() -> None:
    img, want = _arc_strip(STEEP)
    along = MarkerCornerDetector().detect(img)
    np.testing.assert_allclose(along.corners, want[np.argsort(want[:, 1])], atol=0.3)
    assert np.all(along.polarity[1:] == -along.polarity[:-1])
    # the paper's polarity: the chain steps over the flipped corner, so that its polarities
    # alternate over a skipped corner (the stereo indices after it would be one off)
    image = MarkerCornerDetector(DetectorSettings(chain_polarity="image")).detect(img)
    assert image.corners.shape[0] < 5


def test_an_unknown_chain_polarity_is_refused() -> None:
    with pytest.raises(InputError, match="chain_polarity"):
        DetectorSettings(chain_polarity="sideways")
