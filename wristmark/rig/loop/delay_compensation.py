"""Delay compensation of the tip measurement: what the arm did between a frame's capture and now.

A frame shows the tip at its capture time ``t_capture``, but the controller's command takes
effect ``t_now``; on a camera that gap varies from cycle to cycle (rendering, encoding,
transport, decoding, the frame's phase against the loop), and commands sent in between already
moved the arm. :class:`DelayCompensator` keeps a short history of the commanded configurations
with the times they were sent and adds the nominal model's predicted tip motion over the gap:

    p_compensated = p_measured(t_capture) + tip(model(t_now)) - tip(model(t_capture))

where ``model(t)`` is the configuration the arm is expected to have at ``t``: the last command
sent at or before ``t`` (``tau = 0``: commands take effect at once), or the commands passed
through a first-order lag of time constant ``tau`` [s] per actuator (the actuators' own lag), or
each command reached ``reach`` [s] after its send (the ``--model`` link inverts the lag so that
each target is reached a cycle after it went out; rig ``delay_compensation_reach``).
The measured orientation (a rotation mapping the tip frame's axes into {w}) is moved on the same
way, by the model's turn of the tip frame over the gap, in {w}:

    R_compensated = R_model(t_now) @ R_model(t_capture).T @ R_measured

Only the difference of the model between the two instants is used, so the model's own error
(calibration, backlash, load) cancels to first order. The servo loop records the configuration the
arm is expected to follow for each command (``Controller.output_model``): with a dead-band
inversion that is the nominal configuration, not the motor command, whose jumps across the band
do not move the arm (recording them predicted tip motion that never happened). With a
``correction`` (rig/loop/motion_correction.py) the model's motion is mapped by the 3x3 matrix learnt
from the measurements themselves (:meth:`DelayCompensator.observe`): the model's gain errors
would otherwise leave a bias that grows with the frames' age. All times on the loop's clock [s], tips
in {w} [m], configurations psi [rad, m, rad, rad, rad, rad].
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_spec import Arm
from wristmark.models.kinematics import forward_kinematics, tip_position
from wristmark.rig.loop.motion_correction import MotionCorrection

Array = NDArray[np.float64]


@dataclass(frozen=True)
class _Sent:
    """A command sent at ``t`` [s]: its configuration, and the modelled actuators then (before it)."""

    t: float
    psi: Array
    a_cmd: Array
    a_model: Array


class DelayCompensator:
    """History of sent commands and the predicted tip motion between two instants.

    tau: first-order lag [s] of every actuator assumed by the model (0: a command takes effect
    at once); reach: each command is reached this long [s] after its send, along the lag's curve
    (a link that inverts the lag, rig/link/model_link.py; 0: by the lag alone); horizon: how far
    back [s] the history reaches (older captures are predicted from its oldest entry);
    correction: the learnt map of the model's motion to the arm's (None: the model as it is)."""

    def __init__(self, params: Arm, tau: float = 0.0, horizon: float = 1.0,
                 correction: MotionCorrection | None = None, reach: float = 0.0) -> None:
        if not (math.isfinite(tau) and tau >= 0):
            raise ValueError(f"tau must be >= 0 s, got {tau}")
        if not (math.isfinite(reach) and reach >= 0):
            raise ValueError(f"reach must be >= 0 s, got {reach}")
        self.params = params
        self.tau = float(tau)
        self.reach = float(reach)
        self.horizon = float(horizon)
        self.correction = correction
        self._sent: deque[_Sent] = deque()
        # model_psi per instant until the history changes: a cycle asks for the same two
        # instants twice (the tip's motion, then its turn), and with a lag each is a solve
        self._psi_at: dict[float, Array | None] = {}

    def reset(self) -> None:
        """Forget every command (a new run) and the learnt correction."""
        self._sent.clear()
        self._psi_at.clear()
        if self.correction is not None:
            self.correction.reset()

    def observe(self, p_measured: Array, t_capture: float) -> None:
        """An accepted measurement [m] in {w} captured at ``t_capture`` [s]: the correction (if
        any) learns from the measured motion since the previous one against the model's."""
        c = self.correction
        if c is None:
            return
        prev = c.last_capture
        motion = self.predicted_motion(prev, t_capture) if math.isfinite(prev) else None
        c.observe(p_measured, t_capture, motion)

    def record(self, t: float, psi: Array) -> None:
        """A command ``psi`` was sent at ``t`` [s] (times must not decrease)."""
        if self._sent and t < self._sent[-1].t:
            raise ValueError(f"command times must not decrease: {t} after {self._sent[-1].t}")
        q = np.asarray(psi, float).copy()
        a_cmd = actuators_from_psi(self.params, q)
        a_model = self._actuators_at(t) if self._sent else a_cmd
        self._sent.append(_Sent(float(t), q, a_cmd, a_model))
        self._psi_at.clear()
        while len(self._sent) > 2 and self._sent[1].t < t - self.horizon:
            self._sent.popleft()

    def _entry_at(self, t: float) -> _Sent | None:
        """The last command sent at or before ``t`` (the oldest one when ``t`` precedes them all)."""
        if not self._sent:
            return None
        for e in reversed(self._sent):
            if e.t <= t:
                return e
        return self._sent[0]

    def _actuators_at(self, t: float) -> Array:
        e = self._entry_at(t)
        assert e is not None
        gap = max(0.0, t - e.t)
        if self.reach > 0.0:  # reached ``reach`` after the send, along the lag's curve (a link inverting it)
            if gap >= self.reach:
                return e.a_cmd
            share = gap / self.reach if self.tau == 0.0 else \
                -math.expm1(-gap / self.tau) / -math.expm1(-self.reach / self.tau)
            return e.a_model + (e.a_cmd - e.a_model) * share
        if self.tau == 0.0:
            return e.a_cmd
        return e.a_cmd + (e.a_model - e.a_cmd) * math.exp(-gap / self.tau)

    def model_psi(self, t: float) -> Array | None:
        """The configuration the model expects at ``t`` [s] (None before any command; solved
        once per instant until the next :meth:`record`)."""
        if t in self._psi_at:
            return self._psi_at[t]
        e = self._entry_at(t)
        if e is None:
            psi = None
        elif self.tau == 0.0 and self.reach == 0.0:
            psi = e.psi
        else:
            psi = psi_from_actuators(self.params, self._actuators_at(t), delta_hint=e.psi)
        if len(self._psi_at) > 64:  # many instants between two commands (not a loop's pattern)
            self._psi_at.clear()
        self._psi_at[t] = psi
        return psi

    def predicted_motion(self, t_capture: float, t_now: float) -> Array:
        """The model's tip motion in {w} [m] from ``t_capture`` to ``t_now`` (zeros without a
        history, when nothing changed, or when the two instants are the same). ``t_now`` may
        precede ``t_capture``: a frame captured after the instant it is compensated to (a cycle's
        start) is moved back by the motion the model expects in between."""
        if not (math.isfinite(t_capture) and math.isfinite(t_now)) or t_now == t_capture:
            return np.zeros(3)
        before, after = self.model_psi(t_capture), self.model_psi(t_now)
        if before is None or after is None or np.array_equal(before, after):
            return np.zeros(3)
        return tip_position(self.params, after) - tip_position(self.params, before)

    def compensate(self, p_measured: Array, t_capture: float, t_now: float) -> Array:
        """The measured tip [m] in {w} moved on by the model (corrected, with a correction) from
        its capture to ``t_now``."""
        motion = self.predicted_motion(t_capture, t_now)
        if self.correction is not None:
            motion = self.correction.apply(motion)
        return np.asarray(p_measured, float) + motion

    def predicted_turn(self, t_capture: float, t_now: float) -> Array:
        """The model's turn of the tip frame in {w} (3x3) from ``t_capture`` to ``t_now`` [s]:
        R_tip(model(t_now)) @ R_tip(model(t_capture)).T (identity without a history, when nothing
        changed, or when the two instants are the same)."""
        if not (math.isfinite(t_capture) and math.isfinite(t_now)) or t_now == t_capture:
            return np.eye(3)
        before, after = self.model_psi(t_capture), self.model_psi(t_now)
        if before is None or after is None or np.array_equal(before, after):
            return np.eye(3)
        R_before = forward_kinematics(self.params, before).T_world_tip[:3, :3]
        R_after = forward_kinematics(self.params, after).T_world_tip[:3, :3]
        return np.asarray(R_after @ R_before.T, float)

    def compensate_rotation(self, R_measured: Array, t_capture: float, t_now: float) -> Array:
        """The measured tip-frame orientation (3x3, tip axes in {w}) turned on by the model from
        its capture to ``t_now`` [s] (the learnt correction maps positions only: not applied)."""
        return self.predicted_turn(t_capture, t_now) @ np.asarray(R_measured, float)
