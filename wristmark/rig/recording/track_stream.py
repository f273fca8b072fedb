"""Track the marker through a frame source as one sequence, with the outputs of ``wristmark
track --source``: a line per frame (the caller's), annotated frames, a ROS 2 recording, a
progress bar for finite sources and a rate/latency summary.

Before the first frame, :func:`prepare_tracker` pays the tracker's one-time costs on synthetic
frames (cvs.tracking.warmup) and freezes the heap (rig.loop.heap_freeze), so that neither a first
use of a code path nor a full garbage collection (60-65 ms with this process's ~120 000
start-up objects, measured) lands on a frame: at 60 fps either drops frames.

Latency is the time from a frame's capture (``t_capture``, host monotonic clock) to its
tracking result: for files read unpaced it is the tracking time (t_capture is when the frame
was read); for live and paced sources it also holds the transport and any wait in the queue.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame, StereoSource, frames
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackResult
from wristmark.cvs.tracking.warmup import WarmUp, warm_up_tracker
from wristmark.models.marker import MarkerModel
from wristmark.rig.loop.heap_freeze import freeze_heap


@dataclass
class TrackOutputs:
    """Where tracked frames go besides the per-frame line: annotated frames and a recording."""

    camera: StereoCamera
    marker: MarkerModel
    annotator: Any = None  # cvs.tracking.annotate.AnnotationWriter
    recorder: Any = None  # rig.recording.bag_recorder.BagRecorder

    @classmethod
    def open(cls, annotate: str | None, record: str | None, record_jpeg: bool, camera: StereoCamera,
             marker: MarkerModel, fps: float = 30.0) -> TrackOutputs:
        """Open the annotation target and the recording (InputError if they cannot be)."""
        out = cls(camera, marker)
        if record:
            from wristmark.rig.recording.bag_recorder import BagRecorder

            out.recorder = BagRecorder(record, jpeg=record_jpeg, world_T_left=camera.T_world_left)
        if annotate:
            from wristmark.cvs.tracking.annotate import AnnotationWriter

            try:
                out.annotator = AnnotationWriter(Path(annotate), fps)
            except BaseException:
                out.close()
                raise
        return out

    def add(self, frame: StereoFrame, res: TrackResult) -> None:
        """Annotate and record one tracked frame."""
        if self.recorder is not None:
            self.recorder.write_frame(frame)
            if res.ok and res.T_left_marker is not None and res.tip_left is not None:
                self.recorder.write_pose(frame.t_capture, res.T_left_marker, res.tip_left)
        if self.annotator is not None:
            from wristmark.cvs.tracking.annotate import annotate_pair

            self.annotator.write(annotate_pair(frame.left, frame.right, res, self.camera, self.marker), frame.index)

    def close(self) -> None:
        """Finish the annotated video and the recording (idempotent)."""
        if self.annotator is not None:
            self.annotator.close()
        if self.recorder is not None:
            self.recorder.close()


@dataclass
class TrackSummary:
    """A run through a source: frames tracked and found, wall time [s], latencies [s], dropped."""

    frames: int = 0
    found: int = 0
    wall_s: float = 0.0
    dropped: int = 0
    latency_s: list[float] = field(default_factory=list)

    @property
    def rate_fps(self) -> float:
        """Frames per second of wall time."""
        return self.frames / self.wall_s if self.wall_s > 0 else 0.0

    def latency_ms(self, q: float) -> float:
        """The q-th percentile of the latency [ms] (NaN without frames)."""
        return float(1e3 * np.percentile(self.latency_s, q)) if self.latency_s else float("nan")

    def line(self) -> str:
        """One summary line for stderr."""
        return (f"track: {self.frames} frames ({self.found} with a pose) in {self.wall_s:.2f} s, "
                f"{self.rate_fps:.1f} fps; latency median {self.latency_ms(50):.1f} ms, "
                f"p95 {self.latency_ms(95):.1f} ms; dropped {self.dropped}")


def prepare_tracker(tracker: MarkerTracker, grayscale: bool) -> tuple[WarmUp, float]:
    """Warm ``tracker`` up on the image kinds it will get (grey views with ``grayscale``, else
    grey and BGR), then freeze the heap; returns the warm-up and the freeze's time [s]."""
    warm = warm_up_tracker(tracker, (1,) if grayscale else (1, 3))
    return warm, freeze_heap()


def track_source(source: StereoSource, tracker: MarkerTracker, emit: Callable[[StereoFrame, TrackResult], None],
                 outputs: TrackOutputs | None = None, limit: int | None = None,
                 axis_hint_left: NDArray[np.float64] | None = None) -> TrackSummary:
    """Track every frame of ``source`` (up to ``limit``) in order; ``emit`` gets each result."""
    from tqdm import tqdm

    from wristmark.cvs.sources.open_source import source_length

    n = source_length(source)
    total = min(n, limit) if n is not None and limit is not None else n
    summary = TrackSummary()
    t0 = time.monotonic()
    with tqdm(total=total, file=sys.stderr, unit="frame", disable=None if total else True, leave=False) as bar:
        for frame in frames(source, limit):
            res = tracker.track(frame.left, frame.right, axis_hint_left=axis_hint_left)
            summary.latency_s.append(time.monotonic() - frame.t_capture)
            summary.frames += 1
            summary.found += int(res.ok)
            emit(frame, res)
            if outputs is not None:
                outputs.add(frame, res)
            bar.update(1)
    summary.wall_s = time.monotonic() - t0
    summary.dropped = source.dropped
    return summary
