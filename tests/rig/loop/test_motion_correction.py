"""The compensation's learnt motion map: a known linear mismatch between the model's tip motion
and the arm's is recovered from noisy measurements; directions the motion never excites stay at
the identity; reused, far-apart, non-finite and absurd measurements do not corrupt it; the delay
compensation applies it to the model's motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wristmark.models.kinematics import tip_position
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.loop.delay_compensation import DelayCompensator
from wristmark.rig.loop.motion_correction import MotionCorrection

G = np.array([[1.06, 0.03, 0.0], [-0.03, 0.95, 0.02], [-0.07, 0.0, 1.01]])  # the arm's motion = G @ the model's
DT = 0.06  # [s] between frames
NOISE = 3e-5  # [m] per axis, the tracker's noise


def _feed(corr: MotionCorrection, model_steps: np.ndarray, seed: int = 0, t0: float = 0.0) -> None:
    """Observe the measured tips of an arm that moves G @ each model step (plus noise)."""
    rng = np.random.default_rng(seed)
    p_true = np.array([0.05, -0.01, 0.12])
    corr.observe(p_true + rng.normal(0, NOISE, 3), t0, None)
    for k, dp in enumerate(model_steps, start=1):
        p_true = p_true + G @ dp
        corr.observe(p_true + rng.normal(0, NOISE, 3), t0 + k * DT, dp)


def test_a_linear_mismatch_is_recovered_from_noisy_measurements() -> None:
    rng = np.random.default_rng(1)
    steps = rng.normal(0, 0.6e-3, (200, 3))  # ~1 mm per frame, every direction
    corr = MotionCorrection(window=5.0)
    _feed(corr, steps)
    assert corr.updates == 200
    np.testing.assert_allclose(corr.matrix, G, atol=0.02)
    dp = np.array([1e-3, -5e-4, 2e-4])
    np.testing.assert_allclose(corr.apply(dp), corr.matrix @ dp, rtol=0, atol=1e-18)


def test_a_held_arm_and_unexcited_directions_stay_at_the_identity() -> None:
    held = MotionCorrection()
    _feed(held, np.zeros((100, 3)))
    np.testing.assert_allclose(held.matrix, np.eye(3), atol=1e-12)
    along_x = MotionCorrection()
    _feed(along_x, np.tile([1e-3, 0.0, 0.0], (150, 1)))
    M = along_x.matrix
    np.testing.assert_allclose(M[:, 0], G[:, 0], atol=0.02)  # learnt where it moved
    np.testing.assert_allclose(M[:, 1:], np.eye(3)[:, 1:], atol=1e-12)  # the prior elsewhere


def test_it_forgets_an_old_mismatch_within_its_window() -> None:
    rng = np.random.default_rng(2)
    corr = MotionCorrection(window=2.0)
    _feed(corr, rng.normal(0, 0.6e-3, (150, 3)))  # 9 s of G
    p, t = np.array([0.05, -0.01, 0.12]), 150 * DT + 0.01
    corr.observe(p, t, None)  # (not paired: no model motion known)
    for k in range(1, 200):  # 12 s of a perfect model
        dp = rng.normal(0, 0.6e-3, 3)
        p = p + dp
        corr.observe(p, t + k * DT, dp)
    np.testing.assert_allclose(corr.matrix, np.eye(3), atol=0.01)


def test_reused_far_apart_non_finite_and_absurd_measurements() -> None:
    corr = MotionCorrection(max_gap=0.5, max_deviation=0.3)
    p = np.array([0.0, 0.0, 0.1])
    corr.observe(p, 1.0, None)
    corr.observe(p + [1e-3, 0, 0], 1.0, np.array([1e-3, 0, 0]))  # the same capture again: a reused frame
    corr.observe(p + [1e-3, 0, 0], 0.9, np.array([1e-3, 0, 0]))  # older
    corr.observe(np.array([math.nan, 0, 0.1]), 1.1, np.array([1e-3, 0, 0]))
    corr.observe(p + [5e-3, 0, 0], 1.7, np.array([1e-3, 0, 0]))  # 0.7 s after the last: not paired
    corr.observe(p + [5e-3, 0, 0], 1.76, np.array([math.nan, 0, 0]))
    assert corr.updates == 0 and np.array_equal(corr.matrix, np.eye(3))
    for k in range(1, 50):  # the arm "moves" three times what the model says: clipped
        corr.observe(p + [5e-3 + 3e-3 * k, 0, 0], 1.76 + 0.06 * k, np.array([1e-3, 0, 0]))
    assert corr.matrix[0, 0] == pytest.approx(1.3)
    corr.reset()
    assert corr.updates == 0 and np.array_equal(corr.matrix, np.eye(3)) and corr.last_capture == -math.inf
    with pytest.raises(ValueError, match="window"):
        MotionCorrection(window=0.0)
    with pytest.raises(ValueError, match="prior"):
        MotionCorrection(prior=math.nan)


def test_the_compensation_learns_from_the_model_between_captures_and_applies_the_map() -> None:
    P = RobotParams()
    psi_a = np.array(HOME_PSI, float)
    steps = [psi_a + k * np.array([0.01, 0.001, 0.02, 0.05 * (-1) ** k, -0.01, 0.03]) for k in range(30)]
    corrected = DelayCompensator(P, tau=0.0, correction=MotionCorrection(window=5.0))
    plain = DelayCompensator(P, tau=0.0)
    p_meas = tip_position(P, steps[0])
    for k, psi in enumerate(steps):  # a command at k*DT, a frame half a cycle later
        corrected.record(k * DT, psi)
        plain.record(k * DT, psi)
        if k:
            p_meas = p_meas + G @ (tip_position(P, psi) - tip_position(P, steps[k - 1]))
        corrected.observe(p_meas, k * DT + 0.03)
    assert corrected.correction is not None and corrected.correction.updates == len(steps) - 1
    np.testing.assert_allclose(corrected.correction.matrix, G, atol=0.02)
    corrected.record(len(steps) * DT, steps[-1] + 0.02)
    t_cap, t_now = (len(steps) - 1) * DT + 0.03, len(steps) * DT + 0.01
    plain.record(len(steps) * DT, steps[-1] + 0.02)
    model = plain.predicted_motion(t_cap, t_now)
    assert np.linalg.norm(model) > 1e-3
    np.testing.assert_allclose(corrected.compensate(p_meas, t_cap, t_now),
                               p_meas + corrected.correction.matrix @ model, rtol=0, atol=1e-15)
    corrected.reset()
    assert corrected.correction.updates == 0
