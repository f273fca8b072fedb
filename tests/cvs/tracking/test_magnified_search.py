"""The tracker's enlarged search of a lost pair (TrackerSettings.magnify, off by default): a small
marker (quarter-size frames) tracked in a clean pair and lost in the next, noisier one at the
image's own scale, found again in the box around the last corners enlarged twice. Its fit (3 + 3
corners 8 px apart at 0.45 px under strong noise) is then held to its residual by the small-fit
gate (max_small_fit_tip_sigma_m), which refuses it (docs/notes/steep-views.md)."""

from __future__ import annotations

import numpy as np

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.sim.render.settings import noise_preset
from wristmark.sim.render.stereo_renderer import StereoRenderer
from wristmark.sim.visibility import random_visible_psi

CAM = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.25)
MARKER = MarkerModel()
SPREAD = (0.25, 0.012, 0.2, 0.6, 0.3, 0.6)  # as `wristmark render`


def test_a_pair_lost_at_its_own_scale_is_found_enlarged() -> None:
    params = RobotParams()
    psi = random_visible_psi(params, CAM, MARKER, np.random.default_rng(23), SPREAD)
    shape = arm_shape(params, psi)
    clean = StereoRenderer(CAM, MARKER, noise_preset("none"), seed=23).render(shape)
    noisy = StereoRenderer(CAM, MARKER, noise_preset("strong"), seed=23).render(shape)
    W = CAM.T_world_left
    assert W is not None
    results = {}
    for magnify, small_gate in ((1.0, np.inf), (2.0, np.inf), (2.0, TrackerSettings().max_small_fit_tip_sigma_m)):
        trk = MarkerTracker(CAM, MARKER, TrackerSettings(magnify=magnify, max_small_fit_tip_sigma_m=small_gate))
        assert trk.track(clean.left, clean.right).ok
        results[magnify, small_gate] = trk.track(noisy.left, noisy.right)
    assert not results[1.0, np.inf].ok and "magnified" not in results[1.0, np.inf].timings
    res = results[2.0, np.inf]
    assert res.ok and "magnified" in res.timings, res.reason
    assert res.tip_left is not None
    assert np.linalg.norm(W[:3, :3] @ res.tip_left + W[:3, 3] - shape.frames.tip) < 1e-3
    gated = results[2.0, TrackerSettings().max_small_fit_tip_sigma_m]  # the default gate: its residual is too large
    assert not gated.ok and "magnified" in gated.timings and "small marker's corner noise" in gated.reason
    assert gated.tip_sigma_m > TrackerSettings().max_small_fit_tip_sigma_m and gated.pose is not None
