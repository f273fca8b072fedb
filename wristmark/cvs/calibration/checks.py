"""Shared checks of every calibration reader (cvs/calib_<format>.py): shapes, distortion, units.

Each helper raises a one-line :class:`ConfigError` naming the file, the key and what to do.
Lengths are metres; a baseline longer than :data:`MAX_BASELINE` is taken for millimetres.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from wristmark.cvs.camera import StereoCamera
from wristmark.models.errors import ConfigError

MAX_BASELINE = 0.5  # [m] a stereo endoscope's baseline is millimetres: |T| above this is in mm
FISHEYE_MODELS = {"equidistant", "fisheye", "kannala_brandt", "kb4", "omni", "ds", "eucm", "fov"}


def matrix(value: Any, key: str, src: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (a flat list of the right size is reshaped
    for vectors); a 3x4 where a 3x3 belongs is named as a projection matrix."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{src}: '{key}' must be numbers of shape {list(shape)}") from e
    if a.shape != shape:
        if a.size == int(np.prod(shape)) and len(shape) == 1:
            a = a.reshape(shape)
        elif shape == (3, 3) and a.shape == (3, 4):
            raise ConfigError(f"{src}: '{key}' is 3x4 (a projection matrix P?) where the 3x3 camera matrix K "
                              "belongs: give K (for P = K [R | t], its left 3x3 block with R = I)")
        else:
            raise ConfigError(f"{src}: '{key}' must have shape {list(shape)}, got {list(a.shape)}")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{src}: '{key}' must be finite")
    return a


def dist5(value: Any, key: str, src: str) -> np.ndarray:
    """OpenCV radial-tangential distortion as 5 numbers [k1, k2, p1, p2, k3] (4 -> k3 = 0;
    longer lists only when the extra terms are zero)."""
    try:
        d = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{src}: '{key}' must be 5 numbers [k1, k2, p1, p2, k3]") from e
    if d.size == 4:
        d = np.append(d, 0.0)
    if d.size != 5 and not (d.size > 5 and np.all(d[5:] == 0)):
        raise ConfigError(f"{src}: '{key}' must be 5 numbers [k1, k2, p1, p2, k3], got {d.size}"
                          " (rational/thin-prism models are not supported: recalibrate with 5 coefficients)")
    if not np.all(np.isfinite(d)):
        raise ConfigError(f"{src}: '{key}' must be finite")
    return d[:5]


def check_distortion_model(model: Any, key: str, src: str, accepted: tuple[str, ...]) -> None:
    """Refuse fisheye/equidistant (and any other non-pinhole-radtan) distortion models."""
    name = str(model).strip().lower()
    if name in accepted:
        return
    if name in FISHEYE_MODELS:
        raise ConfigError(f"{src}: '{key}' is '{model}' (a fisheye/equidistant model), which wristmark does not "
                          "support: recalibrate with the pinhole radial-tangential model (OpenCV's default, "
                          "ROS plumb_bob, Kalibr pinhole-radtan)")
    raise ConfigError(f"{src}: '{key}' is '{model}': expected one of {', '.join(accepted)}")


def same_size(left: tuple[int, int], right: tuple[int, int], src: str) -> tuple[int, int]:
    """The common image size of both cameras; mismatched sizes are refused."""
    if tuple(left) != tuple(right):
        raise ConfigError(f"{src}: the left and right images differ in size ({left[0]}x{left[1]} vs "
                          f"{right[0]}x{right[1]}): calibrate both cameras at the same resolution")
    return int(left[0]), int(left[1])


def validated(cam: StereoCamera, src: str) -> StereoCamera:
    """``cam`` after :meth:`StereoCamera.validate` and the millimetre check of the baseline."""
    try:
        cam.validate()
    except ConfigError as e:
        raise ConfigError(f"{src}: {e}") from None
    b = float(np.linalg.norm(np.asarray(cam.T, float)))
    if b > MAX_BASELINE:
        raise ConfigError(f"{src}: the baseline |T| = {b:g} looks like millimetres (lengths are metres; a "
                          f"stereo endoscope's is ~0.005 m): divide T by 1000")
    if cam.T_world_left is not None and float(np.linalg.norm(np.asarray(cam.T_world_left)[:3, 3])) > 10.0:
        raise ConfigError(f"{src}: 'world_T_left' translation looks like millimetres (lengths are metres): "
                          "divide it by 1000")
    return cam
