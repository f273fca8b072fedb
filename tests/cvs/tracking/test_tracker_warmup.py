"""Paying the tracker's one-time costs before the first timed frame: synthetic marker frames
(cvs.marker.synthetic) that the tracker really tracks, the warm-up over every code path
(cvs.tracking.warmup), the process's explicit warm-up (``wristmark.warm_up``: building a tracker
or a detector changes no process state), and ``wristmark track --source`` preparing its tracker
(warm-up, frozen heap) before the first frame (rig.recording.track_stream.prepare_tracker)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.marker.synthetic import marker_pose_ahead, synthetic_pair
from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings
from wristmark.cvs.tracking.warmup import warm_up_tracker
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel

ROOT = Path(__file__).resolve().parents[3]
CAM = scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 0.5)
CODED = MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")


@pytest.mark.parametrize("coded", [False, True])
def test_synthetic_pair_is_tracked_where_it_was_drawn(coded: bool) -> None:
    marker = CODED if coded else MarkerModel()
    left, right = synthetic_pair(CAM, marker)
    assert left.shape == right.shape == (CAM.image_size[1], CAM.image_size[0]) and left.dtype == np.uint8
    res = MarkerTracker(CAM, marker, TrackerSettings(strict_direction=False)).track(left, right)
    assert res.ok, res.reason
    T = marker_pose_ahead(marker, CAM)
    assert np.linalg.norm(res.tip_left - (T[:3, :3] @ marker.tip() + T[:3, 3])) < 0.3e-3  # type: ignore[operator]
    assert res.roll_known == coded and (res.axis_source == "code") == coded
    bgr = synthetic_pair(CAM, marker, channels=3)[0]
    assert bgr.shape == (*left.shape, 3) and np.array_equal(bgr[..., 1], left)


def test_warm_up_runs_every_path_and_leaves_no_state() -> None:
    tracker = MarkerTracker(CAM, CODED)
    warm = warm_up_tracker(tracker, (1, 3))
    # per image kind: cold, ROI, with a hint (found) and an empty pair (lost: whole frame and second detector)
    assert warm.pairs == 8 and warm.found == 6 and warm.seconds > 0
    assert tracker._second is not None  # the 'auto' detector's saddle fallback was built and run
    left, right = synthetic_pair(CAM, CODED)
    fresh = MarkerTracker(CAM, CODED).track(left, right)
    after = tracker.track(left, right)  # a cold pair again: the warm-up's ROI state is gone
    assert after.ok and "second_detector" not in after.timings
    assert np.array_equal(after.corners_left, fresh.corners_left) and after.rms_px == fresh.rms_px
    assert np.allclose(after.T_left_marker, fresh.T_left_marker)  # type: ignore[arg-type]


_FIRST_FRAME = textwrap.dedent("""
    import gc, json, sys, time
    import cv2
    from numba.core.registry import CPUDispatcher
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.cvs.tracking.warmup import warm_up_tracker
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.marker import MarkerModel
    from wristmark.sim.render.motion_video import render_motion

    full = load_calibration(CONFIG_DIR / "camera.yaml")
    cam = scaled_stereo_camera(full, 0.5)
    marker = MarkerModel.load(CONFIG_DIR / "marker_coded.yaml")
    pairs = [[cv2.cvtColor(v, cv2.COLOR_BGR2GRAY) for v in (p.left, p.right)]
             for p in render_motion(full, 4, scale=0.5, seed=3, marker=marker)]
    tracker = MarkerTracker(cam, marker)
    if sys.argv[1] == "warm":
        warm_up_tracker(tracker, (1,))
    elif sys.argv[1] == "process":
        import wristmark
        wristmark.warm_up()

    def kernels():
        return sum(len(o.signatures) for o in gc.get_objects() if isinstance(o, CPUDispatcher))

    def cpu_ms(pair):
        t = time.thread_time()
        res = tracker.track(*pair)
        assert res.ok, res.reason
        return 1e3 * (time.thread_time() - t)

    before = kernels()
    first = cpu_ms(pairs[0])  # the first frame: whole-frame search, every start, code
    roi = [cpu_ms(p) for p in pairs[1:]]
    again = []
    for _ in range(3):  # the same cold pair, once the process has seen every path
        tracker.reset()
        again.append(cpu_ms(pairs[0]))
    print(json.dumps({"first_ms": first, "cold_again_ms": min(again), "roi_ms": roi,
                      "kernels_loaded": kernels() - before}))
