"""One constant-curvature segment: closed form vs the paper's equation, limits, Jacobians."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wristmark.models.constant_curvature import (
    f_g,
    rot_y,
    rot_z,
    segment_jacobian,
    segment_point,
    segment_pose,
    segment_transform,
)
from wristmark_testing.reference_chain import segment, segment_eq1

SEEDED = settings(max_examples=80, derandomize=True, deadline=None)
lengths = st.floats(0.005, 0.2)
thetas = st.one_of(
    st.floats(0.0, math.pi), st.sampled_from([0.0, 1e-10, 1e-6, 9.99e-4, 1e-3, 1.001e-3, math.pi])
)
deltas = st.floats(-2 * math.pi, 2 * math.pi)


def _series(t: float) -> tuple[float, float, float, float]:
    """f, g, f', g' from 25 Taylor terms summed with fsum (reference for |t| <= 1)."""
    fac = math.factorial
    f = math.fsum((-1) ** k * t ** (2 * k + 1) / fac(2 * k + 2) for k in range(25))
    g = math.fsum((-1) ** k * t ** (2 * k) / fac(2 * k + 1) for k in range(25))
    df = math.fsum((-1) ** k * (2 * k + 1) * t ** (2 * k) / fac(2 * k + 2) for k in range(25))
    dg = math.fsum((-1) ** k * 2 * k * t ** (2 * k - 1) / fac(2 * k + 1) for k in range(1, 25))
    return f, g, df, dg


@SEEDED
@given(st.one_of(st.floats(-1.0, 1.0), st.sampled_from([0.0, 1e-10, 0.2, 0.2 - 1e-16, -0.2])))
def test_f_g_to_a_few_ulp_of_a_long_series(t: float) -> None:
    ref = _series(t)
    for got, want in zip(f_g(t), ref):
        # relative 2e-14 covers the direct g' = (cos t - g)/t just above the switch at 0.2
        assert got == pytest.approx(want, rel=2e-14, abs=1e-300)


@SEEDED
@given(st.floats(1.0, 3.2))
def test_f_g_match_direct_formulas_away_from_zero(t: float) -> None:
    f, g, df, dg = f_g(t)
    assert f == pytest.approx((1 - math.cos(t)) / t, rel=1e-14)
    assert g == pytest.approx(math.sin(t) / t, rel=1e-14, abs=1e-16)
    assert df == pytest.approx((t * math.sin(t) - 1 + math.cos(t)) / t**2, rel=1e-14)
    assert dg == pytest.approx((t * math.cos(t) - math.sin(t)) / t**2, rel=1e-14)


def test_f_g_is_exact_at_zero_and_tiny_theta() -> None:
    assert f_g(0.0) == (0.0, 1.0, 0.5, 0.0)
    f, g, df, dg = f_g(1e-10)
    assert f == pytest.approx(0.5e-10, rel=1e-15)
    assert g == 1.0 and df == 0.5
    assert dg == pytest.approx(-1e-10 / 3, rel=1e-15)


@SEEDED
@given(st.floats(-2.0, 2.0))
def test_f_g_derivatives_vs_central_differences(t: float) -> None:
    h = 1e-6
    fp, gp, _, _ = f_g(t + h)
    fm, gm, _, _ = f_g(t - h)
    _, _, df, dg = f_g(t)
    # error O(h^2) + O(eps/h) ~ 1e-10
    assert df == pytest.approx((fp - fm) / (2 * h), abs=1e-8)
    assert dg == pytest.approx((gp - gm) / (2 * h), abs=1e-8)


def test_rotations_follow_right_hand_rule() -> None:
    np.testing.assert_allclose(rot_z(math.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rot_y(math.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-15)


@SEEDED
@given(lengths, thetas, deltas)
def test_segment_matches_independent_chord_form(L: float, theta: float, delta: float) -> None:
    T = segment_transform(L, theta, delta)
    ref = segment(L, theta, delta)
    np.testing.assert_allclose(T[:3, 3], ref[:3, 3], rtol=0, atol=1e-15)  # [m]
    np.testing.assert_allclose(T[:3, :3], ref[:3, :3], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    R, p = segment_pose(L, theta, delta)
    np.testing.assert_array_equal(np.reshape(R, (3, 3)), T[:3, :3])
    np.testing.assert_array_equal(p, T[:3, 3])


@SEEDED
@given(lengths, st.floats(0.05, math.pi), deltas)
def test_segment_matches_paper_equation_1(L: float, theta: float, delta: float) -> None:
    np.testing.assert_allclose(
        segment_transform(L, theta, delta), segment_eq1(L, theta, delta), rtol=0, atol=1e-15
    )


def test_straight_segment_is_a_translation_along_z() -> None:
    for theta in (0.0, 1e-10):
        T = segment_transform(0.1, theta, 0.7)
        np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-10)
        np.testing.assert_allclose(T[:3, 3], [0, 0, 0.1], atol=1e-11)
    np.testing.assert_array_equal(segment_transform(0.1, 0.0, 0.7)[:3, :3], np.eye(3))


def test_quarter_bend_in_plane_zero_ends_at_radius() -> None:
    L = 0.1
    r = L / (math.pi / 2)  # bending radius [m]
    T = segment_transform(L, math.pi / 2, 0.0)
    np.testing.assert_allclose(T[:3, 3], [r, 0, r], atol=1e-15)
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-15)  # end tangent along +x


def test_segment_point_runs_along_the_arc() -> None:
    L, th, de = 0.08, 1.2, -0.4
    np.testing.assert_allclose(segment_point(L, th, de, 0.0), 0.0, atol=0)
    np.testing.assert_allclose(segment_point(L, th, de, 1.0), segment_transform(L, th, de)[:3, 3])
    centre = (L / th) * np.array([math.cos(de), -math.sin(de), 0.0])  # centre of the arc
    for s in np.linspace(0, 1, 7):
        assert np.linalg.norm(segment_point(L, th, de, s) - centre) == pytest.approx(L / th)


@SEEDED
@given(lengths, thetas, deltas)
def test_segment_jacobian_vs_central_differences(L: float, theta: float, delta: float) -> None:
    h = 1e-6
    Jv, Jw = segment_jacobian(L, theta, delta)
    for j, (dt, dd) in enumerate(((h, 0.0), (0.0, h))):
        Tp = segment_transform(L, theta + dt, delta + dd)
        Tm = segment_transform(L, theta - dt, delta - dd)
        v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
        np.testing.assert_allclose(Jv[:, j], v, rtol=0, atol=1e-9)  # [m/rad]
        np.testing.assert_allclose(Jw[:, j], w, rtol=0, atol=1e-8)  # [rad/rad]
