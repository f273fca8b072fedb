"""The play probe: the servo loop measures each actuator's play before a closed-loop walk.

Run by :class:`rig.loop.servo_loop.ServoLoop` (through the narrow view of it in
rig/loop/probe_loop.py, :class:`ProbeLoop`) between the closed loop's first settle and a second,
short one, when the controller asks for it (``play_probe: true`` with the encoders' dead-band
inversion, solvers/play_observer.py). The controller's feedback is paused: each actuator in
turn, the others held at the settled command, follows a triangle of ``play_probe_amplitude`` x
its largest play (out, back through, return: it ends moving up, at the settled command) over
``play_probe_time`` seconds, one target per cycle within the velocity limits. Every cycle the
frame is measured and the encoders read; the tracker's 6-DoF tip pose turned into actuator
values by the nominal pose IK (models/pose_ik.py, models/actuation.py) is the arm side, the
encoders interpolated to the frame's capture time (on the wall clock they are read after the
frame arrived) the motor side; solvers/play_probe_fit.py fits the play per actuator. The
inversion then starts from the fitted play, on a known side and place in the band. Each motor's
first-order lag is fitted too, from the targets sent and the encoders read alone (both stamped
on the loop's clock; no pose needed), for the inversion's reversal burst (``backlash_motor_burst``).

An arm whose pose does not give its actuators (fewer than 6 joints, or more actuators than
joints: tendons) is probed the same way with the controller's ``play_probe_from_tip`` (off by
default: skipped with a note), each actuator's output read from the tip alone along the tip's
motion it causes (:class:`TipProjection`; any marker). Otherwise the probe assumes a 6-DoF
pose: without one in the settle's last ``POSE_RECENT_CYCLES`` cycles (the reference marker, or a
coded marker whose roll code was not read in any of them; one cycle that missed it does not
count) nothing moves, the loop's ``play_probe_note`` says so (the experiments put it in
result.json; not on stderr, where a run prints only its one-line stop), and the inversion learns
the play online at the reversals as without a probe. The probe's cycles are logged as
``phase + ':probe'`` and are not counted in the walk's errors; more than the rig's
``max_lost_cycles`` probe cycles in a row without a pose (a coded sleeve's unread roll is none)
hold the arm and stop the run (MarkerLostError), as in the loop. Works the same on the simulated
bench and on the hardware path (GET_STATE gives the encoders, the frames the pose).
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm, arm_size
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import clamp_psi, clamp_velocity
from wristmark.models.pose_ik import solve_pose_ik
from wristmark.models.units import on_micro_grid
from wristmark.rig.loop.probe_loop import ProbeLoop
from wristmark.rig.loop.servo_cycle import CycleOutcome, CycleTarget
from wristmark.solvers.play_probe_fit import PlayFit, fit_motor_lag, fit_play, fused_readout

if TYPE_CHECKING:
    from wristmark.rig.loop.tip_sensors import TipMeasurement

Array = NDArray[np.float64]
RESTORE_CYCLES = 3  # cycles the probe waits after its last command (the motor's lag is ~0.07 s)
TURN_MAX = 0.1  # [rad] a tip turn read since the probe's first beyond this is not one it caused (TipProjection.turn)
POSE_RECENT_CYCLES = 10  # a 6-DoF pose in the settle's last this many cycles lets the probe run
FEW_JOINTS = ("play probe skipped: the arm has fewer than 6 joints, so a measured pose does not give its actuators "
              "(the play is learnt online; play_probe_from_tip: true reads each from the tip)")
MORE_ACTUATORS = ("play probe skipped: the arm has more actuators than joints (tendons or pairs), so a measured pose "
                  "does not give each actuator's output (the play is learnt online; play_probe_from_tip: true reads "
                  "each from the tip)")
NO_TIP = "play probe skipped: no tip measured at the end of the settle; the play is learnt online at the reversals"
NO_POSE = "play probe skipped: the tracker gives no 6-DoF pose (position-only marker or roll code not read); " \
          "the play is learnt online at the reversals"


def triangle(n: int, amplitude: float) -> Array:
    """Offsets of one actuator for the probe's n cycles: 0 -> +A -> -A -> 0 (ends moving up)."""
    x = np.arange(1, n + 1) / n
    return np.interp(x, [0.0, 0.25, 0.75, 1.0], [0.0, amplitude, -amplitude, 0.0])