""")


def _first_frame(mode: str) -> dict[str, float]:
    r = subprocess.run([sys.executable, "-c", _FIRST_FRAME, mode], capture_output=True, text=True, timeout=300,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out: dict[str, float] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


@pytest.mark.wallclock
def test_after_the_warm_up_the_first_real_frame_costs_what_a_cold_frame_costs() -> None:
    """In a fresh process: without the warm-up the first rendered frame loads numba kernels
    (the code decoder's, the direction check's: about twice a cold frame's CPU here, 24-27 ms
    against 11-17 ms); after it, no kernel is loaded on a real frame and the first frame's CPU
    is within 1.5x (+3 ms) of the same cold pair tracked again."""
    cold = _first_frame("cold")
    assert cold["kernels_loaded"] > 0
    warm = _first_frame("warm")
    assert warm["kernels_loaded"] == 0
    assert warm["first_ms"] <= 1.5 * warm["cold_again_ms"] + 3.0, warm


def test_after_the_process_warm_up_a_tracked_pair_loads_no_kernel() -> None:
    """``wristmark.warm_up()`` (no tracker given) loads every kernel a fresh tracker's real
    frames run: none is loaded on the first frame nor after."""
    assert _first_frame("process")["kernels_loaded"] == 0


_CONSTRUCT = textwrap.dedent("""
    import json
    import cv2
    import wristmark
    from wristmark.cvs.corners.detector import MarkerCornerDetector
    from wristmark.cvs.corners.saddle import SaddleCornerDetector
    from wristmark.cvs.marker.synthetic import synthetic_pair
    from wristmark.cvs.tracking.warmup import _JIT_READY
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.models.marker import MarkerModel

    cv2.setNumThreads(3)  # not OpenCV's default nor the warm-up's: any change shows
    cam = wristmark.cvs.scaled_stereo_camera(wristmark.load_calibration(CONFIG_DIR / "camera.yaml"), 0.25)
    tracker = MarkerTracker(cam, MarkerModel.load(CONFIG_DIR / "marker_coded.yaml"))
    MarkerCornerDetector(), SaddleCornerDetector()
    res = tracker.track(*synthetic_pair(cam, tracker.marker))
    out = {"after_build_and_track": cv2.getNumThreads(), "tracked": res.ok, "jit_ready": bool(_JIT_READY)}
    wristmark.warm_up(opencv_threads=None, jit=False)
    out["none"] = cv2.getNumThreads()
    seconds = wristmark.warm_up()
    out["default"], out["jit_ready_after"], out["seconds"] = cv2.getNumThreads(), bool(_JIT_READY), seconds
    wristmark.warm_up(opencv_threads=2)
    out["two"] = cv2.getNumThreads()
    print(json.dumps(out))
