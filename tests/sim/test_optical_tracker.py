"""OpticalTracker: seeded, unbiased, 3D RMS within statistical bounds; its 6-DoF orientation noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wristmark.sim.optical_tracker import OpticalTracker

P = np.array([0.01, -0.02, 0.15])


def _noise(tracker: OpticalTracker, n: int) -> np.ndarray:
    return np.array([tracker.measure(P) - P for _ in range(n)])


def test_rms_within_statistical_bounds() -> None:
    rms, n = 0.12e-3, 20000
    e = _noise(OpticalTracker(rms=rms, seed=3), n)
    est = math.sqrt(float(np.mean(np.sum(e**2, axis=1))))
    # mean of |e|^2 = rms^2 chi2(3)/3 has relative std sqrt(2/(3n)); 5 sigma, halved for the sqrt
    assert abs(est / rms - 1.0) < 5 * math.sqrt(2.0 / (3 * n)) / 2
    sigma = rms / math.sqrt(3.0)
    per_axis = np.sqrt(np.mean(e**2, axis=0))
    assert np.all(np.abs(per_axis / sigma - 1.0) < 5 * math.sqrt(2.0 / n) / 2)
    assert np.all(np.abs(e.mean(axis=0)) < 5 * sigma / math.sqrt(n))


def test_seeded_and_reproducible() -> None:
    a = _noise(OpticalTracker(seed=5), 10)
    b = _noise(OpticalTracker(seed=5), 10)
    c = _noise(OpticalTracker(seed=6), 10)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_configurable_rms() -> None:
    e = _noise(OpticalTracker(rms=1e-3, seed=1), 4000)
    assert 0.9e-3 < math.sqrt(float(np.mean(np.sum(e**2, axis=1)))) < 1.1e-3
    np.testing.assert_array_equal(OpticalTracker(rms=0.0).measure(P), P)


R0 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.slow
def test_six_dof_orientation_noise_statistics() -> None:
    """Vega class: the orientation error's RMS angle is 0.2 deg, isotropic and unbiased."""
    from wristmark.models.so3 import angle_between, rotation_error

    rms, n = np.deg2rad(0.2), 20000
    tracker = OpticalTracker(seed=4)
    assert tracker.rotation_rms == rms and tracker.rms == 0.12e-3
    Rs = [tracker.measure_pose(P, R0)[1] for _ in range(n)]
    for R in Rs[:50]:
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)  # proper rotations
        assert np.linalg.det(R) > 0.999
    ang = np.array([angle_between(R, R0) for R in Rs])
    assert abs(math.sqrt(float(np.mean(ang**2))) / rms - 1.0) < 5 * math.sqrt(2.0 / (3 * n)) / 2
    # the mean angle of a Maxwell distribution is rms sqrt(8 / (3 pi)) (0.184 deg here)
    assert float(np.mean(ang)) == pytest.approx(rms * math.sqrt(8 / (3 * math.pi)), rel=0.02)
    vec = np.array([rotation_error(R, R0) for R in Rs])  # the noise rotation vector in {w}
    sigma = rms / math.sqrt(3.0)
    assert np.all(np.abs(np.sqrt(np.mean(vec**2, axis=0)) / sigma - 1.0) < 5 * math.sqrt(2.0 / n) / 2)
    assert np.all(np.abs(vec.mean(axis=0)) < 5 * sigma / math.sqrt(n))


def test_pose_measurement_keeps_the_position_noise_stream() -> None:
    """The position noise of measure_pose is that of measure with the same seed (results of
    position-only runs do not move when the tracker also measures the orientation)."""
    a, b = OpticalTracker(seed=9), OpticalTracker(seed=9, rotation_rms=0.0)
    for _ in range(5):
        p, R = b.measure_pose(P, R0)
        np.testing.assert_array_equal(a.measure(P), p)
        np.testing.assert_array_equal(R, R0)  # rotation_rms 0: exact
    with pytest.raises(ValueError, match="rotation rms"):
        OpticalTracker(rotation_rms=-1.0)
