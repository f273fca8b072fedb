"""The simulated true arm: follows actuator commands through the errors of a plant file.

Signal path, per actuator: target -> first-order motor lag (actuator_tau) -> motor position
(what the encoders measure) -> backlash play operator of width b (the output that moves the
backbones) -> nominal inverse actuation map -> psi_out. Then the arm's true bending (gains,
plane offsets, stem coupling, tip load): models/plant_map.py, shared with the identification's
fit.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_shape import ArmShape, shape_from_frames
from wristmark.models.arm_spec import Arm, ArmSpec, arm_size
from wristmark.models.errors import InputError
from wristmark.models.kinematics import ArmFrames, check_psi
from wristmark.models.plant_map import plant_bend, true_arm
from wristmark.models.plant_params import PlantParams

Array = NDArray[np.float64]


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
        self._true: Arm = true_arm(params, plant)
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

    def _bend(self, q_out: Array) -> tuple[Array, ArmFrames, Array]:
        """The true configuration, frames and stem for the backbones' configuration ``q_out``
        (models/plant_map.py)."""
        return plant_bend(self._true, self.plant, q_out)
