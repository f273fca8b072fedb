"""Per-frame tracking time over a recorded stereo sequence, unpaced: prints JSON.

Usage: .venv/bin/python bench/replay_tracking.py SOURCE [--calib CALIB.yaml] [--image-scale S]
                                                  [--marker MARKER.yaml] [--spike-ms 30]

SOURCE is any frame-source SPEC (a ``--record``ed MCAP bag of ``wristmark servo`` or ``track``,
a video, a dataset folder). The frames go one after the other through a ``MarkerTracker``
prepared as ``wristmark track --source`` prepares it (a warm-up of every code path, the heap
frozen), as in the servo loop's ROI tracking from frame to frame, without pacing. It prints the
tracking time per stereo pair (median, p95, p99, max [ms], the first pair apart), the frames
slower than ``--spike-ms`` (index and time), and how many pairs were found. ``--calib`` is the
calibration at full size (default the shipped configs/camera.yaml) and ``--image-scale`` the
fraction of it that the frames have (the virtual lab's ``--image-scale``). Run it on two builds
(e.g. from a worktree of an older commit with ``PYTHONPATH``) to compare them on the same frames.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from wristmark.cli.option_types import positive_float
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.config_files import default_config
from wristmark.models.marker import MarkerModel
from wristmark.rig.recording.track_stream import prepare_tracker


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", help="frame-source SPEC (bag, video, folder)")
    ap.add_argument("--calib", default=str(default_config("camera.yaml")), help="calibration at full size")
    ap.add_argument("--image-scale", type=positive_float(1.0), default=1.0, help="the frames' fraction of it")
    ap.add_argument("--marker", help="marker file (default the reference sleeve)")
    ap.add_argument("--spike-ms", type=positive_float(10_000.0), default=30.0, help="a slow pair [ms]")
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    cam = load_calibration(a.calib)
    if a.image_scale != 1.0:
        cam = scaled_stereo_camera(cam, a.image_scale)
    marker = MarkerModel.load(a.marker) if a.marker else MarkerModel()
    tracker = MarkerTracker(cam, marker)
    prepare_tracker(tracker, grayscale=False)
    source = open_stereo_source(a.source, SourceOptions(image_size=cam.image_size))
    times, found = [], 0
    try:
        while (frame := source.read()) is not None:
            t0 = time.perf_counter()
            res = tracker.track(frame.left, frame.right)
            times.append(1000.0 * (time.perf_counter() - t0))
            found += int(res.ok)
    finally:
        source.close()
    if not times:
        print("replay_tracking: the source gave no frame", file=sys.stderr)
        return 2
    ms = np.asarray(times)
    rest = ms[1:] if ms.size > 1 else ms
    q = {f"p{p}": round(float(np.percentile(rest, p)), 2) for p in (50, 95, 99)}
    out = {"source": a.source, "pairs": int(ms.size), "found": found, "first_ms": round(float(ms[0]), 2),
           "tracking_ms_after_first": {**q, "max": round(float(rest.max()), 2)},
           "spikes": [[int(k), round(float(x), 1)] for k, x in enumerate(ms) if k and x > a.spike_ms]}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
