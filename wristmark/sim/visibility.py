"""Is the wrist marker seen by both cameras? And random configurations where it is."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.marker.in_view import marker_in_view
from wristmark.models.arm_shape import ArmShape, arm_shape
from wristmark.models.arm_spec import Arm, home_psi
from wristmark.models.errors import InputError
from wristmark.models.limits import clamp_psi
from wristmark.models.marker import MarkerModel

Array = NDArray[np.float64]


def marker_visible(
    camera: StereoCamera, marker: MarkerModel, shape: ArmShape, min_corners: int = 3, margin_px: float = 20.0
) -> bool:
    """True if the whole sleeve projects inside both images (``margin_px`` from the border) and
    each camera sees at least ``min_corners`` corners with cos_view > 0.3."""
    if camera.T_world_left is None:
        raise InputError("the calibration has no 'world_T_left': cannot place the arm in the images")
    W = np.linalg.inv(np.asarray(camera.T_world_left, float))
    return marker_in_view(camera, marker, W @ shape.T_world_marker, min_corners, margin_px)


def random_visible_psi(
    params: Arm,
    camera: StereoCamera,
    marker: MarkerModel,
    rng: np.random.Generator,
    spread: tuple[float, ...],
    max_tries: int = 400,
) -> Array:
    """A configuration drawn uniformly within ``spread`` around the arm's home, clamped to the joint
    limits, at which the marker is visible to both cameras."""
    home = home_psi(params)
    half = np.asarray(spread, float)
    for _ in range(max_tries):
        q = clamp_psi(params, home + rng.uniform(-half, half))
        if marker_visible(camera, marker, arm_shape(params, q)):
            return q
    raise InputError(f"no configuration with the marker in both views after {max_tries} draws: check the calibration")
