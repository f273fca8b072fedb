"""docs/design.md's calibration YAML (image_size, left/right K and dist, R, T, world_T_left) [m, px]."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cvs.calibration.checks import dist5, matrix, validated
from wristmark.cvs.camera import Camera, StereoCamera
from wristmark.models.config_io import save_yaml
from wristmark.models.errors import ConfigError

YAML_KEYS = {"image_size", "left", "right", "R", "T", "world_T_left"}
_CAM_KEYS = {"K", "dist"}


def image_size(value: Any, key: str, src: str) -> tuple[int, int]:
    """[width, height] as two positive integers."""
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ConfigError(f"{src}: '{key}' must be [width, height], got {value!r}")
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{src}: '{key}' must be two integers, got {value!r}")
    return int(value[0]), int(value[1])


def _camera(data: Any, name: str, src: str) -> Camera:
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: '{name}' must be a mapping with keys K and dist")
    unknown = sorted(set(data) - _CAM_KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown key '{name}.{unknown[0]}' (valid keys: K, dist)")
    for k in ("K", "dist"):
        if k not in data:
            raise ConfigError(f"{src}: missing key '{name}.{k}'")
    return Camera(matrix(data["K"], f"{name}.K", src, (3, 3)), dist5(data["dist"], f"{name}.dist", src))


def from_yaml_mapping(data: dict[str, Any], src: str) -> StereoCamera:
    """A validated StereoCamera from docs/design.md's mapping (``src`` names the file in errors): the
    one mapping -> camera function (calibration files, run records' config.json, replay)."""
    unknown = sorted(set(data) - YAML_KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown key '{unknown[0]}' (valid keys: {', '.join(sorted(YAML_KEYS))})")
    for k in ("image_size", "left", "right", "R", "T"):
        if k not in data:
            raise ConfigError(f"{src}: missing key '{k}'")
    W = data.get("world_T_left")
    cam = StereoCamera(
        image_size(data["image_size"], "image_size", src),
        _camera(data["left"], "left", src),
        _camera(data["right"], "right", src),
        matrix(data["R"], "R", src, (3, 3)),
        matrix(data["T"], "T", src, (3,)),
        None if W is None else matrix(W, "world_T_left", src, (4, 4)),
    )
    return validated(cam, src)


def calibration_mapping(cam: StereoCamera) -> dict[str, Any]:
    """The calibration as docs/design.md's YAML mapping (plain lists, SI units): the one camera ->
    mapping function (calibration files, run records' config.json); :func:`from_yaml_mapping`
    reads it back."""
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
    """Validate ``cam`` and write it as the project's calibration YAML (docs/formats.md)."""
    validated(cam, str(path))
    save_yaml(path, calibration_mapping(cam))
