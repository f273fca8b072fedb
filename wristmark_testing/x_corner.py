"""An X-corner drawn at a sub-pixel position, for the corner fits' tests."""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["x_corner_radiance"]


def x_corner_radiance(centre: tuple[float, float], angles_deg: tuple[float, float], white: tuple[float, float],
                      dark: float, size: int, k: int = 8) -> np.ndarray:
    """A size x size float32 image of an X-corner at ``centre`` [px] (pixel centres at integers)
    whose two edges run at ``angles_deg`` [deg]: the two white squares (on the positive and the
    negative side of the first edge) at ``white``, the dark ones at ``dark`` [grey levels, may
    exceed 255], drawn k times finer and averaged down (a point-sampled edge is aliased)."""
    fine = (np.arange(size * k) + 0.5) / k - 0.5
    xx, yy = np.meshgrid(fine, fine)
    dx, dy = xx - centre[0], yy - centre[1]
    a, b = np.radians(angles_deg)
    ua = -np.sin(a) * dx + np.cos(a) * dy
    ub = -np.sin(b) * dx + np.cos(b) * dy
    radiance = np.where(ua * ub > 0, np.where(ua > 0, white[0], white[1]), dark).astype(np.float32)
    return cv2.resize(radiance, (size, size), interpolation=cv2.INTER_AREA)
