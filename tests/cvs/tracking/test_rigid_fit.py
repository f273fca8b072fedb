"""cvs.tracking.rigid_fit: start poses from corresponding points."""

from __future__ import annotations

import numpy as np
import pytest

from wristmark.cvs.tracking.rigid_fit import chord_starts


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_chord_starts_put_both_points_on_their_observations_and_one_is_near_the_truth(seed: int) -> None:
    rng = np.random.default_rng(seed)
    P = rng.normal(scale=0.005, size=(2, 3))  # [m]
    R, t = _rotation(rng.normal(size=3), rng.uniform(0, np.pi)), rng.normal(scale=0.05, size=3)
    X = P @ R.T + t
    starts = chord_starts(P, X, 12)
    assert len(starts) == 12
    for T in starts:
        np.testing.assert_allclose(P @ T[:3, :3].T + T[:3, 3], X, atol=1e-12)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    err = [np.degrees(np.arccos(np.clip((np.trace(T[:3, :3].T @ R) - 1) / 2, -1, 1))) for T in starts]
    assert min(err) <= 15.0 + 1e-9  # half the 30 deg step about the chord


def test_chord_starts_of_opposite_chords() -> None:
    P = np.array([[0.0, 0, 0], [0.01, 0, 0]])
    X = np.array([[0.01, 0, 0.1], [0.0, 0, 0.1]])  # the same chord, reversed: a half turn
    for T in chord_starts(P, X, 4):
        np.testing.assert_allclose(P @ T[:3, :3].T + T[:3, 3], X, atol=1e-12)
