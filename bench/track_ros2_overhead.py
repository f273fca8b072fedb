"""What publishing on ROS 2 costs `wristmark track --ros2` a pair: one in-process run of the
tracking loop of `track --source` (rig.recording.track_stream.track_source: read, track, emit)
over a rendered dataset of a smooth path (--pairs pairs around the home configuration, read
--passes times), publishing each pair's tip and marker pose (rig/ros2/track_publisher.py) in
alternate blocks of --block pairs, with a subscriber in another process on loopback (the loopback
configuration set here). Prints one JSON document: the median time of a pair (one emit to the
next: reading, tracking, the line, the hook) with publishing on and off (the first pair of each
block left out), their difference, and the tracking thread's time in the hook [ms].

    .venv/bin/python bench/track_ros2_overhead.py [--pairs 45] [--block 5] [--passes 4] [--dataset DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
READER = """
import os, signal, sys, time
signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from wristmark.rig.ros2.messages import PoseStamped, topic_name
dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
ns = os.environ["NS"]
qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(64))
readers = [DataReader(dp, Topic(dp, topic_name(ns + "/" + n), PoseStamped), qos)
           for n in ("measured_cp", "marker/measured_cp")]
n = 0
t_end = time.monotonic() + float(os.environ["LIFE_S"])
try:
    while time.monotonic() < t_end:
        for r in readers:
            n += len([m for m in r.take(N=64) if hasattr(m, "pose")])
        time.sleep(0.01)
finally:
    print(n, flush=True)
"""


def render_path(out: Path, pairs: int) -> None:
    """A dataset of ``pairs`` pairs along a smooth closed path around HOME_PSI (PNG, JPEG round trip 90)."""
    from wristmark.cli.main import main as wristmark
    from wristmark.models.robot_params import HOME_PSI

    k = np.arange(pairs)[:, None] * 2 * np.pi / pairs
    amp = np.array([0.08, 0.004, 0.06, 0.2, 0.1, 0.2])
    psi = np.asarray(HOME_PSI) + amp * np.sin(k + np.arange(6) * 0.9)
    psi_file = out.parent / "psi.txt"
    psi_file.write_text("\n".join(" ".join(f"{x:.9f}" for x in q) for q in psi) + "\n")
    with contextlib.redirect_stdout(sys.stderr):  # stdout: the JSON document only
        code = wristmark(["render", "--out", str(out), "--psi-file", str(psi_file), "--jpeg", "90", "--seed", "1"])
    if code != 0:
        raise SystemExit("render failed")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=45,
                    help="pairs of the rendered path (an odd number of blocks: on in one pass, off in the next)")
    ap.add_argument("--block", type=int, default=5, help="pairs per on / off block")
    ap.add_argument("--passes", type=int, default=4, help="times the dataset is read")
    ap.add_argument("--dataset", type=Path, help="a dataset folder to use instead (rendered when not given)")
    args = ap.parse_args()
    from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG

    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # benchmarks: always the loopback configuration
    os.environ["ROS_DOMAIN_ID"] = str(random.randint(100, 199))
    ns = f"wm_bench_track_{os.getpid()}"
    tmp = tempfile.TemporaryDirectory(prefix="wm-track-ros2-")
    dataset = args.dataset
    if dataset is None:
        dataset = Path(tmp.name) / "ds"
        render_path(dataset, args.pairs)
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.sources.open_source import open_stereo_source
    from wristmark.cvs.tracking.tracker import MarkerTracker
    from wristmark.cvs.tracking.warmup import warm_up
    from wristmark.models.marker import MarkerModel
    from wristmark.rig.recording.track_stream import prepare_tracker, track_source
    from wristmark.rig.ros2.track_publisher import TrackPublisher

    camera = load_calibration(dataset / "calib.yaml")
    marker = MarkerModel.load(dataset / "marker.yaml")
    reader = subprocess.Popen([sys.executable, "-c", READER], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(ROOT), "NS": ns, "LIFE_S": "600"})
    publisher = TrackPublisher(ns, camera.T_world_left)
    warm_up()
    tracker = MarkerTracker(camera, marker)
    prepare_tracker(tracker, False)
    time.sleep(1.0)  # discovery
    stamps: list[tuple[float, bool]] = []
    found = 0

    def emit(frame: Any, res: Any) -> None:
        nonlocal found
        on = (len(stamps) // args.block) % 2 == 0
        found += int(res.ok)
        if on:
            publisher.on_pair(frame.t_capture, res)
        json.dumps({"left": frame.name_left, "ok": res.ok})  # the line `track --json` prints, roughly
        stamps.append((time.perf_counter(), on))

    t0 = time.perf_counter()
    for _ in range(args.passes):
        source = open_stereo_source(str(dataset))
        try:
            track_source(source, tracker, emit, None, None, None)
        finally:
            source.close()
    wall = time.perf_counter() - t0
    publisher.close()
    time.sleep(0.5)
    reader.terminate()
    received = reader.communicate(timeout=10)[0].strip()
    t = np.array([s[0] for s in stamps])
    on = np.array([s[1] for s in stamps])
    dt_ms = 1000.0 * np.diff(t)
    same = on[1:] == on[:-1]  # the pair ended in the same block it began (first of a block left out)
    pair_on, pair_off = dt_ms[same & on[1:]], dt_ms[same & ~on[1:]]
    hook_ms = 1000.0 * np.asarray(publisher.hook_s)
    print(json.dumps({
        "pairs": int(len(t)), "found": found, "wall_s": wall,
        "pair_ms": {"on_median": float(np.median(pair_on)), "off_median": float(np.median(pair_off)),
                    "extra_median": float(np.median(pair_on) - np.median(pair_off)),
                    "on_p90": float(np.percentile(pair_on, 90)), "off_p90": float(np.percentile(pair_off, 90)),
                    "n_on": int(pair_on.size), "n_off": int(pair_off.size)},
        "hook_ms": {"median": float(np.median(hook_ms)), "p99": float(np.percentile(hook_ms, 99)),
                    "max": float(hook_ms.max())},
        "published": publisher.report(), "received_by_subscriber": int(received) if received.isdigit() else received,
    }, indent=1))
    tmp.cleanup()


if __name__ == "__main__":
    main()
