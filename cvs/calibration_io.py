"""Stereo calibration files: DESIGN.md's YAML and OpenCV FileStorage (M1, D1, M2, D2, R, T).

The format is detected by content: an OpenCV FileStorage file starts with ``%YAML:1.0`` or is
XML, or holds the key ``M1``; anything else is read as DESIGN.md's YAML. Every loaded
calibration is validated with :meth:`StereoCamera.validate`; errors are one-line
:class:`ConfigError` messages naming the key and the file. Units: metres, pixels.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from cvs.camera import Camera, StereoCamera
from models.config_io import check_file_size, load_yaml, save_yaml
from models.errors import ConfigError

_YAML_KEYS = {"image_size", "left", "right", "R", "T", "world_T_left"}
_CAM_KEYS = {"K", "dist"}


def _matrix(value: Any, key: str, src: str, shape: tuple[int, ...]) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{src}: '{key}' must be numbers of shape {list(shape)}") from e
    if a.shape != shape:
        if a.size == int(np.prod(shape)) and len(shape) == 1:
            a = a.reshape(shape)
        else:
            raise ConfigError(f"{src}: '{key}' must have shape {list(shape)}, got {list(a.shape)}")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{src}: '{key}' must be finite")
    return a


def _dist5(value: Any, key: str, src: str) -> np.ndarray:
    try:
        d = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{src}: '{key}' must be 5 numbers [k1, k2, p1, p2, k3]") from e
    if d.size == 4:
        d = np.append(d, 0.0)
    if d.size != 5 and not (d.size > 5 and np.all(d[5:] == 0)):
        raise ConfigError(f"{src}: '{key}' must be 5 numbers [k1, k2, p1, p2, k3], got {d.size}")
    return d[:5]


def _validated(cam: StereoCamera, src: str) -> StereoCamera:
    try:
        cam.validate()
    except ConfigError as e:
        raise ConfigError(f"{src}: {e}") from None
    return cam


def _image_size(value: Any, src: str) -> tuple[int, int]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ConfigError(f"{src}: 'image_size' must be [width, height], got {value!r}")
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{src}: 'image_size' must be two integers, got {value!r}")
    return int(value[0]), int(value[1])


def _camera_from_yaml(data: Any, name: str, src: str) -> Camera:
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: '{name}' must be a mapping with keys K and dist")
    unknown = sorted(set(data) - _CAM_KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown key '{name}.{unknown[0]}' (valid keys: K, dist)")
    for k in ("K", "dist"):
        if k not in data:
            raise ConfigError(f"{src}: missing key '{name}.{k}'")
    return Camera(_matrix(data["K"], f"{name}.K", src, (3, 3)), _dist5(data["dist"], f"{name}.dist", src))


def _from_yaml(path: Path) -> StereoCamera:
    src = str(path)
    data = load_yaml(path)
    unknown = sorted(set(data) - _YAML_KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown key '{unknown[0]}' (valid keys: {', '.join(sorted(_YAML_KEYS))})")
    for k in ("image_size", "left", "right", "R", "T"):
        if k not in data:
            raise ConfigError(f"{src}: missing key '{k}'")
    W = data.get("world_T_left")
    cam = StereoCamera(
        _image_size(data["image_size"], src),
        _camera_from_yaml(data["left"], "left", src),
        _camera_from_yaml(data["right"], "right", src),
        _matrix(data["R"], "R", src, (3, 3)),
        _matrix(data["T"], "T", src, (3,)),
        None if W is None else _matrix(W, "world_T_left", src, (4, 4)),
    )
    return _validated(cam, src)


def _is_opencv_storage(text: str) -> bool:
    head = text.lstrip()[:200]
    return head.startswith("%YAML:1.0") or head.startswith("<?xml") or "opencv-matrix" in text[:4000]


def _from_opencv(path: Path) -> StereoCamera:
    src = str(path)
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as e:
        raise ConfigError(f"{src}: not a readable OpenCV FileStorage file") from e
    if not fs.isOpened():
        raise ConfigError(f"{src}: not a readable OpenCV FileStorage file")
    try:
        mats: dict[str, np.ndarray] = {}
        for k in ("M1", "D1", "M2", "D2", "R", "T"):
            node = fs.getNode(k)
            if node.empty():
                raise ConfigError(f"{src}: missing key '{k}' (OpenCV stereo file needs M1, D1, M2, D2, R, T)")
            m = node.mat()
            if m is None:
                raise ConfigError(f"{src}: '{k}' is not a matrix")
            mats[k] = np.asarray(m, dtype=float)
        size: tuple[int, int] | None = None
        for k in ("image_size", "imageSize", "size"):
            node = fs.getNode(k)
            if not node.empty():
                m = node.mat()
                vals = (
                    np.asarray(m, float).ravel()
                    if m is not None
                    else np.array([node.at(i).real() for i in range(node.size())])
                )
                if vals.size != 2:
                    raise ConfigError(f"{src}: '{k}' must be [width, height]")
                size = (int(vals[0]), int(vals[1]))
        if size is None:
            wn, hn = fs.getNode("image_width"), fs.getNode("image_height")
            if not wn.empty() and not hn.empty():
                size = (int(wn.real()), int(hn.real()))
    except (cv2.error, SystemError) as e:
        raise ConfigError(f"{src}: corrupt OpenCV FileStorage file") from e
    finally:
        fs.release()
    if size is None:  # a pinhole's principal point is near the centre: (2 cx + 1, 2 cy + 1)
        K = mats["M1"]
        size = (int(round(2 * K[0, 2] + 1)), int(round(2 * K[1, 2] + 1))) if K.shape == (3, 3) else (0, 0)
    cam = StereoCamera(
        size,
        Camera(_matrix(mats["M1"], "M1", src, (3, 3)), _dist5(mats["D1"], "D1", src)),
        Camera(_matrix(mats["M2"], "M2", src, (3, 3)), _dist5(mats["D2"], "D2", src)),
        _matrix(mats["R"], "R", src, (3, 3)),
        _matrix(mats["T"], "T", src, (3,)),
    )
    return _validated(cam, src)


def load_calibration(path: str | Path) -> StereoCamera:
    """Load and validate a stereo calibration (DESIGN.md YAML or OpenCV FileStorage)."""
    p = check_file_size(path, what="calibration file")  # before YAML or cv2.FileStorage reads it
    try:
        text = p.read_text(errors="replace")
    except OSError as e:
        raise ConfigError(f"{p}: cannot read the calibration file ({e.strerror})") from e
    if _is_opencv_storage(text):
        return _from_opencv(p)
    return _from_yaml(p)


def calibration_mapping(cam: StereoCamera) -> dict[str, Any]:
    """The calibration as DESIGN.md's YAML mapping (plain lists, SI units)."""
    out: dict[str, Any] = {
        "image_size": [int(cam.image_size[0]), int(cam.image_size[1])],
        "left": {"K": np.asarray(cam.left.K, float).tolist(), "dist": np.asarray(cam.left.dist, float).tolist()},
        "right": {"K": np.asarray(cam.right.K, float).tolist(), "dist": np.asarray(cam.right.dist, float).tolist()},
        "R": np.asarray(cam.R, float).tolist(),
        "T": np.asarray(cam.T, float).ravel().tolist(),
    }
    if cam.T_world_left is not None:
        out["world_T_left"] = np.asarray(cam.T_world_left, float).tolist()
    return out


def save_calibration(path: str | Path, cam: StereoCamera) -> None:
    """Validate ``cam`` and write it as DESIGN.md's calibration YAML."""
    _validated(cam, str(path))
    save_yaml(path, calibration_mapping(cam))
