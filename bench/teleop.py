"""Teleoperation over ROS 2: how closely the simulated arm follows a surgeon's input device.

A device in this process (it knows only the message types: Cyclone DDS and
wristmark.rig.ros2.messages) publishes ``NS/servo_cp`` at --rate Hz along a hand-like path: three
slow sines per axis (0.11-0.37 Hz, --amplitude mm, peak speed under --max-speed) plus an 9.5 Hz
physiological tremor of --tremor mm; --dropout S of silence in the middle of the run (the loop
must hold, then resume). ``wristmark servo --ros2 NS --target ros2`` runs the simulated bench
(truth-noise sensor unless --sensor vision) as its own process; both on loopback (the loopback
DDS configuration set here). The true tip (the bench's log) is compared with the device's
target at the same instant (host monotonic clock): the following error [mm] (median, p95, max)
with and without the best constant delay, that delay [ms], and the loop's counts (received,
dropped, clamped, holds). Prints one JSON document.

    .venv/bin/python bench/teleop.py [--duration 20] [--rate 100] [--amplitude 6] [--tremor 0.05] \
        [--dropout 0.6] [--max-speed 0.03] [--sensor truth-noise]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FREQS = ((0.11, 0.23, 0.37), (0.13, 0.29, 0.17), (0.19, 0.07, 0.31))  # [Hz] per axis x_w, y_w, z_w
TREMOR_HZ = 9.5


def hand_path(t: float, amplitude: float, tremor: float) -> np.ndarray:
    """Offset [m] of the device from its start at time ``t`` [s] (0 at t = 0)."""
    out = np.zeros(3)
    for axis, freqs in enumerate(FREQS):
        scale = 0.5 if axis == 1 else 1.0  # y_w: depth from the camera, the smaller side of the box
        out[axis] = scale * amplitude / 3 * sum(math.sin(2 * math.pi * f * t) for f in freqs)
    out += tremor * np.array([1.0, 0.3, 0.6]) * math.sin(2 * math.pi * TREMOR_HZ * t)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=20.0, help="the loop's run [s]")
    ap.add_argument("--rate", type=float, default=100.0, help="device rate [Hz]")
    ap.add_argument("--amplitude", type=float, default=6.0, help="hand motion per axis [mm]")
    ap.add_argument("--tremor", type=float, default=0.05, help="tremor amplitude [mm]")
    ap.add_argument("--dropout", type=float, default=0.6, help="device silent this long mid-run [s] (0: none)")
    ap.add_argument("--max-speed", type=float, default=0.03, help="the loop's target speed bound [m/s]")
    ap.add_argument("--sensor", choices=("truth-noise", "vision"), default="truth-noise")
    args = ap.parse_args()

    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.rig.recording.run_log import read_log_csv
    from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
    from wristmark.rig.ros2.messages import PoseStamped, pose_stamped, topic_name

    domain = random.randint(100, 199)
    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # benchmarks: always the loopback configuration
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    ns = f"teleop_{os.getpid()}"
    tmp = Path(tempfile.mkdtemp(prefix="wristmark-teleop-"))
    controller = tmp / "controller.yaml"  # the shipped controller without its play probe: the walk starts at once
    controller.write_text((ROOT / "wristmark" / "configs" / "controller.yaml").read_text()
                          .replace("play_probe: true", "play_probe: false"))
    servo = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "servo", "--ros2", ns, "--target", "ros2", "--sensor", args.sensor,
         "--duration", str(args.duration), "--settle", "0.3", "--max-speed", str(args.max_speed),
         "--controller-config", str(controller), "--no-progress", "--out", str(tmp / "run"),
         "--json", str(tmp / "res.json")],
        cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)

    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(10))
    cp = DataReader(dp, Topic(dp, topic_name(f"{ns}/measured_cp"), PoseStamped), qos)
    writer = DataWriter(dp, Topic(dp, topic_name(f"{ns}/servo_cp"), PoseStamped), qos)
    sent: list[tuple[float, list[float]]] = []
    stop = threading.Event()

    def device() -> None:
        start = None
        while start is None and not stop.is_set():  # the tip where the loop holds it: the device's origin
            got = cp.take(N=64)
            if got:
                p = got[-1].pose.position
                start = np.array([p.x, p.y, p.z])
            time.sleep(0.01)
        t0 = time.monotonic()
        period = 1.0 / args.rate
        k = 0
        while not stop.is_set():
            t = time.monotonic() - t0
            mid = 0.5 * (args.duration + 2.0)
            if not (args.dropout > 0 and mid <= t < mid + args.dropout):
                target = (start + hand_path(t, args.amplitude / 1000, args.tremor / 1000)).tolist()
                writer.write(pose_stamped(time.time(), "world", target))
                sent.append((time.monotonic(), target))
            cp.take(N=64)  # keep the reader's queue short
            k += 1
            time.sleep(max(0.0, t0 + k * period - time.monotonic()))

    th = threading.Thread(target=device, daemon=True)
    th.start()
    try:
        _, err = servo.communicate(timeout=120 + 3 * args.duration)
    finally:
        stop.set()
        th.join(timeout=5)
        servo.kill()
    if servo.returncode != 0:
        sys.exit(f"wristmark servo failed: {err.strip()[-2000:]}")
    res = json.loads((tmp / "res.json").read_text())
    log = read_log_csv(tmp / "run" / "log.csv")
    walk = np.array([ph == "servo" for ph in log["phase"]])
    t_wall = np.asarray(log["t_wall"])[walk]
    p_true = np.stack([np.asarray(log[f"p_true_{c}"]) for c in "xyz"], axis=1)[walk]
    ts = np.array([s[0] for s in sent])
    ps = np.array([s[1] for s in sent])

    def device_at(t: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, ts, ps[:, i]) for i in range(3)], axis=1)

    inside = (t_wall > ts[0] + 1.0) & (t_wall < ts[-1])  # after the first second of steering
    gaps = np.diff(ts) > 0.1
    if gaps.any():  # leave out the dropout and the second after it
        i = int(np.argmax(gaps))
        inside &= ~((t_wall > ts[i]) & (t_wall < ts[i + 1] + 1.0))
    err0 = 1000 * np.linalg.norm(p_true[inside] - device_at(t_wall[inside]), axis=1)
    delays = np.arange(0.0, 0.6, 0.005)
    med = [np.median(np.linalg.norm(p_true[inside] - device_at(t_wall[inside] - d), axis=1)) for d in delays]
    best = float(delays[int(np.argmin(med))])
    err_d = 1000 * np.linalg.norm(p_true[inside] - device_at(t_wall[inside] - best), axis=1)
    speed = np.linalg.norm(np.diff(ps, axis=0), axis=1) / np.maximum(np.diff(ts), 1e-9)
    print(json.dumps({
        "device": {"rate_hz": args.rate, "amplitude_mm": args.amplitude, "tremor_mm": args.tremor,
                   "sent": len(sent), "peak_speed_mm_s": round(1000 * float(np.percentile(speed, 99)), 1),
                   "dropout_s": args.dropout},
        "loop": {"sensor": args.sensor, "control_dt_s": res["control_dt_s"], "cycles": int(inside.sum()),
                 "max_speed_mps": args.max_speed, "targets": res["targets"],
                 "closed_loop_vs_asked_mm": {"mean": res["closed_loop"]["mean_mm"],
                                             "max": res["closed_loop"]["max_mm"]},
                 "ros2_hook_ms": res["ros2"]["hook_ms"]},
        "following_error_mm": {"median": float(np.median(err0)), "p95": float(np.percentile(err0, 95)),
                               "max": float(err0.max())},
        "best_delay_ms": 1000 * best,
        "following_error_after_delay_mm": {"median": float(np.median(err_d)), "p95": float(np.percentile(err_d, 95)),
                                           "max": float(err_d.max())},
        "run_dir": str(tmp / "run"),
    }, indent=1))


if __name__ == "__main__":
    main()
