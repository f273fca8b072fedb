"""Where the viewer's camera sits: framed on the arm (centimetres), not Meshcat's metres away.

Meshcat 0.3.2's orbit controls always look at the scene origin, and its camera object lives in
a three.js Y-up frame. So the scene is shifted by ``-target`` (the middle of what must be seen)
and the camera is put at ``eye_offset`` from it. ``project`` reproduces the browser's pinhole
(three.js ``PerspectiveCamera`` with a vertical field of view) so tests can say where on the
screenshot a point of {w} must appear. Frames: {w} world, metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import InputError

Array = NDArray[np.float64]

MESHCAT_FOV_DEG = 75.0  # [deg] vertical field of view of Meshcat's default camera
DEFAULT_DIRECTION = (-0.55, -0.75, 0.40)  # from the target towards the eye, in {w}: in front of the
# arm (the endoscope's side, -y_w), to its left and above, so the endoscope shows on the right


@dataclass(frozen=True)
class CameraView:
    """The viewer's camera: it looks at ``target`` [m, {w}] from ``target + eye_offset``, z_w up."""

    target: Array
    eye_offset: Array
    fov_deg: float = MESHCAT_FOV_DEG

    @property
    def distance(self) -> float:
        """Eye-to-target distance [m]."""
        return float(np.linalg.norm(self.eye_offset))

    def threejs_position(self) -> list[float]:
        """Camera position for ``/Cameras/default/rotated/<object>`` (three.js Y-up: x, z, -y)."""
        x, y, z = (float(v) for v in self.eye_offset)
        return [x, z, -y]

    def scene_shift(self) -> Array:
        """4x4 transform of the scene root: translation by -target, so the target is the origin."""
        T = np.eye(4)
        T[:3, 3] = -np.asarray(self.target, float)
        return T

    def project(self, points_world: Array, width: int, height: int) -> Array:
        """Pixel coordinates (N, 2) [px, origin top-left] of points in {w} on a width x height
        canvas; rows behind the camera are NaN."""
        P = np.asarray(points_world, float).reshape(-1, 3) - np.asarray(self.target, float)
        eye = np.asarray(self.eye_offset, float)
        fwd = -eye / np.linalg.norm(eye)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        rel = P - eye
        xc, yc, zc = rel @ right, rel @ up, rel @ fwd
        t = math.tan(math.radians(self.fov_deg) / 2.0)
        aspect = width / height
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = xc / (zc * t * aspect)
            yn = yc / (zc * t)
        uv = np.column_stack([(xn + 1.0) / 2.0 * width, (1.0 - yn) / 2.0 * height])
        uv[zc <= 0] = np.nan
        return uv


def frame_points(
    points_world: Array,
    direction: tuple[float, float, float] = DEFAULT_DIRECTION,
    margin: float = 1.0,
    fov_deg: float = MESHCAT_FOV_DEG,
    min_radius: float = 0.02,
) -> CameraView:
    """A view that looks at the points' bounding box centre from ``direction`` and keeps their
    bounding sphere (radius [m], at least ``min_radius``) inside the vertical field of view."""
    P = np.asarray(points_world, float).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    if len(P) == 0:
        raise InputError("nothing to frame: no finite points")
    d = np.asarray(direction, float)
    if d.shape != (3,) or not np.linalg.norm(d) > 0 or abs(d[2]) >= np.linalg.norm(d):
        raise InputError(f"view direction must be a non-vertical 3-vector, got {direction}")
    lo, hi = P.min(axis=0), P.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = max(float(np.max(np.linalg.norm(P - centre, axis=1))), min_radius)
    dist = margin * radius / math.sin(math.radians(fov_deg) / 2.0)
    return CameraView(centre, dist * d / np.linalg.norm(d), fov_deg)
