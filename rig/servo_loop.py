"""The servo loop on the simulated bench: plant stepped finely, camera frames, control every dt.

One cycle k at simulated time t_k = t0 + k dt:
1. the world runs to t_k; the camera captures the true arm; the optical tracker measures it;
2. closed loop: the vision pipeline estimates the tip (default: rendered pixels -> tracker);
   the measurement is gated (jump from the previous accepted one, distance from the model's
   commanded tip); the controller computes the next commanded configuration, clamped to the
   joint and velocity limits; a lost or rejected measurement holds the arm (command unchanged);
   open loop: the nominal model's IK of the desired tip gives the command;
3. the command reaches the actuators ``vision_latency`` after the capture (open loop: at once).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.actuation import actuators_from_psi, psi_from_actuators
from models.errors import WristmarkError
from models.ik import solve_tip_ik
from models.kinematics import forward_kinematics, tip_position
from models.limits import clamp_psi, wrap_angle
from models.plant_interface import ActuatedArm
from models.robot_params import RobotParams
from rig.actuator_link import ActuatorLink
from rig.progress import PhaseProgress
from rig.rig_config import RigConfig
from rig.run_log import CycleRecord, RunLog
from rig.tip_sensors import TipSensor
from rig.trajectories import Trajectory, feedforward_velocity
from sim.optical_tracker import OpticalTracker
from solvers.controller import Controller

Array = NDArray[np.float64]


def ramp_to(params: RobotParams, start: Array, target: Array, dt: float) -> list[Array]:
    """Intermediate configurations from ``start`` to ``target`` (both excluded), one per cycle of
    ``dt`` [s], each step within the joint velocity limits; bending-plane angles take the short way."""
    diff = np.asarray(target, float) - np.asarray(start, float)
    for i in (3, 5):  # delta1, delta2 [rad]: the short way (phi is not wrapped: the stem has end stops)
        diff[i] = wrap_angle(float(diff[i]))
    steps = int(np.ceil(np.max(np.abs(diff) / (np.asarray(params.max_velocity, float) * dt)) - 1e-9))
    return [clamp_psi(params, np.asarray(start, float) + diff * (k / steps)) for k in range(1, steps)]


class MarkerLostError(WristmarkError):
    """The marker stayed out of sight longer than the loop allows; the arm was held.

    ``stats`` holds the phase's counters up to the stop (None when raised elsewhere)."""

    def __init__(self, message: str, stats: PhaseStats | None = None) -> None:
        super().__init__(message)
        self.stats = stats


@dataclass
class PhaseStats:
    """Counters of one phase."""

    cycles: int = 0
    lost: int = 0
    rejected: int = 0
    max_consecutive_lost: int = 0
    stopped: str = ""


