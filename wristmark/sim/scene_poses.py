"""Random configurations of a scene's arms (``wristmark render --scene``, bench/several_arms.py)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import ArmSpec, home_psi
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import psi_bounds
from wristmark.rig.targets.trajectories import workspace_centre

Array = NDArray[np.float64]

__all__ = ["random_tip_psi"]


def random_tip_psi(params: Any, size: tuple[float, float, float], rng: np.random.Generator,
                   near: Array | None = None, step: float = 0.008, stem_roll: float = 0.3) -> Array:
    """A configuration [rad, m, ...] whose tip lies at random in the box of edges 1.5 ``size``
    [m] around the arm's workspace centre in its {w} (or within ``step`` [m] of the tip of the
    configuration ``near``), by the position IK from home (from ``near``); the reference arm's
    stem is also rolled at random by up to ``stem_roll`` [rad] first (its sleeve seen from other
    sides). Clamped to the joint limits."""
    if near is None:
        p = workspace_centre(params, size) + rng.uniform(-0.75, 0.75, 3) * np.asarray(size)
        q0 = home_psi(params).copy()
        if not isinstance(params, ArmSpec):
            q0[0] += rng.uniform(-stem_roll, stem_roll)
    else:
        p = forward_kinematics(params, near).tip + rng.uniform(-1.0, 1.0, 3) * step / np.sqrt(3)
        q0 = np.asarray(near, float)
    lo, hi = psi_bounds(params)
    return np.asarray(np.clip(solve_tip_ik(params, p, q0).psi, lo, hi), float)
