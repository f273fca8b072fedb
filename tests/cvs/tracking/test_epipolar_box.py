"""cvs.tracking.epipolar_box: the box of the other view that holds where one view's pixels can be."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.epipolar_box import epipolar_box
from wristmark.models.config_files import CONFIG_DIR

CAM = load_calibration(CONFIG_DIR / "camera.yaml")


@pytest.mark.parametrize("from_right", [False, True])
def test_the_box_holds_the_points_seen_at_every_depth_in_range_and_not_far_beyond(from_right: bool) -> None:
    rng = np.random.default_rng(7)
    P = np.column_stack([rng.uniform(-0.01, 0.01, (12, 2)), rng.uniform(0.03, 0.15, 12)])  # in {ll} [m]
    seen, other = (CAM.project_right(P), CAM.project_left(P)) if from_right else (CAM.project_left(P),
                                                                                  CAM.project_right(P))
    box = epipolar_box(CAM, seen, from_right, (0.02, 0.2), 5.0)
    assert box is not None
    x, y, w, h = box
    assert np.all((other[:, 0] >= x) & (other[:, 0] <= x + w) & (other[:, 1] >= y) & (other[:, 1] <= y + h))
    for uv, truth in zip(seen, other):  # one corner: its ray runs along the rows of this near-parallel pair
        x, y, w, h = epipolar_box(CAM, uv[None], from_right, (0.02, 0.2), 5.0) or (0, 0, 0, 0)
        assert x <= truth[0] <= x + w and y <= truth[1] <= y + h
        assert h < 20 and w > 100
        short = epipolar_box(CAM, uv[None], from_right, (0.02, 0.025), 5.0)
        assert short is not None and short[2] < w

def test_rays_that_leave_the_other_image_give_no_box() -> None:
    uv = np.array([[5.0, 5.0]])  # the left image's corner, seen only from far off the right camera's axis
    assert epipolar_box(CAM, uv, False, (0.001, 0.0012), 0.0) is None
