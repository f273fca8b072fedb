"""X-corners between clipped white squares (cvs.corners.clipped_fit)."""

from __future__ import annotations

import cv2
import numpy as np

from wristmark.cvs.corners.clipped_fit import clipped_htm_refine
from wristmark.cvs.corners.subpixel import htm_refine
from wristmark_testing.x_corner import x_corner_radiance

CENTRE = (30.37, 29.81)
ANGLES = (12.0, 97.0)


def _clipped_corner(white: tuple[float, float], blur: float, size: int = 61) -> np.ndarray:
    """An X-corner at CENTRE [px] whose edges run at ANGLES [deg], its two white squares at
    ``white`` grey levels (above full scale: overexposed), the dark ones at 20, blurred by a
    Gaussian of ``blur`` px, with 1.5 grey levels of noise, clipped to 8 bits."""
    img = cv2.GaussianBlur(x_corner_radiance(CENTRE, ANGLES, white, 20.0, size), (0, 0), blur)
    img = img + np.random.default_rng(7).normal(0.0, 1.5, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def test_a_corner_whose_white_clips_at_five_times_full_scale_is_found_where_the_plain_fit_is_not() -> None:
    """Both whites at 1200 (4.7 x full scale), 2.5 px of blur: the dark squares' tips are eroded
    apart. Started 1 px off, the censored fit lands within 0.05 px; the HTM fit that never clips
    (the paper detector's window) stays more than 0.3 px off."""
    img = _clipped_corner((1200.0, 1200.0), 2.5)
    assert (img >= 250).mean() > 0.3 and img[int(CENTRE[1]), int(CENTRE[0])] >= 250  # the corner itself clips
    start = np.array([[31.2, 29.2]])
    edges = np.radians([ANGLES])
    fitted, ok = clipped_htm_refine(img, start, edges, spacing=40.0)
    assert ok[0] and np.hypot(*(fitted[0] - CENTRE)) < 0.05
    plain, _, plain_ok = htm_refine(img, start, edges, 4, 4.0)
    assert not plain_ok[0] or np.hypot(*(plain[0] - CENTRE)) > 0.3


def test_unequal_whites_leave_the_corner_within_a_pixel() -> None:
    """Whites at 3.5 and 5.5 x full scale erode the dark squares unequally and the clipping hides
    by how much: the fit is off, but by less than a pixel (the tracker counts such corners at
    TrackerSettings.clipped_sigma_px, 1 px)."""
    img = _clipped_corner((900.0, 1400.0), 2.5)
    fitted, ok = clipped_htm_refine(img, np.array([[31.2, 29.2]]), np.radians([ANGLES]), spacing=40.0)
    assert ok[0] and 0.05 < np.hypot(*(fitted[0] - CENTRE)) < 1.0


def test_a_window_outside_the_image_or_without_clipped_pixels_returns_the_input() -> None:
    img = _clipped_corner((1200.0, 1200.0), 2.5)
    start = np.array([[3.0, 30.0], [30.0, 57.0]])  # its window would leave the image (R = 12 px)
    out, ok = clipped_htm_refine(img, start, np.radians([ANGLES, ANGLES]), spacing=40.0)
    assert not ok.any()
    np.testing.assert_array_equal(out, start)
    dim = (_clipped_corner((1200.0, 1200.0), 2.5).astype(float) * 0.5).astype(np.uint8)  # nothing clips
    out, ok = clipped_htm_refine(dim, np.array([[31.2, 29.2]]), np.radians([ANGLES]), spacing=40.0)
    assert not ok[0] and np.array_equal(out[0], [31.2, 29.2])
