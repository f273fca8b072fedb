"""``wristmark track``: tip and marker pose in each stereo frame (docs/design.md "Command line",
"Stereo frame sources", "Recording").

Frames come from ``LEFT RIGHT ...`` image pairs or ``--source SPEC`` (dataset folder, video,
two videos, V4L2 camera, HTTP/RTSP stream, ROS 2 bag: cvs.sources.open_source) and are tracked in
order as one sequence (ROI tracking from frame to frame). With ``--json`` one object per frame
and line: left, right, ok, tip, R, t (pose of {wm} in {ll}, metres), corners_left,
corners_right (raw pixels), rms_px, time_ms, and axis_source (what decided the direction of
z_wm: cvs.tracking.tracker); with ``--source`` also ``frame`` (the source's index) and
``t_capture`` (host monotonic clock [s]). ``"ok": false`` with a ``reason`` when the marker is
not found, or "direction ambiguous" when nothing tells which way the marker points (the
direction is never guessed unless --lenient-direction; docs/conventions.md); the exit status
stays 0 (that is a result, not an error). When ok, also ``roll_known`` (a coded sleeve's code was
read: R includes the roll) and ``ids`` ({"left": [...], "right": [...]}: absolute column ids of
the corners, null when the roll is unknown).

With ``--source``: a progress bar on stderr for finite sources (on a terminal), and at the end
one summary line on stderr: frames, rate [fps], tracking latency (result time minus
``t_capture``) median and p95 [ms], dropped frames. Before the source is opened the tracker
is warmed up on synthetic frames and the heap frozen (rig.recording.track_stream.prepare_tracker), so a
live source drops nothing meanwhile; ``--rt-priority N`` runs the tracker and the source's
threads under SCHED_FIFO (rig.loop.realtime_priority). ``--annotate`` writes the frames with the
corners, their indices and the marker axes drawn (cvs.tracking.annotate); ``--record FILE.mcap`` writes
the frames and poses as a ROS 2 bag (rig.recording.bag_recorder) that ``--source FILE.mcap`` replays.
``--ros2 [NS]`` publishes each pair's tip and marker pose over ROS 2 (rig.ros2.track_publisher:
off the tracking thread; a pair without a pose publishes nothing) and ends with one line on stderr.

Errors are for the whole command (one line on stderr, exit 2): an odd number of paths, a
missing file (all paths are checked before any pair is tracked), a source that cannot be
opened, an unreadable (corrupt) or wrong-size image or a stalled stream — those are found when
their frame is reached, after the earlier frames' lines were printed.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from wristmark.cli.common_options import add_config_option, add_json_flag, set_example
from wristmark.cli.option_types import MAX_RMS_PX, float_in, int_in, positive_float
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.models.errors import InputError

DEFAULT_TIMEOUT_S = 5.0


def size_type(text: str) -> tuple[int, int]:
    """``WxH`` as (width, height) [px], each in 1..16384."""
    parts = text.lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a size WxH (e.g. 3840x1080)") from None
    if not (0 < w <= 16384 and 0 < h <= 16384):
        raise argparse.ArgumentTypeError(f"{text}: width and height must be in 1..16384 px")
    return w, h


size_type.__name__ = "size"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_config_option(p, "--calib", required=True)
    add_config_option(p, "--marker", repeat=True,
                      note="repeat it for several arms (coded sleeves of one family, each naming its 'arm': "
                           "one JSON object per marker file and pair, with \"arm\"; image pairs only)")
    p.add_argument("--arm-processes", action="store_true",
                   help="with several --marker files: track every arm but the first in a worker process of its own "
                        "(both cores at once; the same results; ~2-3 s to start, so for many pairs)")
    add_config_option(p, "--registration", note="the JSON then also has tip_world, in {w} and metres")
    p.add_argument("images", nargs="*", metavar="LEFT RIGHT", help="stereo pairs: left and right image paths")
    p.add_argument("--source", metavar="SPEC", help="frame source instead of image pairs: DIR, VIDEO, LEFT,RIGHT, "
                   "/dev/videoN, device:N, http://..., rtsp://..., FILE.mcap, BAGDIR, ros2:LEFT,RIGHT (two ROS 2 "
                   "image topics; docs/ros2.md)")
    p.add_argument("--frames", type=int_in(1, 10**9), metavar="N", help="stop after N frames (e.g. of a live source)")
    p.add_argument("--layout", choices=("sbs", "tb"), default="sbs",
                   help="how one frame holds both views: side by side (left view left) or top-bottom")
    p.add_argument("--topics", metavar="LEFT,RIGHT", help="image topics of a bag "
                   "(default /stereo/left/image_raw,/stereo/right/image_raw)")
    p.add_argument("--size", type=size_type, metavar="WxH", help="camera frame size to request [px] (whole frame)")
    p.add_argument("--fps", type=positive_float(1000.0), metavar="F", help="camera frame rate to request [1/s]")
    p.add_argument("--fourcc", default="MJPG", help="camera pixel format (default MJPG)")
    p.add_argument("--timeout", type=positive_float(3600.0), default=DEFAULT_TIMEOUT_S, metavar="S",
                   help=f"live source: open and stall timeout [s] (default {DEFAULT_TIMEOUT_S:g})")
    p.add_argument("--paced", action="store_true",
                   help="play a video or bag at its recorded rate in wall-clock time "
                   "(video: newest frame, drops counted)")
    p.add_argument("--rt-priority", type=int_in(1, 99), metavar="N",
                   help="with --source: track (and read the source's frames) under SCHED_FIFO at priority N, so a "
                        "loaded host keeps a live or paced source's rate (needs root or CAP_SYS_NICE)")
    p.add_argument("--grayscale", action="store_true",
                   help="hand the tracker grey views (an MJPG video then decodes only its luma: 2-5x faster)")
    p.add_argument("--annotate", metavar="DIR|FILE.mp4", help="write annotated frames to a folder or a video "
                   "(.mp4, .avi, .mkv)")
    p.add_argument("--record", metavar="FILE.mcap", help="record frames and poses as a ROS 2 bag (MCAP)")
    p.add_argument("--record-jpeg", action="store_true", help="record images as JPEG (CompressedImage)")
    p.add_argument(
        "--detector",
        choices=("auto", "paper", "saddle"),
        default="auto",
        help="corner detector (auto: the paper's detector when installed)",
    )
    p.add_argument(
        "--max-rms",
        type=positive_float(MAX_RMS_PX),
        default=None,
        metavar="PX",
        help="largest accepted reprojection RMS [px] (default 0.75)",
    )
    p.add_argument(
        "--axis-hint",
        type=float_in(-1e6, 1e6),
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="expected direction of the marker's z axis (towards the tip) in the left camera frame; "
        "default: a coded sleeve's code, a consistent previous pair or the images decide (else 'direction ambiguous')",
    )
    p.add_argument(
        "--lenient-direction",
        action="store_true",
        help="guess which way the marker points when nothing decides it (one-band image evidence, else +x: the "
        "arm entering from the left); default: 'direction ambiguous' unless the code, --axis-hint, a consistent "
        "previous pair or the image beyond the tip decides",
    )
    p.add_argument("--ros2", nargs="?", const="wristmark", metavar="NS",
                   help="publish each tracked pair's tip on NS/measured_cp and the marker's pose on "
                        "NS/marker/measured_cp (PoseStamped; frame_id world with world_T_left, else left_camera; "
                        "default NS: wristmark; loopback only unless CYCLONEDDS_URI is set; docs/ros2.md)")
    add_json_flag(p, "one object per frame and line")
    set_example(p, "wristmark track --calib runs/tour/demo/calib.yaml runs/tour/demo/pair_00_left.png "
                   "runs/tour/demo/pair_00_right.png --json --axis-hint 1 0 0",
                "wristmark track --source stereo.avi --calib calib.yaml --json")


def _round(a: Any, nd: int) -> Any:
    return np.round(np.asarray(a, float), nd).tolist()


def _ids(res: Any) -> dict[str, list[int | None]] | None:
    """Absolute column ids of corners_left / corners_right (None: corner not used), or None when
    the roll is unknown (reference sleeve, or a code that could not be read)."""
    if not res.roll_known or res.ids_left is None or res.ids_right is None:
        return None
    pairs = (("left", res.ids_left), ("right", res.ids_right))
    return {k: [int(i) if i >= 0 else None for i in ids] for k, ids in pairs}


def result_fields(res: Any) -> dict[str, Any]:
    """The JSON fields of one TrackResult after left/right (docs/design.md order)."""
    out: dict[str, Any] = {"ok": res.ok}
    if res.ok and res.T_left_marker is not None and res.tip_left is not None:
        out |= {
            "tip": _round(res.tip_left, 9),
            "R": _round(res.T_left_marker[:3, :3], 9),
            "t": _round(res.T_left_marker[:3, 3], 9),
        }
    else:
        out["reason"] = res.reason
    out |= {
        "corners_left": _round(res.corners_left, 4),
        "corners_right": _round(res.corners_right, 4),
        "rms_px": round(res.rms_px, 5) if res.ok else None,
        "time_ms": round(res.time_ms, 3),
    }
    if res.ok:
        sigma = float(res.tip_sigma_m)
        out["tip_sigma_m"] = round(sigma, 9) if np.isfinite(sigma) else None
        out["axis_source"] = res.axis_source
        out["roll_known"] = res.roll_known
        out["ids"] = _ids(res)
    return out


def _text_line(frame: StereoFrame, res: Any) -> str:
    left, right = frame.name_left.rsplit("/", 1)[-1], frame.name_right.rsplit("/", 1)[-1]
    names = left if left == right else f"{left} {right}"
    if res.ok and res.tip_left is not None:
        x, y, z = (1e3 * res.tip_left).tolist()
        return (f"{names}: tip in {{ll}} [{x:.3f}, {y:.3f}, {z:.3f}] mm, "
                f"rms {res.rms_px:.3f} px, {res.time_ms:.1f} ms")
    return f"{names}: no pose ({res.reason})"


def _settings(args: argparse.Namespace) -> Any:
    from wristmark.cvs.tracking.tracker import TrackerSettings

    settings = TrackerSettings(detector=args.detector, strict_direction=not args.lenient_direction)
    if args.max_rms is not None:
        settings = replace(settings, max_rms_px=args.max_rms, good_rms_px=min(settings.good_rms_px, args.max_rms))
    return settings


def _topics(text: str | None) -> tuple[str, str]:
    from wristmark.cvs.sources.open_source import DEFAULT_TOPICS

    if text is None:
        return DEFAULT_TOPICS
    parts = [t.strip() for t in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise InputError(f"--topics must be LEFT,RIGHT (two topic names), got '{text}'")
    return parts[0], parts[1]


def check_ros2(namespace: str) -> None:
    """``--ros2 NS``: a valid namespace and cyclonedds installed (InputError, one line)."""
    from wristmark.rig.ros2.bridge import clean_namespace
    from wristmark.rig.ros2.dds_config import require_cyclonedds

    try:
        clean_namespace(namespace)
    except ValueError as e:
        raise InputError(f"--ros2: {e}") from None
    require_cyclonedds("--ros2")


def run(args: argparse.Namespace) -> int:
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.calibration.registration_file import apply_registration
    from wristmark.cvs.sources.open_source import open_stereo_source
    from wristmark.models.marker import MarkerModel

    def fields(res: Any) -> dict[str, Any]:
        out = result_fields(res)
        if args.registration and res.ok and res.tip_world is not None:
            out["tip_world"] = _round(res.tip_world, 9)
        return out

    if args.source is not None and args.images:
        raise InputError("give either LEFT RIGHT image pairs or --source SPEC, not both")
    if args.source is None and not args.images:
        raise InputError("nothing to track: give LEFT RIGHT image pairs or --source SPEC")
    if args.source is None and (args.annotate or args.record):
        raise InputError("--annotate and --record need --source SPEC (e.g. --source DIR for a dataset folder)")
    if args.rt_priority is not None and args.source is None:
        raise InputError("--rt-priority needs --source SPEC (a live or paced source)")
    if args.record_jpeg and not args.record:
        raise InputError("--record-jpeg needs --record FILE.mcap")
    if args.arm_processes and len(args.marker or []) < 2:
        raise InputError("--arm-processes needs several --marker files (one worker per arm but the first)")
    if args.ros2 is not None:
        check_ros2(args.ros2)  # a valid namespace and cyclonedds installed, before anything is opened
    hint = None
    if args.axis_hint is not None:
        hint = np.asarray(args.axis_hint, float)
        if not np.linalg.norm(hint) > 0:
            raise InputError(f"--axis-hint must be a non-zero direction, got {args.axis_hint}")
    if args.source is None:
        source = open_stereo_source(args.images)  # paths checked before anything is loaded
    camera = apply_registration(load_calibration(args.calib), args.registration)
    marker_files = args.marker or []
    markers = [MarkerModel.load(f) for f in marker_files] or [MarkerModel()]
    if len(markers) > 1:
        from wristmark.models.marker import check_marker_set

        if args.source is not None or args.ros2 is not None:
            raise InputError("several --marker files: track image pairs (LEFT RIGHT ...), not --source or --ros2")
        check_marker_set(markers, [str(f) for f in marker_files])
        return _track_arms(args, camera, markers, hint, fields, source)
    marker = markers[0]
    publisher = None
    if args.ros2 is not None:  # before the warm-up: subscribers are discovered meanwhile
        from wristmark.rig.ros2.track_publisher import TrackPublisher

        publisher = TrackPublisher(args.ros2, camera.T_world_left)
    try:
        return _track(args, camera, marker, hint, fields, publisher, None if args.source is not None else source)
    finally:
        if publisher is not None:
            publisher.close()
            print(publisher.line(), file=sys.stderr, flush=True)


def arm_objects(results: dict[str, Any], fields: Any) -> list[dict[str, Any]]:
    """One object per arm for one pair tracked with a marker set (cvs.tracking.arm_set): the pose
    fields where the arm's own code identified its sleeve, else ``"ok": false`` with the reason
    (not in view, or a sleeve in view could not be identified: a pose with an undecided identity
    is no arm's)."""
    return [{"arm": a} | (fields(res) if res.ok else {"ok": False, "reason": res.reason}) for a, res in results.items()]


def _track_arms(args: argparse.Namespace, camera: Any, markers: list[Any], hint: Any, fields: Any,
                source: Any) -> int:
    """Image pairs with a marker set: every sleeve in each pair, one line per arm and pair."""
    from wristmark.cvs.tracking.arm_set import ArmSetTracker
    from wristmark.cvs.tracking.warmup import warm_up

    warm_up()
    tracker = ArmSetTracker(camera, markers, _settings(args), names=[str(f) for f in args.marker],
                            search_every=1, processes=args.arm_processes)  # image pairs: any arm anywhere
    hints = {m.arm: hint for m in markers} if hint is not None else None
    with tracker:
        return _print_arms(args, tracker, source, hints, fields)


def _print_arms(args: argparse.Namespace, tracker: Any, source: Any, hints: Any, fields: Any) -> int:
    """Each pair of ``source`` tracked by the arm set, one line per arm and pair."""
    for frame in iter(source.read, None):
        try:
            results = tracker.track(frame.left, frame.right, axis_hints_left=hints)
        except InputError as e:
            raise InputError(f"{frame.name_left} / {frame.name_right}: {e}") from e
        for obj in arm_objects(results, fields):
            out = {"left": frame.name_left, "right": frame.name_right} | obj
            if args.json:
                print(json.dumps(out), flush=True)
            elif obj["ok"]:
                print(f"{obj['arm']}: {_text_line(frame, results[obj['arm']])}", flush=True)
            else:
                print(f"{obj['arm']}: no pose ({obj['reason']})", flush=True)
    return 0


def _track(args: argparse.Namespace, camera: Any, marker: Any, hint: Any, fields: Any, publisher: Any,
           source: Any) -> int:
    """Track the image pairs (``source``) or ``--source``; each pair to ``publisher`` too (None: no --ros2)."""
    from wristmark.cvs.sources.open_source import SourceOptions
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.cvs.tracking.warmup import warm_up

    warm_up()  # OpenCV's threads and the tracker's kernels, before the first pair (cvs.tracking.warmup)
    tracker = MarkerTracker(camera, marker, _settings(args))
    if args.source is None:
        for frame in iter(source.read, None):
            try:
                res = tracker.track(frame.left, frame.right, axis_hint_left=hint)
            except InputError as e:
                raise InputError(f"{frame.name_left} / {frame.name_right}: {e}") from e
            if publisher is not None:
                publisher.on_pair(frame.t_capture, res)
            out = {"left": frame.name_left, "right": frame.name_right} | fields(res)
            print(json.dumps(out) if args.json else _text_line(frame, res), flush=True)
        return 0
    options = SourceOptions(layout=args.layout, size=args.size, fps=args.fps, fourcc=args.fourcc or None,
                            topics=_topics(args.topics), timeout=args.timeout, paced=args.paced,
                            image_size=camera.image_size, grayscale=args.grayscale)
    from wristmark.rig.recording.track_stream import TrackOutputs, prepare_tracker, track_source

    def emit(frame: StereoFrame, res: Any) -> None:
        if publisher is not None:
            publisher.on_pair(frame.t_capture, res)
        if args.json:
            line = {"left": frame.name_left, "right": frame.name_right} | fields(res)
            print(json.dumps(line | {"frame": frame.index, "t_capture": round(frame.t_capture, 6)}), flush=True)
        else:
            print(_text_line(frame, res), flush=True)

    if args.rt_priority is not None:  # before the source's threads start: they inherit it
        from wristmark.rig.loop.realtime_priority import request_realtime_priority

        request_realtime_priority(args.rt_priority)
    prepare_tracker(tracker, args.grayscale)  # no first use of a code path nor full collection on a frame
    from wristmark.rig.ros2.image_source import open_frame_source

    source = open_frame_source(args.source, options)  # open_stereo_source, and ros2:LEFT,RIGHT
    try:
        fps = float(getattr(source, "fps", 0.0) or 30.0)  # a video's own rate for an annotated video
        outputs = TrackOutputs.open(args.annotate, args.record, args.record_jpeg, camera, marker, fps)
    except BaseException:
        source.close()
        raise
    try:
        summary = track_source(source, tracker, emit, outputs, args.frames, hint)
    finally:
        source.close()
        outputs.close()
    print(summary.line(), file=sys.stderr, flush=True)
    return 0
