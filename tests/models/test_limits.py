"""Joint limits: wrap, normalize, clamp, check, velocity clamp, actuator bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.errors import LimitError
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import (
    actuator_bounds,
    check_limits,
    clamp_psi,
    clamp_velocity,
    normalize_psi,
    psi_bounds,
    within_limits,
    wrap_angle,
)
from wristmark.models.robot_params import HOME_PSI, RobotParams

PARAMS = RobotParams()
SEEDED = settings(max_examples=80, derandomize=True, deadline=None)
anything = st.tuples(*[st.floats(-10.0, 10.0)] * 6).map(np.array)


@SEEDED
@given(st.floats(-100.0, 100.0))
def test_wrap_angle_range_and_equivalence(a: float) -> None:
    w = wrap_angle(a)
    assert -math.pi < w <= math.pi
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-12)
    assert math.sin(w) == pytest.approx(math.sin(a), abs=1e-12)


def test_wrap_angle_edges() -> None:
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(math.pi) == math.pi
    assert wrap_angle(3 * math.pi) == pytest.approx(math.pi)
    assert wrap_angle(0.0) == 0.0


@SEEDED
@given(anything)
def test_normalize_keeps_the_pose(psi: np.ndarray) -> None:
    q = normalize_psi(psi)
    assert q[2] >= 0 and q[4] >= 0
    assert -math.pi < q[3] <= math.pi and -math.pi < q[5] <= math.pi
    a = forward_kinematics(PARAMS, psi).T_world_tip
    b = forward_kinematics(PARAMS, q).T_world_tip
    np.testing.assert_allclose(a, b, atol=1e-13)


@SEEDED
@given(anything)
def test_clamp_lands_inside_and_is_idempotent(psi: np.ndarray) -> None:
    q = clamp_psi(PARAMS, psi)
    assert within_limits(PARAMS, q)
    np.testing.assert_array_equal(check_limits(PARAMS, q), q)
    np.testing.assert_array_equal(clamp_psi(PARAMS, q), q)


def test_clamp_hits_the_bounds() -> None:
    q = clamp_psi(PARAMS, [5.0, -0.1, 3.0, 0.0, 0.5, 0.0])
    lo, hi = psi_bounds(PARAMS)
    assert q[0] == hi[0] and q[1] == lo[1] and q[2] == PARAMS.theta_max[0]
    assert q[4] == 0.5


@pytest.mark.parametrize(
    "psi, name",
    [
        ([4.0, 0.05, 0.1, 0, 0.1, 0], "phi"),
        ([0.0, 0.2, 0.1, 0, 0.1, 0], "d"),
        ([0.0, -1e-3, 0.1, 0, 0.1, 0], "d"),
        ([0.0, 0.05, 2.0, 0, 0.1, 0], "theta1"),
        ([0.0, 0.05, 0.1, 0, 2.5, 0], "theta2"),
    ],
)
def test_check_limits_names_the_joint(psi: list[float], name: str) -> None:
    assert not within_limits(PARAMS, psi)
    with pytest.raises(LimitError) as e:
        check_limits(PARAMS, psi)
    assert str(e.value).startswith(f"{name} = ")
    assert "outside" in str(e.value)


def test_home_is_within_limits() -> None:
    assert within_limits(PARAMS, HOME_PSI)


@SEEDED
@given(st.tuples(*[st.floats(-50.0, 50.0)] * 6).map(np.array))
def test_velocity_clamp_keeps_direction(v: np.ndarray) -> None:
    out = clamp_velocity(PARAMS, v)
    vmax = np.array(PARAMS.max_velocity)
    assert np.all(np.abs(out) <= vmax * (1 + 1e-12))
    if np.all(np.abs(v) <= vmax):
        np.testing.assert_array_equal(out, v)
    else:
        assert np.isclose(np.max(np.abs(out) / vmax), 1.0)
        # same direction: out = s v with 0 < s <= 1
        s = float(out @ v / (v @ v))
        assert 0 < s <= 1
        np.testing.assert_allclose(out, s * v, rtol=0, atol=1e-12)


def test_actuator_bounds_cover_the_joint_range() -> None:
    lo, hi = actuator_bounds(PARAMS)
    rng = np.random.default_rng(3)
    plo, phi_ = psi_bounds(PARAMS)
    plo, phi_ = np.where(np.isinf(plo), -math.pi, plo), np.where(np.isinf(phi_), math.pi, phi_)
    for _ in range(200):
        q = rng.uniform(plo, phi_)
        a = actuators_from_psi(PARAMS, q)
        assert np.all(a >= lo - 1e-15) and np.all(a <= hi + 1e-15)
    a = actuators_from_psi(PARAMS, [0, 0, PARAMS.theta_max[0], 0, PARAMS.theta_max[1], 0])
    assert a[2] == pytest.approx(hi[2]) and a[4] == pytest.approx(hi[4])
