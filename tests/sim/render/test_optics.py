"""The renderer's linear optics (sim.render.optics): the motion-blur kernel."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.sim.render.optics import motion_kernel


@pytest.mark.parametrize("length", [0.5, 2.0, 3.0, 5.0, 7.0, 10.0])
def test_the_motion_blur_kernel_is_centred_at_every_angle(length: float) -> None:
    """The truth of a blurred frame is the middle of its exposure: the kernel's centroid is its
    centre pixel at any angle (drawn with cv2.line into a kernel as wide as the segment it moved
    by up to 0.2 px at 5 px and 0.71 px at 7 px, and every corner of the frame with it), it sums
    to 1, and its spread along the motion is that of the segment (length / sqrt(12), 3 % more for
    its discrete samples) widened by at most the bilinear splat's (1/4 px^2)."""
    for angle in np.linspace(0.0, np.pi, 25):
        k = motion_kernel(length, float(angle)).astype(np.float64)
        n = k.shape[0]
        c = (n - 1) / 2
        y, x = np.mgrid[0:n, 0:n]
        assert n % 2 == 1
        assert k.sum() == pytest.approx(1.0, abs=1e-6)
        assert abs((k * x).sum() - c) < 1e-4 and abs((k * y).sum() - c) < 1e-4
        along = (x - c) * np.cos(angle) + (y - c) * np.sin(angle)
        spread = float(np.sqrt((k * along**2).sum()))
        assert length / np.sqrt(12) <= spread <= np.hypot(1.03 * length / np.sqrt(12), 0.5)