class ServoLoop:
    """Runs trajectories open or closed loop on one arm through one actuator link."""

    def __init__(
        self,
        params: RobotParams,
        rig: RigConfig,
        link: ActuatorLink,
        arm: ActuatedArm,
        tracker: OpticalTracker,
        sensor: TipSensor | None = None,
        controller: Controller | None = None,
        on_cycle: object = None,
    ) -> None:
        self.params = params
        self.rig = rig
        self.link = link
        self.arm = arm
        self.tracker = tracker
        self.sensor = sensor
        self.controller = controller
        self.on_cycle = on_cycle
        self.t = arm.time
        self.psi_cmd: Array | None = None
        self._wall0 = time.perf_counter()
        self._sim0 = self.t

    # -- helpers -------------------------------------------------------------------------
    def _advance(self, t: float) -> None:
        if self.rig.realtime:
            ahead = (t - self._sim0) - (time.perf_counter() - self._wall0)
            if ahead > 0:
                time.sleep(ahead)
        self.link.advance_to(t)
        self.t = t

    def _send(self, psi: Array) -> None:
        self.link.send_target(actuators_from_psi(self.params, psi))

    def start_at(self, psi: Array) -> None:
        """Move to ``psi`` and let the arm settle there (2 s of simulated time).

        The way there is a ramp from where the encoders say the arm is, one target per control
        cycle, each step within the joint velocity limits (an arm far from the start never gets
        one big jump; a simulated arm already there gets no ramp)."""
        target = clamp_psi(self.params, psi)
        dt = self.rig.control_dt
        for step in ramp_to(self.params, self._encoder_psi(target), target, dt):
            self.psi_cmd = step
            self._send(step)
            self._advance(self.t + dt)
        self.psi_cmd = target
        self._send(target)
        self._advance(self.t + 2.0)

    def _encoder_psi(self, hint: Array) -> Array:
        """The configuration the encoders report (``hint`` picks delta where it is ambiguous)."""
        return psi_from_actuators(self.params, self.link.measured_actuators(), delta_hint=hint)

    # -- one phase -----------------------------------------------------------------------
    def run(
        self,
        traj: Trajectory,
        phase: str,
        closed_loop: bool,
        log: RunLog,
        settle: float = 0.0,
        progress: bool = False,
    ) -> PhaseStats:
        """Follow ``traj`` (times relative to now); log every cycle under ``phase``.

        ``settle`` seconds of holding the trajectory's start come first (logged as
        ``phase + ':settle'``). Raises MarkerLostError after too many lost frames (arm held).
        """
        if closed_loop and (self.sensor is None or self.controller is None):
            raise WristmarkError("closed loop needs a tip sensor and a controller")
        if self.psi_cmd is None:
            ik = solve_tip_ik(self.params, traj.sample(0.0)[0], np.asarray(self.params_home()))
            self.start_at(ik.psi)
        assert self.psi_cmd is not None
        dt = self.rig.control_dt
        n_settle = int(round(settle / dt))
        n_traj = int(np.floor(traj.duration / dt)) + 1
        stats = PhaseStats()
        t0 = self.t
        last_ok: Array | None = None
        lost_run = 0
        bar = PhaseProgress(phase, n_settle, n_traj, progress)
        for k in range(n_settle + n_traj):
            t_k = t0 + k * dt
            self._advance(t_k)
            tau_raw = (k - n_settle) * dt  # trajectory time; negative while settling
            tau = max(0.0, tau_raw)
            p_des, _ = traj.sample(tau)
            # feed-forward: the desired path previewed by the loop's delay, with a lead for the
            # actuators' lag; the preview also covers the start of motion (zero until then)
            v_des = feedforward_velocity(traj, tau_raw, dt, self.rig.feedforward_preview, self.rig.feedforward_lead)
            # open loop commands a position reached over the coming cycle: aim at its end
            p_next = traj.sample(tau + dt)[0] if k >= n_settle - 1 else p_des
            shape = self.arm.true_shape()
            p_true = shape.tip.copy()
            p_trk = self.tracker.measure(p_true)
            psi_true = np.asarray(getattr(self.arm, "true_psi", np.full(6, np.nan)), float)
            p_est: Array | None = None
            meas_ok = rejected = False
            vision_ms = ctrl_us = 0.0
            if closed_loop:
                assert self.sensor is not None and self.controller is not None
                model = forward_kinematics(self.params, self.psi_cmd)  # the commanded arm, nominal model
                hint = model.T_world_marker[:3, 2]  # which way the marker points
                meas = self.sensor.measure(shape, axis_hint_world=hint)
                vision_ms = meas.time_ms
                p_model = model.tip
                if meas.ok and meas.p_world is not None and np.all(np.isfinite(meas.p_world)):
                    p_est = meas.p_world
                    jump_ok = last_ok is None or (
                        np.linalg.norm(p_est - last_ok) <= self.rig.gate * (1 + lost_run)
                    )
                    model_ok = np.linalg.norm(p_est - p_model) <= self.rig.model_gate
                    rejected = not (jump_ok and model_ok)
                    meas_ok = not rejected
                if meas_ok:
                    assert p_est is not None
                    last_ok = p_est
                    lost_run = 0
                    c0 = time.perf_counter()
                    step = self.controller.step(self.psi_cmd, p_est, p_des, v_des, dt)
                    ctrl_us = 1e6 * (time.perf_counter() - c0)
                    self.psi_cmd = step.psi_next
                else:
                    stats.lost += int(not rejected)
                    stats.rejected += int(rejected)
                    lost_run += 1
                    stats.max_consecutive_lost = max(stats.max_consecutive_lost, lost_run)
                    if lost_run > self.rig.max_lost_cycles:
                        self.link.hold()
                        stats.stopped = f"marker lost for {lost_run} cycles at t = {t_k:.2f} s"
                        log.add(self._record(t_k, phase, k < n_settle, p_des, p_est, p_true,
                                             p_trk, psi_true, False, rejected, vision_ms, 0.0))
                        raise MarkerLostError(stats.stopped + ": arm held", stats)
                self._advance(t_k + self.rig.vision_latency)
            else:
                ik = solve_tip_ik(self.params, p_next, self.psi_cmd)
                self.psi_cmd = clamp_psi(self.params, ik.psi)
            self._send(self.psi_cmd)
            stats.cycles += 1
            rec = self._record(t_k, phase, k < n_settle, p_des, p_est, p_true, p_trk, psi_true,
                               meas_ok, rejected, vision_ms, ctrl_us)
            log.add(rec)
            if callable(self.on_cycle):
                self.on_cycle(rec)
            bar.step()
        bar.close()
        return stats

    def params_home(self) -> Array:
        """Home configuration used as the IK start."""
        from models.robot_params import HOME_PSI

        return np.asarray(HOME_PSI, float)

    def _record(self, t: float, phase: str, settling: bool, p_des: Array, p_est: Array | None,
                p_true: Array, p_trk: Array, psi_true: Array, meas_ok: bool, rejected: bool,
                vision_ms: float, ctrl_us: float) -> CycleRecord:
        assert self.psi_cmd is not None
        return CycleRecord(
            t=t, phase=phase + (":settle" if settling else ""), p_des=np.asarray(p_des, float),
            p_cmd=tip_position(self.params, self.psi_cmd), p_est=p_est, p_true=p_true,
            p_trk=np.asarray(p_trk, float), psi_cmd=self.psi_cmd.copy(), psi_true=psi_true,
            meas_ok=meas_ok, rejected=rejected, vision_ms=vision_ms, ctrl_us=ctrl_us,
        )
