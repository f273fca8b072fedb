"""What one cycle and one phase of the servo loop (rig.loop.servo_loop) carry: the cycle's target,
the closed loop's memory across cycles, a cycle's outcome, the phase's counters, the errors that
stop a phase, the ramp that joins two configurations within the velocity limits, and the two
builders of a cycle: its target from the trajectory and its log record. Positions in {w} [m],
times [s], configurations [rad, m]."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.arm_spec import Arm
from wristmark.models.errors import WristmarkError
from wristmark.models.kinematics import tip_position
from wristmark.models.limits import clamp_psi, delta_indices, velocity_limits, wrap_angle
from wristmark.rig.loop.ground_truth import TruthSample
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.tip_sensors import TipMeasurement
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.rig.targets.trajectories import Trajectory, feedforward_velocity

Array = NDArray[np.float64]


def ramp_to(params: Arm, start: Array, target: Array, dt: float, speed: float = 1.0) -> list[Array]:
    """Intermediate configurations from ``start`` to ``target`` (both excluded), one per cycle of
    ``dt`` [s], each step within ``speed`` (0..1] x the joint velocity limits; bending-plane angles
    take the short way."""
    diff = np.asarray(target, float) - np.asarray(start, float)
    for i in delta_indices(params):  # delta1, delta2 [rad]: the short way (phi is not wrapped: the stem has end stops)
        diff[i] = wrap_angle(float(diff[i]))
    steps = int(np.ceil(np.max(np.abs(diff) / (velocity_limits(params) * speed * dt)) - 1e-9))
    return [clamp_psi(params, np.asarray(start, float) + diff * (k / steps)) for k in range(1, steps)]


@dataclass
class PhaseStats:
    """Counters of one phase: cycles run, measurements lost (no frame or no marker) and
    rejected by the gates, lost cycles that dithered the held arm (rig ``lost_dither``), cycles
    without a new frame, the cycles driven by the last measurement, compensated (rig
    ``reuse_measurement_age``: without a new frame, and with ``reuse_lost`` a frame without the
    marker or rejected), the longest run of lost cycles, cycles skipped because the host
    fell a whole period behind the wall clock (a late cycle runs at once; the ones it missed are
    not made up), and why the phase stopped early ("" when it did not)."""

    cycles: int = 0
    lost: int = 0
    rejected: int = 0
    no_frame: int = 0
    reused: int = 0
    max_consecutive_lost: int = 0
    skipped: int = 0
    open_on_lost: int = 0  # cycles walked open loop while the marker was lost (rig open_loop_on_lost)
    stopped: str = ""
    dithers: int = 0  # lost cycles that moved the held arm a little (rig ``lost_dither``)


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
    cycles without an accepted measurement (and why the last one failed; of that run, the last
    cycles in a row without a new frame, and why the last frame that came failed)."""

    last_ok: Array | None = None
    lost_run: int = 0
    last_reason: str = ""
    no_frame_run: int = 0  # of the lost run, the last cycles in a row that had no new frame
    last_frame_reason: str = ""  # why the lost run's last frame gave no accepted measurement
    last_meas: TipMeasurement | None = None  # the last accepted measurement (for cycles without a frame)
    held_psi: Array | None = None  # the command in force when the marker was lost (the dither's centre)
    reused_run: int = 0  # of the lost run, the cycles that stepped on the last measurement (rig reuse_lost)


@dataclass(frozen=True)
class CycleOutcome:
    """One closed-loop cycle's measurement and what the loop made of it."""

    meas: TipMeasurement | None
    truth: TruthSample
    accepted: bool
    rejected: bool
    ctrl_us: float
    reused: bool = False  # no frame (or marker: reuse_lost): the last measurement, compensated, drove the controller


def cycle_target(traj: Trajectory, rig: RigConfig, k: int, t_k: float, n_settle: int) -> CycleTarget:
    """Cycle ``k`` (the first ``n_settle`` hold the start) at ``t_k`` [s, the loop's clock]: the
    desired tip and orientation in {w} [m], the feed-forward velocity [m/s] previewed by the
    loop's delay with a lead for the actuators' lag, and the open loop's aim at the cycle's end."""
    dt = rig.control_dt
    tau_raw = (k - n_settle) * dt  # trajectory time; negative while settling
    tau = max(0.0, tau_raw)
    p_des, _ = traj.sample(tau)
    v_des = feedforward_velocity(traj, tau_raw, dt, rig.feedforward_preview, rig.feedforward_lead)
    # open loop commands a position reached over the coming cycle: aim at its end
    p_next = traj.sample(tau + dt)[0] if k >= n_settle - 1 else p_des
    o, o_next = traj.sample_orientation(tau), traj.sample_orientation(tau + dt if k >= n_settle - 1 else tau)
    R, w, R_next = (None, None, None) if o is None or o_next is None else (o[0], o[1], o_next[0])
    return CycleTarget(k, t_k, k < n_settle, p_des, v_des, p_next, R, w, R_next)


def cycle_record(params: Arm, psi_cmd: Array, target: CycleTarget, t_wall: float, phase: str,
                 outcome: CycleOutcome, latency_s: float, arrival: float | None = None) -> CycleRecord:
    """The log record of a cycle: its target, the command ``psi_cmd`` [rad, m] in force, the
    outcome's measurement and truth; ``latency_s`` capture -> command [s]; ``arrival`` the frame's
    arrival on the wall clock [s] (None: no transport time, e.g. the simulated bench)."""
    meas, truth = outcome.meas, outcome.truth
    ok = meas is not None and meas.ok and meas.p_world is not None and bool(np.all(np.isfinite(meas.p_world)))
    p_est = meas.p_world if ok and meas is not None else None
    psi_true = np.asarray(truth.psi_true, float)
    if psi_true.shape != psi_cmd.shape:  # no observer (hardware): NO_TRUTH's NaNs, one per entry of psi
        psi_true = np.full(psi_cmd.shape, np.nan)
    return CycleRecord(
        t=target.t, phase=phase + (":settle" if target.settling else ""), p_des=np.asarray(target.p_des, float),
        p_cmd=tip_position(params, psi_cmd), p_est=p_est, p_true=np.asarray(truth.p_true, float),
        p_trk=np.asarray(truth.p_trk, float), psi_cmd=psi_cmd.copy(),
        psi_true=psi_true, meas_ok=outcome.accepted, rejected=outcome.rejected,
        vision_ms=meas.time_ms if meas is not None else 0.0, ctrl_us=outcome.ctrl_us, t_wall=t_wall,
        t_capture=meas.t_capture if meas is not None else float("nan"), latency_ms=1000.0 * latency_s,
        transport_ms=1000.0 * (arrival - meas.t_capture) if meas is not None and arrival is not None else float("nan"),
        R_des=target.R_des, R_est=meas.R_world if ok and meas is not None else None,
        R_true=np.asarray(truth.R_true, float), R_trk=np.asarray(truth.R_trk, float),
        T_marker_est=meas.T_world_marker if ok and meas is not None else None,
        tip_sigma=meas.tip_sigma_m if ok and meas is not None else float("nan"),
    )
