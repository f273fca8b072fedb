"""What a trajectory asks of the tip frame's orientation (docs/design.md, "Orientation in the loop").

Modes: ``none`` (position only, as the paper), ``hold`` (the tip frame's orientation at the
start, kept while the tip walks the path) and ``follow`` (our definition; docs/design.md only names
it): the orientation the nominal model gives the tip frame along the path when the tip follows
it by position-only IK from the start (what the open loop of a position trajectory commands),
so that the closed loop turns the true tool as the plan turns it. The start's orientation is the
nominal model's tip frame at the start configuration (position IK of the first waypoint from
home). Rotations map the tip frame's axes into {w}; angular velocities [rad/s] are in {w}.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from wristmark.models.arm_spec import Arm, home_psi
from wristmark.models.errors import ConfigError
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics

Array = NDArray[np.float64]
ORIENTATION_MODES = ("none", "hold", "follow")
FOLLOW_STEP_S = 0.05  # [s] sampling of the position-IK path that ``follow`` interpolates


def check_orientation_mode(mode: str, controller_kind: str) -> str:
    """``mode`` if it names an orientation mode the controller ``controller_kind`` can control
    (ConfigError otherwise: the paper's controller is position-only, as the paper defines it)."""
    if mode not in ORIENTATION_MODES:
        raise ConfigError(f"orientation must be one of {', '.join(ORIENTATION_MODES)}, got {mode!r}")
    if mode != "none" and controller_kind == "paper":
        raise ConfigError(f"--orientation {mode} needs --controller qp: the paper controller is "
                          "position-only (eq. 17-21), as the paper defines it")
    return mode


@dataclass(frozen=True)
class OrientationPath:
    """Desired tip-frame orientations at ``times`` (N,) [s], slerp-interpolated, held at the ends."""

    mode: str
    times: Array
    rotations: Array  # (N, 3, 3)

    def sample(self, t: float) -> tuple[Array, Array]:
        """Desired rotation (3x3) and angular velocity (3,) [rad/s] in {w} at time ``t`` [s]."""
        ts = self.times
        if len(ts) == 1 or t <= ts[0] or t >= ts[-1]:
            i = 0 if len(ts) == 1 or t <= ts[0] else len(ts) - 1
            return self.rotations[i].copy(), np.zeros(3)
        R = self._slerp([t]).as_matrix()[0]
        i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2))
        step = Rotation.from_matrix(self.rotations[i + 1] @ self.rotations[i].T).as_rotvec()
        return np.asarray(R, float), np.asarray(step / (ts[i + 1] - ts[i]), float)

    @cached_property
    def _slerp(self) -> Slerp:
        return Slerp(self.times, Rotation.from_matrix(self.rotations))

    def shifted(self, duration: float) -> OrientationPath:
        """The same path cut to its first ``duration`` [s] (kept as is when shorter)."""
        keep = self.times <= duration
        if keep.all():
            return self
        R_end = self.sample(duration)[0]
        return OrientationPath(self.mode, np.append(self.times[keep], duration),
                               np.concatenate([self.rotations[keep], R_end[None]]))


def start_configuration(params: Arm, p_start: Array) -> Array:
    """The start configuration of a path: position IK of its first point from home."""
    return solve_tip_ik(params, np.asarray(p_start, float), home_psi(params)).psi


def orientation_path(mode: str, params: Arm, positions: object, duration: float) -> OrientationPath | None:
    """The orientation a trajectory asks for: None for ``none``; ``positions(t)`` gives the
    desired tip [m] at time t [s] along a path of ``duration`` [s] (``follow`` samples it every
    FOLLOW_STEP_S)."""
    if mode not in ORIENTATION_MODES:
        raise ConfigError(f"unknown orientation mode {mode!r}; valid: {', '.join(ORIENTATION_MODES)}")
    if mode == "none":
        return None
    assert callable(positions)
    psi = start_configuration(params, positions(0.0))
    R0 = forward_kinematics(params, psi).T_world_tip[:3, :3]
    if mode == "hold":
        return OrientationPath(mode, np.zeros(1), R0[None].copy())
    ts = np.append(np.arange(0.0, duration, FOLLOW_STEP_S), duration)
    rots = []
    for t in ts:
        psi = solve_tip_ik(params, positions(float(t)), psi).psi
        rots.append(forward_kinematics(params, psi).T_world_tip[:3, :3])
    return OrientationPath(mode, ts, np.asarray(rots))
