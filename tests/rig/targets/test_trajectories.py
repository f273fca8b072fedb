"""Cube trajectory (paper IV.C) and accuracy targets (paper IV.B)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from wristmark.models.errors import InputError
from wristmark.rig.targets.trajectories import (
    Trajectory,
    accuracy_targets,
    cube_trajectory,
    feedforward_velocity,
)

CENTRE = np.array([0.01, -0.005, 0.16])
SIZE = (0.040, 0.020, 0.040)
SPEED = 0.010


def _dense(traj: object, dt: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ts = np.arange(0.0, traj.duration + 1e-12, dt)  # type: ignore[attr-defined]
    ps, vs = zip(*(traj.sample(float(t)) for t in ts))  # type: ignore[attr-defined]
    return ts, np.array(ps), np.array(vs)


def test_constant_speed() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    ts, ps, vs = _dense(traj)
    inner = (ts > 1e-9) & (ts < traj.duration - 1e-9)
    np.testing.assert_allclose(np.linalg.norm(vs[inner], axis=1), SPEED, rtol=1e-12)
    # positions advance at the speed (finite differences, away from corners)
    steps = np.linalg.norm(np.diff(ps, axis=0), axis=1)
    assert np.max(steps) <= SPEED * 0.01 * (1 + 1e-9)
    assert np.median(steps) == pytest.approx(SPEED * 0.01, rel=1e-9)


@pytest.mark.slow
def test_continuous() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    _, ps, _ = _dense(traj, 0.001)
    assert np.max(np.linalg.norm(np.diff(ps, axis=0), axis=1)) <= SPEED * 0.001 * (1 + 1e-9)


def test_visits_all_corners_and_stays_on_the_box() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    half = 0.5 * np.asarray(SIZE)
    corners = [CENTRE + half * np.array(s) for s in itertools.product((-1, 1), repeat=3)]
    wp = traj.waypoints
    for c in corners:
        assert np.min(np.linalg.norm(wp - c, axis=1)) < 1e-12
    _, ps, _ = _dense(traj)
    rel = np.abs(ps - CENTRE) / half
    assert np.all(rel <= 1 + 1e-9)
    # on an edge: at least two coordinates are at a face
    assert np.all(np.sum(np.isclose(rel, 1.0, atol=1e-9), axis=1) >= 2)


def test_covers_all_twelve_edges_with_the_right_lengths() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    half = 0.5 * np.asarray(SIZE)
    signs = np.rint((traj.waypoints - CENTRE) / half).astype(int)
    edges = set()
    for a, b, pa, pb in zip(signs[:-1], signs[1:], traj.waypoints[:-1], traj.waypoints[1:]):
        axis = int(np.flatnonzero(a != b)[0])
        assert np.sum(a != b) == 1  # every leg runs along one box edge
        assert np.linalg.norm(pb - pa) == pytest.approx(SIZE[axis], rel=1e-12)
        edges.add(frozenset((tuple(a), tuple(b))))
    assert len(edges) == 12
    legs = len(traj.waypoints) - 1
    assert traj.duration == pytest.approx(
        sum(np.linalg.norm(np.diff(traj.waypoints, axis=0), axis=1)) / SPEED, rel=1e-12
    )
    assert legs >= 12


def test_sample_holds_at_the_ends() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    p0, v0 = traj.sample(-1.0)
    p1, v1 = traj.sample(traj.duration + 5.0)
    np.testing.assert_allclose(p0, traj.waypoints[0])
    np.testing.assert_allclose(p1, traj.waypoints[-1])
    assert np.all(v0 == 0.0) and np.all(v1 == 0.0)


def test_accuracy_targets() -> None:
    t = accuracy_targets(CENTRE, n=40, seed=4)
    assert t.shape == (40, 3)
    assert np.all(np.isfinite(t))
    assert np.max(np.abs(t - CENTRE)) <= 0.05
    steps = np.linalg.norm(np.diff(np.vstack([CENTRE, t]), axis=0), axis=1)
    assert np.all(steps > 0.0) and np.all(steps < 0.02)  # incremental moves
    np.testing.assert_array_equal(t, accuracy_targets(CENTRE, n=40, seed=4))
    assert not np.allclose(t, accuracy_targets(CENTRE, n=40, seed=5))


def test_truncated_keeps_the_first_seconds() -> None:
    traj = cube_trajectory(np.zeros(3))
    short = traj.truncated(2.5)
    assert short.duration == pytest.approx(2.5)
    for t in (0.0, 1.0, 2.4999):
        np.testing.assert_allclose(short.sample(t)[0], traj.sample(t)[0], atol=1e-12)
    assert traj.truncated(1e6) is traj
    with pytest.raises(ValueError, match="duration"):
        traj.truncated(0.0)


def test_feedforward_is_the_path_velocity_on_straight_edges() -> None:
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    for t in (0.5, 1.3, 7.0):  # well inside an edge (edges take 2 s or 4 s)
        v = traj.sample(t + 0.035)[1]
        np.testing.assert_allclose(feedforward_velocity(traj, t, 0.06, 0.035, 0.06), v, atol=1e-15)


@pytest.mark.parametrize("preview, lead", [(0.0, 0.0), (0.035, 0.06), (0.1, 0.02)])
def test_feedforward_integrates_to_the_led_path(preview: float, lead: float) -> None:
    """Summed over cycles, the feed-forward moves the command exactly to p_des(t + preview) +
    lead v_des(t + preview), corners included (a lead bends the command outward at a corner)."""
    traj = cube_trajectory(CENTRE, SIZE, SPEED)
    dt, t0 = 0.06, -0.2
    ts = t0 + dt * np.arange(200)  # through the first corners (2 s, 6 s)
    steps = np.array([feedforward_velocity(traj, float(t), dt, preview, lead) for t in ts]) * dt
    p0, v0 = traj.sample(t0 + preview)
    end = ts[-1] + dt + preview
    p1, v1 = traj.sample(end)
    np.testing.assert_allclose(p0 + lead * v0 + steps.sum(axis=0), p1 + lead * v1, atol=1e-12)
    if lead == 0.0:  # without a lead the command never moves faster than the path
        assert np.linalg.norm(steps / dt, axis=1).max() <= SPEED * (1 + 1e-9)


def test_orientation_modes_of_a_cube() -> None:
    """none: no orientation; hold: the nominal tip frame at the start configuration, all along;
    follow: the nominal tip frame of the position IK along the path; cut paths keep theirs."""
    from wristmark.models.ik import solve_tip_ik
    from wristmark.models.kinematics import forward_kinematics
    from wristmark.models.robot_params import HOME_PSI, RobotParams
    from wristmark.models.so3 import angle_between
    from wristmark.rig.targets.trajectories import workspace_centre

    P = RobotParams()
    traj = cube_trajectory(workspace_centre(P), SIZE, SPEED)
    assert traj.sample_orientation(3.0) is None and traj.orientation_mode == "none"
    psi0 = solve_tip_ik(P, traj.sample(0.0)[0], np.array(HOME_PSI)).psi
    R0 = forward_kinematics(P, psi0).T_world_tip[:3, :3]
    hold = traj.with_orientation("hold", P)
    for t in (0.0, 2.5, 17.0, traj.duration + 1.0):
        R, w = hold.sample_orientation(t)  # type: ignore[misc]
        np.testing.assert_allclose(R, R0, atol=1e-12)
        np.testing.assert_array_equal(w, np.zeros(3))
    follow = traj.truncated(6.0).with_orientation("follow", P)
    psi = psi0
    turned = 0.0
    for t in np.arange(0.0, 6.0, 0.05):
        psi = solve_tip_ik(P, follow.sample(float(t))[0], psi).psi
        R_ik = forward_kinematics(P, psi).T_world_tip[:3, :3]
        R, _ = follow.sample_orientation(float(t))  # type: ignore[misc]
        assert angle_between(R, R_ik) < 1e-6
        turned = max(turned, angle_between(R, R0))
    assert turned > np.deg2rad(1.0)  # the plan does turn the tool (so follow differs from hold)
    # angular velocity: R(t + h) ~ Exp(w h) R(t) between samples
    R1, w1 = follow.sample_orientation(2.02)  # type: ignore[misc]
    R2, _ = follow.sample_orientation(2.03)  # type: ignore[misc]
    from scipy.spatial.transform import Rotation

    np.testing.assert_allclose(Rotation.from_rotvec(w1 * 0.01).as_matrix() @ R1, R2, atol=1e-9)
    cut = hold.truncated(4.0)
    assert cut.orientation_mode == "hold" and cut.duration == pytest.approx(4.0)


def test_unknown_orientation_mode_lists_the_valid_ones() -> None:
    from wristmark.models.errors import ConfigError
    from wristmark.models.robot_params import RobotParams

    with pytest.raises(ConfigError, match="none, hold, follow"):
        cube_trajectory(CENTRE, SIZE, SPEED).with_orientation("keep", RobotParams())


def test_from_waypoints_walks_the_points_in_order_at_the_speed() -> None:
    theta = np.deg2rad(np.arange(0, 361, 10))
    pts = np.column_stack([0.004 * np.cos(theta), np.zeros_like(theta), 0.1 + 0.004 * np.sin(theta)])
    traj = Trajectory.from_waypoints(pts.tolist(), 0.01)  # any (N, 3) array-like [m]
    assert traj.waypoints.shape == (37, 3) and traj.speed == 0.01
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    assert traj.duration == pytest.approx(seg.sum() / 0.01)
    for k in (0, 5, 36):
        np.testing.assert_allclose(traj.sample(traj.times[k])[0], pts[k], atol=1e-12)
    assert np.linalg.norm(traj.sample(0.5 * traj.times[1])[1]) == pytest.approx(0.01)


@pytest.mark.parametrize(("points", "speed", "message"), [
    ([[0, 0, 0.1]], 0.01, r"shape \(N, 3\) with N >= 2"),
    ([[0, 0], [0, 1]], 0.01, r"shape \(N, 3\) with N >= 2"),
    ([[0, 0, 0.1], ["a", 0, 0.1]], 0.01, "must be numbers"),
    ([[0, 0, 0.1], [0, np.inf, 0.1]], 0.01, "waypoint 1 is not finite"),
    ([[0, 0, 0.1], [0.001, 0, 0.1], [0.001, 0, 0.1]], 0.01, "waypoints 1 and 2 coincide"),
    ([[0, 0, 0.1], [0.001, 0, 0.1]], 0.0, "speed must be a finite number > 0"),
    ([[0, 0, 0.1], [0.001, 0, 0.1]], float("nan"), "speed must be a finite number > 0"),
])
def test_from_waypoints_refuses_bad_input_in_one_line(points: object, speed: float, message: str) -> None:
    with pytest.raises(InputError, match=message) as e:
        Trajectory.from_waypoints(points, speed)  # type: ignore[arg-type]
    assert "\n" not in str(e.value)
