"""Tissue-like background for the synthetic endoscope: mottled mucosa, folds with edges,
branching vessels and specular glints, lit by the coaxial light (brighter in the middle)."""

from __future__ import annotations

import functools
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

F32 = NDArray[np.float32]


def _smooth_noise(rng: np.random.Generator, h: int, w: int, sigma: float) -> F32:
    """Zero-mean, unit-std Gaussian-filtered noise, generated coarse and upsampled (fast)."""
    step = max(1, int(sigma / 2))
    small: Any = rng.standard_normal((h // step + 2, w // step + 2)).astype(np.float32)
    small = cv2.GaussianBlur(small, (0, 0), sigma / step)
    big = cv2.resize(small, ((w // step + 2) * step, (h // step + 2) * step), interpolation=cv2.INTER_CUBIC)[:h, :w]
    return ((big - big.mean()) / (big.std() + 1e-9)).astype(np.float32)


def tissue_texture(rng: np.random.Generator, width: int, height: int) -> F32:
    """A BGR albedo image (height, width, 3), values ~0-1, of endoscopic tissue."""
    h, w = height, width
    s = max(w, h) / 1920.0  # scale features with the image
    base = np.array([0.36, 0.42, 0.82], np.float32)  # pink-red mucosa (B, G, R)
    mott = 0.10 * _smooth_noise(rng, h, w, 90 * s) + 0.06 * _smooth_noise(rng, h, w, 20 * s)
    fine = 0.03 * _smooth_noise(rng, h, w, 2.5 * s)
    img = base[None, None, :] * (1.0 + mott + fine)[..., None]
    # folds: dark shadowed creases with one bright rim (edges in the background)
    folds: Any = np.zeros((h, w), np.float32)
    for _ in range(int(rng.integers(3, 6))):
        pts = np.cumsum(rng.normal(0, 60 * s, (12, 2)), axis=0) + rng.uniform([0, 0], [w, h])
        cv2.polylines(folds, [pts.astype(np.int32)], False, 1.0, max(2, int(14 * s)), cv2.LINE_AA)
    folds = cv2.GaussianBlur(folds, (0, 0), 6 * s)
    rim = np.roll(folds, int(max(2, 8 * s)), axis=0)
    img *= (1.0 - 0.45 * folds + 0.15 * rim)[..., None]
    # vessels: branching random walks, dark red-purple
    ves: Any = np.zeros((h, w), np.float32)
    for _ in range(int(rng.integers(6, 11))):
        p = rng.uniform([0, 0], [w, h])
        ang = rng.uniform(0, 2 * np.pi)
        thick = rng.uniform(1.0, 5.0) * s
        for _ in range(3):  # one trunk and its branches
            walk: list[Any] = [p]
            for _ in range(int(rng.integers(15, 40))):
                ang += rng.normal(0, 0.25)
                walk.append(walk[-1] + 18 * s * np.array([np.cos(ang), np.sin(ang)]))
            cv2.polylines(ves, [np.asarray(walk).astype(np.int32)], False, 1.0, max(1, int(thick)), cv2.LINE_AA)
            p = walk[int(rng.integers(1, len(walk)))]
            ang += rng.choice([-1.0, 1.0]) * 0.8
            thick *= 0.6
    ves = cv2.GaussianBlur(ves, (0, 0), 1.0 * s + 0.3)
    img *= 1.0 - ves[..., None] * np.array([0.35, 0.6, 0.35], np.float32)
    return np.clip(img, 0.0, 1.5).astype(np.float32)


def glints(rng: np.random.Generator, width: int, height: int) -> F32:
    """Specular highlights of the wet tissue: small bright ellipses (height, width) in 0-1."""
    s = max(width, height) / 1920.0
    g = np.zeros((height, width), np.float32)
    for _ in range(int(rng.integers(25, 50))):
        c = (int(rng.uniform(0, width)), int(rng.uniform(0, height)))
        ax = (max(1, int(rng.uniform(2, 14) * s)), max(1, int(rng.uniform(1, 5) * s)))
        cv2.ellipse(g, c, ax, float(rng.uniform(0, 180)), 0, 360, float(rng.uniform(0.5, 1.0)), -1, cv2.LINE_AA)
    return np.asarray(cv2.GaussianBlur(g, (0, 0), 1.2 * s + 0.3), np.float32)


def illumination(width: int, height: int, spot: float = 0.55) -> F32:
    """Irradiance of the coaxial light on the tissue: 1 at the centre, falling off outwards."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((x - (width - 1) / 2) ** 2 + (y - (height - 1) / 2) ** 2) / (0.5 * max(width, height)) ** 2
    return (1.0 / (1.0 + spot * r2) ** 2).astype(np.float32)


def stereo_backgrounds(
    rng: np.random.Generator, size: tuple[int, int], disparity_px: float, exposure: float
) -> tuple[F32, F32]:
    """Left and right BGR background radiance [grey levels]: the same tissue, shifted by the
    stereo disparity [px] between the eyes."""
    w, h = size
    pad = int(abs(disparity_px)) + 2
    tex = tissue_texture(rng, w + pad, h)
    gl = glints(rng, w + pad, h)
    light = illumination(w, h)
    out = []
    for x0 in (pad, pad - int(round(disparity_px))):
        x0 = int(np.clip(x0, 0, pad))
        alb = tex[:, x0 : x0 + w]
        rad = exposure * (alb * light[..., None] + 1.6 * gl[:, x0 : x0 + w, None] * light[..., None])
        out.append(np.ascontiguousarray(rad, dtype=np.float32))
    return out[0], out[1]


@functools.lru_cache(maxsize=4)
def seeded_stereo_backgrounds(
    seed: int, size: tuple[int, int], disparity_px: float, exposure: float
) -> tuple[F32, F32]:
    """:func:`stereo_backgrounds` drawn from ``seed``'s own generator, built once per process for
    each (seed, size, disparity, exposure) and shared: renderers of the same seed draw the same
    tissue. Read-only: copy before writing into them."""
    return stereo_backgrounds(np.random.default_rng([int(seed), 0]), size, disparity_px, exposure)
