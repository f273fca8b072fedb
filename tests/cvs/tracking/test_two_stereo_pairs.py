"""The tracker's start from two stereo pairs and single-view corners (cvs.tracking.tracker
``_start_poses``, cvs.tracking.rigid_fit ``chord_starts``): a stripe over a different corner in
each view leaves each chain 3 corners, of which only 2 are seen by both cameras."""

from __future__ import annotations

import numpy as np

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import StereoRenderer


def test_two_stereo_pairs_and_one_corner_in_each_view_alone_give_the_pose() -> None:
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    marker = MarkerModel()
    shape = arm_shape(RobotParams(), np.asarray(HOME_PSI, float))
    f = StereoRenderer(cam, marker, RenderSettings(), seed=2).render(shape)
    seen = {c.index for c in f.corners_left if c.cos_view > 0.3}
    seen &= {c.index for c in f.corners_right if c.cos_view > 0.3}
    a = min(i for i in seen if all((i + k) % marker.columns in seen for k in range(4)))
    ids = [(a + k) % marker.columns for k in range(4)]
    uv_l = {c.index: c.uv for c in f.corners_left}
    uv_r = {c.index: c.uv for c in f.corners_right}
    left, right = [ids[0], ids[1], ids[3]], [ids[1], ids[2], ids[3]]  # ids[2] washed out on the left, ids[0] right
    pol = [marker.polarity(i) for i in range(marker.columns)]
    tr = MarkerTracker(cam, marker)
    res = tr.track_corners(np.array([uv_l[i] for i in left]), np.array([uv_r[i] for i in right]),
                           np.array([pol[i] for i in left]), np.array([pol[i] for i in right]))
    assert res.ok, res.reason
    assert res.match is not None and res.match.n_pairs == 2
    assert res.tip_left is not None and np.linalg.norm(res.tip_left - f.tip_left) < 0.05e-3
