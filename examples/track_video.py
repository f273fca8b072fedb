"""Track the wrist marker in a side-by-side stereo video, through the public API.

The video is made here by the simulated bench (``wristmark.sim``): the marked arm in smooth
motion, rendered through the shipped calibration and written as MJPG. It is then read back as
any user's video would be (``open_stereo_source``: FFmpeg through OpenCV), and each frame's
tip in {ll} is compared with the renderer's ground truth.

Run: ``python examples/track_video.py [--fast] [--out DIR]`` (``--fast``: 8 frames at 0.35 x
1080p; else 40 frames at 0.5 x). Prints one JSON line per frame, then a summary line.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from wristmark import MarkerModel, MarkerTracker, SourceOptions, load_calibration, open_stereo_source, warm_up
from wristmark.cvs import iter_frames, scaled_stereo_camera
from wristmark.models import default_config
from wristmark.sim import render_motion, write_stereo_video

FPS = 30.0  # [1/s] frame rate written into the video


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="CI mode: 8 small frames")
    parser.add_argument("--out", type=Path, help="folder for the video (default: a temporary folder)")
    args = parser.parse_args()
    n, scale = (8, 0.35) if args.fast else (40, 0.5)

    calibration = load_calibration(default_config("camera.yaml"))  # or your own: load_calibration("calib.yaml")
    marker = MarkerModel()
    camera = scaled_stereo_camera(calibration, scale)  # the video's resolution
    pairs = render_motion(calibration, n, scale=scale, seed=1, marker=marker)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        video = write_stereo_video(folder / "stereo.avi", pairs, FPS)

        warm_up()  # one OpenCV thread, the tracker's numba kernels loaded: the first frame is not slow
        tracker = MarkerTracker(camera, marker)
        source = open_stereo_source(str(video), SourceOptions(layout="sbs", image_size=camera.image_size))
        errors_mm = []
        try:
            for frame, truth in zip(iter_frames(source), pairs):
                res = tracker.track(frame.left, frame.right)
                err = float(1000 * np.linalg.norm(res.tip_left - truth.tip_left)) if res.ok else None
                if err is not None:
                    errors_mm.append(err)
                print(json.dumps({"frame": frame.index, "ok": res.ok, "reason": res.reason,
                                  "tip_left_m": None if res.tip_left is None else res.tip_left.tolist(),
                                  "tip_error_mm": err, "time_ms": res.time_ms}))
        finally:
            source.close()
    print(json.dumps({"summary": True, "frames": n, "tracked": len(errors_mm),
                      "tip_error_mean_mm": float(np.mean(errors_mm)) if errors_mm else None,
                      "tip_error_max_mm": float(np.max(errors_mm)) if errors_mm else None}))


if __name__ == "__main__":
    main()
