"""The clearance between arms (solvers/clearance.py) and the qp's constraint on it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wristmark.models.arm_shape import arm_shape
from wristmark.models.arm_spec import Arm, as_spec, load_arm
from wristmark.models.config_files import default_config
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import tip_position
from wristmark.models.limits import psi_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.solvers import clearance
from wristmark.solvers.clearance import (
    Capsules,
    body_capsules,
    clearance_rows,
    min_distance,
    segment_closest,
    transformed,
)
from wristmark.solvers.controller import ControllerConfig
from wristmark.solvers.controller_registry import make_controller
from wristmark.solvers.qp_controller import BoxQp, QpController

DT = 0.06
CLEARANCE = 0.002
CONFIG = dataclasses.replace(ControllerConfig(), backlash_compensation=False, ki=0.0)


def _brute(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray, k: int = 401) -> float:
    s = np.linspace(0.0, 1.0, k)[:, None]
    a = p1 + s * (q1 - p1)
    b = p2 + s * (q2 - p2)
    return float(np.min(np.linalg.norm(a[:, None] - b[None], axis=-1)))


def _random_pairs() -> list[tuple[np.ndarray, ...]]:
    rng = np.random.default_rng(7)
    out = [tuple(rng.normal(size=(4, 3))) for _ in range(25)]
    for _ in range(8):  # parallel (same and opposite direction, overlapping or not along the axis)
        p1, d, off = rng.normal(size=(3, 3))
        scale = rng.uniform(-2.0, 2.0)
        p2 = p1 + off * 0.3 + rng.uniform(-1, 1) * d
        out.append((p1, p1 + d, p2, p2 + scale * d))
    for _ in range(5):  # crossing: both through one point
        x, d1, d2 = rng.normal(size=(3, 3))
        out.append((x - 0.4 * d1, x + 0.6 * d1, x - 0.7 * d2, x + 0.3 * d2))
    p, q = rng.normal(size=(2, 3))
    out += [(p, p, q, q + 1.0), (p, p + 1.0, q, q), (p, p, q, q)]  # zero-length segments (points)
    return out


@pytest.mark.parametrize("case", range(len(_random_pairs())))
def test_segment_distance_matches_brute_force_sampling(case: int) -> None:
    p1, q1, p2, q2 = _random_pairs()[case]
    s, t, c1, c2 = segment_closest(p1, q1, p2, q2)
    assert 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0
    np.testing.assert_allclose(c1, p1 + s * (q1 - p1), atol=1e-12)
    np.testing.assert_allclose(c2, p2 + t * (q2 - p2), atol=1e-12)
    d = float(np.linalg.norm(c1 - c2))
    brute = _brute(p1, q1, p2, q2)
    step = (np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)) / 400
    assert d <= brute + 1e-12  # never more than any sampled pair
    assert d >= brute - step  # and no less than the samples allow


def test_crossing_segments_are_at_distance_zero_and_min_distance_subtracts_radii() -> None:
    a = Capsules(np.array([[-1.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([0.1]))
    b = Capsules(np.array([[0.0, -1, 0.5]]), np.array([[0.0, 1, 0.5]]), np.array([0.2]))
    d, pa, pb, i, j = min_distance(a, b)
    assert d == pytest.approx(0.5 - 0.3) and (i, j) == (0, 0)
    np.testing.assert_allclose(pa, [0, 0, 0.1], atol=1e-12)
    np.testing.assert_allclose(pb, [0, 0, 0.3], atol=1e-12)
    c = Capsules(np.array([[0.0, -1, 0.0]]), np.array([[0.0, 1, 0.0]]), np.array([0.2]))
    assert min_distance(a, c)[0] == pytest.approx(-0.3)


def _arms() -> list[tuple[str, Arm, np.ndarray]]:
    out: list[tuple[str, Arm, np.ndarray]] = [("reference", RobotParams(), np.array(HOME_PSI))]
    for name in ("tendon3", "single_tendon", "planar"):
        arm = load_arm(default_config(f"robots/{name}.yaml"))
        out.append((name, arm, arm.home_psi()))
    return out


@pytest.mark.parametrize("which", range(4))
def test_body_capsules_follow_the_arm(which: int) -> None:
    """The last capsule ends at the tip; every centreline point of the finely sampled shape, with
    the tube's radius around it, lies inside a capsule (the chords' sagitta covers the arc)."""
    _, arm, home = _arms()[which]
    lo, hi = psi_bounds(arm)
    rng = np.random.default_rng(which)
    lo, hi = np.maximum(lo, home - 0.8), np.minimum(hi, home + 0.8)
    for q in [home, *rng.uniform(lo, hi, size=(5, home.size))]:
        caps = body_capsules(arm, q)
        shape = arm_shape(arm, q, samples_per_segment=64)
        np.testing.assert_allclose(caps.end[-1], shape.tip, atol=1e-12)
        np.testing.assert_allclose(caps.start[0], [0.0, 0.0, 0.0], atol=0)
        P = shape.centreline
        _, _, c1, c2 = segment_closest(P[:, None], P[:, None], caps.start[None], caps.end[None])
        slack = caps.radius[None] - np.linalg.norm(c1 - c2, axis=-1) - shape.radius
        assert slack.max(axis=1).min() >= -1e-12
        # the far test's sphere (clearance._beyond_reach) holds the whole body
        spec = as_spec(arm)
        lay = clearance._layout(spec, clearance.PER_SEGMENT, clearance.SLEEVE_RADIUS,
                                clearance.SLEEVE_HALF_LENGTH, None)
        sphere = abs(float(q[spec.layout.prismatic].sum())) + lay.extent
        reach = np.maximum(np.linalg.norm(caps.start, axis=1), np.linalg.norm(caps.end, axis=1)) + caps.radius
        assert reach.max() <= sphere


def test_transformed_moves_the_capsules_rigidly() -> None:
    p = RobotParams()
    a = body_capsules(p, HOME_PSI)
    b = body_capsules(p, [0.3, 0.06, 0.4, 1.0, 0.2, 0.0])
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    T[:3, 3] = [0.05, 0.01, 0.0]
    bt = transformed(b, T)
    np.testing.assert_allclose(bt.start[3], T[:3, :3] @ b.start[3] + T[:3, 3])
    d = min_distance(a, bt)[0]
    assert min_distance(transformed(a, T), transformed(bt, T))[0] == pytest.approx(d, abs=1e-12)
    assert min_distance(a, b)[0] < 0  # two arms from one incision overlap there
    assert d != pytest.approx(min_distance(a, b)[0])


def _column(x: float, arm: Arm | None = None, psi: object = (0.0, 0.12, 0.0, 0.0, 0.0, 0.0)) -> Capsules:
    """Another arm standing straight up, its {w} at (x, 0, 0) in this arm's {w}."""
    T = np.eye(4)
    T[:3, 3] = [x, 0.0, 0.0]
    return transformed(body_capsules(RobotParams() if arm is None else arm, psi), T)


