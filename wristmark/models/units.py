"""Unit constants shared by the layers: the actuator wire's resolution (docs/design.md, the serial
protocol) is one micro-unit of the SI unit (1 urad, 1 um)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

MICRO = 1e6  # micro-units per SI unit (urad per rad, um per m)


def on_micro_grid(x: ArrayLike) -> NDArray[np.float64]:
    """``x`` [rad, m] rounded to the wire's micro-units (1 urad, 1 um), still in SI units: a value
    read through the serial link and one taken in process then agree."""
    return np.rint(np.asarray(x, float) * MICRO) / MICRO
