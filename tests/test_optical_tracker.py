"""OpticalTracker: seeded, unbiased, 3D RMS within statistical bounds."""

from __future__ import annotations

import math

import numpy as np

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
