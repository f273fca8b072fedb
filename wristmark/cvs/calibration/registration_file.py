"""Registration files (docs/design.md "Registration"): ``world_T_left`` (4x4, pose of {ll} in {w},
metres), ``rms_m`` (residual RMS of the marker centres [m]) and ``poses`` (how many). The one
place that reads them; ``--registration FILE`` on track, experiment, servo and register goes
through :func:`apply_registration`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.calibration.checks import matrix
from wristmark.cvs.camera import StereoCamera
from wristmark.models.config_io import load_yaml, save_yaml
from wristmark.models.errors import ConfigError

Array = NDArray[np.float64]
KEYS = {"world_T_left", "rms_m", "poses"}


@dataclass(frozen=True)
class Registration:
    """Pose of {ll} in {w} (4x4, metres), residual RMS of the marker centres [m], pose count."""

    world_T_left: Array
    rms_m: float
    poses: int


def check_transform(W: Array, key: str, src: str) -> Array:
    """A proper 4x4 rigid transform in metres, else a one-line ConfigError."""
    W = matrix(W, key, src, (4, 4))
    R = W[:3, :3]
    if not np.allclose(W[3], [0, 0, 0, 1]) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ConfigError(f"{src}: '{key}' must be a 4x4 rigid transform (proper rotation, last row 0 0 0 1)")
    if float(np.linalg.norm(W[:3, 3])) > 10.0:
        raise ConfigError(f"{src}: '{key}' translation looks like millimetres (lengths are metres): divide it by 1000")
    return W


def load_registration(path: str | Path) -> Registration:
    """Read and validate a registration file (world_T_left: pose of {ll} in {w}, 4x4 [m])."""
    src = str(path)
    data = load_yaml(path)
    unknown = sorted(set(data) - KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown key '{unknown[0]}' (valid keys: {', '.join(sorted(KEYS))})")
    if "world_T_left" not in data:
        raise ConfigError(f"{src}: missing key 'world_T_left' (is this a registration file?)")
    W = check_transform(data["world_T_left"], "world_T_left", src)
    rms, n = data.get("rms_m", float("nan")), data.get("poses", 0)
    if isinstance(rms, bool) or not isinstance(rms, int | float) or rms < 0:
        raise ConfigError(f"{src}: 'rms_m' must be a number >= 0 [m], got {rms!r}")
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ConfigError(f"{src}: 'poses' must be an integer >= 0, got {n!r}")
    return Registration(W, float(rms), int(n))


def save_registration(path: str | Path, reg: Registration) -> None:
    """Write a registration file (SI units)."""
    check_transform(reg.world_T_left, "world_T_left", str(path))
    save_yaml(path, {"world_T_left": np.asarray(reg.world_T_left, float).tolist(), "rms_m": float(reg.rms_m),
                     "poses": int(reg.poses)})


def apply_registration(cam: StereoCamera, path: str | Path | None) -> StereoCamera:
    """``cam`` with world_T_left replaced by the registration file's (``path`` None: unchanged)."""
    if path is None:
        return cam
    return dataclasses.replace(cam, T_world_left=load_registration(path).world_T_left)
