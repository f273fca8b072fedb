"""Pseudo-rigid URDF of any arm (models.arm_spec), in models.urdf's chord construction.

Kinematic tree (lengths [m], angles [rad]), root link ``incision`` = {w}:

    stem joint 1 (revolute z or prismatic z, named as in the robot file) -> stem_1 -> ...
    -> last stem joint -> seg1_base {1b}      (no stem: a fixed joint ``stem_mount``)
    -> segment 1 -> seg1_end {1e} -> fixed Tz(spacer_2) -> seg2_base {2b} -> ... -> segN_end {Ne}
    -> fixed Tz(marker_offset) -> marker {wm} -> fixed Tz(tip_offset) -> tip

Segment t, N links: segt_plane_in (revolute z, -delta_t) -> segt_bend_0 (revolute y,
theta_t/2N) -> segt_chord_1 (prismatic z, the chord 2 L/theta sin(theta/2N)) -> segt_bend_1
(theta_t/N) -> ... -> segt_chord_N -> segt_bend_N (theta_t/2N) -> segt_plane_out (revolute z,
delta_t) -> segt_end. A planar segment's plane joints are fixed, turned by -planar and +planar
(origin rpy), and its bends range over [-theta_max, theta_max]. Exact for every N
(models.arm_pinocchio maps psi to the joints). Visuals as models.urdf: cylinders at the nominal
chord length L/N, the rigid spacers, the marker sleeve and a small gripper.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from wristmark.models.arm_spec import ArmSpec, Segment
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.urdf import ROOT_LINK, _add_gripper, _add_rigid_tube, _cylinder, _fmt, _UrdfBuilder, chord_length

# segments 3 and 4 of a longer arm (models.urdf.MATERIALS has segment1, segment2)
EXTRA_MATERIALS: dict[str, tuple[float, float, float, float]] = {
    "segment3": (0.85, 0.35, 0.55, 1.0),
    "segment4": (0.60, 0.45, 0.90, 1.0),
}


def arm_frame_names(spec: ArmSpec) -> tuple[str, ...]:
    """The named frames of the arm's URDF, proximal first: seg1_base, seg1_end, ..., marker, tip."""
    segs = tuple(f"seg{t}_{r}" for t in range(1, len(spec.segments) + 1) for r in ("base", "end"))
    return (*segs, "marker", "tip")


def segment_joint_names(seg: Segment, t: int, links: int) -> list[str]:
    """Names of the URDF joints of segment ``t`` (1-based) in chain order (module doc)."""
    inner = [f"seg{t}_bend_0"] + [f"seg{t}_{kind}_{k}" for k in range(1, links + 1) for kind in ("chord", "bend")]
    return inner if seg.planar is not None else [f"seg{t}_plane_in", *inner, f"seg{t}_plane_out"]


def _turn(b: _UrdfBuilder, joint: str, yaw: float) -> None:
    """Set the origin of the (fixed) ``joint`` to a rotation by ``yaw`` about z [rad]."""
    el = b.robot.find(f"joint[@name='{joint}']/origin")
    if el is not None:
        el.set("rpy", _fmt(0.0, 0.0, yaw))


def _segment(b: _UrdfBuilder, t: int, base: str, seg: Segment, links: int, radius: float) -> str:
    """Append segment ``t`` (1-based) after link ``base``; return the name of its end link."""
    pre, material = f"seg{t}", f"segment{t}"
    planar = seg.planar is not None
    b.link(f"{pre}_plane")
    if planar:
        b.joint(f"{pre}_plane_in", "fixed", base, f"{pre}_plane")
        _turn(b, f"{pre}_plane_in", -float(seg.planar or 0.0))
    else:
        b.joint(f"{pre}_plane_in", "revolute", base, f"{pre}_plane", axis=(0, 0, 1), limits=(-math.pi, math.pi))
    parent = f"{pre}_plane"
    chord_min = chord_length(seg.length, seg.theta_max, links)
    nominal = seg.length / links
    for k in range(links + 1):
        bend_max = seg.theta_max / links * (0.5 if k in (0, links) else 1.0)
        disk = f"{pre}_link_{k}" if k < links else f"{pre}_tilted"
        lk = b.link(disk)
        if k < links:
            b.shape(lk, material, _cylinder(radius, nominal), (0.0, 0.0, nominal / 2.0))
        b.joint(f"{pre}_bend_{k}", "revolute", parent, disk, axis=(0, 1, 0),
                limits=(-bend_max if planar else 0.0, bend_max))
        parent = disk
        if k < links:
            ring = f"{pre}_ring_{k + 1}"
            b.link(ring)
            b.joint(f"{pre}_chord_{k + 1}", "prismatic", parent, ring, axis=(0, 0, 1), limits=(chord_min, nominal))
            parent = ring
    end = f"{pre}_end"
    b.link(end)
    if planar:
        b.joint(f"{pre}_plane_out", "fixed", parent, end)
        _turn(b, f"{pre}_plane_out", float(seg.planar or 0.0))
    else:
        b.joint(f"{pre}_plane_out", "revolute", parent, end, axis=(0, 0, 1), limits=(-math.pi, math.pi))
    return end


