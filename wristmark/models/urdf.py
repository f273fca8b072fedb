"""URDF of the arm: stem joints plus pseudo-rigid segments in the chord construction (docs/design.md).

Kinematic tree (all lengths [m], angles [rad]), root link ``incision`` = {w}:

    phi (revolute z) -> d (prismatic z) -> seg1_base {1b}
    -> seg1_plane_in (revolute z, -delta1) -> seg1_bend_0 (revolute y, theta1/2N)
    -> seg1_chord_1 (prismatic z, chord) -> seg1_bend_1 (revolute y, theta1/N) -> ...
    -> seg1_chord_N -> seg1_bend_N (revolute y, theta1/2N) -> seg1_plane_out (revolute z, delta1)
    -> seg1_end {1e} -> fixed Tz(L_r) -> seg2_base {2b} -> (segment 2 alike) -> seg2_end {2e}
    -> fixed Tz(l_marker) -> marker {wm} -> fixed Tz(tip_offset) -> tip

The chord of an arc of angle theta/N and radius L/theta has length 2 L/theta sin(theta/2N);
a prismatic joint per chord makes the model exact for every N (see models.pinocchio_model for
the map psi -> q). Link visuals are cylinders at the nominal chord length L/N (URDF cylinders
lie along z); the marker sleeve and a small two-jaw gripper are drawn on the marker link.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams

ROOT_LINK = "incision"
FRAME_NAMES = ("seg1_base", "seg1_end", "seg2_base", "seg2_end", "marker", "tip")

# name -> RGBA, so a viewer can tell the parts apart.
MATERIALS: dict[str, tuple[float, float, float, float]] = {
    "stem": (0.55, 0.57, 0.60, 1.0),
    "segment1": (0.20, 0.45, 0.85, 1.0),
    "segment2": (0.15, 0.70, 0.45, 1.0),
    "rigid": (0.40, 0.40, 0.42, 1.0),
    "sleeve": (0.95, 0.60, 0.10, 1.0),
    "gripper": (0.80, 0.80, 0.82, 1.0),
}

_JOINT_EFFORT = 10.0  # [N or N*m], nominal: the URDF is kinematic only
_JOINT_VELOCITY = 10.0  # [m/s or rad/s], nominal


def chord_length(length: float, theta: float, links: int) -> float:
    """Chord of one of ``links`` equal arcs of a segment of ``length`` [m] bent by ``theta`` [rad].

    Equals 2 L/theta sin(theta/2N) = (L/N) sinc(theta/2N); -> L/N as theta -> 0 (no division).
    """
    x = theta / (2.0 * links)
    if abs(x) < 1e-4:
        x2 = x * x
        sinc = 1.0 - x2 / 6.0 + x2 * x2 / 120.0
    else:
        sinc = math.sin(x) / x
    return length / links * sinc


def _fmt(*values: float) -> str:
    return " ".join(repr(float(v)) for v in values)


class _UrdfBuilder:
    """Small helper that appends links and joints to a <robot> element."""

    def __init__(self, name: str) -> None:
        self.robot = ET.Element("robot", name=name)
        for mat, rgba in MATERIALS.items():
            m = ET.SubElement(self.robot, "material", name=mat)
            ET.SubElement(m, "color", rgba=_fmt(*rgba))

    def link(self, name: str) -> ET.Element:
        return ET.SubElement(self.robot, "link", name=name)

    def joint(
        self,
        name: str,
        kind: str,
        parent: str,
        child: str,
        xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
        axis: tuple[float, float, float] | None = None,
        limits: tuple[float, float] | None = None,
    ) -> None:
        j = ET.SubElement(self.robot, "joint", name=name, type=kind)
        ET.SubElement(j, "origin", xyz=_fmt(*xyz), rpy="0 0 0")
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=child)
        if axis is not None:
            ET.SubElement(j, "axis", xyz=_fmt(*axis))
        if limits is not None:
            ET.SubElement(
                j,
                "limit",
                lower=_fmt(limits[0]),
                upper=_fmt(limits[1]),
                effort=_fmt(_JOINT_EFFORT),
                velocity=_fmt(_JOINT_VELOCITY),
            )

    @staticmethod
    def shape(
        link: ET.Element,
        material: str,
        geometry: tuple[str, dict[str, str]],
        xyz: tuple[float, float, float],
        collision: bool = True,
    ) -> None:
        """Add a visual (and optionally the same collision) geometry to ``link``."""
        kinds = ("visual", "collision") if collision else ("visual",)
        for kind in kinds:
            el = ET.SubElement(link, kind)
            ET.SubElement(el, "origin", xyz=_fmt(*xyz), rpy="0 0 0")
            g = ET.SubElement(el, "geometry")
            ET.SubElement(g, geometry[0], attrib=geometry[1])
            if kind == "visual":
                ET.SubElement(el, "material", name=material)


def _cylinder(radius: float, length: float) -> tuple[str, dict[str, str]]:
    return "cylinder", {"radius": _fmt(radius), "length": _fmt(length)}


def _box(sx: float, sy: float, sz: float) -> tuple[str, dict[str, str]]:
    return "box", {"size": _fmt(sx, sy, sz)}


def _add_segment(
    b: _UrdfBuilder, t: int, base: str, length: float, theta_max: float, links: int, radius: float
) -> str:
    """Append segment ``t`` (1 or 2) after link ``base``; return the name of its end link."""
    pre = f"seg{t}"
    material = f"segment{t}"
    b.link(f"{pre}_plane")
    b.joint(
        f"{pre}_plane_in",
        "revolute",
        base,
        f"{pre}_plane",
        axis=(0, 0, 1),
        limits=(-math.pi, math.pi),
    )
    parent = f"{pre}_plane"
    chord_min = chord_length(length, theta_max, links)
    nominal = length / links
    for k in range(links + 1):
        half = k in (0, links)
        bend_max = theta_max / links * (0.5 if half else 1.0)
        disk = f"{pre}_link_{k}" if k < links else f"{pre}_tilted"
        lk = b.link(disk)
        if k < links:
            b.shape(lk, material, _cylinder(radius, nominal), (0.0, 0.0, nominal / 2.0))
        b.joint(f"{pre}_bend_{k}", "revolute", parent, disk, axis=(0, 1, 0), limits=(0.0, bend_max))
        parent = disk
        if k < links:
            ring = f"{pre}_ring_{k + 1}"
            b.link(ring)
            b.joint(
                f"{pre}_chord_{k + 1}",
                "prismatic",
                parent,
                ring,
                axis=(0, 0, 1),
                limits=(chord_min, nominal),
            )
            parent = ring
    end = f"{pre}_end"
    b.link(end)
    b.joint(f"{pre}_plane_out", "revolute", parent, end, axis=(0, 0, 1), limits=(-math.pi, math.pi))
    return end


def _add_rigid_tube(b: _UrdfBuilder, link_name: str, length: float, r: float) -> None:
    """A rigid tube of ``length`` [m] and radius ``r`` [m] drawn along z from the origin of link
    ``link_name`` (the rigid link after segment 1, the marker offset after segment 2)."""
    link = b.robot.find(f"link[@name='{link_name}']")
    if link is not None and length > 0:
        b.shape(link, "rigid", _cylinder(r, length), (0.0, 0.0, length / 2.0))


def generate_urdf(
    params: RobotParams, links_per_segment: int = 8, marker: MarkerModel | None = None
) -> str:
    """URDF text of the arm with ``links_per_segment`` pseudo-rigid links per segment.

    Frames: links ``seg1_base`` {1b}, ``seg1_end`` {1e}, ``seg2_base`` {2b}, ``seg2_end`` {2e},
    ``marker`` {wm}, ``tip``; root link ``incision`` = {w}. Lengths from ``params`` [m]
    (the tip lies ``params.tip_offset`` along z of {wm}); the sleeve size from ``marker``.
    """
    if isinstance(links_per_segment, bool) or not isinstance(links_per_segment, int):
        raise InputError(f"links per segment must be an integer >= 1, got {links_per_segment!r}")
    if links_per_segment < 1:
        raise InputError(f"links per segment must be >= 1, got {links_per_segment}")
    try:
        params.validate()
    except ConfigError as e:
        raise ConfigError(f"robot parameters: {e}") from e
    mk = marker if marker is not None else MarkerModel()
    mk.validate()
    r = params.outer_diameter / 2.0
    L1, L2 = params.segment_lengths
    b = _UrdfBuilder("wristmark_arm")

    b.link(ROOT_LINK)
    b.link("stem")
    b.joint("phi", "revolute", ROOT_LINK, "stem", axis=(0, 0, 1), limits=params.phi_range)
    base1 = b.link("seg1_base")
    stem_len = params.d_range[1] if params.d_range[1] > 0 else L1
    b.shape(base1, "stem", _cylinder(r, stem_len), (0.0, 0.0, -stem_len / 2.0))
    b.joint("d", "prismatic", "stem", "seg1_base", axis=(0, 0, 1), limits=params.d_range)

    end1 = _add_segment(b, 1, "seg1_base", L1, params.theta_max[0], links_per_segment, r)
    _add_rigid_tube(b, end1, params.rigid_length, r)
    b.link("seg2_base")
    b.joint("rigid_link", "fixed", end1, "seg2_base", xyz=(0.0, 0.0, params.rigid_length))

    end2 = _add_segment(b, 2, "seg2_base", L2, params.theta_max[1], links_per_segment, r)
    _add_rigid_tube(b, end2, params.marker_offset, r)
    mlink = b.link("marker")
    b.joint("marker_mount", "fixed", end2, "marker", xyz=(0.0, 0.0, params.marker_offset))
    b.shape(mlink, "sleeve", _cylinder(mk.radius, 2.0 * mk.row_height), (0.0, 0.0, 0.0))
    _add_gripper(b, mlink, params.tip_offset, mk.row_height, r)
    b.link("tip")
    b.joint("tip_mount", "fixed", "marker", "tip", xyz=(0.0, 0.0, params.tip_offset))

    ET.indent(b.robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(b.robot, encoding="unicode") + "\n"


def _add_gripper(b: _UrdfBuilder, link: ET.Element, tip: float, start: float, r: float) -> None:
    """A wrist body from the sleeve to 60% of the way to the tip, then two jaws (visual only)."""
    if tip <= start:
        return
    jaw_start = start + 0.6 * (tip - start)
    body = jaw_start - start
    b.shape(link, "gripper", _cylinder(0.8 * r, body), (0.0, 0.0, start + body / 2.0), False)
    jaw = tip - jaw_start
    for side in (-1.0, 1.0):
        b.shape(
            link,
            "gripper",
            _box(0.5 * r, 1.2 * r, jaw),
            (side * 0.45 * r, 0.0, jaw_start + jaw / 2.0),
            False,
        )


def write_urdf(
    path: str | Path,
    params: RobotParams,
    links_per_segment: int = 8,
    marker: MarkerModel | None = None,
) -> Path:
    """Write :func:`generate_urdf`'s text to ``path``; return the path."""
    p = Path(path)
    text = generate_urdf(params, links_per_segment, marker)
    try:
        p.write_text(text)
    except OSError as e:
        raise InputError(f"cannot write URDF to {p}: {e.strerror or e}") from e
    return p