@dataclasses.dataclass
class ProbeSamples:
    """Per cycle: the actuator probed, the encoders at the frame's capture and the arm-side
    actuator values from the measured pose (NaN when not measured) [rad, m, m, m, m, m]."""

    probed: list[int] = dataclasses.field(default_factory=list)
    motor: list[Array] = dataclasses.field(default_factory=list)
    arm: list[Array] = dataclasses.field(default_factory=list)
    turn: list[Array] = dataclasses.field(default_factory=list)  # TipProjection.turn's readouts (NaN: none)


class TipProjection:
    """The arm side of one actuator from the measured tip alone, for an arm whose pose does not
    give its actuators (fewer than 6 joints, or more actuators than joints): with the others held,
    actuator j's output moves the tip along v_j = d tip / d a_j and turns the tip frame by
    w_j = d theta / d a_j (a rotation vector in {w}) at the probe's start (nominal model,
    models/actuation.py's inverse map). Its output is read twice, as a0_j + v_j . (p - tip0) /
    |v_j|^2 from the tip's place (:meth:`output`) and as a0_j + w_j . theta / |w_j|^2 from the tip
    frame's turn theta since the first orientation read (:meth:`turn`) [rad or m]: affine proxies,
    all solvers/play_probe_fit.py needs; ``fused_readout`` weighs the two by their noise (a stem's
    roll turns the tip by its own angle but moves it only by the arm's lever: read from the place
    alone, the probe refused a single_tendon stem's play as too noisy at 4 of 6 seeds)."""

    def __init__(self, params: Arm, psi0: Array, step: float = 1e-5) -> None:
        self.a0 = actuators_from_psi(params, psi0)
        self.tip0 = forward_kinematics(params, psi0).tip
        rows, turns = [], []
        for j in range(self.a0.size):
            e = np.zeros(self.a0.size)
            e[j] = step
            ends = [forward_kinematics(params, psi_from_actuators(params, self.a0 + s * e, delta_hint=psi0)).T_world_tip
                    for s in (1.0, -1.0)]
            rows.append((ends[0][:3, 3] - ends[1][:3, 3]) / (2.0 * step))
            turns.append(Rotation.from_matrix(ends[0][:3, :3] @ ends[1][:3, :3].T).as_rotvec() / (2.0 * step))
        self.v = np.array(rows)  # (actuators, 3) [m per rad or m]
        self.w = np.array(turns)  # (actuators, 3) [rad per rad or m]
        self._R_first: Array | None = None  # the first tip orientation read, in {w}

    def turn(self, j: int, R_world: Array | None) -> float:
        """Actuator j's output read from the measured tip frame's orientation ``R_world`` (3x3,
        any frame fixed to the tip, in {w}): its turn since the first one read, along w_j. NaN
        where nothing is read, the tip does not turn with it, or the turn is over
        ``TURN_MAX`` [rad] (a reference sleeve's roll read a column off)."""
        w = self.w[j]
        nw = float(w @ w)
        if R_world is None or nw <= 1e-12 or not np.all(np.isfinite(R_world)):
            return float("nan")
        R = np.asarray(R_world, float)
        if self._R_first is None:
            self._R_first = R
        theta = Rotation.from_matrix(R @ self._R_first.T).as_rotvec()
        if float(np.linalg.norm(theta)) > TURN_MAX:
            return float("nan")
        return float(self.a0[j] + w @ theta / nw)

    def output(self, j: int, p_world: Array) -> float:
        """Actuator j's output read from the measured tip ``p_world`` in {w} [m] (NaN where the
        tip does not move with it)."""
        v = self.v[j]
        nv = float(v @ v)
        return float(self.a0[j] + v @ (np.asarray(p_world, float) - self.tip0) / nv) if nv > 1e-12 else float("nan")


