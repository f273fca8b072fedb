"""Actuation map psi <-> [phi, d, s1a, s1b, s2a, s2b]: round trip, sign convention, Jacobian."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wristmark.models.actuation import (
    ACTUATOR_NAMES,
    actuator_jacobian,
    actuators_from_psi,
    psi_from_actuators,
)
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams

PARAMS = RobotParams()
SEEDED = settings(max_examples=80, derandomize=True, deadline=None)

psis = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(0.0, 0.15),
    st.floats(1e-6, PARAMS.theta_max[0]),
    st.floats(-math.pi, math.pi, exclude_min=True),
    st.floats(1e-6, PARAMS.theta_max[1]),
    st.floats(-math.pi, math.pi, exclude_min=True),
).map(np.array)


@SEEDED
@given(psis)
def test_round_trip_psi_actuators_psi(psi: np.ndarray) -> None:
    back = psi_from_actuators(PARAMS, actuators_from_psi(PARAMS, psi))
    np.testing.assert_allclose(back[[0, 1, 2, 4]], psi[[0, 1, 2, 4]], rtol=0, atol=1e-14)
    # delta is recovered up to rounding amplified by 1/theta (theta >= 1e-6 here)
    dd = np.angle(np.exp(1j * (back[[3, 5]] - psi[[3, 5]])))
    np.testing.assert_allclose(dd, 0.0, atol=1e-9)


def test_classic_multi_backbone_form_and_sign() -> None:
    r1, r2 = PARAMS.backbone_radius
    a = actuators_from_psi(PARAMS, [0.1, 0.02, 0.5, 0.3, 1.0, -2.0])
    assert tuple(ACTUATOR_NAMES) == ("phi", "d", "s1a", "s1b", "s2a", "s2b")
    np.testing.assert_allclose(a[:2], [0.1, 0.02])
    # s = r_b theta cos(delta - sigma') with backbones at sigma' = 0 and -90 deg
    s1 = [r1 * 0.5 * math.cos(0.3), r1 * 0.5 * math.cos(0.3 + math.pi / 2)]
    np.testing.assert_allclose(a[2:4], s1)
    np.testing.assert_allclose(a[4:], [r2 * math.cos(-2.0), r2 * math.cos(-2.0 + math.pi / 2)])
    # bending towards +x of {tb} (delta = 0) pulls the backbone on +x: s_a > 0, s_b = 0
    b = actuators_from_psi(PARAMS, [0, 0, 1.0, 0.0, 0, 0])
    assert b[2] > 0 and b[3] == 0.0


def test_straight_segment_takes_delta_from_hint() -> None:
    a = actuators_from_psi(PARAMS, [0.0, 0.01, 0.0, 1.3, 0.0, -0.7])
    np.testing.assert_array_equal(a[2:], 0.0)
    q = psi_from_actuators(PARAMS, a, delta_hint=[0, 0, 0, 1.3, 0, -0.7])
    np.testing.assert_array_equal(q, [0.0, 0.01, 0.0, 1.3, 0.0, -0.7])
    q0 = psi_from_actuators(PARAMS, a)
    assert q0[3] == 0.0 and q0[5] == 0.0


@SEEDED
@given(psis)
def test_actuator_jacobian_vs_central_differences(psi: np.ndarray) -> None:
    h = 1e-5  # truncation ~h^2 r_b ~ 1e-13, rounding ~eps |psi| / h ~ 1e-10
    J = actuator_jacobian(PARAMS, psi)

    def a_of(q: np.ndarray) -> np.ndarray:
        return actuators_from_psi(PARAMS, q)

    Jfd = np.column_stack([(a_of(psi + h * e) - a_of(psi - h * e)) / (2 * h) for e in np.eye(6)])
    np.testing.assert_allclose(J, Jfd, rtol=0, atol=1e-9)  # [m/rad]


def test_bad_input_is_rejected() -> None:
    with pytest.raises(InputError, match="finite"):
        actuators_from_psi(PARAMS, [0, 0, math.nan, 0, 0, 0])
    with pytest.raises(InputError, match="6 entries"):
        psi_from_actuators(PARAMS, [0, 0, 0])
