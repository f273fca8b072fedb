"""uint8 grey images from grey, BGR or BGRA input, whole or cropped.

Cropping comes first and the colour conversion second, so that ROI tracking converts only its
box (measured: cv2.cvtColor of a 1920x1080 BGR frame 0.6 ms, of a 250x380 box 0.03 ms; the grey
levels are the same either way, the conversion being per pixel). Boxes are (x0, y0, x1, y1)
[px], x1 and y1 exclusive.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError

Box = tuple[int, int, int, int]


def check_image(img: Any) -> NDArray[np.uint8]:
    """The image as an array after checking that it is uint8 grey (h, w) or BGR / BGRA
    (h, w, 3 | 4); InputError (a ValueError) otherwise. Nothing is converted."""
    a = np.asarray(img)
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] in (3, 4))) or a.dtype != np.uint8:
        raise InputError(f"expected a uint8 grayscale or BGR image, got {a.dtype} {a.shape}")
    return a


def to_gray(img: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """uint8 grey levels of a checked image (the image itself when already grey)."""
    if img.ndim == 2:
        return img
    code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
    return np.asarray(cv2.cvtColor(img, code), np.uint8)


def gray_crop(img: NDArray[np.uint8], box: Box) -> NDArray[np.uint8]:
    """uint8 grey levels of ``img[y0:y1, x0:x1]`` (cropped first, then converted)."""
    x0, y0, x1, y1 = box
    return to_gray(img[y0:y1, x0:x1])


def check_view(img: Any, size: tuple[int, int], name: str) -> NDArray[np.uint8]:
    """The image as an array after checking shape, size and dtype (InputError, one line);
    nothing is converted: the detectors crop first and convert only what they search."""
    a = np.asarray(img)
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] in (3, 4))):
        raise InputError(f"{name} image must be grayscale (h, w) or BGR (h, w, 3), got shape {a.shape}")
    w, h = size
    if a.shape[:2] != (h, w):
        raise InputError(f"{name} image is {a.shape[1]}x{a.shape[0]} but the calibration expects {w}x{h}")
    if a.dtype != np.uint8:
        raise InputError(f"{name} image must be 8-bit (uint8), got {a.dtype}")
    return a
