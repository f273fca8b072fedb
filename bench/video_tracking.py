"""Tracking from a stereo video played at its real frame rate: prints JSON.

Usage: python bench/video_tracking.py [--frames 600] [--fps 60] [--scale 1.0] [--repeat 5] [--video FILE] [--bgr]
                                     [--no-prepare] [--rt-priority N]
Renders ``--frames`` pairs of a smooth motion of the marked arm (sim.render.motion_video, 1920x1080
per eye at scale 1) and writes them as one side-by-side MJPG video (3840x1080, quality 95) at
``--fps`` (or plays ``--video``). Then, in the same run:
- decode_only: the video read unpaced through cvs.sources.open_source (demux + JPEG decode + split),
  per-frame time, decoding BGR and grey views (grey decodes only the JPEG's luma);
- tracked_unpaced: the same source with MarkerTracker on every frame, as fast as it goes;
- paced: the file played by the paced video source at its real rate in wall-clock time
  (newest-frame semantics) with MarkerTracker on each frame handed out, ``--repeat`` times:
  frames processed, dropped (consumer too slow) and decode_skipped (the decoder was late),
  the drop rate, per-frame tracking time and latency (result time minus the frame's scheduled
  capture time) median/p95 [ms], the frame's age when the tracker got it (decode + wait), the
  CPU time the process got (per frame, and as a share of wall time: on a loaded machine the
  share, not the code, limits the rate), the garbage collections during the run (count per
  generation, longest pause) and the slowest frames with their stages (``spikes``: tracking
  longer than one frame period, with any collection that ran inside it).
The tracked runs use grey views (``--bgr``: BGR). Each tracked run's tracker is prepared as
``wristmark track --source`` prepares it (rig.recording.track_stream.prepare_tracker: a warm-up of every
code path on synthetic frames, then the heap frozen); ``--no-prepare`` instead warms the numba
kernels on the video's first frame with another tracker and freezes nothing (how this bench
ran before, for comparison). ``--rt-priority N``: the whole bench (tracker and decoder threads)
under SCHED_FIFO, as ``wristmark track --rt-priority N``. The target is at most 1 % of frames dropped at 60 fps;
``run(...)`` returns the dict (bench/virtual_lab.py calls it).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from wristmark.cli.option_types import int_in, positive_float  # noqa: E402
from wristmark.cvs.calibration.load import load_calibration  # noqa: E402
from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera  # noqa: E402
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source  # noqa: E402
from wristmark.cvs.tracking.tracker import MarkerTracker  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.errors import WristmarkError
from wristmark.models.marker import MarkerModel  # noqa: E402
from wristmark.rig.loop.realtime_priority import request_realtime_priority
from wristmark.rig.recording.track_stream import prepare_tracker

MAX_SPIKES = 8  # slowest frames listed per run

ROOT = Path(__file__).resolve().parents[1]


def _ms(values: list[float]) -> dict[str, float]:
    a = 1e3 * np.asarray(values, float)
    if a.size == 0:
        return {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {"median": round(float(np.median(a)), 3), "p95": round(float(np.percentile(a, 95)), 3),
            "max": round(float(a.max()), 3)}


def make_video(path: Path, frames: int, fps: float, scale: float, seed: int = 0) -> Path:
    """Render the motion and write it as a side-by-side MJPG video; returns the path."""
    from wristmark.sim.render.motion_video import render_motion, write_stereo_video

    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    return write_stereo_video(path, render_motion(cam, frames, scale=scale, seed=seed), fps=fps)


def _decode_only(video: Path, camera: StereoCamera, grayscale: bool) -> dict[str, Any]:
    src = open_stereo_source(str(video), SourceOptions(image_size=camera.image_size, grayscale=grayscale))
    times: list[float] = []
    t = time.perf_counter()
    while src.read() is not None:
        now = time.perf_counter()
        times.append(now - t)
        t = now
    src.close()
    return {"frames": len(times), "per_frame_ms": _ms(times)}


class _GcLog:
    """Garbage collections while it is installed: (generation, start [s], pause [s])."""

    def __init__(self) -> None:
        self.events: list[tuple[int, float, float]] = []
        self._start = 0.0

    def __call__(self, phase: str, info: dict[str, Any]) -> None:
        if phase == "start":
            self._start = time.perf_counter()
        else:
            self.events.append((int(info["generation"]), self._start, time.perf_counter() - self._start))

    def summary(self) -> dict[str, Any]:
        return {"collections": {g: sum(1 for e in self.events if e[0] == g) for g in (0, 1, 2)},
                "max_pause_ms": round(1e3 * max((e[2] for e in self.events), default=0.0), 2)}


def _tracker(camera: StereoCamera, marker: MarkerModel, prepare: bool, grayscale: bool) -> MarkerTracker:
    tracker = MarkerTracker(camera, marker)
    if prepare:
        prepare_tracker(tracker, grayscale)
    return tracker


def _track_all(video: Path, camera: StereoCamera, marker: MarkerModel, paced: bool, grayscale: bool,
               prepare: bool = True, period_s: float = 1.0 / 60.0) -> dict[str, Any]:
    tracker = _tracker(camera, marker, prepare, grayscale)
    src = open_stereo_source(str(video), SourceOptions(paced=paced, image_size=camera.image_size, grayscale=grayscale))
    track_s, latency_s, age_s, found, n = [], [], [], 0, 0
    slow: list[tuple[float, int, float, dict[str, float]]] = []
    log = _GcLog()
    gc.callbacks.append(log)
    t0, cpu0 = time.monotonic(), time.process_time()
    try:
        while (frame := src.read()) is not None:
            age_s.append(time.monotonic() - frame.t_capture)
            t1 = time.perf_counter()
            res = tracker.track(frame.left, frame.right)
            t2 = time.perf_counter()
            track_s.append(t2 - t1)
            latency_s.append(time.monotonic() - frame.t_capture)
            if t2 - t1 > period_s:
                slow.append((t1, frame.index, t2 - t1, res.timings))
            found += int(res.ok)
            n += 1
    finally:
        gc.callbacks.remove(log)
    wall, cpu = time.monotonic() - t0, time.process_time() - cpu0
    src.close()
    skipped = int(getattr(src, "decode_skipped", 0))
    spikes = [{"frame": k, "ms": round(1e3 * dt, 1), "stages_ms": {s: round(v, 1) for s, v in tm.items()},
               "gc_ms": [round(1e3 * p, 1) for _, st, p in log.events if t1 <= st <= t1 + dt]}
              for t1, k, dt, tm in sorted(slow, key=lambda x: -x[2])[:MAX_SPIKES]]
    out: dict[str, Any] = {"processed": n, "found": found, "wall_s": round(wall, 3),
                           "rate_fps": round(n / wall, 2) if wall > 0 else 0.0, "tracking_ms": _ms(track_s),
                           "latency_ms": _ms(latency_s), "age_at_take_ms": _ms(age_s),
                           # CPU this process got (decoder thread + tracker): per processed frame, and
                           # as a share of the wall time (2.0 = both cores)
                           "cpu_ms_per_frame": round(1e3 * cpu / n, 2) if n else None,
                           "cpu_share": round(cpu / wall, 2) if wall > 0 else None,
                           "gc": log.summary(), "frames_over_one_period": len(slow), "spikes": spikes}
    if paced:
        total = n + src.dropped
        out |= {"dropped": src.dropped, "decode_skipped": skipped,
                "dropped_by_consumer": src.dropped - skipped,
                "dropped_percent": round(100.0 * src.dropped / total, 2) if total else 0.0}
    return out


def run(frames: int = 600, fps: float = 60.0, scale: float = 1.0, repeat: int = 5, video: str | Path | None = None,
        workdir: str | Path | None = None, grayscale: bool = True, prepare: bool = True,
        rt_priority: int | None = None) -> dict[str, Any]:
    """The benchmark of the module docstring; returns its JSON as a dict. grayscale: the
    tracked runs decode grey views (``--grayscale`` of ``wristmark track``); prepare: each
    tracker prepared as ``wristmark track --source`` does (else the old one-frame warm-up);
    rt_priority: SCHED_FIFO priority for the timed runs (None: normal scheduling)."""
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    camera = scaled_stereo_camera(cam, scale) if scale != 1.0 else cam
    marker = MarkerModel()
    with tempfile.TemporaryDirectory(prefix="wristmark-video-bench-", dir=workdir) as tmp:
        t = time.perf_counter()
        path = Path(video) if video is not None else make_video(Path(tmp) / "stereo_sbs.avi", frames, fps, scale)
        render_s = time.perf_counter() - t
        size_mb = path.stat().st_size / 1e6
        if rt_priority is not None:  # before any decoder thread starts: they inherit it
            request_realtime_priority(rt_priority)
        if not prepare:  # the old warm-up: the numba kernels on the first frame, another tracker
            warm = open_stereo_source(str(path))
            first = warm.read()
            warm.close()
            if first is not None:
                MarkerTracker(camera, marker).track(first.left, first.right)
        result: dict[str, Any] = {
            "machine": {"cpus": os.cpu_count(), "loadavg_1min": round(os.getloadavg()[0], 2)},
            "video": {"frames": frames, "fps": fps, "size_px": [2 * camera.image_size[0], camera.image_size[1]],
                      "codec": "MJPG", "mb_per_frame": round(size_mb / max(frames, 1), 3),
                      "render_s": round(render_s, 1)},
            "grayscale": grayscale, "prepared": prepare, "rt_priority": rt_priority,
            "decode_only": {"bgr": _decode_only(path, camera, False), "grey": _decode_only(path, camera, True)},
            "tracked_unpaced": _track_all(path, camera, marker, False, grayscale, prepare, 1.0 / fps),
            "paced": [_track_all(path, camera, marker, True, grayscale, prepare, 1.0 / fps)
                      for _ in range(max(repeat, 1))],
        }
    drops = [r["dropped_percent"] for r in result["paced"]]
    result["target"] = {"max_dropped_percent": 1.0, "worst_dropped_percent": max(drops),
                        "median_dropped_percent": float(np.median(drops)), "met": bool(max(drops) <= 1.0)}
    result["machine"]["loadavg_1min_end"] = round(os.getloadavg()[0], 2)
    return result


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int_in(2, 100000), default=600, help="rendered frames (default 600: 10 s)")
    ap.add_argument("--fps", type=positive_float(1000.0), default=60.0, help="the video's frame rate (default 60)")
    ap.add_argument("--scale", type=positive_float(2.0), default=1.0, help="camera scale (1: 1920x1080 per eye)")
    ap.add_argument("--repeat", type=int_in(1, 100), default=5, help="paced runs (default 5)")
    ap.add_argument("--bgr", action="store_true", help="track BGR frames (default: grey, as track --grayscale)")
    ap.add_argument("--no-prepare", action="store_true", help="do not prepare the trackers (no warm-up "
                    "of every path, no frozen heap): the bench as it was, for comparison")
    ap.add_argument("--rt-priority", type=int_in(1, 99), help="run under SCHED_FIFO at this priority "
                    "(as wristmark track --rt-priority; needs root or CAP_SYS_NICE)")
    ap.add_argument("--video", help="play this side-by-side video instead of rendering one (calibration: "
                    "configs/camera.yaml at --scale)")
    a = ap.parse_args()
    try:
        out = run(a.frames, a.fps, a.scale, a.repeat, a.video, grayscale=not a.bgr,
                  prepare=not a.no_prepare, rt_priority=a.rt_priority)
    except WristmarkError as e:
        print(f"video_tracking: {e}", file=sys.stderr)
        return 2
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