def test_a_row_is_the_rate_of_its_pairs_distance() -> None:
    """A psi_dot along the row's direction changes the pair's distance as the row predicts."""
    p = RobotParams()
    q = np.array(HOME_PSI)
    other = _column(0.095)
    A, lo = clearance_rows(p, q, other, CLEARANCE, DT, influence_m=0.05, m_max=1)
    assert A.shape == (1, 6) and lo[0] < 0
    d0 = min_distance(body_capsules(p, q), other)[0]
    assert lo[0] == pytest.approx(-0.5 * (d0 - CLEARANCE) / DT)
    rng = np.random.default_rng(3)
    for _ in range(5):
        v = rng.normal(size=6)
        h = 1e-6
        d1 = min_distance(body_capsules(p, q + h * v), other)[0]
        assert (d1 - d0) / h == pytest.approx(float(A[0] @ v), rel=1e-3, abs=1e-6)


def _run(arm: Arm, q0: np.ndarray, other: Capsules, target: np.ndarray, obstacles: bool,
         steps: int = 200) -> tuple[np.ndarray, set[str], np.ndarray]:
    c = make_controller(arm, CONFIG)
    c.set_obstacles(other if obstacles else None, CLEARANCE)
    lo, hi = psi_bounds(arm)
    q = np.asarray(q0, float).copy()
    dist, status = [], set()
    for _ in range(steps):
        psi_dot, _, s = c.velocity(q, tip_position(arm, q), target, np.zeros(3), DT)
        status.add(s)
        q = np.clip(q + psi_dot * DT, lo, hi)
        dist.append(min_distance(body_capsules(arm, q), other)[0])
    return np.array(dist), status, q


def test_the_reference_arm_keeps_its_clearance_from_an_arm_in_its_path() -> None:
    p = RobotParams()
    q0 = np.array(HOME_PSI)
    other = _column(0.095)  # stands between the tip and the target
    target = np.array([0.12, 0.0, 0.147])
    free, st_free, _ = _run(p, q0, other, target, obstacles=False)
    assert free.min() < 0.0 and st_free == {"ok"}  # unconstrained, it drives through the other arm
    kept, status, q = _run(p, q0, other, target, obstacles=True)
    assert kept.min() >= CLEARANCE - 1e-6
    assert "clearance" in status and "qp-failed" not in status
    assert tip_position(p, q)[0] > 0.085  # it still went towards the target, up to the other arm


