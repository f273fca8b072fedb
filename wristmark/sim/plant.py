"""The simulated true arm: follows actuator commands through the errors of a plant file.

Signal path, per actuator: target -> first-order motor lag (actuator_tau) -> motor position
(what the encoders measure) -> backlash play operator of width b (the output that moves the
backbones) -> nominal inverse actuation map -> psi_out. Then the arm's true bending:
theta_t = g_t theta_out, delta_t = delta_out + o_t; the exposed stem (length d, incision to
{1b}) bends as a constant-curvature arc of angle zeta * theta_1 in segment 1's plane (stem
coupling); a tip force F adds to each segment's bend vector the moment of F about the
segment's base, perpendicular to its axis, divided by its stiffness (small-deflection,
evaluated on the unloaded shape). A bend (theta, delta) is the vector theta [sin d, cos d] in
the base-ring plane (the rotation axis of eq. 2), so load bends compose with commanded ones.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_shape import ArmShape, shape_from_frames
from wristmark.models.arm_spec import Arm, ArmSpec, arm_size
from wristmark.models.constant_curvature import rot_z, segment_point
from wristmark.models.errors import InputError
from wristmark.models.kinematics import ArmFrames, check_psi, forward_kinematics
from wristmark.sim.plant_params import PlantParams

Array = NDArray[np.float64]


def _add_bend(theta: float, delta: float, dv: Array) -> tuple[float, float]:
    bx = theta * math.sin(delta) + dv[0]
    by = theta * math.cos(delta) + dv[1]
    th = math.hypot(bx, by)
    return th, (math.atan2(bx, by) if th > 0 else delta)


class TruePlant:
    """Simulated true arm implementing :class:`models.plant_interface.ActuatedArm`: commanded psi
    [rad, m, ...] in, true shape in {w} [m] out, integrated in steps of ``dt_internal`` [s].

    history: how far back [s] the arm remembers its backbones' positions (every internal step),
    so that :meth:`true_shape_at` can give its shape at an earlier instant (a camera whose frames
    are that old; 0: no memory)."""

    def __init__(self, params: Arm, plant: PlantParams, psi0: Array | None = None,
                 dt_internal: float = 1e-3, history: float = 0.0) -> None:
        self.params = params
        n, m = arm_size(params)
        segments = len(params.segments) if isinstance(params, ArmSpec) else 2
        self.plant = plant = plant.for_arm(segments, m)
        self._m = m
        # any arm: the true arm's planar segments bend in their plane turned by the plane offset
        self._true: Arm = params
        if isinstance(params, ArmSpec):
            self._true = replace(params, segments=tuple(
                replace(sg, planar=sg.planar + plant.plane_offset[t]) if sg.planar is not None else sg
                for t, sg in enumerate(params.segments)))
        self.dt_internal = float(dt_internal)
        q0 = check_psi(psi0 if psi0 is not None else np.zeros(n), params)
        a0 = actuators_from_psi(params, q0)
        self._target = a0.copy()
        self._motor = a0.copy()
        self._output = a0.copy()
        self._half_play = 0.5 * np.asarray(plant.backlash, float)
        self._delta_hint = q0.copy()
        self._time = 0.0
        self._cache: tuple[Array, ArmFrames, Array] | None = None
        self.history = float(history)
        self._past: deque[tuple[float, Array]] = deque([(0.0, self._output.copy())])

    # -- ActuatedArm ---------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self._time

    def command(self, actuators: Array) -> None:
        """Set actuator targets [rad, m, m, m, m, m] (any arm: its m actuators)."""
        a = np.asarray(actuators, float)
        if a.shape != (self._m,) or not np.all(np.isfinite(a)):
            raise InputError(f"actuator targets must be {self._m} finite numbers, got {a}")
        self._target = a.copy()

    def hold(self) -> None:
        """Freeze the targets at the motors' current positions."""
        self._target = self._motor.copy()

    def advance(self, dt: float) -> None:
        """Integrate motors (exact first-order step) and backlash for ``dt`` seconds."""
        if dt <= 0:
            return
        n = max(1, int(math.ceil(dt / self.dt_internal - 1e-9)))
        h = dt / n
        tau = self.plant.actuator_tau
        alpha = 1.0 if tau == 0 else 1.0 - math.exp(-h / tau)
        for i in range(n):
            self._motor += alpha * (self._target - self._motor)
            self._output = np.clip(self._output, self._motor - self._half_play, self._motor + self._half_play)
            if self.history > 0:
                self._past.append((self._time + (i + 1) * h, self._output.copy()))
        self._time += dt
        self._cache = None
        while len(self._past) > 2 and self._past[1][0] < self._time - self.history:
            self._past.popleft()

    def measured_actuators(self) -> Array:
        """Motor encoder positions (before backlash)."""
        return self._motor.copy()

    def true_shape(self) -> ArmShape:
        """The true arm's shape now."""
        psi, frames, stem = self._state()
        return shape_from_frames(self._true, psi, frames, stem_points=stem)

    def true_shape_at(self, t: float) -> ArmShape:
        """The true arm's shape at the earlier instant ``t`` [s] of its clock: its backbones'
        positions interpolated between internal steps (raises InputError beyond the ``history``
        it keeps; ``t`` at or after now: the shape now)."""
        if t >= self._time:
            return self.true_shape()
        if self.history <= 0 or t < self._past[0][0] - 1e-12:
            raise InputError(f"the simulated arm keeps {self.history:g} s of history: no shape at t = {t:.4f} s "
                             f"(now {self._time:.4f} s)")
        ts = np.fromiter((p[0] for p in self._past), float, len(self._past))
        outs = np.array([p[1] for p in self._past])
        output = np.array([np.interp(t, ts, outs[:, i]) for i in range(outs.shape[1])])
        psi, frames, stem = self._bend(psi_from_actuators(self.params, output, self._delta_hint))
        return shape_from_frames(self._true, psi, frames, stem_points=stem)

    # -- truth -----------------------------------------------------------------------------
    @property
    def true_psi(self) -> Array:
        """Effective configuration of the true arm (after backlash, gains, offsets, load)."""
        return self._state()[0].copy()

    def true_tip(self) -> Array:
        """True tip position in {w} [m]."""
        return self._state()[1].tip.copy()

    def _state(self) -> tuple[Array, ArmFrames, Array]:
        if self._cache is None:
            q = psi_from_actuators(self.params, self._output, self._delta_hint)
            self._delta_hint = q
            self._cache = self._bend(q)
        return self._cache

    def _chain(self, q: Array) -> tuple[ArmFrames, Array]:
        """The model's chain (models.kinematics) with the stem bent by stem_coupling x theta1, and
        points along the bent stem."""
        if isinstance(self._true, ArmSpec):
            spec = self._true
            lay = spec.layout
            th1 = float(q[spec.theta_index[0]])
            de1 = spec.segments[0].planar if spec.delta_index[0] is None else float(q[spec.delta_index[0]])
            theta_s = self.plant.stem_coupling * th1
            R_w_s = rot_z(float(q[lay.revolute].sum()))
            d = float(q[lay.prismatic].sum())
            stem = np.array([R_w_s @ segment_point(d, theta_s, de1 or 0.0, s) for s in np.linspace(0, 1, 8)])
            return forward_kinematics(spec, q, stem_bend=theta_s), stem
        theta_s = self.plant.stem_coupling * q[2]
        R_w_s = rot_z(q[0])
        stem = np.array([R_w_s @ segment_point(q[1], theta_s, q[3], s) for s in np.linspace(0, 1, 8)])
        return forward_kinematics(self.params, q, stem_bend=theta_s), stem

    def _bend(self, q_out: Array) -> tuple[Array, ArmFrames, Array]:
        if isinstance(self._true, ArmSpec):
            return self._bend_any(self._true, q_out)
        P = self.plant
        q = q_out.copy()
        for t in range(2):
            q[2 + 2 * t] *= P.bend_gain[t]
            q[3 + 2 * t] += P.plane_offset[t]
        frames, stem = self._chain(q)
        F = np.asarray(P.tip_force, float)
        if np.any(F != 0.0):
            for t, T_base in ((0, frames.T_world_1b), (1, frames.T_world_2b)):
                M = np.cross(frames.tip - T_base[:3, 3], F)
                m_loc = T_base[:3, :3].T @ M
                th, de = _add_bend(q[2 + 2 * t], q[3 + 2 * t], m_loc[:2] / P.segment_stiffness[t])
                q[2 + 2 * t], q[3 + 2 * t] = th, de
            frames, stem = self._chain(q)
        return q, frames, stem

    def _bend_any(self, spec: ArmSpec, q_out: Array) -> tuple[Array, ArmFrames, Array]:
        """:meth:`_bend` for any arm: per segment the gain on theta and the offset on delta (a
        planar segment's offset is in its turned plane), then the tip load's bend."""
        P = self.plant
        q = q_out.copy()
        idx = list(zip(spec.theta_index, spec.delta_index))
        for t, (ti, di) in enumerate(idx):
            q[ti] *= P.bend_gain[t]
            if di is not None:
                q[di] += P.plane_offset[t]
        frames, stem = self._chain(q)
        F = np.asarray(P.tip_force, float)
        if np.any(F != 0.0):
            for t, ((ti, di), T_base) in enumerate(zip(idx, frames.segment_bases)):
                M = np.cross(frames.tip - T_base[:3, 3], F)
                dv = (T_base[:3, :3].T @ M)[:2] / P.segment_stiffness[t]
                if di is None:  # planar: the load's bend along the plane, theta [sin p, cos p]
                    plane = spec.segments[t].planar or 0.0
                    q[ti] += dv[0] * math.sin(plane) + dv[1] * math.cos(plane)
                else:
                    q[ti], q[di] = _add_bend(q[ti], q[di], dv)
            frames, stem = self._chain(q)
        return q, frames, stem