def probe_report(fits: list[PlayFit] | None, note: str) -> list[dict[str, Any]] | str | None:
    """What a result file says of the probe: the fits per actuator (SI units), why it was
    skipped, or None when it was not asked for."""
    if fits is not None:
        return [dataclasses.asdict(f) for f in fits]
    return note or None


def run_play_probe(loop: ProbeLoop, template: CycleTarget) -> list[PlayFit] | None:
    """Probe every actuator's play from the loop's settled command and hand the fits to the
    controller (None when skipped: no 6-DoF pose). ``template`` is the target logged."""
    ctrl = loop.controller
    n, m = arm_size(loop.params)
    cfg, params, dt = ctrl.config, loop.params, loop.rig.control_dt
    base = loop.psi_cmd.copy()
    a0 = actuators_from_psi(params, base)
    # a 6-DoF pose gives every actuator of an arm with 6 or more joints and no more actuators than
    # joints; any other arm: each probed actuator's output along the tip's motion it causes
    if (n < 6 or m > n) and not cfg.play_probe_from_tip:
        loop.skip(FEW_JOINTS if n < 6 else MORE_ACTUATORS)
        ctrl.start_play(None)
        return None
    projection = TipProjection(params, base) if (n < 6 or m > n) else None
    # a 6-DoF pose in the settle's last cycles, not only its last one (one cycle may miss the code)
    measured = _recent(loop.last_pose, loop.now(), POSE_RECENT_CYCLES * dt) if projection is None \
        else loop.last_measurement is not None
    if not measured:
        loop.skip(NO_POSE if projection is None else NO_TIP)
        ctrl.start_play(None)
        return None
    play_max = np.asarray(ctrl.play_max, float)
    n = max(4, int(round(cfg.play_probe_time / dt)))
    samples = ProbeSamples()
    reads: list[tuple[float, Array]] = []  # (time on the frames' clock, encoders)
    hint, psi = base, base
    lost = 0  # consecutive probe cycles without a measured pose
    raw: list[PlayFit] = []
    sends: list[tuple[float, Array]] = []  # (time on the frames' clock, actuator targets) of this actuator's probe
    for j in range(a0.size):
        first_read = len(reads)
        sends.clear()
        # cycle i: sample (the arm after i targets), then send target i + 1; sample 0 is taken
        # before the actuator moves, the last one a cycle after its last target (the settled command)
        offsets = triangle(n, cfg.play_probe_amplitude * float(play_max[j]))
        for i in range(n + 1):
            target = dataclasses.replace(template, k=len(samples.probed), t=loop.next_cycle(), settling=False)
            hint, ok = _sample(loop, target, j, samples, reads, hint, projection)
            lost = 0 if ok else lost + 1
            if lost > loop.rig.max_lost_cycles:  # as in the loop: a lost marker holds the arm
                loop.lost_marker(f"marker lost for {lost} cycles during the play probe", target.t)
            if i < n:
                a = a0.copy()
                a[j] += offsets[i]
                want = clamp_psi(params, psi_from_actuators(params, a, delta_hint=base))
                psi = clamp_psi(params, psi + clamp_velocity(params, (want - psi) / dt) * dt)
                loop.command(psi)
                sends.append((loop.now(), actuators_from_psi(params, psi)))
        # fitted at once, a cycle's work (on the wall clock the box's watchdog wants a command
        # every 250 ms: six fits at the end were 0.47 s of silence in the virtual lab)
        loop.command(psi)
        rows = np.flatnonzero(np.asarray(samples.probed) == j)
        motor, arm = np.asarray(samples.motor)[rows, j], np.asarray(samples.arm)[rows, j]
        if projection is not None:  # the tip's place and its turn, weighed by their noise
            arm = fused_readout(motor, [arm, np.asarray(samples.turn)[rows, j]], float(play_max[j]))
        fit = fit_play(motor, arm, float(play_max[j]))
        seg = reads[first_read:]  # the motor's lag from the encoders alone (no pose needed)
        tau = fit_motor_lag(np.array([t for t, _ in sends]), np.array([a[j] for _, a in sends]),
                            np.array([t for t, _ in seg]), np.array([m[j] for _, m in seg]))
        raw.append(dataclasses.replace(fit, motor_tau=tau))
    fits = _carry(raw, samples, np.asarray([m for _, m in reads]))
    # the nominal command: the output as it was before the probe (known where the fit is trusted)
    u = np.array([f.first_output if f.ok else a0[j] for j, f in enumerate(fits)])
    out = ctrl.start_play(fits, reads[-1][1], psi_from_actuators(params, u, delta_hint=base))
    loop.command(base if out is None else out)
    for _ in range(RESTORE_CYCLES):  # the motors reach it before the feedback resumes
        target = dataclasses.replace(template, k=len(samples.probed), t=loop.next_cycle(), settling=False)
        _sample(loop, target, a0.size - 1, samples, reads, hint, projection)
    return fits


