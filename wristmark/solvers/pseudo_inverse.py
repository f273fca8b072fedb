"""The singularity-robust pseudo-inverse of the paper's eq. 20, shared by the controller base
(its path rates) and the paper's controller."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def sr_pseudo_inverse(J: Array, gamma: float, xi: float) -> Array:
    """Eq. 20: damped pseudo-inverse when the smallest singular value is below xi."""
    s = np.linalg.svd(J, compute_uv=False)
    if s[-1] < xi:
        return np.asarray(J.T @ np.linalg.inv(J @ J.T + gamma * np.eye(J.shape[0])), float)
    return np.asarray(np.linalg.pinv(J), float)
