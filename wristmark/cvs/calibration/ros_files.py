"""ROS camera_info pairs ``LEFT.yaml,RIGHT.yaml`` as ROS camera_calibration writes them.

Per camera: ``image_width``, ``image_height``, ``camera_matrix`` (K), ``distortion_model``
(plumb_bob / rational_polynomial with zero extra terms), ``distortion_coefficients`` (D),
``rectification_matrix`` (R_i: raw camera i -> rectified frame) and ``projection_matrix`` (P_i).
The rig follows stereo_image_proc's definitions: both rectified frames are parallel and the
right one sits at x = -Tx/fx' with Tx = P2[0,3] (= -fx' * baseline), so
``R = R2^T R1`` and ``T = R2^T [P2[0,3] / P2[0,0], 0, 0]`` (X_right = R X_left + T) [m].
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cvs.calibration.checks import check_distortion_model, dist5, matrix, same_size, validated
from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.config_io import load_yaml
from wristmark.models.errors import ConfigError

REQUIRED = ("image_width", "image_height", "camera_matrix", "distortion_coefficients",
            "rectification_matrix", "projection_matrix")


def is_camera_info(data: dict[str, Any]) -> bool:
    """Whether a YAML mapping looks like one ROS camera_info file."""
    return "camera_matrix" in data and "projection_matrix" in data


def _ros_matrix(data: dict[str, Any], key: str, src: str, shape: tuple[int, int]) -> np.ndarray:
    node = data[key]
    if not isinstance(node, dict) or "data" not in node:
        raise ConfigError(f"{src}: '{key}' must be a mapping with rows, cols and data")
    rows, cols = node.get("rows"), node.get("cols")
    flat = np.asarray(node["data"], dtype=float).ravel() if isinstance(node["data"], list) else None
    if flat is None or not isinstance(rows, int) or not isinstance(cols, int) or flat.size != rows * cols:
        raise ConfigError(f"{src}: '{key}' must have integer rows, cols and rows*cols numbers in data")
    a = flat.reshape(rows, cols)
    if shape[0] == 1:  # distortion: any 1xN / Nx1
        return a.ravel()
    return matrix(a, key, src, shape)


def _one(path: Path) -> tuple[tuple[int, int], Camera, np.ndarray, np.ndarray]:
    src = str(path)
    data = load_yaml(path)
    for k in REQUIRED:
        if k not in data:
            raise ConfigError(f"{src}: missing key '{k}' (a ROS camera_info file needs {', '.join(REQUIRED)})")
    check_distortion_model(data.get("distortion_model", "plumb_bob"), "distortion_model", src,
                           ("plumb_bob", "rational_polynomial", "radtan", "radial-tangential"))
    w, h = data["image_width"], data["image_height"]
    if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (w, h)):
        raise ConfigError(f"{src}: 'image_width' and 'image_height' must be positive integers")
    K = _ros_matrix(data, "camera_matrix", src, (3, 3))
    D = dist5(_ros_matrix(data, "distortion_coefficients", src, (1, 0)), "distortion_coefficients", src)
    Rr = _ros_matrix(data, "rectification_matrix", src, (3, 3))
    P = _ros_matrix(data, "projection_matrix", src, (3, 4))
    if not np.allclose(Rr @ Rr.T, np.eye(3), atol=1e-5) or np.linalg.det(Rr) < 0:
        raise ConfigError(f"{src}: 'rectification_matrix' must be a proper rotation")
    return (int(w), int(h)), Camera(K, D), Rr, P


def load_ros_pair(left: Path, right: Path) -> StereoCamera:
    """Read and validate a ROS camera_info pair (left, right)."""
    src = f"{left},{right}"
    size_l, cam_l, R1, _P1 = _one(left)
    size_r, cam_r, R2, P2 = _one(right)
    size = same_size(size_l, size_r, src)
    if P2[0, 0] <= 0:
        raise ConfigError(f"{right}: 'projection_matrix' must have fx' = P[0,0] > 0")
    tx = P2[0, 3] / P2[0, 0]
    if tx == 0:
        raise ConfigError(f"{right}: 'projection_matrix' has Tx = P[0,3] = 0: is this the right camera's file? "
                          "(give LEFT.yaml,RIGHT.yaml in that order)")
    R = R2.T @ R1
    T = R2.T @ np.array([tx, 0.0, 0.0])
    return validated(StereoCamera(size, cam_l, cam_r, R, T), src)
