"""The HTM fit's window (cvs.corners.subpixel.htm_radius, htm_refine's ``window_sigmas``,
DetectorSettings.refine_window_sigmas): at least 1.5 sigma of its Gaussian weights, so that a
blurred corner is not fitted from its flat centre alone."""

from __future__ import annotations

import numpy as np
import pytest

from tests.cvs.corners.test_corner_detector import synthetic_corner
from wristmark.cvs.corners.subpixel import htm_radius, htm_refine, htm_weight_sigma
from wristmark.cvs.corners.xcorners import DetectorSettings
from wristmark.models.errors import InputError

EDGES = (np.radians(92.0), np.radians(3.0))


def test_the_window_covers_one_and_a_half_sigma_of_the_weights_and_never_less_than_the_radius() -> None:
    spacing = np.array([10.0, 22.0, 23.0, 27.0, 28.0, 40.0, 80.0])
    sw = htm_weight_sigma(spacing)  # 1.5, 2.64, 2.76, 3.24, 3.36, 4, 4 px
    assert htm_radius(sw, 4, 1.5).tolist() == [4, 4, 5, 5, 6, 6, 6]
    assert htm_radius(sw, 4, 0.0).tolist() == [4] * 7  # 0: the radius for every corner
    assert htm_radius(4.0, 7, 1.5).tolist() == [7]  # the radius is the least window


def test_a_window_per_corner_gives_each_corner_the_fit_of_its_own_window() -> None:
    """Corners of two window sizes fitted in one call land where each lands alone."""
    centres = [(20.3, 19.8), (60.6, 20.4)]
    img = np.hstack([synthetic_corner((20.3, 19.8), *EDGES, blur=2.0, noise=1.5, seed=1),
                     synthetic_corner((19.6, 20.4), *EDGES, blur=2.0, noise=1.5, seed=2)])  # 41 px each
    start = np.array([[20.0, 20.0], [60.0, 20.0]])
    edges = np.array([EDGES, EDGES]) + 0.05
    sw = np.array([2.0, 4.0])  # windows of 4 and 6 px at 1.5 sigma
    both, _, ok = htm_refine(img, start, edges, 4, sw, window_sigmas=1.5)
    assert ok.all()
    for k, r in enumerate((4, 6)):
        alone, _, _ = htm_refine(img, start[k:k + 1], edges[k:k + 1], r, float(sw[k]))
        assert np.array_equal(both[k], alone[0])
    assert np.hypot(*(both[1] - centres[1])) < 0.1


def test_a_blurred_corner_is_fitted_closer_in_a_window_of_one_and_a_half_sigma() -> None:
    """A corner blurred by 2 px (defocus: a circle of confusion of ~5 px), 4 px weights: the
    9 x 9 window ends at one sigma of them, the 13 x 13 at 1.5. Measured: 0.075 -> 0.044 px RMS."""
    rng = np.random.default_rng(7)
    err: dict[float, list[float]] = {0.0: [], 1.5: []}
    for k in range(40):
        c = (20.0 + rng.uniform(-0.5, 0.5), 20.0 + rng.uniform(-0.5, 0.5))
        g = synthetic_corner(c, *EDGES, blur=2.0, noise=3.0, seed=k)
        for window in err:
            ref, _, ok = htm_refine(g, np.array([[20.0, 20.0]]), np.array([EDGES]) + 0.05, 4, 4.0,
                                    window_sigmas=window)
            assert ok.tolist() == [True]
            err[window].append(float(np.hypot(*(ref[0] - c))))
    rms = {w: float(np.sqrt(np.mean(np.square(e)))) for w, e in err.items()}
    assert rms[1.5] < 0.85 * rms[0.0], rms


@pytest.mark.parametrize("value", [-1.0, float("nan")])
def test_a_negative_or_nan_window_is_refused(value: float) -> None:
    with pytest.raises(InputError, match="refine_window_sigmas"):
        DetectorSettings(refine_window_sigmas=value)
