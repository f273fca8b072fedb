"""The print's dark bars as extra features of the pose (cvs.tracking.print_edges): every sample
sits on a dark/white boundary with its white side across it and its partner on the bar's other
boundary; on a rendered coded sleeve the bars' centre lines are found where the true pose puts
them; a pose tilted off the truth is brought back by the bars; the negative of the print (a roll
one column off) is recognised; and the tracker's bar refinement is off at edge_sigma_px 0."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.print_edges import (
    bar_pairs,
    edges_tip_sigma,
    measure_edges,
    print_is_negative,
    printed_edges,
    refine_with_edges,
)
from wristmark.cvs.tracking.tip_uncertainty import tip_sigma
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings
from wristmark.models.arm_shape import arm_shape
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.sim.render.settings import RenderSettings
from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer

CAM = load_calibration(CONFIG_DIR / "camera.yaml")
CODED = MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")


def _pair(marker: MarkerModel, seed: int = 3) -> RenderedPair:
    return StereoRenderer(CAM, marker, RenderSettings(), seed=seed).render(
        arm_shape(RobotParams(), np.asarray(HOME_PSI, float)))


def _rotated(T: np.ndarray, axis: np.ndarray, deg: float, about: np.ndarray) -> np.ndarray:
    """T turned by ``deg`` about ``axis`` ({ll}) through the point ``about`` ({ll})."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    th = math.radians(deg)
    R = np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K
    out = T.copy()
    out[:3, :3] = R @ T[:3, :3]
    out[:3, 3] = R @ (T[:3, 3] - about) + about
    return out


@pytest.mark.parametrize("marker", [MarkerModel(), CODED], ids=["reference", "coded"])
def test_every_sample_is_on_a_boundary_with_its_partner_across_the_bar(marker: MarkerModel) -> None:
    e = printed_edges(marker)
    assert e.points.shape[0] > 0 and np.array_equal(e.partner[e.partner], np.arange(e.points.shape[0]))
    delta = 2e-5  # 20 um across the boundary, along the surface
    for p, acr, q in zip(e.points, e.across, e.points[e.partner]):
        def colour(x: np.ndarray) -> bool:
            return marker.is_black(math.atan2(x[1], x[0]), float(x[2]))
        tangent = acr / np.linalg.norm(acr)
        assert not colour(p + delta * tangent) and colour(p - delta * tangent)  # white across, dark behind
        same_height, same_angle = abs(p[2] - q[2]) < 1e-12, abs(math.atan2(p[1], p[0]) - math.atan2(q[1], q[0])) < 1e-9
        assert same_height != same_angle  # a bar around the sleeve, or one along it
    assert e.coded.any() == (marker.code is not None)


def test_the_bars_of_a_rendered_coded_sleeve_are_found_where_the_true_pose_puts_them() -> None:
    pair = _pair(CODED)
    e = printed_edges(CODED)
    for right in (False, True):
        found = measure_edges(pair.right if right else pair.left, CAM, right, pair.T_left_marker, e)
        Pa, uva, na, Pb, uvb, nb = bar_pairs(e, found)
        assert Pa.shape[0] >= 20 and e.coded[np.isin(np.arange(e.points.shape[0]), found.index)].any()
        project = CAM.project_right if right else CAM.project_left
        R, t = pair.T_left_marker[:3, :3], pair.T_left_marker[:3, 3]
        ra = np.einsum("ij,ij->i", project(Pa @ R.T + t) - uva, na)
        rb = np.einsum("ij,ij->i", project(Pb @ R.T + t) - uvb, nb)
        bar = 0.5 * (ra - rb)
        assert abs(bar.mean()) < 0.05 and np.sqrt(np.mean(bar**2)) < 0.2  # [px]


def test_the_joint_fit_reaches_one_pose_from_a_tilted_start() -> None:
    """Three corners on one arc and the bars found at the rendered pose: iterated from that pose
    and from 0.5 deg of tilt about the sleeve's centre, the joint fit ends at the same pose (its
    Jacobian is right), within 0.2 deg and 30 um of the rendered one."""
    pair = _pair(CODED)
    T_true = pair.T_left_marker
    e = printed_edges(CODED)
    found = [measure_edges(v, CAM, i == 1, T_true, e) for i, v in enumerate((pair.left, pair.right))]
    bars = (bar_pairs(e, found[0]), bar_pairs(e, found[1]))
    ids = np.array([c.index for c in pair.corners_left if c.cos_view > 0.5])[:3]
    P = CODED.corners()[ids]
    uv_l = np.array([c.uv for c in pair.corners_left if c.index in ids])
    uv_r = np.array([c.uv for c in pair.corners_right if c.index in ids])
    assert uv_l.shape == uv_r.shape == (3, 2)
    corners = ((P, uv_l, np.full(3, 0.1)), (P, uv_r, np.full(3, 0.1)))
    T_a, rc, rb = refine_with_edges(CAM, T_true, corners, bars, 0.5, iterations=10)
    T_b, _, _ = refine_with_edges(CAM, _rotated(T_true, T_true[:3, 0], 0.5, T_true[:3, 3]), corners, bars, 0.5,
                                  iterations=10)
    assert _turn_deg(T_a, T_b) < 0.01 and np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]) < 2e-6
    assert _turn_deg(T_a, T_true) < 0.2 and np.linalg.norm(T_a[:3, 3] - T_true[:3, 3]) < 30e-6
    assert rc.size == 12 and rb.size == bars[0][0].shape[0] + bars[1][0].shape[0]


