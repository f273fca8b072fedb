"""What the play probe (rig/loop/play_probe.py) needs of the servo loop, and nothing more.

The probe runs inside one closed-loop phase of :class:`rig.loop.servo_loop.ServoLoop` with the
controller's feedback paused: it reads the settled command, the last measurement and the
controller, runs its own cycles (time on to the next one, sense, command, log) and, when the
marker stays lost, stops the phase as the loop would. :class:`ProbeLoop` lists exactly those
operations; the servo loop hands the probe an adapter bound to its phase (servo_loop.py), so
the probe does not import the loop. Configurations [rad, m, ...], times [s] on the frames' clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NoReturn, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from wristmark.models.arm_spec import Arm
    from wristmark.rig.loop.ground_truth import TruthSample
    from wristmark.rig.loop.rig_config import RigConfig
    from wristmark.rig.loop.servo_cycle import CycleOutcome, CycleTarget
    from wristmark.rig.loop.tip_sensors import TipMeasurement
    from wristmark.solvers.controller import Controller

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ProbeReading:
    """One probe cycle's sensing: the frame's measurement (None: no frame), the time the encoders
    were read on the frames' clock [s], their readings [rad, m, m, m, m, m] and the ground truth."""

    meas: TipMeasurement | None
    t_read: float
    encoders: Array
    truth: TruthSample


class ProbeLoop(Protocol):
    """The servo loop as the play probe sees it: one closed-loop phase, feedback paused."""

    @property
    def params(self) -> Arm:
        """The nominal arm model."""
        ...

    @property
    def rig(self) -> RigConfig:
        """The rig's settings (the control cycle, how many lost cycles in a row stop a phase)."""
        ...

    @property
    def controller(self) -> Controller:
        """The closed loop's controller: the probe's settings and :meth:`Controller.start_play`."""
        ...

    @property
    def psi_cmd(self) -> Array:
        """The configuration last commanded [rad, m, ...]."""
        ...

    @property
    def last_measurement(self) -> TipMeasurement | None:
        """The loop's last measurement (None: none yet)."""
        ...

    @property
    def last_pose(self) -> TipMeasurement | None:
        """The loop's last measurement with a 6-DoF pose: orientation and roll known (None: none yet)."""
        ...

    def now(self) -> float:
        """The time on the frames' clock [s]."""
        ...

    def next_cycle(self) -> float:
        """Let the loop's time run one control cycle on; returns the new cycle's start [s]."""
        ...

    def command(self, psi: Array) -> None:
        """Make ``psi`` the command and send it to the actuators."""
        ...

    def sense(self, target: CycleTarget) -> ProbeReading:
        """This cycle's frame measured (the commanded arm's marker axis as the hint), the
        encoders read and the ground truth observed, in the loop's order."""
        ...

    def log_cycle(self, target: CycleTarget, t_wall: float, outcome: CycleOutcome) -> None:
        """Log one probe cycle (under the phase's ``:probe``) and hand it to the loop's hook."""
        ...

    def lost_marker(self, what: str, t: float) -> NoReturn:
        """Hold the arm and stop the phase: MarkerLostError saying ``what`` happened at ``t``."""
        ...

    def skip(self, note: str) -> None:
        """The probe did not run: ``note`` says why (the loop's ``play_probe_note``)."""
        ...
