"""Kalibr camchain YAML (pinhole-radtan): ``cam0``, ``cam1`` with ``intrinsics [fu, fv, pu, pv]``,
``distortion_model: radtan``, ``distortion_coeffs [k1, k2, p1, p2]``, ``resolution [w, h]``,
and ``cam1.T_cn_cnm1`` (4x4, X_cam1 = T X_cam0: the rig's [R T]) [m]."""

from __future__ import annotations

from typing import Any

import numpy as np

from wristmark.cvs.calibration.checks import check_distortion_model, dist5, matrix, same_size, validated
from wristmark.cvs.calibration.yaml_files import image_size
from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.errors import ConfigError


def is_camchain(data: dict[str, Any]) -> bool:
    """Whether a YAML mapping looks like a Kalibr camchain."""
    return "cam0" in data


def _cam(data: dict[str, Any], name: str, src: str) -> tuple[tuple[int, int], Camera]:
    node = data.get(name)
    if not isinstance(node, dict):
        raise ConfigError(f"{src}: missing key '{name}' (a Kalibr camchain needs cam0 and cam1)")
    for k in ("intrinsics", "distortion_coeffs", "resolution"):
        if k not in node:
            raise ConfigError(f"{src}: missing key '{name}.{k}'")
    model = node.get("camera_model", "pinhole")
    if str(model).lower() != "pinhole":
        raise ConfigError(f"{src}: '{name}.camera_model' is '{model}': only 'pinhole' is supported "
                          "(recalibrate with Kalibr's pinhole-radtan)")
    check_distortion_model(node.get("distortion_model", "radtan"), f"{name}.distortion_model", src, ("radtan",))
    intr = node["intrinsics"]
    if not isinstance(intr, list) or len(intr) != 4:
        raise ConfigError(f"{src}: '{name}.intrinsics' must be [fu, fv, pu, pv], got {intr!r}")
    fu, fv, pu, pv = matrix(intr, f"{name}.intrinsics", src, (4,))
    K = np.array([[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]])
    return image_size(node["resolution"], f"{name}.resolution", src), Camera(
        K, dist5(node["distortion_coeffs"], f"{name}.distortion_coeffs", src))


def from_camchain(data: dict[str, Any], src: str) -> StereoCamera:
    """A validated StereoCamera from a Kalibr camchain mapping."""
    size0, c0 = _cam(data, "cam0", src)
    size1, c1 = _cam(data, "cam1", src)
    size = same_size(size0, size1, src)
    if "T_cn_cnm1" not in data["cam1"]:
        raise ConfigError(f"{src}: missing key 'cam1.T_cn_cnm1' (the pose of cam0 in cam1)")
    T = matrix(data["cam1"]["T_cn_cnm1"], "cam1.T_cn_cnm1", src, (4, 4))
    if not np.allclose(T[3], [0, 0, 0, 1]):
        raise ConfigError(f"{src}: 'cam1.T_cn_cnm1' must be a 4x4 homogeneous transform (last row 0 0 0 1)")
    return validated(StereoCamera(size, c0, c1, T[:3, :3], T[:3, 3].copy()), src)
