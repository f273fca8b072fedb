"""The identification's excitation: the arm moved through poses, each approached from a chosen
side of every actuator's play, and its tip measured at rest (docs/identification.md).

Per pose: a ramp to the approach point, at the velocity limits (fast: the motors' lag shows) or,
at every ``slow_every``-th pose, at ``slow_speed`` x them (the same lag seen at another speed),
each actuator ``approach`` x its play unit past the pose on its side (random per pose and
actuator, so that every play is seen from both sides in many combinations), a short hold, the
step to the pose, ``settle`` [s] at rest, then ``frames`` measured frames. Every cycle the
encoders are read and the target sent is recorded: the fit (solvers/identification.py) runs the
play through those readings, so the path between poses needs no model. Works through any
:class:`rig.link.actuator_link.ActuatorLink` with a frame feed and a tip sensor: the simulated
bench, the virtual lab and hardware alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm, arm_size, home_psi
from wristmark.models.ik import solve_tip_ik
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.limits import clamp_psi
from wristmark.rig.link.actuator_link import ActuatorLink
from wristmark.rig.loop.frame_feed import FrameFeed
from wristmark.rig.loop.servo_cycle import ramp_to
from wristmark.rig.loop.tip_sensors import TipSensor
from wristmark.rig.targets.trajectories import CUBE_SIZE, workspace_centre
from wristmark.solvers.identification import ExcitationData

Array = NDArray[np.float64]
MEASURE_TRIES = 4  # live camera: cycles at rest per frame to measure, at most (frames the tracker gave up on)
__all__ = ["ExcitationPlan", "excitation_plan", "run_excitation"]


@dataclass(frozen=True)
class ExcitationPlan:
    """The poses (N, n) [rad, m, ...], per pose and actuator the side (+-1) it is approached from,
    the approach distance per actuator (actuator units), the hold at the approach point and the
    settle at the pose [s], the frames measured per pose, and every ``slow_every``-th pose's ramp
    at ``slow_speed`` x the velocity limits (0: all at full speed); ``loads``: per pose a known
    tip force [N] in {w} hung on the arm (a bench that can load it: run_excitation's apply_load)."""

    poses: Array
    sides: Array
    approach: Array
    hold: float = 0.12
    settle: float = 0.42
    frames: int = 2
    slow_every: int = 4
    slow_speed: float = 0.3
    loads: Array | None = None  # per pose a known tip force added to the arm's own [N] in {w} (None: none)

    def speed(self, i: int) -> float:
        """The ramp's speed into pose ``i``'s approach point, x the velocity limits."""
        return self.slow_speed if self.slow_every > 0 and i % self.slow_every == self.slow_every - 1 else 1.0

    def duration(self, dt: float, params: Arm) -> float:
        """Seconds of arm motion the plan takes at control cycle ``dt`` (ramps included)."""
        total, psi = 0.0, self.poses[0]
        for i, (q, side) in enumerate(zip(self.poses, self.sides)):
            a = psi_from_actuators(params, actuators_from_psi(params, q) + side * self.approach, delta_hint=q)
            ramp = ramp_to(params, psi, a, dt, self.speed(i))
            total += (len(ramp) + 1) * dt + self.hold + self.settle + self.frames * dt
            psi = q
        return total


def excitation_plan(params: Arm, play_unit: Array, poses: int = 30, seed: int = 0, spread: float = 1.5,
                    joint_noise: float = 0.08) -> ExcitationPlan:
    """``poses`` poses around the experiments' cube (tips uniform in ``spread`` x its size about
    the workspace centre, position IK from home, then each joint moved at random by up to
    ``joint_noise`` / 0.08 x 0.15 rad or 3 mm, so that the gains, offsets and coupling are seen in
    more than the IK's family of shapes while the marker stays in view), ordered nearest first,
    approached from random sides 2.5 x the play unit away."""
    rng = np.random.default_rng(seed)
    centre = workspace_centre(params)
    q0 = home_psi(params)
    n, m = arm_size(params)
    size = np.asarray(CUBE_SIZE) * spread
    out = []
    for _ in range(poses):
        p = centre + (rng.uniform(-0.5, 0.5, 3) * size)
        q = solve_tip_ik(params, p, q0).psi
        q = q + rng.uniform(-1.0, 1.0, n) * np.where(_is_prismatic(params, n), 0.003, 0.15) * joint_noise / 0.08
        out.append(clamp_psi(params, q))
    sides = rng.choice([-1.0, 1.0], size=(poses, m))
    return ExcitationPlan(_nearest_first(params, np.array(out)), sides, 2.5 * np.asarray(play_unit, float))


def _nearest_first(params: Arm, poses: Array) -> Array:
    """The poses reordered greedily, each next the one the velocity limits reach soonest (the
    ramps between poses are most of the excitation's time)."""
    from wristmark.models.limits import velocity_limits

    v = velocity_limits(params)
    left = list(range(1, len(poses)))
    order = [0]
    while left:
        here = poses[order[-1]]
        k = min(left, key=lambda i: float(np.max(np.abs(poses[i] - here) / v)))
        order.append(k)
        left.remove(k)
    return poses[order]


def _is_prismatic(params: Arm, n: int) -> NDArray[np.bool_]:
    from wristmark.models.arm_spec import ArmSpec

    idx = set(params.layout.prismatic.tolist()) if isinstance(params, ArmSpec) else {1}
    return np.array([i in idx for i in range(n)])


def run_excitation(params: Arm, link: ActuatorLink, frames: FrameFeed, sensor: TipSensor, plan: ExcitationPlan,
                   dt: float, on_pose: object = None, frame_wait: float = 0.0,
                   apply_load: Callable[[Array], None] | None = None) -> ExcitationData:
    """Move the arm through ``plan`` one target per control cycle of ``dt`` [s], reading the
    encoders every cycle and measuring ``plan.frames`` frames at rest at every pose; the arm is
    held at the end. ``on_pose(i)`` after each pose (progress).

    frame_wait > 0 (a live camera on the wall clock: hardware, the virtual lab): each measured
    frame is one that arrived after its cycle began, waited for up to ``frame_wait`` [s] (a live
    feed otherwise hands out the same newest frame once, then nothing); the encoders are read
    again after the wait, which feeds the box's watchdog before the frame is tracked; a frame
    not tracked (the tracker's budget ran out: the first frame at a new pose may need a search of
    the whole image) is not recorded, and the pose is held for up to MEASURE_TRIES x
    ``plan.frames`` cycles until ``plan.frames`` frames were tracked.

    A plan with ``loads`` needs ``apply_load(F)``, which hangs the known tip force F [N] in {w}
    on the arm (the simulated bench; on hardware a person, rig/loop/known_load.py); it is called
    before each pose's approach (the excitation's clock then goes on from the link's time, however
    long it took), and each measured tip's load is recorded for the fit."""
    if plan.loads is not None and apply_load is None:
        raise ValueError("an excitation with known loads needs a bench that applies them (apply_load)")
    times: list[float] = []
    enc: list[Array] = []
    tgt: list[Array] = []
    idx: list[int] = []
    tips: list[Array] = []
    hints: list[Array] = []
    loads: list[Array] = []
    load = np.zeros(3)
    psi = psi_from_actuators(params, np.asarray(link.measured_actuators(), float), delta_hint=plan.poses[0])
    t = float(link.time)

    def cycle(command: Array, measure: bool) -> bool:
        nonlocal t
        t += dt
        link.advance_to(t)
        times.append(t)
        enc.append(np.asarray(link.measured_actuators(), float).copy())
        if measure:
            if frame_wait > 0:
                now = time.monotonic()
                frame = frames.take(fresh_after=now, wait_until=now + frame_wait)
                link.measured_actuators()  # a GET_STATE: the watchdog fed before the tracking
            else:
                frame = frames.take()
            axis = forward_kinematics(params, command).T_world_marker[:3, 2]
            meas = None if frame is None else sensor.measure(frame, axis_hint_world=axis)
            ok = meas is not None and meas.ok and meas.p_world is not None
            if ok or frame_wait <= 0:
                idx.append(len(times) - 1)
                tips.append(np.asarray(meas.p_world, float) if ok and meas is not None and meas.p_world is not None
                            else np.full(3, np.nan))
                hints.append(np.asarray(command, float))
                loads.append(load.copy())
        a = actuators_from_psi(params, command)
        link.send_target(a)
        tgt.append(a)
        return measure and ok

    try:
        for i, (q, side) in enumerate(zip(plan.poses, plan.sides)):
            if plan.loads is not None and apply_load is not None:
                load = np.asarray(plan.loads[i], float)
                apply_load(load)
                t = max(t, float(link.time))  # a person hung the weight meanwhile: the ramps go on from now
            a_q = actuators_from_psi(params, q) + side * plan.approach
            approach = clamp_psi(params, psi_from_actuators(params, a_q, delta_hint=q))
            for step in ramp_to(params, psi, approach, dt, plan.speed(i)) + [approach]:
                cycle(step, False)
            for _ in range(max(1, round(plan.hold / dt))):
                cycle(approach, False)
            for _ in range(max(1, round(plan.settle / dt))):
                cycle(q, False)
            if frame_wait > 0:  # a live camera: up to MEASURE_TRIES x the frames until that many are tracked
                got = 0
                for _ in range(MEASURE_TRIES * plan.frames):
                    got += cycle(q, True)
                    if got >= plan.frames:
                        break
            else:
                for _ in range(plan.frames):
                    cycle(q, True)
            psi = q
            if callable(on_pose):
                on_pose(i)
    finally:
        link.hold()
    return ExcitationData(np.array(times), np.array(enc), np.array(tgt), np.array(idx, dtype=int),
                          np.array(tips).reshape(-1, 3), np.array(hints).reshape(len(hints), -1),
                          {"motion_s": float(times[-1] - times[0]) if times else 0.0, "poses": len(plan.poses)},
                          loads=None if plan.loads is None else np.array(loads).reshape(-1, 3))
