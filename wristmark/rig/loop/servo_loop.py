"""The servo loop: frames in, tip measured, commands out, one cycle every ``control_dt``.

One cycle k at t_k = t0 + k dt on the loop's clock:
1. time runs to t_k (the link waits on the wall clock, or steps the simulated world); on the wall
   clock a host that fell a whole period behind skips the cycles it missed (counted), and with
   rig ``frame_phase_lock`` the grid t0 + k dt is shifted by the lock (rig/loop/frame_phase_lock.py)
   so that the camera's frames come at a fixed phase of the cycle;
2. closed loop: a stereo frame is taken from the frame feed (the simulated bench renders the
   true arm now; a live camera hands out its newest frame, waiting a bounded time for one
   that arrives after the cycle began, or after t_k for a cycle that began late); the tip
   sensor measures it; the measurement is gated (jump from the previous accepted one, distance
   from the model's commanded tip); the controller computes the next commanded configuration,
   clamped to the joint and velocity limits; no frame, a lost or a rejected measurement steps
   the controller on the last accepted measurement (compensated) while it is young enough (rig
   ``reuse_measurement_age``; without a frame on the wall clock only, a lost or rejected one with
   ``reuse_lost``), else holds the arm (the command unchanged). Open loop: the nominal model's IK
   of the desired tip gives the command (pose IK when the trajectory asks for an orientation; closed loop, the measured
   orientation then goes to the controller's orientation task);
3. the command is sent: on the wall clock as soon as it is computed, or, with a rig
   ``command_phase`` > 0, at that fixed instant after the cycle's nominal start (at once when it
   is computed later), as on the simulated bench, where it goes out ``vision_latency`` after the
   capture (open loop: at once). The measurement is compensated to the cycle's start (rig.loop.delay_compensation),
   with the configuration the arm is expected to follow (the controller's output model: a dead-band
   inversion's offsets move the motors across the band, not the arm).
   The capture-to-command latency is measured from the frame's capture time.

Ground truth (true tip, optical tracker, true configuration) is logged when an optional
:class:`rig.loop.ground_truth.GroundTruth` observer is given: only the simulated bench has one.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import NoReturn

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame
from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm, home_psi
from wristmark.models.errors import WristmarkError
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import clamp_psi
from wristmark.models.pose_ik import nominal_ik
from wristmark.rig.link.actuator_link import ActuatorLink, box_actuators
from wristmark.rig.loop.delay_compensation import DelayCompensator
from wristmark.rig.loop.frame_feed import FrameFeed
from wristmark.rig.loop.frame_phase_lock import FramePhaseLock
from wristmark.rig.loop.ground_truth import NO_TRUTH, GroundTruth, TruthSample
from wristmark.rig.loop.motion_correction import MotionCorrection
from wristmark.rig.loop.probe_loop import ProbeReading
from wristmark.rig.loop.progress import PhaseProgress
from wristmark.rig.loop.rig_config import RigConfig
from wristmark.rig.loop.servo_cycle import (
    CameraStalledError,
    CycleOutcome,
    CycleTarget,
    MarkerLostError,
    PhaseStats,
    TrackingMemory,
    cycle_record,
    cycle_target,
    ramp_to,
)
from wristmark.rig.loop.tip_sensors import TipMeasurement, TipSensor
from wristmark.rig.recording.run_log import CycleRecord, RunLog
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.solvers.controller import Controller, OrientationTask
from wristmark.solvers.play_probe_fit import PlayFit

Array = NDArray[np.float64]
NO_FRAME = "no new frame from the camera"


class ServoLoop:
    """Runs trajectories open or closed loop through one actuator link.

    frames + sensor: the closed loop's measurements (a frame feed and a tip sensor);
    truth: optional ground-truth observer (the simulated bench); wall_clock: the loop's time is
    the host's ``time.monotonic()`` (frames stamped on it, commands sent when computed) rather
    than simulated time (commands sent ``rig.vision_latency`` after the capture);
    frame_wait: on the wall clock, how long [s] a cycle waits for a frame that arrived after it began;
    on_cycle(record) after every cycle; on_frame(frame, measurement) after every measured frame
    (both must return at once: e.g. the live view's hooks).
    """

    def __init__(
        self,
        params: Arm,
        rig: RigConfig,
        link: ActuatorLink,
        *,
        frames: FrameFeed | None = None,
        sensor: TipSensor | None = None,
        controller: Controller | None = None,
        truth: GroundTruth | None = None,
        wall_clock: bool = False,
        frame_wait: float = 0.04,
        on_cycle: object = None,
        on_frame: object = None,
    ) -> None:
        self.params = params
        self.rig = rig
        self.link = link
        self.frames = frames
        self.sensor = sensor
        self.controller = controller
        self.truth = truth
        self.wall_clock = bool(wall_clock)
        self.frame_wait = float(frame_wait)
        self.on_cycle = on_cycle
        self.on_frame = on_frame
        self.last_measurement: TipMeasurement | None = None
        self.last_pose: TipMeasurement | None = None  # the last measurement with a 6-DoF pose (roll known)
        self.last_frame: StereoFrame | None = None
        self.t = float(link.time)
        self.psi_cmd: Array | None = None
        self._wall0 = time.perf_counter()
        self._sim0 = self.t
        self._advanced = False  # a cycle (or a ramp step) has had its time: self.t is its start
        self._cycle_start = -math.inf  # wall clock: the current cycle's start [s]
        self._command_at = -math.inf  # wall clock: the current cycle's command instant [s]
        self.ready_after_arrival_ms: list[float] = []  # wall clock: frame arrival -> command computed
        window = rig.delay_compensation_learn_window
        learn = MotionCorrection(window) if window > 0 else None
        self.delay = DelayCompensator(params, rig.delay_compensation_tau, correction=learn,
                                       reach=rig.delay_compensation_reach) \
            if rig.delay_compensation else None
        self.play_fits: list[PlayFit] | None = None  # the play probe's fits per actuator (rig/loop/play_probe.py)
        self.play_probe_note = ""  # why the play probe was skipped ("" when it ran or was not asked for)
        # wall clock: the cycle grid shifted so that the frames come at a fixed phase of it
        lock = wall_clock and rig.frame_phase_lock != "none"
        self.phase_lock = FramePhaseLock(rig.frame_lock_phase, rig.control_dt) if lock else None

    # -- time and commands ----------------------------------------------------------------
    def advance_to(self, t: float) -> None:
        """Let the loop's time run to ``t`` [s] (the link waits on the wall clock or steps the
        simulated world; a real-time simulated loop also sleeps to keep pace)."""
        if self.rig.realtime and not self.wall_clock:
            ahead = (t - self._sim0) - (time.perf_counter() - self._wall0)
            if ahead > 0:
                time.sleep(ahead)
        self.link.advance_to(t)
        self.t = t
        self._advanced = True

    def now(self) -> float:
        """The time on the frames' clock [s]: the wall clock, or the loop's simulated time."""
        return time.monotonic() if self.wall_clock else self.t

    def elapsed(self, t: float) -> float:
        """Time [s] from the loop's start to ``t`` on its clock."""
        return t - self._sim0

    def send(self, psi: Array) -> None:
        """Send the configuration ``psi`` [rad, m, ...] to the link, and record it for the delay
        compensation as the configuration the arm should follow."""
        # the controller's targets: with a dead-band inversion in actuator space, its offsets ride on them
        self.link.send_target(self.controller.actuator_targets(psi) if self.controller is not None
                              else actuators_from_psi(self.params, psi))
        if self.delay is not None:  # what the arm should do: a dead-band inversion's offsets do not move it
            expected = self.controller.output_model(psi) if self.controller is not None else psi
            self.delay.record(self.now(), expected)

    def start_at(self, psi: Array) -> None:
        """Move to ``psi`` and let the arm settle there (2 s).

        The way there is a ramp from where the encoders say the arm is, one target per control
        cycle, each step within the joint velocity limits (an arm far from the start never gets
        one big jump; a simulated arm already there gets no ramp)."""
        target = clamp_psi(self.params, psi)
        dt = self.rig.control_dt
        before = np.asarray(self.link.measured_actuators(), float)
        for step in ramp_to(self.params, psi_from_actuators(self.params, before, delta_hint=target), target, dt):
            self.psi_cmd = step
            self.send(step)
            self.advance_to(self.t + dt)
        self.psi_cmd = target
        self.send(target)
        self.advance_to(self.t + 2.0)
        if self.controller is not None and self.controller.uses_encoders:  # where the ramp left each play
            self.controller.note_start_move(before, np.asarray(self.link.measured_actuators(), float))

    def params_home(self) -> Array:
        """Home configuration used as the IK start."""
        return home_psi(self.params)

    # -- one phase -----------------------------------------------------------------------
    def run(self, traj: Trajectory, phase: str, closed_loop: bool, log: RunLog, settle: float = 0.0,
            progress: bool = False) -> PhaseStats:
        """Follow ``traj`` (times relative to now); log every cycle under ``phase``.

        ``settle`` seconds of holding the trajectory's start come first (logged as
        ``phase + ':settle'``); closed loop, a controller that asks for a play probe gets it
        after them (rig/loop/play_probe.py, ``phase + ':probe'``), then play_probe_settle more.
        Raises MarkerLostError after too many lost measurements and CameraStalledError after
        too many cycles without a frame or when the stream fails (the arm held in both cases)."""
        if closed_loop and (self.sensor is None or self.controller is None or self.frames is None):
            raise WristmarkError("closed loop needs a frame feed, a tip sensor and a controller")
        if self.psi_cmd is None:
            ik = solve_tip_ik(self.params, traj.sample(0.0)[0], self.params_home())
            self.start_at(ik.psi)
        dt = self.rig.control_dt
        n_settle = int(round(settle / dt))
        n_traj = int(np.floor(traj.duration / dt)) + 1
        stats = PhaseStats()
        memory = TrackingMemory()
        ctrl = self.controller if closed_loop else None
        n_after = int(round(ctrl.config.play_probe_settle / dt)) if ctrl and ctrl.wants_play_probe else 0
        bar = PhaseProgress(phase, n_settle, n_traj, progress)  # the probe and its settle not on it
        if ctrl is not None and ctrl.wants_play_probe:  # settle, probe, settle again, walk
            n_settle = self.probe_play(traj, phase, log, stats, memory, n_settle, bar)
        self._cycles(traj, phase, closed_loop, log, stats, memory, bar, n_settle + n_traj, n_settle, n_after)
        bar.close()
        return stats

    def probe_play(self, traj: Trajectory, phase: str, log: RunLog, stats: PhaseStats, memory: TrackingMemory,
                   n_settle: int, bar: PhaseProgress | None = None) -> int:
        """Closed loop, for a controller that asks for it: ``n_settle`` cycles holding the
        trajectory's start, the play probe (rig/loop/play_probe.py, logged as ``phase + ':probe'``),
        and return how many settle cycles are still due before the walk (``play_probe_settle``)."""
        from wristmark.rig.loop.play_probe import run_play_probe

        assert self.controller is not None
        bar = bar if bar is not None else PhaseProgress(phase, n_settle, 0, False)
        lead_in = n_settle + 10**6  # the first settle sees no preview of the walk's start
        self._cycles(traj, phase, True, log, stats, memory, bar, n_settle, lead_in)
        start = cycle_target(traj, self.rig, 0, self.t, lead_in)
        self.play_fits = run_play_probe(_ProbeView(self, phase, log, memory, stats), start)
        memory.last_ok = None  # the probe moved the tip: no jump gate just after it
        return int(round(self.controller.config.play_probe_settle / self.rig.control_dt))

    def _cycles(self, traj: Trajectory, phase: str, closed_loop: bool, log: RunLog, stats: PhaseStats,
                memory: TrackingMemory, bar: PhaseProgress, n: int, n_settle: int, unbarred: int = 0) -> None:
        """Cycles 0..n-1 from now, the first ``n_settle`` of them holding the trajectory's start
        (the first ``unbarred`` of them not shown on the bar: the settle after a play probe)."""
        dt = self.rig.control_dt
        # on the wall clock self.t is the last cycle's start: the grid goes on a cycle later (a new
        # grid at that same instant began a whole cycle late, and a loop late by most of a cycle
        # could stay a frame behind its camera); the simulated clock is past it by the latency
        t0 = self.t + dt if self.wall_clock and self._advanced else self.t
        shift0 = self._grid_shift()
        k = 0
        while k < n:
            target = cycle_target(traj, self.rig, k, t0 + k * dt + self._grid_shift() - shift0, n_settle)
            self.advance_to(target.t)
            t_wall = time.monotonic()
            missed = min(int((t_wall - target.t) // dt), n - 1 - k) if self.wall_clock else 0
            if missed > 0:  # a whole cycle late on the wall clock: skip to the current cycle
                stats.skipped += missed
                k += missed
                for i in range(missed):
                    if k - missed + i >= unbarred:
                        bar.step()
                continue
            if closed_loop:
                try:
                    rec = self._closed_cycle(target, t_wall, phase, memory, stats)
                except MarkerLostError as e:
                    if e.record is not None:
                        log.add(e.record)
                    raise
            else:
                rec = self._open_cycle(target, t_wall, phase)
            stats.cycles += 1
            log.add(rec)
            if callable(self.on_cycle):
                self.on_cycle(rec)
            k += 1
            if k > unbarred:
                bar.step()

    def step(self, target: CycleTarget, phase: str, closed_loop: bool, memory: TrackingMemory,
             stats: PhaseStats) -> CycleRecord:
        """One cycle at ``target`` (the loop's time already advanced to ``target.t``), open or
        closed loop, counted in ``stats``: what :meth:`run` does per cycle, for a caller that
        steps several loops in lockstep (sim.several_arms). Raises MarkerLostError as :meth:`run`."""
        if closed_loop:
            rec = self._closed_cycle(target, time.monotonic(), phase, memory, stats)
        else:
            rec = self._open_cycle(target, time.monotonic(), phase)
        stats.cycles += 1
        return rec

    def observe(self) -> TruthSample:
        """The ground-truth observer's sample now (NO_TRUTH without one: hardware)."""
        return self.truth.observe() if self.truth is not None else NO_TRUTH

    # -- open loop ------------------------------------------------------------------------
    def _open_cycle(self, target: CycleTarget, t_wall: float, phase: str) -> CycleRecord:
        truth = self.observe()
        assert self.psi_cmd is not None
        self.psi_cmd = clamp_psi(self.params, nominal_ik(self.params, target.p_next, target.R_next, self.psi_cmd))
        self.send(self.psi_cmd)
        return self.record(target, t_wall, phase, CycleOutcome(None, truth, False, False, 0.0), float("nan"))

    # -- closed loop ----------------------------------------------------------------------
    def _closed_cycle(self, target: CycleTarget, t_wall: float, phase: str, memory: TrackingMemory,
                      stats: PhaseStats) -> CycleRecord:
        # wall clock: the cycle's nominal start (the link's time is time.monotonic() there; t_wall
        # is a little later), to which the measurement is compensated, and its command instant:
        # both on the nominal schedule, so a cycle that starts late does not move its command
        self._cycle_start = target.t
        self._command_at = target.t + self.rig.command_phase
        frame = self.take_frame(target, phase, memory, stats)
        truth = self.observe()
        outcome = self._measure_and_control(frame, truth, target, memory)
        walking = False
        if outcome.accepted:
            memory.lost_run = 0
            memory.reused_run = 0
            memory.no_frame_run = 0
            memory.last_frame_reason = ""
            memory.held_psi = None
        else:
            self._count_lost(outcome, memory, stats)
            walking = memory.lost_run * self.rig.control_dt <= self.rig.open_loop_on_lost
            if walking:  # walk on open loop (the arm does not hold: no dither)
                assert self.psi_cmd is not None
                stats.open_on_lost += 1
                self.psi_cmd = clamp_psi(self.params, nominal_ik(self.params, target.p_next, target.R_next,
                                                                 self.psi_cmd))
            if memory.lost_run > self.rig.max_lost_cycles:
                self._stop_lost(target, t_wall, phase, outcome, memory, stats)
            if not walking:
                self._dither(outcome, memory, stats)
        if not self.wall_clock:
            self.advance_to(target.t + self.rig.vision_latency)  # the simulated processing time
        else:
            self._wait_for_command_phase(outcome)
        assert self.psi_cmd is not None
        self.send(self.psi_cmd)
        latency = self.now() - outcome.meas.t_capture if outcome.accepted and outcome.meas else float("nan")
        rec = self.record(target, t_wall, phase, outcome, latency)
        rec.open_on_lost = walking
        return rec

    def _grid_shift(self) -> float:
        """Wall clock with ``rig.frame_phase_lock``: how far [s] the cycle grid has moved to meet
        the camera's frames (0 otherwise)."""
        return self.phase_lock.shift if self.phase_lock is not None else 0.0

    def _wait_for_command_phase(self, outcome: CycleOutcome) -> None:
        """Wall clock: note when the command was ready after its frame's arrival [ms], then sleep
        until the cycle's command instant (``command_phase`` after its start; at once when later)."""
        now = time.monotonic()
        if outcome.accepted and self.frames is not None:
            self.ready_after_arrival_ms.append(1000.0 * (now - self.frames.last_arrival))
        if self._command_at > now:
            time.sleep(self._command_at - now)

    def take_frame(self, target: CycleTarget, phase: str, memory: TrackingMemory,
                    stats: PhaseStats) -> StereoFrame | None:
        """This cycle's frame: on the wall clock one that arrived after the cycle began (after its
        nominal start for a cycle that began over ``frame_wait`` / 2 late) if it comes within
        ``frame_wait``, else the newest unseen one (None: none at all)."""
        assert self.frames is not None
        try:
            if self.wall_clock:
                t_start = time.monotonic()
                # a cycle that began late by over half its frame wait takes the frame that arrived
                # since its nominal start at once (else it waited for the next one, and the loop could
                # stay a frame behind its camera); on time, a frame that arrived after it began
                late = t_start - target.t > 0.5 * self.frame_wait
                frame = self.frames.take(fresh_after=target.t if late else t_start,
                                         wait_until=t_start + self.frame_wait)
            else:
                frame = self.frames.take()
        except FrameSourceError as e:
            self.link.hold()
            stats.stopped = f"camera: {e} at t = {self.elapsed(target.t):.2f} s"
            raise CameraStalledError(stats.stopped + ": arm held", stats) from None
        if frame is not None:
            self.last_frame = frame
            if self.phase_lock is not None:  # when it was captured or arrived, from the cycle's start
                at = frame.t_capture if self.rig.frame_phase_lock == "capture" else self.frames.last_arrival
                self.phase_lock.observe(at - target.t)
        return frame

    def _measure_and_control(self, frame: StereoFrame | None, truth: TruthSample, target: CycleTarget,
                             memory: TrackingMemory) -> CycleOutcome:
        """Measure the frame, gate the measurement, and step the controller when it is accepted."""
        assert self.sensor is not None and self.controller is not None and self.psi_cmd is not None
        if frame is None:
            memory.last_reason = NO_FRAME
            return self._reuse(truth, target, memory)
        model = forward_kinematics(self.params, self.psi_cmd)  # the commanded arm, nominal model
        meas = self.sensor.measure(frame, axis_hint_world=model.T_world_marker[:3, 2])  # which way it points
        self.last_measurement = meas
        if meas.ok and meas.R_world is not None and meas.roll_known:
            self.last_pose = meas
        if callable(self.on_frame):
            self.on_frame(frame, meas)
        if not (meas.ok and meas.p_world is not None and np.all(np.isfinite(meas.p_world))):
            memory.last_reason = meas.reason or "marker not found"
            if self.rig.reuse_lost:  # step on the last measurement, as a cycle without a frame
                reused = self._reuse(truth, target, memory, any_clock=True)
                return dataclasses.replace(reused, meas=meas)
            return CycleOutcome(meas, truth, False, False, 0.0)
        p_est = meas.p_world
        # the jump gate widens with every lost cycle that held the arm; with reuse_lost, cycles that
        # stepped on the last measurement moved the arm as it predicts: the jump counts from there
        last, widen = memory.last_ok, memory.lost_run
        if self.rig.reuse_lost and memory.reused_run > 0 and memory.last_meas is not None:
            last, widen = self._compensated(memory.last_meas), memory.lost_run - memory.reused_run
        jump_ok = last is None or np.linalg.norm(p_est - last) <= self.rig.gate * (1 + widen)
        model_ok = np.linalg.norm(p_est - model.tip) <= self.rig.model_gate
        if not (jump_ok and model_ok):
            memory.last_reason = "measurement rejected by the gates"
            if self.rig.reuse_lost:  # the same: the last accepted measurement, not this one
                reused = self._reuse(truth, target, memory, any_clock=True)
                return dataclasses.replace(reused, meas=meas, rejected=True)
            return CycleOutcome(meas, truth, False, True, 0.0)
        memory.last_ok = p_est
        memory.last_meas = meas
        if self.delay is not None:  # the compensation's learnt map of the model's motion to the arm's
            self.delay.observe(p_est, meas.t_capture)
        ctrl_us = self._control(target, self._compensated(meas), meas)
        return CycleOutcome(meas, truth, True, False, ctrl_us)

    def _compensated(self, meas: TipMeasurement) -> Array:
        """The measured tip [m] moved on by the delay compensation to this cycle's start, the
        instant whose arm the simulated bench's frame shows (its command goes out
        ``vision_latency`` later, which the controller's feed-forward is tuned for)."""
        assert meas.p_world is not None
        if self.delay is None:
            return meas.p_world
        t_start = self._cycle_start if self.wall_clock else self.t
        return self.delay.compensate(meas.p_world, meas.t_capture, t_start)

    def _compensated_rotation(self, meas: TipMeasurement) -> Array | None:
        """The measured tip-frame orientation (3x3 in {w}; None without one) turned on by the delay
        compensation to this cycle's start, as :meth:`_compensated` moves the tip: a measurement
        reused on cycles without a frame would otherwise ask for the same turn again each cycle."""
        if meas.R_world is None or self.delay is None:
            return meas.R_world
        t_start = self._cycle_start if self.wall_clock else self.t
        return self.delay.compensate_rotation(meas.R_world, meas.t_capture, t_start)

    def _control(self, target: CycleTarget, p_est: Array, meas: TipMeasurement) -> float:
        """One controller step from the tip ``p_est`` [m] (and the measurement's orientation);
        returns its time [us]."""
        assert self.controller is not None and self.psi_cmd is not None
        # the encoders, for a controller that uses them (the encoders' dead-band inversion)
        enc = self.link.measured_actuators() if self.controller.uses_encoders else None
        c0 = time.perf_counter()
        orient = OrientationTask.of(target.R_des, target.w_des, self._compensated_rotation(meas), meas.roll_known)
        step = self.controller.step(self.psi_cmd, p_est, target.p_des, target.v_des, self.rig.control_dt, orient,
                                    encoders=enc)
        self.psi_cmd = step.psi_next
        return 1e6 * (time.perf_counter() - c0)

    def _reuse(self, truth: TruthSample, target: CycleTarget, memory: TrackingMemory,
               any_clock: bool = False) -> CycleOutcome:
        """A cycle without a new frame (wall clock; ``any_clock``: either clock, a frame without
        the marker or with a rejected measurement, rig ``reuse_lost``): the last accepted
        measurement, moved on by the delay compensation, drives the controller while it is at
        most ``reuse_measurement_age`` old at the cycle's start; else (or without the
        compensation) the arm holds."""
        last = memory.last_meas
        if (not (self.wall_clock or any_clock) or self.delay is None or last is None
                or not self._cycle_start - last.t_capture <= self.rig.reuse_measurement_age):
            return CycleOutcome(None, truth, False, False, 0.0)
        ctrl_us = self._control(target, self._compensated(last), last)
        return CycleOutcome(None, truth, False, False, ctrl_us, reused=True)

    def _dither(self, outcome: CycleOutcome, memory: TrackingMemory, stats: PhaseStats) -> None:
        """A frame showed no marker (not a gate's rejection, not a missing frame) for
        ``lost_dither_after`` cycles or more while the arm holds: move the command a little
        around the held one, so that a view the tracker cannot read (e.g. a highlight over the
        marker's corners, docs/notes/highlight-stripe.md) changes before the loop gives up.
        Lost cycle k >= after steps configuration entry j = (k - after) // 2 mod n by
        +-(the step that moves the nominal model's tip ``lost_dither`` [m]) from the held command,
        clamped to the joint limits: each move is bounded by ``lost_dither`` and never adds up
        (counted in ``PhaseStats.dithers``; the log's psi_cmd shows it)."""
        rig = self.rig
        if (rig.lost_dither <= 0 or outcome.meas is None or outcome.rejected or outcome.reused
                or memory.lost_run < rig.lost_dither_after or self.psi_cmd is None):
            return
        if memory.held_psi is None:
            memory.held_psi = self.psi_cmd.copy()
        k = memory.lost_run - rig.lost_dither_after
        base = memory.held_psi
        j = (k // 2) % base.size
        tip0 = forward_kinematics(self.params, base).tip
        probe = base.copy()
        h = 1e-4 if abs(base[j]) < 1 else 1e-4 * abs(base[j])
        probe[j] += h
        rate = float(np.linalg.norm(forward_kinematics(self.params, probe).tip - tip0)) / h  # tip [m] per unit
        if not rate > 0:
            return
        step = base.copy()
        step[j] += (1.0 if k % 2 == 0 else -1.0) * rig.lost_dither / rate
        self.psi_cmd = clamp_psi(self.params, step)
        stats.dithers += 1

    def _count_lost(self, outcome: CycleOutcome, memory: TrackingMemory, stats: PhaseStats) -> None:
        stats.lost += int(not outcome.rejected)
        stats.rejected += int(outcome.rejected)
        stats.no_frame += int(outcome.meas is None)
        stats.reused += int(outcome.reused)
        memory.reused_run += int(outcome.reused)
        memory.lost_run += 1
        if outcome.meas is None:
            memory.no_frame_run += 1
        else:
            memory.no_frame_run = 0
            memory.last_frame_reason = memory.last_reason
        stats.max_consecutive_lost = max(stats.max_consecutive_lost, memory.lost_run)

    def _stop_lost(self, target: CycleTarget, t_wall: float, phase: str, outcome: CycleOutcome,
                   memory: TrackingMemory, stats: PhaseStats) -> None:
        """Hold the arm, log the cycle, raise: the camera stalled (no new frame in the whole lost
        run) or the marker stayed lost (frames came that did not show it; a late frame or two
        among them do not make it the camera's fault: an arm set stops every arm on a stall)."""
        self.link.hold()
        at = f"at t = {self.elapsed(target.t):.2f} s"
        if memory.no_frame_run >= memory.lost_run:
            waited = memory.lost_run * self.rig.control_dt
            name = self.frames.name if self.frames is not None else "camera"
            stats.stopped = f"camera stalled: no new frame from {name} for {memory.lost_run} cycles " \
                            f"({waited:.2f} s) {at}"
            error: type[MarkerLostError] = CameraStalledError
        else:
            why = memory.last_frame_reason or memory.last_reason
            stats.stopped = f"marker lost for {memory.lost_run} cycles {at} ({why})"
            error = MarkerLostError
        rec = self.record(target, t_wall, phase, outcome, float("nan"))
        raise error(stats.stopped + ": arm held", stats, rec)

    # -- the log --------------------------------------------------------------------------
    def record(self, target: CycleTarget, t_wall: float, phase: str, outcome: CycleOutcome,
                latency_s: float) -> CycleRecord:
        """The cycle's log record (rig.loop.servo_cycle.cycle_record) with this loop's command and
        feed, and what the actuator box last saw (its target and encoders, now)."""
        assert self.psi_cmd is not None
        arrival = self.frames.last_arrival if self.frames is not None and self.wall_clock else None
        rec = cycle_record(self.params, self.psi_cmd, target, t_wall, phase, outcome, latency_s, arrival)
        rec.t_act = self.now()
        rec.act_cmd, rec.act_meas = box_actuators(self.link)
        return rec


class _ProbeView:
    """The loop as the play probe sees it (rig.loop.probe_loop.ProbeLoop), bound to the closed-loop
    phase it runs in: its log, tracking memory and counters."""

    def __init__(self, loop: ServoLoop, phase: str, log: RunLog, memory: TrackingMemory, stats: PhaseStats) -> None:
        self.loop, self.phase, self.log, self.memory, self.stats = loop, phase, log, memory, stats

    @property
    def params(self) -> Arm:
        """The nominal arm model."""
        return self.loop.params

    @property
    def rig(self) -> RigConfig:
        """The rig's settings."""
        return self.loop.rig

    @property
    def controller(self) -> Controller:
        """The closed loop's controller."""
        assert self.loop.controller is not None
        return self.loop.controller

    @property
    def psi_cmd(self) -> Array:
        """The configuration last commanded [rad, m, ...]."""
        assert self.loop.psi_cmd is not None
        return self.loop.psi_cmd

    @property
    def last_measurement(self) -> TipMeasurement | None:
        """The loop's last measurement."""
        return self.loop.last_measurement

    @property
    def last_pose(self) -> TipMeasurement | None:
        """The loop's last measurement with a 6-DoF pose (None: none yet)."""
        return self.loop.last_pose

    def now(self) -> float:
        """The time on the frames' clock [s]."""
        return self.loop.now()

    def next_cycle(self) -> float:
        """Time on by one control cycle; the new cycle's start [s]."""
        t = self.loop.t + self.loop.rig.control_dt
        self.loop.advance_to(t)
        return t

    def command(self, psi: Array) -> None:
        """Make ``psi`` the command and send it."""
        self.loop.psi_cmd = psi
        self.loop.send(psi)

    def sense(self, target: CycleTarget) -> ProbeReading:
        """The frame measured (the commanded marker axis as the hint), the encoders, the truth."""
        loop = self.loop
        assert loop.sensor is not None and loop.psi_cmd is not None
        frame = loop.take_frame(target, self.phase, self.memory, self.stats)
        t_ask = loop.now()
        encoders = loop.link.measured_actuators()
        t_read = 0.5 * (t_ask + loop.now())  # the box read them between the request and its reply
        truth = loop.observe()
        axis = forward_kinematics(loop.params, loop.psi_cmd).T_world_marker[:3, 2]  # which way the marker points
        meas = None if frame is None else loop.sensor.measure(frame, axis_hint_world=axis)
        return ProbeReading(meas, t_read, encoders, truth)

    def log_cycle(self, target: CycleTarget, t_wall: float, outcome: CycleOutcome) -> None:
        """Log a probe cycle under ``phase + ':probe'`` and hand it to ``on_cycle``."""
        rec = self.loop.record(target, t_wall, self.phase + ":probe", outcome, float("nan"))
        self.log.add(rec)
        if callable(self.loop.on_cycle):
            self.loop.on_cycle(rec)

    def lost_marker(self, what: str, t: float) -> NoReturn:
        """Hold the arm, stop the phase, raise MarkerLostError."""
        self.loop.link.hold()
        self.stats.stopped = f"{what} at t = {self.loop.elapsed(t):.2f} s"
        raise MarkerLostError(self.stats.stopped + ": arm held", self.stats)

    def skip(self, note: str) -> None:
        """Note why the probe did not run."""
        self.loop.play_probe_note = note
