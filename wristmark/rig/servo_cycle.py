"""What one cycle and one phase of the servo loop (rig.servo_loop) carry: the cycle's target,
the closed loop's memory across cycles, a cycle's outcome, the phase's counters, the errors that
stop a phase, and the ramp that joins two configurations within the velocity limits. Positions
in {w} [m], times [s], configurations [rad, m]."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import WristmarkError
from wristmark.models.limits import clamp_psi, wrap_angle
from wristmark.models.robot_params import RobotParams
from wristmark.rig.ground_truth import TruthSample
from wristmark.rig.run_log import CycleRecord
from wristmark.rig.tip_sensors import TipMeasurement

Array = NDArray[np.float64]


def ramp_to(params: RobotParams, start: Array, target: Array, dt: float) -> list[Array]:
    """Intermediate configurations from ``start`` to ``target`` (both excluded), one per cycle of
    ``dt`` [s], each step within the joint velocity limits; bending-plane angles take the short way."""
    diff = np.asarray(target, float) - np.asarray(start, float)
    for i in (3, 5):  # delta1, delta2 [rad]: the short way (phi is not wrapped: the stem has end stops)
        diff[i] = wrap_angle(float(diff[i]))
    steps = int(np.ceil(np.max(np.abs(diff) / (np.asarray(params.max_velocity, float) * dt)) - 1e-9))
    return [clamp_psi(params, np.asarray(start, float) + diff * (k / steps)) for k in range(1, steps)]


@dataclass
class PhaseStats:
    """Counters of one phase: cycles run, measurements lost (no frame or no marker) and
    rejected by the gates, cycles without a new frame (and of those, the ones driven by the
    last measurement, compensated: rig ``reuse_measurement_age``), the longest run of lost cycles, cycles
    skipped because the host fell a whole period behind the wall clock (a late cycle runs at
    once; the ones it missed are not made up), and why the phase stopped early ("" when it did not)."""

    cycles: int = 0
    lost: int = 0
    rejected: int = 0
    no_frame: int = 0
    reused: int = 0
    max_consecutive_lost: int = 0
    skipped: int = 0
    stopped: str = ""


class MarkerLostError(WristmarkError):
    """The marker stayed out of sight longer than the loop allows; the arm was held.

    ``stats`` holds the phase's counters up to the stop (None when raised elsewhere); ``record``
    the stopping cycle's log record, when it got that far."""

    def __init__(self, message: str, stats: PhaseStats | None = None, record: CycleRecord | None = None) -> None:
        super().__init__(message)
        self.stats = stats
        self.record = record


class CameraStalledError(MarkerLostError):
    """The camera delivered no new frame for longer than the loop allows, or its stream failed
    or ended; the arm was held."""


@dataclass(frozen=True)
class CycleTarget:
    """What cycle k aims at: its time t [s], whether it settles, the desired tip p_des [m] and
    feed-forward velocity v_des [m/s], and (open loop) the desired tip at the cycle's end; the
    desired tip-frame rotation R_des, R_next and angular velocity w_des [rad/s] (None: position only)."""

    k: int
    t: float
    settling: bool
    p_des: Array
    v_des: Array
    p_next: Array
    R_des: Array | None = None
    w_des: Array | None = None
    R_next: Array | None = None


@dataclass
class TrackingMemory:
    """The closed loop's memory across cycles: the last accepted tip [m] and the current run of
    cycles without an accepted measurement (and why the last one failed)."""

    last_ok: Array | None = None
    lost_run: int = 0
    last_reason: str = ""
    last_meas: TipMeasurement | None = None  # the last accepted measurement (for cycles without a frame)


@dataclass(frozen=True)
class CycleOutcome:
    """One closed-loop cycle's measurement and what the loop made of it."""

    meas: TipMeasurement | None
    truth: TruthSample
    accepted: bool
    rejected: bool
    ctrl_us: float
    reused: bool = False  # no new frame: the last accepted measurement, compensated, drove the controller
