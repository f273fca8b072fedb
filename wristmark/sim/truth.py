"""The simulated bench's ground truth for the servo loop's log: the true arm, seen by the
simulated optical tracker (:class:`rig.loop.ground_truth.GroundTruth`)."""

from __future__ import annotations

import numpy as np

from wristmark.models.plant_interface import ActuatedArm
from wristmark.rig.loop.ground_truth import TruthSample
from wristmark.sim.optical_tracker import OpticalTracker


class SimulatedTruth:
    """The true tip and tip frame, their 6-DoF optical-tracker measurement and the true
    configuration of ``arm`` now."""

    def __init__(self, arm: ActuatedArm, tracker: OpticalTracker) -> None:
        self.arm = arm
        self.tracker = tracker

    def observe(self) -> TruthSample:
        """Tip and tracker in {w} [m] with the tip frame's orientations; psi_true [rad, m] (NaN
        when the arm does not expose it)."""
        shape = self.arm.true_shape()
        p_true = shape.tip.copy()
        R_true = shape.frames.T_world_tip[:3, :3].copy()
        p_trk, R_trk = self.tracker.measure_pose(p_true, R_true)
        psi_true = np.asarray(getattr(self.arm, "true_psi", np.full(6, np.nan)), float)
        return TruthSample(p_true, np.asarray(p_trk, float), psi_true, R_true, R_trk)
