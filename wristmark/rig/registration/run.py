"""Collecting registration observations from any rig: move, settle, grab, track, read encoders.

A :class:`RegistrationRig` moves the arm and hands out stereo images: the simulated bench
(sim/registration_bench.py) or the actuator box over serial plus a frame source
(rig/registration/hardware.py). :func:`collect` visits every chosen pose twice, approached from
either side (rig.registration.poses.approach_offset), tracks the marker in {ll} each time and records an
:class:`Observation` per visit (the rows of the registration log, rig/registration/log.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import Arm, ArmSpec
from wristmark.models.kinematics import forward_kinematics
from wristmark.rig.registration.poses import approach_offset
from wristmark.solvers.registration import RegistrationPose

Array = NDArray[np.float64]


class RegistrationRig(Protocol):
    """What registration needs from a rig."""

    def move_to(self, psi: Array) -> None:
        """Move to configuration psi within the velocity limits and wait until settled."""

    def measured_psi(self) -> Array:
        """Configuration from the encoders now (psi of the arm) [rad, m]."""

    def grab(self) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """A stereo pair captured after the last move settled (left, right)."""


@dataclass(frozen=True)
class Observation:
    """One visit: pose index, approach side (-1/+1), commanded and measured psi, and the tracked
    pose of {wm} in {ll} (4x4 [m], None when not tracked: ``reason``), its RMS [px]."""

    pose: int
    approach: int
    psi_cmd: Array
    psi_meas: Array
    T_left_marker: Array | None
    rms_px: float = float("nan")
    reason: str = ""

    @property
    def ok(self) -> bool:
        """Whether the marker was tracked."""
        return self.T_left_marker is not None


def collect(rig: RegistrationRig, tracker: MarkerTracker, params: Arm, poses: list[Array],
            host_world_T_left: Array | None, progress: bool = True) -> list[Observation]:
    """Visit each pose from both sides and track the marker (hint: the model's axis, when the host
    has a world_T_left; else the tracker decides from the images)."""
    out = []
    step = approach_offset(params)
    visits = [(i, s) for i in range(len(poses)) for s in (-1, 1)]
    for i, side in tqdm(visits, desc="register", unit="visit", disable=not progress, leave=False):
        q = np.asarray(poses[i], float)
        rig.move_to(q + side * step)
        rig.move_to(q)
        meas = rig.measured_psi()
        left, right = rig.grab()
        hint = None
        if host_world_T_left is not None:
            hint = np.asarray(host_world_T_left)[:3, :3].T @ forward_kinematics(params, meas).T_world_marker[:3, 2]
        tracker.reset()
        res = tracker.track(left, right, axis_hint_left=hint)
        T = np.asarray(res.T_left_marker, float) if res.ok and res.T_left_marker is not None else None
        out.append(Observation(i, side, q, np.asarray(meas, float), T, float(res.rms_px), res.reason if T is None
                               else ""))
    return out


def registration_poses(params: Arm, observations: list[Observation]) -> list[RegistrationPose]:
    """The tracked observations as solver inputs (encoder psi, centre and z axis in {ll}); for any
    arm (an ArmSpec) also each actuator's last move, the sign of the one before it (from the
    previous visit's pose, in the order visited; unknown, 0, for the first) and the path of
    actuator targets since the first visit's approach point (the plays' state after them all)."""
    out = []
    previous: Array | None = None
    targets: list[Array] = []
    for o in map(as_logged, observations):
        start = np.asarray(o.psi_cmd, float) + o.approach * approach_offset(params)
        move = prior = path = None
        if isinstance(params, ArmSpec):
            a_start = actuators_from_psi(params, start)
            a_end = actuators_from_psi(params, o.psi_cmd)
            move = a_end - a_start
            prior = np.zeros_like(move) if previous is None else np.sign(a_start - actuators_from_psi(params, previous))
            targets += [a_start, a_end]
            path = np.array(targets)
        previous = np.asarray(o.psi_cmd, float)
        if o.T_left_marker is not None:
            out.append(RegistrationPose(o.psi_meas, o.T_left_marker[:3, 3], o.T_left_marker[:3, 2],
                                        f"pose {o.pose}{'-' if o.approach < 0 else '+'}", motion_sign(params, o),
                                        move, prior, path=path))
    return out


def as_logged(o: Observation) -> Observation:
    """``o`` with its configurations and pose to the registration log's 12 significant digits
    (rig.registration.log): the fit of a run and of its log (``--from-log``) then see the same
    numbers. They must: with any arm's plays the fit's cost has kinks (each dead band clips), and
    a difference in the 13th digit once sent tendon3's fit to another of its near-equal minima
    (14 um apart, 2026-12-03)."""
    def r(x: Array) -> Array:
        return np.array([float(f"{v:.12g}") for v in np.ravel(x)]).reshape(np.shape(x))
    T = None if o.T_left_marker is None else np.vstack([r(np.asarray(o.T_left_marker)[:3]), [0.0, 0.0, 0.0, 1.0]])
    return Observation(o.pose, o.approach, r(o.psi_cmd), r(o.psi_meas), T, o.rms_px, o.reason)


def motion_sign(params: Arm, o: Observation) -> Array:
    """Sign of each actuator's last motion before observation ``o``: from psi_cmd + approach *
    approach_offset(params) to psi_cmd."""
    a = actuators_from_psi(params, o.psi_cmd)
    return np.sign(a - actuators_from_psi(params, o.psi_cmd + o.approach * approach_offset(params)))