def test_the_bars_fix_the_tip_that_three_corners_leave_open() -> None:
    """The tip's sigma from the corners and bars together: without bars it is the corners' own
    (cvs.tracking.tip_uncertainty.tip_sigma, whose numerical Jacobian includes the lens
    distortion: within 5 %); the bars of a rendered coded sleeve seen side-on cut it (0.14 ->
    0.10 mm: three corners there fix the tilt fairly well; the steep path-traced pair of
    test_bars_gate goes from 1.05 to 0.10 mm); two corners and no bars do not determine the
    pose."""
    pair = _pair(CODED)
    T = pair.T_left_marker
    e = printed_edges(CODED)
    found = [measure_edges(v, CAM, i == 1, T, e) for i, v in enumerate((pair.left, pair.right))]
    bars = (bar_pairs(e, found[0]), bar_pairs(e, found[1]))
    none = tuple(np.zeros((0, k)) for k in (3, 2, 2, 3, 2, 2))
    ids = np.array([c.index for c in pair.corners_left if c.cos_view > 0.5])[:3]
    P = CODED.corners()[ids]
    uv_l = np.array([c.uv for c in pair.corners_left if c.index in ids])
    uv_r = np.array([c.uv for c in pair.corners_right if c.index in ids])
    corners = ((P, uv_l, np.full(3, 0.1)), (P, uv_r, np.full(3, 0.1)))
    tips = np.stack([CODED.tip(), -CODED.tip()])
    alone = edges_tip_sigma(CAM, T, corners, (none, none), 0.5, tips)
    assert alone == pytest.approx(tip_sigma(CAM, T, P, P, tips, 0.1), rel=0.05)
    assert edges_tip_sigma(CAM, T, corners, bars, 0.5, tips) < 0.8 * alone
    two = ((P[:1], uv_l[:1], np.full(1, 0.1)), (P[1:2], uv_r[1:2], np.full(1, 0.1)))
    assert edges_tip_sigma(CAM, T, two, (none, none), 0.5, tips) == float("inf")


def _turn_deg(A: np.ndarray, B: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((np.trace(A[:3, :3].T @ B[:3, :3]) - 1) / 2, -1, 1)))


def test_the_prints_negative_is_recognised() -> None:
    pair = _pair(MarkerModel())
    T = pair.T_left_marker
    assert not print_is_negative(pair.left, CAM, T, MarkerModel())
    beta = MarkerModel().beta
    one_column = np.eye(4)
    one_column[:3, :3] = [[math.cos(beta), -math.sin(beta), 0], [math.sin(beta), math.cos(beta), 0], [0, 0, 1]]
    assert print_is_negative(pair.left, CAM, T @ one_column, MarkerModel())


def test_the_tracker_refines_with_the_bars_only_when_asked() -> None:
    pair = _pair(CODED)
    off = MarkerTracker(CAM, CODED, TrackerSettings(edge_sigma_px=0.0)).track(pair.left, pair.right)
    on = MarkerTracker(CAM, CODED).track(pair.left, pair.right)
    assert off.ok and on.ok and on.roll_known
    assert "edges" not in off.timings and "edges" in on.timings
    assert not np.array_equal(off.tip_left, on.tip_left)
    assert on.tip_left is not None and np.linalg.norm(on.tip_left - pair.tip_left) < 0.1e-3
    for bad in ({"edge_sigma_px": -1.0}, {"edge_max_rms_px": 0.0}, {"edge_min_samples": 0}):
        with pytest.raises(InputError, match="TrackerSettings"):
            TrackerSettings(**bad)  # type: ignore[arg-type]


def test_an_arm_set_of_several_arms_solves_from_the_corners_alone() -> None:
    """Another sleeve can stand in a bar's search: with several arms, no bars."""
    from wristmark.cvs.tracking.arm_set import ArmSetTracker
    from wristmark.sim.scene_setup import load_scene_setup

    two = load_scene_setup("scenes/two_arms.yaml")
    several = ArmSetTracker(two.camera, two.markers, threads=False)
    assert several.settings.edge_sigma_px == 0.0
    assert all(t.settings.edge_sigma_px == 0.0 for t in several.trackers.values())
    one = ArmSetTracker(two.camera, two.markers[:1], threads=False)
    assert one.settings.edge_sigma_px == TrackerSettings().edge_sigma_px > 0
