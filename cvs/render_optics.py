"""Camera optics and sensor: vignetting, motion and optics blur, shot + read noise, 8-bit
quantisation and an optional JPEG round trip. Images are float32 BGR in grey levels."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from cvs.render_settings import RenderSettings
from models.errors import InputError

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]


def vignetting_map(size: tuple[int, int], strength: float) -> F32:
    """Multiplicative brightness (h, w): 1 at the centre, 1 - strength at the corners (cos^4-like)."""
    w, h = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
    return (1.0 - strength * r2).astype(np.float32)


def motion_kernel(length: float, angle: float) -> F32:
    """Normalised linear motion-blur kernel of ``length`` [px] along ``angle`` [rad]."""
    n = int(np.ceil(length)) | 1
    k = np.zeros((n, n), np.float32)
    c = (n - 1) / 2
    d = np.array([np.cos(angle), np.sin(angle)]) * length / 2
    p0 = (int(round((c - d[0]) * 16)), int(round((c - d[1]) * 16)))
    p1 = (int(round((c + d[0]) * 16)), int(round((c + d[1]) * 16)))
    cv2.line(k, p0, p1, 1.0, 1, cv2.LINE_AA, shift=4)
    return k / max(float(k.sum()), 1e-9)


def apply_optics(img: F32, settings: RenderSettings, vignette: F32, rng: np.random.Generator) -> U8:
    """Vignetting, motion blur, optics blur, noise, quantisation, JPEG; returns uint8 BGR or gray.

    ``vignette`` has the shape of ``img`` (or (h, w) for grayscale output); noise comes from
    OpenCV's RNG seeded from ``rng`` (deterministic, ~5x faster than numpy's normals here)."""
    cv2.setNumThreads(1)
    out: Any = cv2.multiply(img, vignette if vignette.ndim == img.ndim else cv2.merge([vignette] * img.shape[2]))
    if settings.motion_blur > 0:
        out = cv2.filter2D(out, -1, motion_kernel(settings.motion_blur, float(rng.uniform(0, np.pi))))
    if settings.blur_sigma > 0:
        out = cv2.GaussianBlur(out, (0, 0), settings.blur_sigma)
    if not settings.colour:
        out = cv2.cvtColor(out, cv2.COLOR_BGR2GRAY)
    if settings.shot_gain > 0 or settings.read_noise > 0:
        var = np.maximum(out, np.float32(0)) * np.float32(settings.shot_gain) + settings.read_noise**2
        noise: Any = np.empty_like(out)
        cv2.setRNGSeed(int(rng.integers(0, 2**31 - 1)))
        cv2.randn(noise, 0.0, 1.0)  # type: ignore[call-overload]
        out = cv2.add(out, cv2.multiply(cv2.sqrt(var), noise))
    u8: Any = cv2.convertScaleAbs(np.maximum(out, np.float32(0)))  # rounds and saturates to 0..255
    if settings.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", u8, [cv2.IMWRITE_JPEG_QUALITY, int(settings.jpeg_quality)])
        if not ok:
            raise InputError("JPEG encoding failed: try another --jpeg quality")
        u8 = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    return np.asarray(u8, np.uint8)
