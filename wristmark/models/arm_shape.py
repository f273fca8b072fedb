"""The arm's 3D shape for rendering and viewing: backbone centreline, marker pose and tip.

Produced from the nominal model (:func:`arm_shape`) or by the simulated true plant (which may
bend the stem and the segments differently); consumed by the image synthesis and the 3D view.
:func:`transformed` moves a shape rigidly in {w} (several arms in one scene, each from its own
base pose).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_kinematics import bend_angles
from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.constant_curvature import segment_point
from wristmark.models.errors import InputError
from wristmark.models.kinematics import ArmFrames, check_psi, forward_kinematics

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ArmShape:
    """Shape of the arm in {w} [m].

    centreline: (N, 3) backbone points from the incision to the last end ring ({2e}), in order.
    distal_start: index in ``centreline`` of the first point of the last segment's base ring ({2b}).
    frames: poses of the chain's frames (marker {wm}, tip, ...).
    radius: outer radius of the arm's tube [m].
    """

    centreline: Array
    distal_start: int
    frames: ArmFrames
    radius: float

    @property
    def T_world_marker(self) -> Array:
        """Pose of {wm} in {w}."""
        return self.frames.T_world_marker

    @property
    def tip(self) -> Array:
        """Tip position in {w} [m]."""
        return self.frames.tip


def _segment_samples(T_base: Array, length: float, theta: float, delta: float, n: int) -> Array:
    pts = [segment_point(length, theta, delta, s) for s in np.linspace(0.0, 1.0, n)]
    P = np.asarray(pts)
    return P @ T_base[:3, :3].T + T_base[:3, 3]


def shape_from_frames(
    params: Arm,
    psi: object,
    frames: ArmFrames,
    stem_points: Array | None = None,
    samples_per_segment: int = 24,
) -> ArmShape:
    """Assemble an ArmShape from frames; segments are sampled along their arcs with ``psi``'s
    bends. ``stem_points`` (M, 3) in {w} replaces the straight stem from the incision to {1b}."""
    q = check_psi(psi, params)
    if stem_points is None:
        stem = np.array([[0.0, 0.0, 0.0], frames.T_world_1b[:3, 3]])
    else:
        stem = np.asarray(stem_points, float).reshape(-1, 3)
    if isinstance(params, ArmSpec):
        th, de = bend_angles(params, q)
        segs = [_segment_samples(T, s.length, float(th[t]), float(de[t]), samples_per_segment)
                for t, (T, s) in enumerate(zip(frames.segment_bases, params.segments))]
        centre = np.vstack([stem[:-1], *segs])
        return ArmShape(centre, len(centre) - len(segs[-1]), frames, params.outer_diameter / 2.0)
    L1, L2 = params.segment_lengths
    seg1 = _segment_samples(frames.T_world_1b, L1, q[2], q[3], samples_per_segment)
    seg2 = _segment_samples(frames.T_world_2b, L2, q[4], q[5], samples_per_segment)
    centre = np.vstack([stem[:-1], seg1, seg2])
    return ArmShape(centre, len(stem) - 1 + len(seg1), frames, params.outer_diameter / 2.0)


def arm_shape(params: Arm, psi: object, samples_per_segment: int = 24) -> ArmShape:
    """Nominal (model) shape of the arm in {w} [m] at configuration psi [rad, m, rad, rad, rad, rad]."""
    return shape_from_frames(params, psi, forward_kinematics(params, psi), None, samples_per_segment)


def transformed(shape: ArmShape, T: Array) -> ArmShape:
    """The shape moved rigidly in {w}: every point p [m] becomes ``T p`` and every pose F of a
    frame in {w} becomes ``T F`` (centreline, marker, tip, rings), for ``T`` a 4x4 rigid
    transform [m] (e.g. the base pose of a second arm relative to the first one's)."""
    T = np.asarray(T, float)
    R = T[:3, :3] if T.shape == (4, 4) else np.zeros((3, 3))
    if T.shape != (4, 4) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0 \
            or not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError("transformed() needs a 4x4 rigid transform (rotation, translation [m])")
    moved = {f.name: (T @ v if isinstance(v, np.ndarray) else v)
             for f in dataclasses.fields(shape.frames) if (v := getattr(shape.frames, f.name)) is not None}
    frames = dataclasses.replace(shape.frames, **moved)
    return dataclasses.replace(shape, centreline=shape.centreline @ R.T + T[:3, 3], frames=frames)
