"""models.arm_actuation: the actuation map of any arm, its inverse and its Jacobian.

The reference arm against today's models.actuation; round trips on every shipped arm and on
random arms; the Jacobian against finite differences; the tendons' coupling and least squares.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.models.arm_strategies import psis, robot_files, spec_of
from wristmark.models.actuation import actuator_jacobian, actuators_from_psi, psi_from_actuators
from wristmark.models.arm_actuation import arm_actuator_jacobian, arm_actuators, arm_psi_from_actuators
from wristmark.models.arm_spec import ArmSpec, load_arm, shipped_robot_files
from wristmark.models.errors import InputError
from wristmark.models.robot_params import RobotParams

PARAMS = RobotParams()
ROBOTS = {p.name: load_arm(p) for p in shipped_robot_files()}
REFERENCE = [ArmSpec.from_params(PARAMS), ROBOTS["paper.yaml"]]
SEEDED = settings(max_examples=60, derandomize=True, deadline=None,
                  suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _random_psis(spec: ArmSpec, count: int, seed: int = 3) -> np.ndarray:
    lo, hi = spec.bounds()
    lo, hi = np.maximum(lo, -math.pi), np.minimum(hi, math.pi)
    q = np.random.default_rng(seed).uniform(lo, hi, (count, spec.n))
    for t, i in enumerate(spec.theta_index):  # straight, nearly straight segments
        q[t, i] = 0.0
        q[t + 4, i] = 1e-9
    return q


def _same_configuration(spec: ArmSpec, got: np.ndarray, want: np.ndarray, atol: float) -> None:
    """theta and the stem equal; delta equal modulo 2 pi where its segment bends."""
    th = list(spec.theta_index)
    plain = [i for i in range(spec.n) if i not in spec.delta_index]
    np.testing.assert_allclose(got[..., plain], want[..., plain], rtol=0, atol=atol)
    for ti, di in zip(th, spec.delta_index):
        if di is None:
            continue
        bent = np.abs(want[..., ti]) > 1e-6
        diff = np.remainder(got[..., di] - want[..., di] + math.pi, 2 * math.pi) - math.pi
        assert np.all(np.abs(diff[bent]) < atol * 1e3), (got, want)


@pytest.mark.parametrize("spec", REFERENCE, ids=["format 1", "paper.yaml"])
def test_the_reference_arm_equals_todays_map(spec: ArmSpec) -> None:
    assert spec.actuator_names == ("phi", "d", "s1a", "s1b", "s2a", "s2b")
    batch = _random_psis(spec, 100)
    a_batch = arm_actuators(spec, batch)
    for k, psi in enumerate(batch):
        a = actuators_from_psi(PARAMS, psi)
        np.testing.assert_allclose(arm_actuators(spec, psi), a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a_batch[k], a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(arm_actuator_jacobian(spec, psi), actuator_jacobian(PARAMS, psi), rtol=0,
                                   atol=1e-12)
        hint = np.array([0, 0, 0, 0.3, 0, -0.4])
        np.testing.assert_allclose(arm_psi_from_actuators(spec, a, hint), psi_from_actuators(PARAMS, a, hint),
                                   rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_round_trip_on_every_shipped_arm(name: str) -> None:
    spec = ROBOTS[name]
    q = _random_psis(spec, 200)
    a = arm_actuators(spec, q)
    assert a.shape == (200, spec.m)
    back = arm_psi_from_actuators(spec, a, q)
    _same_configuration(spec, back, q, 1e-12)
    np.testing.assert_allclose(arm_actuators(spec, back), a, rtol=0, atol=1e-15)  # [m]
    for k in (0, 5, 17):
        _same_configuration(spec, arm_psi_from_actuators(spec, a[k], q[k]), back[k], 1e-15)  # one = batch


def _finite_difference(spec: ArmSpec, psi: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(spec.n):
        e = np.zeros(spec.n)
        e[i] = h
        cols.append((arm_actuators(spec, psi + e) - arm_actuators(spec, psi - e)) / (2 * h))
    return np.array(cols).T


@SEEDED
@given(data=st.data(), robot=robot_files())
def test_random_arms_round_trip_and_jacobian(tmp_path: Path, data: st.DataObject, robot: dict) -> None:  # type: ignore[type-arg]
    spec = spec_of(robot, tmp_path)
    psi = data.draw(psis(spec))
    a = arm_actuators(spec, psi)
    assert a.shape == (spec.m,)
    back = arm_psi_from_actuators(spec, a, psi)
    _same_configuration(spec, back, psi, 1e-9)
    np.testing.assert_allclose(arm_actuators(spec, back), a, rtol=0, atol=1e-14)
    J = arm_actuator_jacobian(spec, psi)
    assert J.shape == (spec.m, spec.n)
    np.testing.assert_allclose(J, _finite_difference(spec, psi), rtol=0, atol=1e-8)
    np.testing.assert_allclose(arm_actuator_jacobian(spec, np.stack([psi, psi]))[1], J, rtol=0, atol=0)


def test_tendons_are_coupled_and_backbones_are_not() -> None:
    tendon3 = ROBOTS["tendon3.yaml"]  # d, theta1, delta1, theta2, delta2, theta3, delta3
    q = np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    bent = q.copy()
    bent[1:3] = [0.8, 0.4]  # bend segment 1 only
    da = arm_actuators(tendon3, bent) - arm_actuators(tendon3, q)
    r, s1 = 0.0022, np.array(tendon3.segments[1].actuation.angles)
    np.testing.assert_allclose(da[4:7], r * 0.8 * np.cos(0.4 + s1), rtol=1e-14)  # segment 2's tendons move
    assert np.all(np.abs(da[7:10]) > 1e-5)  # and segment 3's
    paper = ROBOTS["paper.yaml"]
    p0 = np.array([0.0, 0.05, 0.0, 0.0, 0.5, 1.0])
    p1 = p0.copy()
    p1[2:4] = [0.8, 0.4]
    np.testing.assert_array_equal(arm_actuators(paper, p1)[4:], arm_actuators(paper, p0)[4:])  # decoupled


def test_tendon_least_squares_ignores_a_common_stretch() -> None:
    """Three tendons 120 deg apart: stretching all of a segment's tendons alike changes no bend."""
    spec = ROBOTS["tendon3.yaml"]
    q = np.array([0.05, 0.7, 1.0, 0.4, -2.0, 1.1, 0.3])
    a = arm_actuators(spec, q)
    a[4:7] += 1e-4  # segment 2's tendons, all alike
    np.testing.assert_allclose(arm_psi_from_actuators(spec, a), q, rtol=0, atol=1e-12)


