"""Chains of exactly two corners (cvs.corners.chain.find_pairs, MarkerCornerDetector.chains_of_two):
the two X-corners of a 3 x 2 checker are one such chain, which the detector's own chain search
(three corners at least) does not return."""

from __future__ import annotations

import cv2
import numpy as np

from wristmark.cvs.corners.chain import find_pairs
from wristmark.cvs.corners.detector import MarkerCornerDetector
from wristmark.cvs.corners.likelihood import find_candidates
from wristmark.cvs.corners.xcorners import DetectorSettings


def _checker(columns: int, size: int = 30) -> np.ndarray:
    """Grey image with ``columns`` x 2 squares of ``size`` px from (60, 40): X-corners at y = 40 + size."""
    img = np.full((160, 120 + columns * size), 150, np.uint8)
    for c in range(columns):
        for r in range(2):
            x0, y0 = 60 + c * size, 40 + r * size
            img[y0:y0 + size, x0:x0 + size] = 40 if (c + r) % 2 == 0 else 220
    return np.asarray(cv2.GaussianBlur(img, (5, 5), 1.2), np.uint8)


def test_two_corners_are_one_chain_of_two_and_no_chain_of_three() -> None:
    img = _checker(3)
    det = MarkerCornerDetector()
    assert det.detect(img).corners.shape[0] == 0
    chains = det.chains_of_two(img)
    assert len(chains) == 1
    found = chains[0].corners[np.argsort(chains[0].corners[:, 0])]
    np.testing.assert_allclose(found, [[89.5, 69.5], [119.5, 69.5]], atol=0.3)  # square edges at pixel boundaries
    assert chains[0].edges.shape == (2, 2)


def test_a_chain_of_three_is_not_a_chain_of_two() -> None:
    img = _checker(4)
    det = MarkerCornerDetector()
    assert det.detect(img).corners.shape[0] == 3
    assert det.chains_of_two(img) == []


def test_find_pairs_gives_each_pair_once_and_at_most_max_pairs() -> None:
    s = DetectorSettings(min_corners=2)
    img = _checker(3)
    pairs = find_pairs(find_candidates(img, s), s, max_pairs=8)
    assert pairs.shape[0] >= 1 and pairs.shape[1] == 2
    assert len({frozenset(p) for p in pairs.tolist()}) == pairs.shape[0]  # each unordered pair once
    assert find_pairs(find_candidates(img, s), s, max_pairs=1).shape == (1, 2)
