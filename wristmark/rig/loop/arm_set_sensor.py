"""Several arms' tip sensors on one camera: every sleeve tracked once per frame.

:class:`ArmSetSensor` runs :class:`cvs.tracking.arm_set.ArmSetTracker` on a frame the first time
any arm asks for it and keeps the results for the other arms (the frame's index is the key);
:meth:`ArmSetSensor.view` gives each arm its :class:`rig.loop.tip_sensors.TipSensor`, measuring
that arm's tip in its own {w} (the camera's pose seen from the arm's base). One arm's lost
sleeve is that arm's failed measurement only. ``hints`` (set by the loop before the frame is
measured) holds each arm's expected marker axis in {ll}; the code decides a coded sleeve's
direction anyway, so they matter only for a pose the code could not decide (which is no arm's).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.cvs.tracking.result import TrackResult
from wristmark.models.marker import MarkerModel
from wristmark.rig.loop.tip_sensors import TipMeasurement, tip_measurement

Array = NDArray[np.float64]

__all__ = ["ArmSetSensor", "ArmSensorView"]


class ArmSetSensor:
    """The sleeves of a marker set tracked in each frame of one stereo camera (poses in {ll})."""

    def __init__(self, camera: StereoCamera, markers: Sequence[MarkerModel], magnify: float = 1.0,
                 processes: bool = False, background_search: bool = False) -> None:
        """``processes``: every arm but the first tracked in a worker process of its own
        (cvs.tracking.arm_set; the same results, faster only with a core to spare); :meth:`close`
        stops them. ``background_search``: a missing arm's whole-frame search does not hold the
        other arms' results (ArmSetTracker; for the wall clock's loop, not a simulated one: what
        it finds then depends on how long it takes)."""
        from wristmark.cvs.tracking.arm_set import ArmSetTracker
        from wristmark.cvs.tracking.settings import TrackerSettings

        self.camera = camera
        self.tracker = ArmSetTracker(camera, markers, TrackerSettings(magnify=magnify), processes=processes,
                                     background_search=background_search)
        self.hints: dict[str, Array] = {}
        self._frame_index: int | None = None
        self._frame: StereoFrame | None = None
        self._results: dict[str, TrackResult] = {}
        self.last_ms = 0.0  # tracking time of the last frame, all sleeves [ms]

    def results(self, frame: StereoFrame) -> dict[str, TrackResult]:
        """Every arm's result for ``frame`` (tracked on the first call for it)."""
        if frame is not self._frame or frame.index != self._frame_index:
            t0 = time.perf_counter()
            self._results = self.tracker.track(frame.left, frame.right, axis_hints_left=self.hints)
            self.last_ms = 1000.0 * (time.perf_counter() - t0)
            self._frame, self._frame_index = frame, frame.index
        return self._results

    def retire(self, arm: str) -> None:
        """Track arm ``arm``'s sleeve no more (its loop has stopped; ArmSetTracker.retire)."""
        self.tracker.retire(arm)

    def close(self) -> None:
        """Stop the tracker's worker processes and threads (idempotent)."""
        self.tracker.close()

    def view(self, arm: str, T_world_left: Array) -> ArmSensorView:
        """Arm ``arm``'s tip sensor in its own {w}: ``T_world_left``, the pose of {ll} in that {w}."""
        if arm not in self.tracker.arms:
            raise KeyError(f"no arm '{arm}' in the marker set ({', '.join(self.tracker.arms)})")
        return ArmSensorView(self, arm, np.asarray(T_world_left, float))


class ArmSensorView:
    """One arm's share of an :class:`ArmSetSensor` (a :class:`rig.loop.tip_sensors.TipSensor`)."""

    def __init__(self, shared: ArmSetSensor, arm: str, T_world_left: Array) -> None:
        self.shared, self.arm, self.T_world_left = shared, arm, T_world_left
        self.last_frame: StereoFrame | None = None

    def measure(self, frame: StereoFrame, axis_hint_world: Array | None = None) -> TipMeasurement:
        """This arm's tip in its {w} from the frame's shared tracking; ``time_ms`` is the frame's
        tracking time for all sleeves. ``axis_hint_world`` is kept as this arm's hint for the
        frames that follow (the frame may have been tracked already, for another arm)."""
        self.last_frame = frame
        if axis_hint_world is not None:
            self.shared.hints[self.arm] = self.T_world_left[:3, :3].T @ np.asarray(axis_hint_world, float)
        res = self.shared.results(frame)[self.arm]
        return tip_measurement(res, frame, self.shared.last_ms, self.T_world_left)
