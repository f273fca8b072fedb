"""Geometry and limits of the continuum manipulator (docs/design.md, "The manipulator"); SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from wristmark.models.config_io import from_mapping, load_layered
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel


@dataclass(frozen=True)
class RobotParams:
    """Reference continuum arm. Lengths [m], angles [rad], velocities [rad/s or m/s].

    psi = [phi, d, theta1, delta1, theta2, delta2]. ``tip_offset`` ({wm} -> tip) belongs to the
    marker (docs/design.md: the marker file's ``tip_offset``): :func:`load_robot` copies it from the
    marker, and a robot file need not (and the shipped one does not) state it.
    """

    segment_lengths: tuple[float, float] = (0.100, 0.020)  # L1, L2 [m]
    rigid_length: float = 0.010  # L_r, {1e} -> {2b} [m]
    marker_offset: float = 0.005  # l_marker, {2e} -> {wm} [m]
    tip_offset: float = 0.015  # {wm} -> tip [m] (paper: 15 mm): the marker's, see load_robot
    phi_range: tuple[float, float] = (-math.pi, math.pi)  # [rad]
    d_range: tuple[float, float] = (0.0, 0.150)  # [m]
    theta_max: tuple[float, float] = (math.pi / 2, 2 * math.pi / 3)  # [rad], theta_t in [0, max]
    outer_diameter: float = 0.0074  # [m]
    backbone_radius: tuple[float, float] = (0.0025, 0.0027)  # pitch radius r_b per segment [m]
    # Velocity limits for psi_dot: phi, d, theta1, delta1, theta2, delta2 [rad/s, m/s].
    max_velocity: tuple[float, float, float, float, float, float] = field(
        default=(1.0, 0.02, 1.0, 4.0, 1.5, 6.0)
    )

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for name in ("segment_lengths", "backbone_radius", "max_velocity"):
            for i, v in enumerate(getattr(self, name)):
                if v <= 0:
                    raise ConfigError(f"'{name}[{i}]' must be > 0, got {v}")
        for name in ("rigid_length", "marker_offset", "tip_offset", "outer_diameter"):
            if getattr(self, name) < 0 or (name == "outer_diameter" and self.outer_diameter == 0):
                raise ConfigError(f"'{name}' must be positive, got {getattr(self, name)}")
        for name in ("phi_range", "d_range"):
            lo, hi = getattr(self, name)
            if not lo < hi:
                raise ConfigError(f"'{name}' is inverted or empty: [{lo}, {hi}]")
        for i, v in enumerate(self.theta_max):
            if not 0 < v <= math.pi:
                raise ConfigError(f"'theta_max[{i}]' must be in (0, pi], got {v}")

    @classmethod
    def load(cls, path: str | Path) -> RobotParams:
        """Load from YAML; the file may be the robot mapping itself or hold it under 'robot'.
        A format-2 file (any arm, docs/your-arm.md) is refused here, saying where it is read."""
        data = load_layered(path, "robot")
        if "format" in data:
            raise ConfigError(f"{path}: format: {data['format']!r}: a format-2 robot file (any arm, "
                              "docs/your-arm.md) is read by 'wristmark fk' and 'wristmark urdf' so far; "
                              "this takes the reference arm's flat file (docs/formats.md)")
        return from_mapping(cls, data, str(path))

    def with_marker(self, marker: MarkerModel) -> RobotParams:
        """These parameters carrying ``marker``'s tip offset [m]."""
        return replace(self, tip_offset=marker.tip_offset)


def load_robot(path: str | Path | None, marker: MarkerModel) -> RobotParams:
    """The robot of the YAML file ``path`` (None: the reference arm) with ``marker``'s tip offset,
    the one definition of it. A robot file that states a different ``tip_offset`` is refused,
    naming the file to fix (ConfigError)."""
    if path is None:
        return RobotParams().with_marker(marker)
    params = RobotParams.load(path)
    if "tip_offset" in load_layered(path, "robot") and params.tip_offset != marker.tip_offset:
        raise ConfigError(f"{path}: 'tip_offset' ({params.tip_offset} m) disagrees with the marker's "
                          f"({marker.tip_offset} m): the tip offset belongs to the marker file; remove it from {path}")
    return params.with_marker(marker)


# Home configuration: the workspace centre (cube centre) is the tip here; the default camera
# (configs/camera.yaml) looks at it from ~80 mm with the marker axis (x_w) horizontal.
HOME_PSI: tuple[float, float, float, float, float, float] = (0.0, 0.04, 0.7, 0.0, 0.9, 0.0)