""")


def test_building_and_tracking_change_no_process_state_and_warm_up_does() -> None:
    """In a fresh process: building a tracker and detectors and tracking a pair leave OpenCV's
    thread count as the process set it (they used to set one thread); ``warm_up`` sets it
    (default 1; None leaves it) and loads the kernels."""
    r = subprocess.run([sys.executable, "-c", _CONSTRUCT], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["after_build_and_track"] == 3 and out["tracked"] and not out["jit_ready"]
    assert out["none"] == 3
    assert out["default"] == 1 and out["jit_ready_after"] and out["seconds"] > 0
    assert out["two"] == 2


@pytest.mark.parametrize("threads", [0, -1, 1.5, True, "1"])
def test_warm_up_refuses_a_bad_thread_count(threads: object) -> None:
    from wristmark import WristmarkError, warm_up

    with pytest.raises(WristmarkError, match="opencv_threads must be a whole number >= 1 or None"):
        warm_up(opencv_threads=threads, jit=False)  # type: ignore[arg-type]


_TRACK = textwrap.dedent("""
    import gc, os, sys
    from wristmark.cli.main import main
    rc = main(sys.argv[1:])
    print("frozen", gc.get_freeze_count(), "fifo", os.sched_getscheduler(0) == os.SCHED_FIFO, file=sys.stderr)
    sys.exit(rc)
""")


def _video(tmp_path: Path) -> list[str]:
    """A 6-frame 30 fps side-by-side MJPG video of the coded sleeve, and the track options for it."""
    from wristmark.cvs.calibration.yaml_files import save_calibration
    from wristmark.sim.render.motion_video import write_stereo_video

    pairs = [synthetic_pair(CAM, CODED, 3, T_left_marker=marker_pose_ahead(CODED, CAM, roll=0.3 + 0.02 * k))
             for k in range(6)]
    video = write_stereo_video(tmp_path / "sbs.avi", pairs, fps=30)
    save_calibration(tmp_path / "calib.yaml", CAM)
    return ["--source", str(video), "--calib", str(tmp_path / "calib.yaml"),
            "--marker", str(CONFIG_DIR / "marker_coded.yaml")]


def _run_track(argv: list[str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", _TRACK, "track", *argv], capture_output=True, text=True,
                          timeout=300, cwd=ROOT)


def test_track_source_prepares_the_tracker_and_reports_the_rate(tmp_path: Path) -> None:
    """``wristmark track --source VIDEO --paced``: the heap is frozen (the start-up objects,
    tens of thousands, are exempt from collections) and the summary line gives the rate and the
    dropped frames, which with the frames processed make up the video (how many are dropped
    depends on the machine's load)."""
    r = _run_track([*_video(tmp_path), "--paced", "--grayscale", "--json"])
    assert r.returncode == 0, r.stderr
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    assert lines and all(o["ok"] and o["roll_known"] for o in lines)
    assert [o["frame"] for o in lines] == sorted({o["frame"] for o in lines})  # newest frames, in order
    summary, frozen = r.stderr.strip().splitlines()[-2:]
    assert int(frozen.split()[1]) > 10000 and frozen.endswith("fifo False")
    assert summary.startswith("track: ") and " fps; latency median " in summary
    fps = float(summary.split(" s, ")[1].split(" fps")[0])
    dropped = int(summary.rsplit("dropped ", 1)[1])
    assert len(lines) + dropped == 6 and 0 < fps <= 31.0  # paced: never faster than the video's 30 fps


@pytest.mark.slow
def test_rt_priority_runs_the_tracker_under_sched_fifo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--rt-priority N`` puts the track command under SCHED_FIFO (where the host allows it;
    else one line saying it was refused, exit 2); without ``--source`` it is an error."""
    from wristmark.cli.main import main
    from wristmark.rig.loop.realtime_priority import realtime_priority_allowed

    left, right = synthetic_pair(CAM, CODED)
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), right)
    argv = _video(tmp_path)
    assert main(["track", "--calib", argv[3], "--rt-priority", "1", str(tmp_path / "l.png"),
                 str(tmp_path / "r.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--rt-priority needs --source" in err[0]
    r = _run_track([*argv, "--rt-priority", "1", "--paced", "--json"])
    if realtime_priority_allowed(1):
        assert r.returncode == 0, r.stderr
        assert r.stderr.strip().endswith("fifo True") and len(r.stdout.splitlines()) >= 1
    else:
        assert r.returncode == 2 and "real-time priority 1 refused" in r.stderr
