"""The scene file: several arms in one endoscope view (docs/formats.md "Scene file"); read by the
simulated bench (sim.scene_setup, which re-exports it as sim.scene) and the hardware path alike.

A scene lists its arms, each with its marker file (a coded sleeve of one family, naming its arm:
``arm: NAME``), optionally its robot file and plant file, and its base pose in the scene's world
frame {w}: the pose of the arm's own {w} (where its robot file puts it) in the scene's. The
camera's ``world_T_left`` is in the scene's {w}. ``clearance`` [m] is the least distance between
two arms' bodies that the controllers keep (0: none); ``clearance_margin`` [m] is added to it in
the controllers' constraint, for the model's shape error near the tip that vision does not
correct (sim.several_arms: with 1 mm the true bodies kept 3 mm where 0 gave 2.3 mm);
``cube_size`` [m] the edges of each arm's cube in ``wristmark experiment cube --scene``.

    clearance: 0.003
    cube_size: [0.02, 0.01, 0.02]
    arms:
      - marker: markers/arm0.yaml
        base: {xyz: [0.0, 0.0, 0.0], rpy: [0.0, 0.0, 0.0]}
      - marker: markers/arm1.yaml
        robot: robots/paper.yaml
        base: {xyz: [0.0, 0.0, -0.032], rpy: [0.0, 0.0, 0.0]}

Paths are relative to the scene file's folder, else shipped configuration files. ``rpy`` [rad]:
roll about x, pitch about y, yaw about z of {w}, applied in that order (R = Rz Ry Rx, as URDF).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.config_files import find_config
from wristmark.models.config_io import load_yaml
from wristmark.models.errors import ConfigError
from wristmark.rig.targets.trajectories import CUBE_SIZE

Array = NDArray[np.float64]
SCENE_KEYS = ("arms", "clearance", "clearance_margin", "cube_size", "camera")
ARM_KEYS = ("marker", "robot", "plant", "base")
MAX_ARMS = 8

__all__ = ["Scene", "SceneArm", "pose_from_xyz_rpy"]


def pose_from_xyz_rpy(xyz: Any, rpy: Any) -> Array:
    """4x4 pose from a translation [m] and roll, pitch, yaw [rad] (R = Rz(yaw) Ry(pitch) Rx(roll))."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry @ Rx
    T[:3, 3] = [float(v) for v in xyz]
    return T


@dataclass(frozen=True)
class SceneArm:
    """One arm of a scene: its marker file (naming the arm), robot and plant files (None: the
    defaults) and ``base``, the 4x4 pose of its {w} in the scene's {w} [m]."""

    name: str
    marker: Path
    robot: Path | None
    plant: Path | None
    base: Array


