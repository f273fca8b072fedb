"""How the simulated true arm differs from the model (docs/design.md "Plant file"); SI units.

Every key is optional; zero (or one, for gains) means ideal. ``PlantParams()`` is therefore the
ideal arm (configs/plant_ideal.yaml), the error model's zero; the command line's default
configs/plant.yaml is the reference simulated arm, a deliberate set of errors
(docs/configuration.md, "One default").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.models.config_io import from_mapping, load_layered
from wristmark.models.errors import ConfigError


@dataclass(frozen=True)
class PlantParams:
    """Error model of the true arm.

    bend_gain: theta_true = g_t theta_cmd per segment [-]. plane_offset: delta_true =
    delta_cmd + o_t [rad]. stem_coupling: the exposed stem (length d) bends by zeta * theta1 in
    segment 1's plane [-]. backlash: dead-band per actuator [rad, m, m, m, m, m].
    actuator_tau: first-order lag of every actuator [s]. tip_force: constant force at the tip
    in {w} [N]. segment_stiffness: bending stiffness turning load moments into bend [N m/rad].
    bend_gain, plane_offset and segment_stiffness have one entry per segment of the arm, backlash
    one per actuator (:meth:`for_arm`; a planar segment's plane_offset turns its fixed plane).
    camera_offset: [x, y, z, rx, ry, rz] (metres; rotation vector, rad) expressed in {ll}: the
    simulated camera truly sits at world_T_left @ T(offset) while the host believes world_T_left.
    """

    bend_gain: tuple[float, ...] = (1.0, 1.0)
    plane_offset: tuple[float, ...] = (0.0, 0.0)
    stem_coupling: float = 0.0
    backlash: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    actuator_tau: float = 0.0
    tip_force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    segment_stiffness: tuple[float, ...] = (0.40, 0.15)
    camera_offset: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for i, g in enumerate(self.bend_gain):
            if not 0.5 <= g <= 1.5:
                raise ConfigError(f"'bend_gain[{i}]' must be in [0.5, 1.5], got {g}")
        for i, o in enumerate(self.plane_offset):
            if abs(o) > 0.5:
                raise ConfigError(f"'plane_offset[{i}]' must be within +-0.5 rad, got {o}")
        if not 0.0 <= self.stem_coupling <= 1.0:
            raise ConfigError(f"'stem_coupling' must be in [0, 1], got {self.stem_coupling}")
        for i, b in enumerate(self.backlash):
            if b < 0:
                raise ConfigError(f"'backlash[{i}]' must be >= 0, got {b}")
        if self.actuator_tau < 0:
            raise ConfigError(f"'actuator_tau' must be >= 0 s, got {self.actuator_tau}")
        for i, k in enumerate(self.segment_stiffness):
            if k <= 0:
                raise ConfigError(f"'segment_stiffness[{i}]' must be > 0 N*m/rad, got {k}")

        if math.hypot(*self.camera_offset[:3]) > 0.05:
            raise ConfigError(f"'camera_offset' translation must be within 0.05 m (metres, not mm), "
                              f"got {list(self.camera_offset[:3])}")
        if math.hypot(*self.camera_offset[3:]) > 0.5:
            raise ConfigError(f"'camera_offset' rotation vector must be within 0.5 rad, "
                              f"got {list(self.camera_offset[3:])}")

    def for_arm(self, segments: int, actuators: int, source: str = "<plant>") -> PlantParams:
        """These errors checked against an arm of ``segments`` segments and ``actuators``
        actuators: a per-segment key needs one entry per segment, ``backlash`` one per actuator
        (ConfigError naming the key and the expected length). A key left at its default (the
        ideal arm; the default stiffness) is sized to the arm."""
        sizes = {"bend_gain": segments, "plane_offset": segments, "segment_stiffness": segments,
                 "backlash": actuators}
        default = PlantParams()
        changes: dict[str, Any] = {}
        for key, want in sizes.items():
            have = getattr(self, key)
            if len(have) == want:
                continue
            if have == getattr(default, key):
                changes[key] = _default_sized(key, want)
                continue
            what = "segment" if key != "backlash" else "actuator"
            raise ConfigError(f"{source}: '{key}' must have {want} entries (one per {what} of the arm), "
                              f"got {len(have)}")
        return replace(self, **changes) if changes else self

    def camera_offset_transform(self) -> NDArray[np.float64]:
        """T(offset): 4x4 pose of the true {ll} in the believed {ll} [m]."""
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(self.camera_offset[3:]).as_matrix()
        T[:3, 3] = self.camera_offset[:3]
        return T

    @classmethod
    def load(cls, path: str | Path) -> PlantParams:
        """Load and validate a plant file."""
        return from_mapping(cls, load_layered(path), str(path))



def _default_sized(key: str, n: int) -> tuple[float, ...]:
    """The default (ideal) value of a per-segment or per-actuator key for ``n`` entries; the
    default stiffness: the reference arm's proximal 0.40 N m/rad, then its distal 0.15."""
    if key == "segment_stiffness":
        return (0.40,) + (0.15,) * (n - 1)
    return ((1.0,) if key == "bend_gain" else (0.0,)) * n
