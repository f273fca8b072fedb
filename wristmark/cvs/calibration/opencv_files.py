"""OpenCV FileStorage stereo files (.yml/.yaml/.xml with M1, D1, M2, D2, R, T), as
``cv2.stereoCalibrate`` samples write them. The image size comes from ``image_size``,
``imageSize``, ``size`` or ``image_width``/``image_height``, else from the principal point."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from wristmark.cvs.calibration.checks import dist5, matrix, validated
from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.errors import ConfigError

KEYS = ("M1", "D1", "M2", "D2", "R", "T")


def is_opencv_storage(text: str) -> bool:
    """Whether a file's text is OpenCV FileStorage (``%YAML:1.0`` header, XML, opencv-matrix)."""
    head = text.lstrip()[:200]
    return head.startswith("%YAML:1.0") or head.startswith("<?xml") or "opencv-matrix" in text[:4000]


def _size(fs: cv2.FileStorage, src: str) -> tuple[int, int] | None:
    for k in ("image_size", "imageSize", "size"):
        node = fs.getNode(k)
        if not node.empty():
            m = node.mat()
            vals = (np.asarray(m, float).ravel() if m is not None
                    else np.array([node.at(i).real() for i in range(node.size())]))
            if vals.size != 2:
                raise ConfigError(f"{src}: '{k}' must be [width, height]")
            return int(vals[0]), int(vals[1])
    wn, hn = fs.getNode("image_width"), fs.getNode("image_height")
    if not wn.empty() and not hn.empty():
        return int(wn.real()), int(hn.real())
    return None


def load_opencv(path: Path) -> StereoCamera:
    """Read and validate an OpenCV FileStorage stereo calibration."""
    src = str(path)
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as e:
        raise ConfigError(f"{src}: not a readable OpenCV FileStorage file") from e
    if not fs.isOpened():
        raise ConfigError(f"{src}: not a readable OpenCV FileStorage file")
    try:
        mats: dict[str, np.ndarray] = {}
        for k in KEYS:
            node = fs.getNode(k)
            if node.empty():
                raise ConfigError(f"{src}: missing key '{k}' (OpenCV stereo file needs M1, D1, M2, D2, R, T)")
            m = node.mat()
            if m is None:
                raise ConfigError(f"{src}: '{k}' is not a matrix")
            mats[k] = np.asarray(m, dtype=float)
        size = _size(fs, src)
    except (cv2.error, SystemError) as e:
        raise ConfigError(f"{src}: corrupt OpenCV FileStorage file") from e
    finally:
        fs.release()
    K1 = matrix(mats["M1"], "M1", src, (3, 3))
    if size is None:  # a pinhole's principal point is near the centre: (2 cx + 1, 2 cy + 1)
        size = (int(round(2 * K1[0, 2] + 1)), int(round(2 * K1[1, 2] + 1)))
    cam = StereoCamera(
        size,
        Camera(K1, dist5(mats["D1"], "D1", src)),
        Camera(matrix(mats["M2"], "M2", src, (3, 3)), dist5(mats["D2"], "D2", src)),
        matrix(mats["R"], "R", src, (3, 3)),
        matrix(mats["T"], "T", src, (3,)),
    )
    return validated(cam, src)