@dataclass(frozen=True)
class Scene:
    """Several arms in one view (see the module docstring); ``source``: the scene file."""

    arms: tuple[SceneArm, ...]
    clearance: float = 0.003
    cube_size: tuple[float, float, float] = CUBE_SIZE
    camera: Path | None = None
    source: str = ""
    clearance_margin: float = 0.001

    @property
    def names(self) -> list[str]:
        """The arms' names, in the file's order."""
        return [a.name for a in self.arms]

    @classmethod
    def load(cls, path: str | Path) -> Scene:
        """Read and validate a scene file (ConfigError, one line naming the file and the cause).
        The markers are loaded to name the arms and checked as a set (distinct names and codes)."""
        from wristmark.models.marker import MarkerModel, check_marker_set

        p = find_config(path)
        data = load_yaml(p)
        where = str(p)
        unknown = sorted(set(data) - set(SCENE_KEYS))
        if unknown:
            raise ConfigError(f"{where}: unknown key '{unknown[0]}' (a scene has {', '.join(SCENE_KEYS)})")
        arms_data = data.get("arms")
        if not isinstance(arms_data, list) or not arms_data:
            raise ConfigError(f"{where}: 'arms' must be a list of at least one arm")
        if len(arms_data) > MAX_ARMS:
            raise ConfigError(f"{where}: {len(arms_data)} arms, more than {MAX_ARMS}")
        clearance = _number(data.get("clearance", 0.003), f"{where}: 'clearance'")
        if not 0.0 <= clearance <= 0.05:
            raise ConfigError(f"{where}: 'clearance' must be in [0, 0.05] m, got {clearance}")
        margin = _number(data.get("clearance_margin", 0.001), f"{where}: 'clearance_margin'")
        if not 0.0 <= margin <= 0.01:
            raise ConfigError(f"{where}: 'clearance_margin' must be in [0, 0.01] m, got {margin}")
        cube = data.get("cube_size", list(CUBE_SIZE))
        if not (isinstance(cube, list) and len(cube) == 3):
            raise ConfigError(f"{where}: 'cube_size' must be [x, y, z] in metres")
        cube_size = tuple(_number(v, f"{where}: 'cube_size'") for v in cube)
        if not all(0.0 < v <= 0.1 for v in cube_size):
            raise ConfigError(f"{where}: 'cube_size' edges must be in (0, 0.1] m, got {list(cube_size)}")
        camera = _path(p, data["camera"], f"{where}: 'camera'") if data.get("camera") is not None else None
        arms = []
        markers = []
        for i, a in enumerate(arms_data):
            what = f"{where}: arm {i}"
            if not isinstance(a, dict):
                raise ConfigError(f"{what}: expected a mapping with {', '.join(ARM_KEYS)}")
            bad = sorted(set(a) - set(ARM_KEYS))
            if bad:
                raise ConfigError(f"{what}: unknown key '{bad[0]}' (an arm has {', '.join(ARM_KEYS)})")
            if "marker" not in a:
                raise ConfigError(f"{what}: needs a 'marker' file (a coded sleeve naming its arm)")
            marker_path = _path(p, a["marker"], f"{what}: 'marker'")
            marker = MarkerModel.load(marker_path)
            if marker.arm is None:
                raise ConfigError(f"{marker_path}: the marker file of a scene's arm must name it ('arm: NAME')")
            markers.append(marker)
            robot = _path(p, a["robot"], f"{what}: 'robot'") if a.get("robot") is not None else None
            plant = _path(p, a["plant"], f"{what}: 'plant'") if a.get("plant") is not None else None
            arms.append(SceneArm(marker.arm, marker_path, robot, plant, _base(a.get("base"), what)))
        if len(markers) > 1:
            check_marker_set(markers, [str(a.marker) for a in arms])
        return cls(tuple(arms), clearance, (cube_size[0], cube_size[1], cube_size[2]), camera, where, margin)


def _number(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ConfigError(f"{what} must be a finite number, got {v!r}")
    return float(v)


def _path(scene: Path, value: Any, what: str) -> Path:
    """A path of the scene file: relative to its folder, else a shipped configuration file."""
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{what} must be a file name, got {value!r}")
    near = scene.parent / value
    p = near if near.is_file() else find_config(value)
    if not p.is_file():
        raise ConfigError(f"{what}: {value} not found (relative to {scene.parent} or shipped)")
    return p


def _base(value: Any, what: str) -> Array:
    """The arm's base pose from ``{xyz: [..], rpy: [..]}`` (missing: the identity)."""
    if value is None:
        return np.eye(4)
    if not isinstance(value, dict) or set(value) - {"xyz", "rpy"}:
        raise ConfigError(f"{what}: 'base' must be {{xyz: [x, y, z], rpy: [roll, pitch, yaw]}} (m, rad)")
    xyz, rpy = value.get("xyz", [0.0, 0.0, 0.0]), value.get("rpy", [0.0, 0.0, 0.0])
    for key, v in (("xyz", xyz), ("rpy", rpy)):
        if not (isinstance(v, list) and len(v) == 3):
            raise ConfigError(f"{what}: 'base.{key}' must be a list of 3 numbers")
        for x in v:
            _number(x, f"{what}: 'base.{key}'")
    return pose_from_xyz_rpy(xyz, rpy)
