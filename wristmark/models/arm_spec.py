"""Any continuum arm: the robot file, format 2 (docs/your-arm.md), as validated dataclasses.

An arm is stem joints (``revolute_z``: Rz(q) [rad], ``prismatic_z``: Tz(q) [m], applied in
order from {w} to {1b}), then 1 to 4 constant-curvature segments (proximal first), a straight
``marker_offset`` from the last end ring {Ne} to the marker centre {wm}, and the tip
``tip_offset`` beyond {wm} along z_wm. Configuration psi: the stem joints' values, then each
segment's theta, delta (theta alone for a ``planar`` segment, whose bending plane is fixed).
Actuators: the stem joints, then each segment's actuators in the order of its ``angles``
(``push_pull``/``tendons``: pull displacements [m]; ``direct``: theta, delta [rad]).

The flat robot file of the reference arm (format 1, :class:`RobotParams`) stays readable:
:func:`load_arm` turns it into the ArmSpec of :meth:`ArmSpec.from_params`, which maps

    phi_range, d_range, max_velocity[0:2] -> stem [phi revolute_z, d prismatic_z]
    segment_lengths[t], theta_max[t], max_velocity[2+2t : 4+2t] -> segment t (theta, delta)
    backbone_radius[t] -> push_pull, pitch_radius r_b, angles [0, pi/2] (the actuators s_ta =
        r_b theta cos(delta), s_tb = r_b theta cos(delta + pi/2) = -r_b theta sin(delta): today's
        models.actuation map and actuator names s1a, s1b, s2a, s2b)
    rigid_length -> segment 2's spacer; marker_offset, outer_diameter, tip_offset as they are.

The tip offset belongs to the marker file (as for :class:`RobotParams`): a format-2 file does not
state it; :meth:`ArmSpec.with_marker` sets it. Lengths [m], angles [rad], velocities [m/s, rad/s].
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.config_io import from_mapping, load_section
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams

Array = NDArray[np.float64]

JOINT_TYPES = ("revolute_z", "prismatic_z")
ACTUATION_TYPES = ("push_pull", "tendons", "direct")
MAX_SEGMENTS = 4
HOME_BEND = 1.0  # [rad] total bend of the default home (ArmSpec.default_home)
_RANK_TOL = 1e-6  # |sin| or |cos| below which actuator directions count as parallel / blind


@dataclass(frozen=True)
class StemJoint:
    """A stem joint from {w} towards {1b}: ``joint`` revolute_z [rad] or prismatic_z [m],
    its ``range`` and ``max_velocity`` [rad/s or m/s]."""

    joint: str
    name: str
    range: tuple[float, float]
    max_velocity: float

    def check(self, key: str) -> None:
        """Raise ConfigError naming ``key`` (e.g. ``stem[0]``) and the bad field."""
        if self.joint not in JOINT_TYPES:
            raise ConfigError(f"{key}.joint: expected one of {', '.join(JOINT_TYPES)}, got {self.joint!r}")
        if not self.name.isidentifier():
            raise ConfigError(f"{key}.name: expected a name of letters, digits and '_', got {self.name!r}")
        lo, hi = self.range
        if not lo < hi:
            raise ConfigError(f"{key}.range: expected [low, high] with low < high, got [{lo}, {hi}]")
        if not self.max_velocity > 0:
            raise ConfigError(f"{key}.max_velocity: expected > 0, got {self.max_velocity}")


@dataclass(frozen=True)
class Actuation:
    """How the box moves a segment: ``type`` push_pull, tendons or direct; for push_pull and
    tendons the ``pitch_radius`` [m] and the actuators' ``angles`` sigma_k [rad] in {tb}
    (from x_tb towards y_tb)."""

    type: str
    pitch_radius: float = 0.0
    angles: tuple[float, ...] = ()


@dataclass(frozen=True)
class Segment:
    """A constant-curvature segment: ``length`` [m], ``theta_max`` [rad], ``max_velocity``
    [rad/s] (theta, delta; theta alone if ``planar``), ``actuation``, ``spacer`` [m] (straight
    rigid length from the previous end ring to this base ring) and ``planar`` (None, or the
    fixed bending-plane angle delta [rad])."""

    length: float
    theta_max: float
    max_velocity: tuple[float, ...]
    actuation: Actuation
    spacer: float = 0.0
    planar: float | None = None

    @property
    def variables(self) -> int:
        """Configuration variables of the segment: 1 if planar, else 2 (theta, delta)."""
        return 1 if self.planar is not None else 2

    @property
    def actuators(self) -> int:
        """Actuators of the segment: one per angle, or its variables for direct actuation."""
        return self.variables if self.actuation.type == "direct" else len(self.actuation.angles)

    def check(self, key: str, index: int, outer_radius: float) -> None:
        """Raise ConfigError naming ``key`` (e.g. ``segments[1]``) and the bad field."""
        if not self.length > 0:
            raise ConfigError(f"{key}.length: expected > 0 [m], got {self.length}")
        if not 0 < self.theta_max <= math.pi:
            raise ConfigError(f"{key}.theta_max: expected in (0, pi] [rad], got {self.theta_max}")
        if self.spacer < 0:
            raise ConfigError(f"{key}.spacer: expected >= 0 [m], got {self.spacer}")
        if index == 0 and self.spacer != 0:
            raise ConfigError(f"{key}.spacer: the first segment starts at {{1b}} and has no spacer, got {self.spacer}")
        if self.planar is not None and not math.isfinite(self.planar):
            raise ConfigError(f"{key}.planar: expected a finite angle [rad], got {self.planar}")
        want = "1 entry (theta; the segment is planar)" if self.planar is not None else "2 entries (theta, delta)"
        if len(self.max_velocity) != self.variables:
            raise ConfigError(f"{key}.max_velocity: expected {want}, got {len(self.max_velocity)}")
        for i, v in enumerate(self.max_velocity):
            if not v > 0:
                raise ConfigError(f"{key}.max_velocity[{i}]: expected > 0, got {v}")
        self._check_actuation(f"{key}.actuation", outer_radius)

    def _check_actuation(self, key: str, outer_radius: float) -> None:
        a = self.actuation
        if a.type not in ACTUATION_TYPES:
            raise ConfigError(f"{key}.type: expected one of {', '.join(ACTUATION_TYPES)}, got {a.type!r}")
        if a.type == "direct":
            if a.pitch_radius or a.angles:
                raise ConfigError(f"{key}: direct actuation takes no pitch_radius or angles")
            return
        if not 0 < a.pitch_radius <= outer_radius:
            raise ConfigError(f"{key}.pitch_radius: expected in (0, outer_diameter/2 = {outer_radius}] [m], "
                              f"got {a.pitch_radius}")
        if a.type == "tendons" and len(a.angles) < 3:
            raise ConfigError(f"{key}.angles: tendons need 3 or more, got {len(a.angles)}")
        if self.planar is not None:
            if not any(abs(math.cos(self.planar + s)) > _RANK_TOL for s in a.angles):
                raise ConfigError(f"{key}.angles: no actuator bends the segment in its plane "
                                  f"(planar: {self.planar}); expected one with cos(planar + angle) != 0")
        elif not any(abs(math.sin(s - t)) > _RANK_TOL for s, t in itertools.combinations(a.angles, 2)):
            raise ConfigError(f"{key}.angles: expected two angles that are not parallel (to set theta and delta), "
                              f"got {list(a.angles)}")


@dataclass(frozen=True, eq=False)
class ArmLayout:
    """Where each quantity of an ArmSpec sits, as numpy arrays (N segments): segment
    ``lengths`` and ``spacers`` [m]; stem indices of the ``revolute`` and ``prismatic`` joints;
    per segment the index of theta in psi (``theta_index``) and of delta in psi extended by the
    ``planar_values`` [rad] (``delta_index``); the non-planar segments (``bending``) and their
    delta's index in psi (``bending_delta_index``); the same as plain Python values for the
    one-configuration path: ``terms`` per segment (length, spacer, theta index, delta index or -1
    if planar, the planar angle or 0), ``revolute_list``, ``prismatic_list``."""

    lengths: Array
    spacers: Array
    revolute: NDArray[np.int_]
    prismatic: NDArray[np.int_]
    theta_index: NDArray[np.int_]
    delta_index: NDArray[np.int_]
    planar_values: Array
    bending: NDArray[np.int_]
    bending_delta_index: NDArray[np.int_]
    terms: tuple[tuple[float, float, int, int, float], ...]  # per segment: L, spacer, theta idx, delta idx or -1, plane
    revolute_list: tuple[int, ...]
    prismatic_list: tuple[int, ...]


@dataclass(frozen=True)
class ArmSpec:
    """A continuum arm (module doc): ``stem`` joints, 1-4 ``segments`` (proximal first),
    ``marker_offset`` {Ne} -> {wm} [m], ``outer_diameter`` [m], ``tip_offset`` {wm} -> tip [m]
    (the marker's, see :meth:`with_marker`)."""

    segments: tuple[Segment, ...]
    stem: tuple[StemJoint, ...] = ()
    name: str = "arm"
    marker_offset: float = 0.0
    outer_diameter: float = 0.0074
    tip_offset: float = 0.015
    format: int = 2
    home: tuple[float, ...] | None = None  # psi at rest; None: default_home()

    def validate(self) -> None:
        """Raise ConfigError with the key of the first bad value (e.g. ``segments[1].length``)."""
        if self.format != 2:
            raise ConfigError(f"format: expected 2 (or no 'format' key: the flat reference-arm file), "
                              f"got {self.format}")
        if not 1 <= len(self.segments) <= MAX_SEGMENTS:
            raise ConfigError(f"segments: expected 1 to {MAX_SEGMENTS} segments, got {len(self.segments)}")
        if not self.outer_diameter > 0:
            raise ConfigError(f"outer_diameter: expected > 0 [m], got {self.outer_diameter}")
        for name in ("marker_offset", "tip_offset"):
            if getattr(self, name) < 0:
                raise ConfigError(f"{name}: expected >= 0 [m], got {getattr(self, name)}")
        for i, j in enumerate(self.stem):
            j.check(f"stem[{i}]")
        for t, s in enumerate(self.segments):
            s.check(f"segments[{t}]", t, self.outer_diameter / 2.0)
        if self.home is not None:
            if len(self.home) != self.n:
                raise ConfigError(f"home: expected {self.n} entries [{', '.join(self.names)}], got {len(self.home)}")
            lo, hi = self.bounds()
            for i, v in enumerate(self.home):
                if not (math.isfinite(v) and lo[i] <= v <= hi[i]):
                    raise ConfigError(f"home[{i}] ({self.names[i]}): expected within [{lo[i]}, {hi[i]}], got {v}")
        seen = set(self.segment_names)
        for i, j in enumerate(self.stem):
            if j.name in seen:
                raise ConfigError(f"stem[{i}].name: {j.name!r} is given twice (configuration names must differ)")
            seen.add(j.name)

    # -- sizes and names ---------------------------------------------------------------
    @cached_property
    def n(self) -> int:
        """Number of configuration variables (length of psi)."""
        return len(self.stem) + sum(s.variables for s in self.segments)

    @cached_property
    def m(self) -> int:
        """Number of actuators."""
        return len(self.stem) + sum(s.actuators for s in self.segments)

    @property
    def segment_names(self) -> tuple[str, ...]:
        """Names of the segments' variables: theta1, delta1, theta2, ... (no delta if planar)."""
        out: list[str] = []
        for t, s in enumerate(self.segments, 1):
            out += [f"theta{t}"] if s.planar is not None else [f"theta{t}", f"delta{t}"]
        return tuple(out)

    @property
    def names(self) -> tuple[str, ...]:
        """Names of psi's entries: the stem joints', then theta1, delta1, theta2, ..."""
        return tuple(j.name for j in self.stem) + self.segment_names

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """Names of the actuators: the stem joints', then s<t><a, b, c...> per pull actuator of
        segment t (the reference arm's s1a, s1b, s2a, s2b) or theta<t>, delta<t> if direct."""
        out = [j.name for j in self.stem]
        for t, s in enumerate(self.segments, 1):
            if s.actuation.type == "direct":
                out += [f"theta{t}"] + ([] if s.planar is not None else [f"delta{t}"])
            else:
                out += [f"s{t}{chr(ord('a') + k)}" for k in range(len(s.actuation.angles))]
        return tuple(out)

    @cached_property
    def layout(self) -> ArmLayout:
        """Index arrays and per-segment constants for the vectorised kinematics (cached)."""
        planar = [t for t, s in enumerate(self.segments) if s.planar is not None]
        delta = [d if d is not None else self.n + planar.index(t) for t, d in enumerate(self.delta_index)]
        bending = [t for t, d in enumerate(self.delta_index) if d is not None]
        return ArmLayout(
            lengths=np.array([s.length for s in self.segments]),
            spacers=np.array([s.spacer for s in self.segments]),
            revolute=np.array([i for i, j in enumerate(self.stem) if j.joint == "revolute_z"], dtype=int),
            prismatic=np.array([i for i, j in enumerate(self.stem) if j.joint == "prismatic_z"], dtype=int),
            theta_index=np.array(self.theta_index, dtype=int),
            delta_index=np.array(delta, dtype=int),
            planar_values=np.array([self.segments[t].planar for t in planar], dtype=float),
            bending=np.array(bending, dtype=int),
            bending_delta_index=np.array([self.delta_index[t] for t in bending], dtype=int),
            terms=tuple((s.length, s.spacer, ti, -1 if di is None else di, s.planar or 0.0)
                        for s, ti, di in zip(self.segments, self.theta_index, self.delta_index)),
            revolute_list=tuple(i for i, j in enumerate(self.stem) if j.joint == "revolute_z"),
            prismatic_list=tuple(i for i, j in enumerate(self.stem) if j.joint == "prismatic_z"),
        )

    @cached_property
    def theta_index(self) -> tuple[int, ...]:
        """Index in psi of each segment's theta."""
        return tuple(self._indices[0])

    @cached_property
    def delta_index(self) -> tuple[int | None, ...]:
        """Index in psi of each segment's delta (None for a planar segment)."""
        return tuple(self._indices[1])

    @cached_property
    def _indices(self) -> tuple[list[int], list[int | None]]:
        th: list[int] = []
        de: list[int | None] = []
        i = len(self.stem)
        for s in self.segments:
            th.append(i)
            de.append(None if s.planar is not None else i + 1)
            i += s.variables
        return th, de

    def bounds(self) -> tuple[Array, Array]:
        """Lower and upper bounds of psi [rad or m]: the stem ranges, theta in [0, theta_max]
        ([-theta_max, theta_max] if planar); delta has none (it wraps): +-inf."""
        lo = [j.range[0] for j in self.stem]
        hi = [j.range[1] for j in self.stem]
        for s in self.segments:
            if s.planar is not None:
                lo.append(-s.theta_max)
                hi.append(s.theta_max)
            else:
                lo += [0.0, -math.inf]
                hi += [s.theta_max, math.inf]
        return np.array(lo), np.array(hi)

    def home_psi(self) -> Array:
        """The configuration at rest (the robot file's ``home``, else :meth:`default_home`)."""
        return np.array(self.home if self.home is not None else self.default_home(), dtype=float)

    def default_home(self) -> tuple[float, ...]:
        """Home when the robot file states none: revolute stem joints at 0 (clipped into their
        range), prismatic ones at mid-range; the segments bent in their plane delta = 0 by a total
        of 1 rad shared in proportion to their lengths (each at most theta_max / 2; a planar segment
        only if its plane is that one, 0 or pi, else straight): the marker's axis tilted towards
        x_w, in the x_w-z_w plane, seen side-on by a camera
        facing the arm along y_w (the simulated bench's, sim.setup.camera_for_arm), with room
        to bend further and back around it (the cube of the experiments)."""
        out = [min(max(0.0, j.range[0]), j.range[1]) if j.joint == "revolute_z" else 0.5 * (j.range[0] + j.range[1])
               for j in self.stem]
        in_plane = [s.planar is None or abs(math.sin(s.planar)) < 1e-9 for s in self.segments]
        total = sum(s.length for s, ok in zip(self.segments, in_plane) if ok)
        for s, ok in zip(self.segments, in_plane):
            th = min(HOME_BEND * s.length / total, 0.5 * s.theta_max) if ok else 0.0
            out += [th if s.planar is None or math.cos(s.planar) > 0 else -th] if s.planar is not None else [th, 0.0]
        return tuple(out)

    def velocity_limits(self) -> Array:
        """|psi_dot| limits in psi's order [rad/s or m/s]."""
        out = [j.max_velocity for j in self.stem]
        for s in self.segments:
            out += s.max_velocity
        return np.array(out)

    # -- construction ------------------------------------------------------------------
    def with_marker(self, marker: MarkerModel) -> ArmSpec:
        """This arm carrying ``marker``'s tip offset [m]."""
        return replace(self, tip_offset=marker.tip_offset)

    @classmethod
    def from_params(cls, params: RobotParams, name: str = "reference") -> ArmSpec:
        """The reference arm of a format-1 robot file as an ArmSpec (mapping in the module doc)."""
        v = params.max_velocity
        stem = (StemJoint("revolute_z", "phi", params.phi_range, v[0]),
                StemJoint("prismatic_z", "d", params.d_range, v[1]))
        segs = tuple(
            Segment(length=params.segment_lengths[t], theta_max=params.theta_max[t],
                    max_velocity=(v[2 + 2 * t], v[3 + 2 * t]),
                    actuation=Actuation("push_pull", params.backbone_radius[t], (0.0, math.pi / 2)),
                    spacer=params.rigid_length if t == 1 else 0.0)
            for t in range(2)
        )
        spec = cls(segments=segs, stem=stem, name=name, marker_offset=params.marker_offset,
                   outer_diameter=params.outer_diameter, tip_offset=params.tip_offset, home=HOME_PSI)
        spec.validate()
        return spec

    @classmethod
    def from_mapping(cls, data: dict[str, Any], source: str = "<robot>") -> ArmSpec:
        """A format-2 robot mapping as an ArmSpec (validated; ConfigError names the key)."""
        if "tip_offset" in data:
            raise ConfigError(f"{source}: tip_offset: belongs to the marker file (its tip_offset); remove it here")
        if "format" not in data:
            raise ConfigError(f"{source}: format: expected 2 for a robot file with stem and segments")
        if "stem" in data and data["stem"] is None:  # "stem:" with nothing under it: no stem joints
            data = {**data, "stem": []}
        _require_keys(data, source)
        return from_mapping(cls, data, source)


Arm = RobotParams | ArmSpec
"""The arm the loop carries: the reference arm's flat parameters or any arm (the model
functions of models.kinematics, limits, actuation, ik take either)."""


def as_spec(arm: Arm) -> ArmSpec:
    """``arm`` as an ArmSpec (the reference arm's through :meth:`ArmSpec.from_params`, cached)."""
    if isinstance(arm, ArmSpec):
        return arm
    return _spec_of_params(arm)


_SPEC_CACHE: dict[RobotParams, ArmSpec] = {}


def _spec_of_params(params: RobotParams) -> ArmSpec:
    spec = _SPEC_CACHE.get(params)
    if spec is None:
        spec = _SPEC_CACHE[params] = ArmSpec.from_params(params)
    return spec


def home_psi(arm: Arm) -> Array:
    """The arm's home configuration: HOME_PSI for the reference arm's flat parameters."""
    return arm.home_psi() if isinstance(arm, ArmSpec) else np.asarray(HOME_PSI, float)


def arm_names(arm: Arm) -> tuple[str, ...]:
    """Names of psi's entries (the reference arm: phi, d, theta1, delta1, theta2, delta2)."""
    return as_spec(arm).names


def actuator_names(arm: Arm) -> tuple[str, ...]:
    """Names of the actuators (the reference arm: phi, d, s1a, s1b, s2a, s2b)."""
    return as_spec(arm).actuator_names


def actuator_units(arm: Arm) -> tuple[str, ...]:
    """SI unit of each of the arm's actuators, in its actuator order: 'rad' for a revolute stem
    joint and a ``direct`` segment's theta / delta, 'm' for a prismatic stem joint and every pull
    (push-pull backbone, tendon). On the wire each travels in micro-units (µrad, µm)."""
    spec = as_spec(arm)
    out = ["rad" if j.joint.startswith("revolute") else "m" for j in spec.stem]
    for s in spec.segments:
        out += ["rad" if s.actuation.type == "direct" else "m"] * s.actuators
    return tuple(out)


def log_psi_names(arm: Arm) -> tuple[str, ...] | None:
    """The names a run log gives psi's entries: None for the reference arm's flat parameters
    (log.csv keeps psi_cmd_0..5), the arm's names otherwise."""
    return None if isinstance(arm, RobotParams) else arm.names


def arm_size(arm: Arm) -> tuple[int, int]:
    """(n, m): configuration variables and actuators (the reference arm: 6, 6)."""
    return (6, 6) if isinstance(arm, RobotParams) else (arm.n, arm.m)


_REQUIRED = {"stem": ("joint", "name", "range", "max_velocity"),
             "segments": ("length", "theta_max", "max_velocity", "actuation")}


def _require_keys(data: dict[str, Any], source: str) -> None:
    """Raise ConfigError naming the first missing required key of a format-2 mapping."""
    if "segments" not in data:
        raise ConfigError(f"{source}: segments: missing (expected 1 to {MAX_SEGMENTS} segments)")
    for group, keys in _REQUIRED.items():
        items = data.get(group) or []
        if not isinstance(items, list):
            continue  # from_mapping names the wrong type
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                continue
            missing = [k for k in keys if k not in item]
            if missing:
                raise ConfigError(f"{source}: {group}[{i}].{missing[0]}: missing")
            act = item.get("actuation")
            if group == "segments" and isinstance(act, dict) and "type" not in act:
                raise ConfigError(f"{source}: {group}[{i}].actuation.type: missing "
                                  f"(expected one of {', '.join(ACTUATION_TYPES)})")


def load_arm(path: str | Path, marker: MarkerModel | None = None) -> ArmSpec:
    """The arm of the robot file ``path``: format 2 (a ``format: 2`` key) or the flat
    reference-arm file (no ``format`` key, :class:`RobotParams`). With ``marker``, its tip
    offset [m] replaces the default."""
    data = load_section(path, "robot")
    if _is_format_2(data):
        spec = ArmSpec.from_mapping(data, str(path))
    else:
        spec = ArmSpec.from_params(RobotParams.load(path))
    return spec.with_marker(marker) if marker is not None else spec


def load_loop_arm(path: str | Path | None, marker: MarkerModel) -> Arm:
    """The arm a servo loop carries, with ``marker``'s tip offset: the reference arm's
    RobotParams for the flat file (or None: the default arm; models.robot_params.load_robot), an
    ArmSpec for a format-2 file."""
    if path is not None and robot_file_format(path) == 2:
        return load_arm(path, marker)
    from wristmark.models.robot_params import load_robot

    return load_robot(path, marker)


def _is_format_2(data: dict[str, Any]) -> bool:
    return bool({"format", "segments", "stem"} & set(data))


def shipped_robot_files() -> list[Path]:
    """The robot files shipped in configs/robots/ (not their ``<name>_plant.yaml`` plant files)."""
    from wristmark.models.config_files import CONFIG_DIR

    return sorted(p for p in (CONFIG_DIR / "robots").glob("*.yaml") if not p.stem.endswith("_plant"))


def robot_file_format(path: str | Path) -> int:
    """2 for a robot file in format 2 (it has ``format``, ``segments`` or ``stem``), else 1
    (the reference arm's flat file)."""
    return 2 if _is_format_2(load_section(path, "robot")) else 1