def _stem(b: _UrdfBuilder, spec: ArmSpec, radius: float) -> None:
    """Root link, the stem joints in order, and seg1_base with the stem tube drawn behind it."""
    b.link(ROOT_LINK)
    parent = ROOT_LINK
    for i, j in enumerate(spec.stem):
        child = "seg1_base" if i == len(spec.stem) - 1 else f"stem_{i + 1}"
        b.link(child)
        kind = "revolute" if j.joint == "revolute_z" else "prismatic"
        b.joint(j.name, kind, parent, child, axis=(0, 0, 1), limits=j.range)
        parent = child
    if not spec.stem:
        b.link("seg1_base")
        b.joint("stem_mount", "fixed", ROOT_LINK, "seg1_base")
    feed = sum(j.range[1] for j in spec.stem if j.joint == "prismatic_z")
    length = feed if feed > 0 else spec.segments[0].length
    base = b.robot.find("link[@name='seg1_base']")
    assert base is not None
    b.shape(base, "stem", _cylinder(radius, length), (0.0, 0.0, -length / 2.0))


def generate_arm_urdf(spec: ArmSpec, links_per_segment: int = 8, marker: MarkerModel | None = None) -> str:
    """URDF text of ``spec`` with ``links_per_segment`` pseudo-rigid links per segment.

    Frames (links): ``incision`` {w}, ``seg<t>_base`` {tb}, ``seg<t>_end`` {te}, ``marker``
    {wm}, ``tip`` (``spec.tip_offset`` along z of {wm}) [m]; the sleeve size from ``marker``.
    """
    if isinstance(links_per_segment, bool) or not isinstance(links_per_segment, int) or links_per_segment < 1:
        raise InputError(f"links per segment must be an integer >= 1, got {links_per_segment!r}")
    try:
        spec.validate()
    except ConfigError as e:
        raise ConfigError(f"robot: {e}") from e
    mk = marker if marker is not None else MarkerModel()
    mk.validate()
    r = spec.outer_diameter / 2.0
    b = _UrdfBuilder(f"wristmark_{spec.name}".replace(" ", "_"))
    for mat, rgba in EXTRA_MATERIALS.items():
        ET.SubElement(ET.SubElement(b.robot, "material", name=mat), "color", rgba=_fmt(*rgba))
    _stem(b, spec, r)
    base = "seg1_base"
    for t, seg in enumerate(spec.segments, 1):
        if t > 1:
            base = f"seg{t}_base"
            _add_rigid_tube(b, f"seg{t - 1}_end", seg.spacer, r)
            b.link(base)
            b.joint(f"spacer_{t}", "fixed", f"seg{t - 1}_end", base, xyz=(0.0, 0.0, seg.spacer))
        _segment(b, t, base, seg, links_per_segment, r)
    last = f"seg{len(spec.segments)}_end"
    _add_rigid_tube(b, last, spec.marker_offset, r)
    mlink = b.link("marker")
    b.joint("marker_mount", "fixed", last, "marker", xyz=(0.0, 0.0, spec.marker_offset))
    b.shape(mlink, "sleeve", _cylinder(mk.radius, 2.0 * mk.row_height), (0.0, 0.0, 0.0))
    _add_gripper(b, mlink, spec.tip_offset, mk.row_height, r)
    b.link("tip")
    b.joint("tip_mount", "fixed", "marker", "tip", xyz=(0.0, 0.0, spec.tip_offset))
    ET.indent(b.robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(b.robot, encoding="unicode") + "\n"


def write_arm_urdf(path: str | Path, spec: ArmSpec, links_per_segment: int = 8,
                   marker: MarkerModel | None = None) -> Path:
    """Write :func:`generate_arm_urdf`'s text to ``path``; return the path."""
    p = Path(path)
    text = generate_arm_urdf(spec, links_per_segment, marker)
    try:
        p.write_text(text)
    except OSError as e:
        raise InputError(f"cannot write URDF to {p}: {e.strerror or e}") from e
    return p