def _recent(meas: TipMeasurement | None, now: float, window: float) -> bool:
    """Whether ``meas`` was captured at most ``window`` [s] before ``now`` (the frames' clock)."""
    return meas is not None and now - meas.t_capture <= window


def _sample(loop: ProbeLoop, target: CycleTarget, j: int, samples: ProbeSamples, reads: list[tuple[float, Array]],
            hint: Array, projection: TipProjection | None = None) -> tuple[Array, bool]:
    """One probe cycle's frame, encoders and pose, logged as actuator ``j``'s sample; returns the
    pose IK's solution (the next start) and whether a pose (with ``projection``: a tip) was
    measured."""
    params = loop.params
    t_wall = time.monotonic()
    reading = loop.sense(target)
    reads.append((reading.t_read, on_micro_grid(reading.encoders)))
    meas = reading.meas
    y = np.full(reading.encoders.size, np.nan)
    turn = np.full(reading.encoders.size, np.nan)
    if projection is not None:
        ok = meas is not None and meas.ok and meas.p_world is not None and bool(np.all(np.isfinite(meas.p_world)))
        if ok and meas is not None and meas.p_world is not None:
            y[j] = projection.output(j, meas.p_world)
            turn[j] = projection.turn(j, meas.R_world)
    else:
        ok = meas is not None and meas.ok and meas.p_world is not None and meas.R_world is not None \
            and meas.roll_known  # a coded sleeve whose code was not read: roll only modulo a column
        if ok and meas is not None:
            sol = solve_pose_ik(params, meas.p_world, meas.R_world, hint)
            hint = sol.psi
            y = actuators_from_psi(params, sol.psi)
    samples.probed.append(j)
    samples.motor.append(_encoders_at(reads, meas.t_capture if meas is not None else reads[-1][0]))
    samples.arm.append(y)
    samples.turn.append(turn)
    loop.log_cycle(target, t_wall, CycleOutcome(meas, reading.truth, ok, False, 0.0))
    return hint, ok


def _encoders_at(reads: list[tuple[float, Array]], t: float) -> Array:
    """The encoders interpolated (linearly, held beyond the ends) to the instant ``t``."""
    ts = np.array([r[0] for r in reads])
    ms = np.array([r[1] for r in reads])
    return np.array([np.interp(t, ts, ms[:, i]) for i in range(ms.shape[1])])


def _carry(fits: list[PlayFit], samples: ProbeSamples, reads: Array) -> list[PlayFit]:
    """Each actuator's fit with its last output carried on through the later encoder readings."""
    probed = np.asarray(samples.probed)
    out = []
    for j, f in enumerate(fits):
        o = f.last_output
        for m in reads[np.flatnonzero(probed == j)[-1] + 1:, j]:
            o = float(np.clip(o, m - f.play / 2, m + f.play / 2))
        out.append(dataclasses.replace(f, last_output=o))
    return out