def test_a_tendon_arm_keeps_its_clearance_from_another_kind_of_arm() -> None:
    arm = load_arm(default_config("robots/tendon3.yaml"))
    q0 = arm.home_psi()
    tip = tip_position(arm, q0)
    other = _column(tip[0] + 0.012, load_arm(default_config("robots/single_tendon.yaml")), [0.0, 0.1, 0.0, 0.0])
    target = tip + np.array([0.03, 0.0, 0.0])
    free, _, _ = _run(arm, q0, other, target, obstacles=False)
    assert free.min() < CLEARANCE
    kept, status, _ = _run(arm, q0, other, target, obstacles=True)
    assert kept.min() >= CLEARANCE - 1e-6 and "qp-failed" not in status


@pytest.mark.parametrize("influence", [None, 2.0])
def test_obstacles_far_away_leave_the_step_as_it_was(influence: float | None) -> None:
    """No row near (None): the box-only QP; rows present but slack (influence 2 m): the same step."""
    p = RobotParams()
    q = np.array(HOME_PSI)
    target = tip_position(p, q) + np.array([0.004, -0.003, 0.002])
    free = make_controller(p, CONFIG)
    held = make_controller(p, CONFIG)
    assert isinstance(held, QpController)
    held.set_obstacles(_column(0.6), CLEARANCE, influence_m=influence)
    assert (len(held.clearance_rows(q, DT)[0]) > 0) == (influence is not None)
    for _ in range(20):
        a, _, sa = free.velocity(q, tip_position(p, q), target, np.zeros(3), DT)
        b, _, sb = held.velocity(q, tip_position(p, q), target, np.zeros(3), DT)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)
        assert sa == sb == "ok"
        q = q + a * DT
    held.set_obstacles(None)
    assert held.obstacles is None


@pytest.mark.parametrize("x", [0.0861, 0.080])
def test_an_arm_already_inside_the_clearance_never_fails_and_comes_no_closer(x: float) -> None:
    """Start 1 mm apart (inside the 2 mm clearance) and 5 mm overlapping, driven into the other arm."""
    p = RobotParams()
    q0 = np.array(HOME_PSI)
    other = _column(x)
    d0 = min_distance(body_capsules(p, q0), other)[0]
    assert d0 < CLEARANCE
    dist, status, _ = _run(p, q0, other, np.array([0.12, 0.0, 0.147]), obstacles=True)
    assert "qp-failed" not in status
    assert dist.min() >= d0 - 1e-9
    away, status, _ = _run(p, q0, other, np.array([0.0, 0.0, 0.147]), obstacles=True, steps=60)
    assert "qp-failed" not in status and away[-1] > CLEARANCE  # leaving is allowed


def test_the_paper_controller_refuses_obstacles() -> None:
    c = make_controller(RobotParams(), dataclasses.replace(CONFIG, kind="paper"))
    c.set_obstacles(None)
    with pytest.raises(ConfigError, match="qp"):
        c.set_obstacles(_column(0.1), CLEARANCE)


def test_clearance_in_the_config_is_validated_and_used() -> None:
    with pytest.raises(ConfigError, match="clearance_m"):
        dataclasses.replace(CONFIG, clearance_m=-0.001).validate()
    c = make_controller(RobotParams(), dataclasses.replace(CONFIG, clearance_m=0.004))
    assert isinstance(c, QpController)
    c.set_obstacles(_column(0.1))
    assert c.clearance_m == 0.004
    with pytest.raises(ConfigError, match="clearance_m"):
        c.set_obstacles(_column(0.1), -1.0)


def test_box_qp_with_rows() -> None:
    """min |x - 1|^2 with x0 <= 2 (box) and -x0 - x1 >= -1 (a row): x = (0.5, 0.5, 1)."""
    qp = BoxQp("daqp", 3, m=4)
    H, g = 2 * np.eye(3), -2 * np.ones(3)
    lo, hi = -5 * np.ones(3), np.array([2.0, 5.0, 5.0])
    np.testing.assert_allclose(qp.solve(H, g, lo, hi, np.array([[-1.0, -1.0, 0.0]]), np.array([-1.0])),
                               [0.5, 0.5, 1.0], atol=1e-9)
    np.testing.assert_allclose(qp.solve(H, g, lo, hi), [1.0, 1.0, 1.0], atol=1e-9)  # rows cleared
    with pytest.raises(ValueError):
        qp.solve(H, g, lo, hi, np.zeros((5, 3)), np.zeros(5))
    with pytest.raises(ValueError):
        BoxQp("daqp", 3).solve(H, g, lo, hi, np.zeros((1, 3)), np.zeros(1))
