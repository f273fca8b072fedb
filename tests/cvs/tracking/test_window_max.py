"""cvs.tracking.window_max: the windows and their bright-channel flags as defined one at a time,
and the bound it rests on (a pixel's grey level is at most its largest colour channel)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from wristmark.cvs.tracking.window_max import bright_windows


def test_no_grey_level_exceeds_the_pixels_largest_colour_channel() -> None:
    b, g, r = np.meshgrid(np.arange(256, dtype=np.uint8), np.arange(256, dtype=np.uint8),
                          np.arange(256, dtype=np.uint8), indexing="ij")
    bgr = np.stack([b.ravel(), g.ravel(), r.ravel()], axis=1).reshape(4096, 4096, 3)  # every colour
    assert np.all(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY) <= bgr.max(axis=2))
    bgra = np.concatenate([bgr, np.full((4096, 4096, 1), 255, np.uint8)], axis=2)
    assert np.all(cv2.cvtColor(bgra, cv2.COLOR_BGRA2GRAY) <= bgr.max(axis=2))


@pytest.mark.parametrize("shape", [(50, 70), (50, 70, 3), (50, 70, 4)])
def test_windows_and_flags_are_as_defined_one_window_at_a_time(shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(len(shape))
    img = rng.integers(0, 200, shape, dtype=np.uint8)
    spots = rng.integers(0, [shape[0], shape[1]], (10, 2))
    img[spots[:, 0], spots[:, 1]] = 252
    if len(shape) == 3 and shape[2] == 4:
        img[..., 3] = 255  # an opaque alpha channel is no colour
    uv = np.column_stack([rng.uniform(-9, 79, 300), rng.uniform(-9, 59, 300)])
    h, w = shape[:2]
    for rad in (1.0, 2.5, 4.0, 6.3):
        flags, boxes = bright_windows(img, uv, rad, 250)
        for k, (x, y) in enumerate(uv):
            u0, u1 = max(int(x - rad), 0), min(int(x + rad) + 1, w)
            v0, v1 = max(int(y - rad), 0), min(int(y + rad) + 1, h)
            colour = img[v0:v1, u0:u1] if img.ndim == 2 else img[v0:v1, u0:u1, :3]
            assert tuple(boxes[k]) == (u0, v0, u1, v1)
            assert flags[k] == bool(u1 > u0 and v1 > v0 and colour.max() >= 250)
        assert flags.any() and not flags.all()
    flags, boxes = bright_windows(img, np.zeros((0, 2)), 3.0, 250)
    assert flags.shape == (0,) and boxes.shape == (0, 4)
