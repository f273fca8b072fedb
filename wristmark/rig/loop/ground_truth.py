"""Ground truth the servo loop may log beside its own measurements, when someone can supply it.

Only the simulated bench knows where the arm truly is (:class:`sim.truth.SimulatedTruth`: the
true tip, its optical-tracker measurement, the true configuration). On hardware there is no
observer and the log's truth columns stay empty; the loop never uses the truth to control.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def _nan(n: int) -> Array:
    return np.full(n, np.nan)


@dataclass(frozen=True)
class TruthSample:
    """The truth at one instant: true tip and its optical-tracker measurement in {w} [m], true
    configuration psi [rad, m], the true tip frame's orientation and its tracker measurement in
    {w} (3x3); NaN where unknown."""

    p_true: Array = field(default_factory=lambda: _nan(3))
    p_trk: Array = field(default_factory=lambda: _nan(3))
    psi_true: Array = field(default_factory=lambda: _nan(6))
    R_true: Array = field(default_factory=lambda: np.full((3, 3), np.nan))
    R_trk: Array = field(default_factory=lambda: np.full((3, 3), np.nan))


NO_TRUTH = TruthSample()


class GroundTruth(Protocol):
    """An observer of the true arm (the simulated bench only)."""

    def observe(self) -> TruthSample:
        """The truth now: on the simulated bench, the instant of the cycle's capture (simulated
        time stands still while the host processes the frame)."""
        ...
