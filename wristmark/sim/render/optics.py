"""Linear camera optics: vignetting, motion blur, optics (Gaussian) blur and grey conversion,
over the whole frame or incrementally over the arm's box. Images are float32 BGR radiance in
grey levels; pixel (u, v) is column u, row v.

All these steps are linear and local (the blurs reach ``radius`` pixels), so where the frame
differs from the cached background only inside a box, the optics of the frame equal the
cached optics of the background outside the box grown by ``radius`` and, inside it, the optics
of a patch of the frame grown by ``2 radius`` (:func:`optics_signal_box`). Borders follow
OpenCV's default (BORDER_REFLECT_101) in both paths: a patch edge that is an image edge
reflects exactly as the whole frame does.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError
from wristmark.sim.render.settings import RenderSettings

F32 = NDArray[np.float32]
Box = tuple[int, int, int, int]  # pixel rectangle (u0, v0, u1, v1), u1 and v1 exclusive


def vignetting_map(size: tuple[int, int], strength: float) -> F32:
    """Multiplicative brightness (h, w): 1 at the centre, 1 - strength at the corners (cos^4-like)."""
    w, h = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
    return (1.0 - strength * r2).astype(np.float32)


def motion_kernel(length: float, angle: float) -> F32:
    """Normalised linear motion-blur kernel of ``length`` [px] along ``angle`` [rad]: the segment
    sampled every 1/8 px, symmetrically about the kernel's centre, and splatted bilinearly into a
    kernel one pixel wider than the segment on each side, so its centroid is the centre exactly
    at any angle (the truth is the middle of the exposure). Drawn with cv2.line into a kernel as
    wide as the segment, it was clipped at the corners: its centroid moved by up to 0.2 px at
    5 px and 0.71 px at 7 px, and every corner of the frame with it."""
    n = (int(np.ceil(length)) + 2) | 1
    k = np.zeros((n, n), np.float64)
    c = (n - 1) / 2
    t = np.linspace(-length / 2, length / 2, max(int(np.ceil(8 * length)), 1) + 1)
    x, y = c + t * np.cos(angle), c + t * np.sin(angle)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        np.add.at(k, (y0 + dy, x0 + dx), w)
    return np.asarray(k / k.sum(), np.float32)


def gaussian_ksize(sigma: float) -> int:
    """Odd Gaussian kernel size [px] for blur sigma [px] (OpenCV's default for float images)."""
    return int(round(sigma * 8 + 1)) | 1 if sigma > 0 else 1


def blur_radius(settings: RenderSettings) -> int:
    """How far [px] the incremental optics reach: the Gaussian kernel's half size (no motion blur)."""
    return gaussian_ksize(settings.blur_sigma) // 2


def grow_box(box: Box, margin: int, size: tuple[int, int]) -> Box:
    """``box`` grown by ``margin`` [px] on every side and clipped to the image ``size`` (w, h)."""
    u0, v0, u1, v1 = box
    return max(0, u0 - margin), max(0, v0 - margin), min(size[0], u1 + margin), min(size[1], v1 + margin)


def _linear_optics(img: F32, vignette: F32, settings: RenderSettings, angle: float) -> F32:
    out: Any = cv2.multiply(img, vignette)
    if settings.motion_blur > 0:
        out = cv2.filter2D(out, -1, motion_kernel(settings.motion_blur, angle))
    if settings.blur_sigma > 0:
        k = gaussian_ksize(settings.blur_sigma)
        out = cv2.GaussianBlur(out, (k, k), settings.blur_sigma)
    if not settings.colour:
        out = cv2.cvtColor(out, cv2.COLOR_BGR2GRAY)
    return np.asarray(out, np.float32)


def optics_signal(img: F32, vignette: F32, settings: RenderSettings, motion_angle: float = 0.0) -> F32:
    """Whole-frame optics of radiance ``img`` (h, w, 3) [grey levels]: vignetting (``vignette``
    (h, w, 3)), motion blur along ``motion_angle`` [rad], optics blur, grey conversion.
    Returns the sensor signal (h, w, 3), or (h, w) for grayscale, in grey levels."""
    return _linear_optics(img, vignette, settings, motion_angle)


def optics_signal_box(
    patch: F32, origin: tuple[int, int], box: Box, vignette: F32, settings: RenderSettings
) -> tuple[F32, tuple[int, int]]:
    """Signal of the frame inside ``box`` grown by :func:`blur_radius`, from ``patch``, the
    frame's radiance over ``box`` grown by twice that (clipped to the image) whose top-left
    pixel is ``origin`` (u, v). Returns the signal patch and its origin; equal to the same
    region of :func:`optics_signal` of the whole frame (no motion blur)."""
    if settings.motion_blur > 0:
        raise InputError("incremental optics need a fixed blur: motion blur changes every frame")
    h, w = vignette.shape[:2]
    r = blur_radius(settings)
    outer = grow_box(box, 2 * r, (w, h))
    if (outer[0], outer[1]) != tuple(origin) or patch.shape[:2] != (outer[3] - outer[1], outer[2] - outer[0]):
        raise InputError(f"patch must cover {outer} (box grown by {2 * r} px), got origin {origin}, {patch.shape}")
    sig = _linear_optics(patch, vignette[outer[1] : outer[3], outer[0] : outer[2]], settings, 0.0)
    inner = grow_box(box, r, (w, h))
    crop = sig[inner[1] - outer[1] : inner[3] - outer[1], inner[0] - outer[0] : inner[2] - outer[0]]
    return np.ascontiguousarray(crop), (inner[0], inner[1])
