"""``wristmark servo --record FILE.mcap``: the run as a ROS 2 bag, written off the loop's path.

Per control cycle the loop hands over (never waiting) the frame it used, the marker pose it
measured and the actuators commanded and measured; a writer thread serialises them with
:class:`rig.recording.bag_recorder.BagRecorder` (topics of docs/design.md "Recording"). When the writer falls
behind, whole cycles are dropped and counted rather than slowing the loop.
"""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import Arm, actuator_names
from wristmark.rig.recording.bag_recorder import BagRecorder
from wristmark.rig.recording.run_log import CycleRecord

Array = NDArray[np.float64]
QUEUE_CYCLES = 64  # cycles buffered between the loop and the writer [-]


class ServoRecorder:
    """Records cycles to ``path`` (.mcap, must not exist) of the arm ``params``, or of several
    arms in one view (``params`` by arm: each its own topics, the shared frames once); jpeg: images
    as CompressedImage; world_T_left: poses also in ``world``."""

    def __init__(self, path: str, params: Arm | Mapping[str, Arm], jpeg: bool = False,
                 world_T_left: Array | None = None) -> None:
        self.arms: dict[str | None, Arm] = {None: params} if not isinstance(params, Mapping) else {
            n: p for n, p in params.items()}
        names = {n: actuator_names(p) for n, p in self.arms.items()}
        self.bag = BagRecorder(path, jpeg=jpeg, world_T_left=world_T_left, actuator_names=names[next(iter(names))],
                               arms={n: a for n, a in names.items() if n is not None} or None)
        self.cycles = 0
        self.dropped = 0
        self.error = ""
        self._last_frame_index: int | None = None
        self._queue: queue.Queue[tuple[Any, ...] | None] = queue.Queue(QUEUE_CYCLES)
        self._thread = threading.Thread(target=self._write_forever, name="servo-recorder", daemon=True)
        self._thread.start()

    def record(self, rec: CycleRecord, loop: Any, link: Any, arm: str | None = None) -> None:
        """Queue one cycle of ``loop`` (rig.loop.servo_loop.ServoLoop; of arm ``arm`` of a scene):
        its new frame (a frame another arm's cycle recorded is not recorded again), its accepted
        measurement, the commanded and the latest measured actuators. Never blocks."""
        frame = loop.last_frame
        if frame is not None and frame.index == self._last_frame_index:
            frame = None  # no new frame this cycle
        meas = loop.last_measurement if rec.meas_ok else None
        params = self.arms[arm]
        commanded = actuators_from_psi(params, rec.psi_cmd)
        state = getattr(link, "state", None)
        measured = np.asarray(state.positions, float) if state is not None else np.full(commanded.size, np.nan)
        t = rec.t_capture if math.isfinite(rec.t_capture) else rec.t_wall
        try:
            self._queue.put_nowait((frame, meas, t, commanded, measured, arm))
        except queue.Full:
            self.dropped += 1
            return
        if frame is not None:
            self._last_frame_index = frame.index
        self.cycles += 1

    def _write_forever(self) -> None:
        while (item := self._queue.get()) is not None:
            frame, meas, t, commanded, measured, arm = item
            try:
                if frame is not None:
                    self.bag.write_frame(frame)
                if meas is not None and meas.T_left_marker is not None and meas.tip_left is not None:
                    self.bag.write_pose(meas.t_capture, meas.T_left_marker, meas.tip_left, arm)
                self.bag.write_actuators(t, commanded, measured, arm)
            except Exception as e:  # noqa: BLE001 - the recording stops; the run goes on
                self.error = self.error or f"recording stopped: {type(e).__name__}: {e}"

    def close(self) -> None:
        """Write what is queued and finish the bag (idempotent)."""
        if not self._thread.is_alive():
            return
        self._queue.put(None)
        self._thread.join()
        self.bag.close()
