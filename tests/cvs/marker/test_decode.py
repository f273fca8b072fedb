"""cvs.marker.decode: a clipped highlight along one column of the coded sleeve."""

from __future__ import annotations

import cv2
import numpy as np

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import StereoRenderer

CODED = MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")
CAM = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.75)


def test_a_clipped_column_is_not_read_and_the_rest_still_decides() -> None:
    """Both checker patches and the cells of the column that faces the cameras best painted
    clipped white along the sleeve (the coaxial light's stripe): that column's cells are not read
    (a dark cell there would read white), and the identity from the others is the same."""
    shape = arm_shape(RobotParams(), np.asarray(HOME_PSI, float))
    f = StereoRenderer(CAM, CODED, RenderSettings(), seed=5).render(shape)
    tr = MarkerTracker(CAM, CODED)
    res = tr.track(f.left, f.right)
    assert res.ok and res.roll_known and res.pose is not None and res.code is not None
    dec = tr.decoder
    assert dec is not None
    T_fit = res.pose.T_fit
    n, r, beta = CODED.columns, CODED.radius, CODED.beta
    a = (np.arange(n) + 0.5) * beta
    facing = -(T_fit[:3, :3] @ np.vstack([np.cos(a), np.sin(a), np.zeros(n)])).T @ (T_fit[:3, 3]
                                                                                   / np.linalg.norm(T_fit[:3, 3]))
    j = int(np.argmax(facing))
    imgs = [f.left.copy(), f.right.copy()]
    ends = np.array([[r * np.cos(a[j]), r * np.sin(a[j]), z, 1.0] for z in (-0.0054, 0.0054)])
    for im, project in ((imgs[0], CAM.project_left), (imgs[1], CAM.project_right)):
        uv = project((T_fit @ ends.T).T[:, :3])
        p0, p1 = (tuple(int(round(v)) for v in p) for p in uv)
        cv2.line(im, p0, p1, (255, 255, 255), 7)
    d_clean, _ = dec._darkness((f.left, f.right), T_fit)
    d_lit, _ = dec._darkness((imgs[0], imgs[1]), T_fit)
    nb = d_lit.size // n
    cells = slice(j * nb, (j + 1) * nb)
    assert np.all(np.isfinite(d_clean[cells])) and np.all(np.isnan(d_lit[cells]))
    reading = dec.read((imgs[0], imgs[1]), T_fit)
    assert reading.ok, reading.reason
    assert (reading.shift, reading.direction) == (res.code.shift, res.code.direction)