def test_direct_and_planar_segments() -> None:
    planar = ROBOTS["planar.yaml"]  # phi, d, theta1 (push-pull pair), theta2 (direct)
    q = np.array([0.3, 0.04, -0.6, 1.2])
    a = arm_actuators(planar, q)
    np.testing.assert_allclose(a, [0.3, 0.04, -0.0018 * 0.6, 0.0018 * 0.6, 1.2], rtol=1e-14)
    np.testing.assert_allclose(arm_psi_from_actuators(planar, a), q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(arm_actuator_jacobian(planar, q)[2:, 2:], [[0.0018, 0], [-0.0018, 0], [0, 1]],
                               rtol=0, atol=1e-18)


def test_straight_segments_take_delta_from_the_hint() -> None:
    spec = ROBOTS["single_tendon.yaml"]
    a = arm_actuators(spec, [0.1, 0.02, 0.0, 2.0])
    assert arm_psi_from_actuators(spec, a)[3] == 0.0
    assert arm_psi_from_actuators(spec, a, [0, 0, 0, 2.5])[3] == 2.5


@pytest.mark.parametrize("bad, words", [([0.0] * 5, "6 entries"), ([0, 0, math.inf, 0, 0, 0], "finite")])
def test_bad_actuators_are_input_errors(bad: list[float], words: str) -> None:
    with pytest.raises(InputError, match=words):
        arm_psi_from_actuators(ROBOTS["paper.yaml"], bad)
    with pytest.raises(InputError, match="psi must have 6"):
        arm_actuators(ROBOTS["paper.yaml"], [0.0] * 4)
