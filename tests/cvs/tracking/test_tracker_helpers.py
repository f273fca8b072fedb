"""cvs.tracking.tracker's small helpers: the exact median, and tip_sigma's built-once steps."""

from __future__ import annotations

import numpy as np

from wristmark.cvs.tracking.tracker import _median, _median_spacing


def test_median_is_numpys_to_the_bit() -> None:
    rng = np.random.default_rng(5)
    for n in range(1, 40):
        for _ in range(50):
            x = rng.uniform(0.0, 80.0, n) * rng.choice([1e-3, 1.0, 1e3])
            assert np.float64(_median(x)).tobytes() == np.float64(np.median(x)).tobytes()
    assert np.isnan(_median(np.array([1.0, np.nan, 3.0])))  # numpy's own answer where not finite
    assert _median(np.array([np.inf, 1.0, 2.0])) == np.median([np.inf, 1.0, 2.0]) == 2.0


def test_median_spacing_of_chains() -> None:
    a = np.array([[0.0, 0.0], [3.0, 4.0], [6.0, 8.0]])
    b = np.array([[0.0, 0.0], [0.0, 2.0]])
    assert _median_spacing(a, b) == 5.0 and _median_spacing(a[:1]) == float("inf")


def test_tip_sigmas_steps_are_the_perturbations_it_built_each_call() -> None:
    from wristmark.cvs.tracking import tip_uncertainty as tu

    for i in range(3):
        w, v = np.zeros(3), np.zeros(3)
        w[i], v[i] = 1e-6, 1e-7
        assert (np.eye(3) + tu._skew(w)).tobytes() == tu._TURNS[i].tobytes()
        assert v.tobytes() == tu._SHIFTS[i].tobytes()
    assert tu._STEPS.tobytes() == np.array([1e-6] * 3 + [1e-7] * 3).tobytes()
