"""Teleoperation over ROS 2: how closely the arm follows a surgeon's input device (#30).

A device in this process (it knows only the message types: Cyclone DDS and
wristmark.rig.ros2.messages) publishes ``HOST/servo_cp`` at --rate Hz along a hand-like path:
three slow sines per axis (0.11-0.37 Hz, --amplitude mm, peak speed under --max-speed) plus a
9.5 Hz physiological tremor of --tremor mm; --dropout S of silence mid-run (the loop must hold,
then resume). It starts where the loop holds the tip (measured_cp's mean over 0.5 s moved less
than 0.2 mm from the 0.5 s before). Everything on loopback (the loopback DDS configuration set here, a random
ROS_DOMAIN_ID in 100-199). Two modes:

* ``--mode lab`` (default): the virtual lab over ROS 2 with vision in the loop, three processes:
  ``wristmark emulator --ros2 LAB --image-scale S --fps F --truth-out truth.csv`` (the simulated
  arm behind LAB/servo_jp, crtk_command, measured_js, its stereo endoscope on two CompressedImage
  topics), ``wristmark servo --actuator ros2:/LAB --camera ros2:... --image-scale S --target ros2
  --ros2 HOST`` (the hardware path: real time, the tip only from tracking the frames) and this
  one. The true tip is the lab's truth (each frame's instant on CLOCK_MONOTONIC, one clock for
  every process on Linux).
* ``--mode inprocess``: ``wristmark servo --ros2 HOST --target ros2`` runs the simulated bench
  (paced to the wall clock) in its own process, with vision in the loop (rendered at
  --image-scale and tracked; ``--sensor truth-noise``: the fast sensor without images). The true
  tip is its log's (at each cycle's ``t_wall``).

Measured: the true tip against the device's target at the same instant, and after the best
constant delay (the loop's lag; the delay of least mean error) [mm]: mean, median, p95, max; the
publish-to-receive latency of ``measured_cp`` on loopback [ms] (a listener in this process: its
receipt, ``time.time_ns()``, minus the sample's DDS source timestamp, which the writer sets from
the system clock when it writes), and the receipt minus the message's header stamp (lab: the
frame's capture; in process: the cycle's start); the loop's time in the ROS 2 bridge's hook per
cycle (the host time publishing adds to a cycle; bench/ros2_overhead.py compares on and off);
the loop's counts (received, dropped, clamped, holds). Prints one JSON document (--json FILE
also writes it) with the settings.

    .venv/bin/python bench/teleop.py [--mode lab|inprocess] [--duration 20] [--image-scale 0.35] \
        [--fps 15] [--sensor vision|truth-noise] [--rate 100] [--amplitude 6] [--tremor 0.05] \
        [--dropout 0.6] [--max-speed 0.03] [--lab-watchdog 0.25] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FREQS = ((0.11, 0.23, 0.37), (0.13, 0.29, 0.17), (0.19, 0.07, 0.31))  # [Hz] per axis x_w, y_w, z_w
TREMOR_HZ = 9.5
STILL_S, STILL_MM = 0.5, 0.2  # the device starts once measured_cp's mean over STILL_S moved < STILL_MM
SKIP_S = 1.0  # the first second of steering, and the second after the dropout, are not scored


def hand_path(t: float, amplitude: float, tremor: float) -> np.ndarray:
    """Offset [m] of the device from its start at time ``t`` [s] (0 at t = 0)."""
    out = np.zeros(3)
    for axis, freqs in enumerate(FREQS):
        scale = 0.5 if axis == 1 else 1.0  # y_w: depth from the camera, the smaller side of the box
        out[axis] = scale * amplitude / 3 * sum(math.sin(2 * math.pi * f * t) for f in freqs)
    out += tremor * np.array([1.0, 0.3, 0.6]) * math.sin(2 * math.pi * TREMOR_HZ * t)
    return out


def stats_ms(x: Any, *, p99: bool = False) -> dict[str, Any]:
    """n, mean, median, p95 (or p90 and p99), max of ``x`` (None when empty), rounded to 3 decimals."""
    a = np.asarray(x, float)
    a = a[np.isfinite(a)]
    if not a.size:
        return {"n": 0}
    out: dict[str, Any] = {"n": int(a.size), "mean": float(a.mean()), "median": float(np.median(a))}
    if p99:
        out.update(p90=float(np.percentile(a, 90)), p99=float(np.percentile(a, 99)))
    else:
        out["p95"] = float(np.percentile(a, 95))
    out["max"] = float(a.max())
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}


class CpListener:
    """Every ``measured_cp`` sample, as it arrives (Cyclone's listener thread): receipt [ns, system
    clock], DDS source timestamp [ns], header stamp [ns], position [m]. Thread-safe."""

    def __init__(self, dp: Any, topic: Any, qos: Any) -> None:
        from cyclonedds.core import Listener
        from cyclonedds.sub import DataReader

        self.rows: list[tuple[int, int, int, float, float, float]] = []
        self.lock = threading.Lock()
        self.reader = DataReader(dp, topic, qos, listener=Listener(on_data_available=self._on_data))

    def _on_data(self, reader: Any) -> None:
        now = time.time_ns()
        for s in reader.take(N=64):
            if not hasattr(s, "pose"):
                continue  # an InvalidSample (the writer left)
            stamp = int(s.header.stamp.sec) * 1_000_000_000 + int(s.header.stamp.nanosec)
            p = s.pose.position
            with self.lock:
                self.rows.append((now, int(s.sample_info.source_timestamp), stamp, p.x, p.y, p.z))

    def snapshot(self) -> np.ndarray:
        """(N, 6) int64/float rows so far (receipt, source, stamp [ns], x, y, z [m])."""
        with self.lock:
            return np.array(self.rows, float).reshape(-1, 6) if self.rows else np.zeros((0, 6))

    def latency(self) -> dict[str, Any]:
        """Publish -> receive and stamp -> receive [ms] (median, p99, ...)."""
        with self.lock:
            rows = list(self.rows)
        recv = np.array([r[0] for r in rows], np.int64)
        src = np.array([r[1] for r in rows], np.int64)
        stamp = np.array([r[2] for r in rows], np.int64)
        return {"publish_to_receive": stats_ms((recv - src) / 1e6, p99=True),
                "stamp_to_receive": stats_ms((recv - stamp) / 1e6, p99=True)}

    def close(self) -> None:
        self.reader.set_listener(None)

    def still_at(self, now_ns: int) -> np.ndarray | None:
        """The tip [m] once it stands still: the mean of measured_cp over the last STILL_S within
        STILL_MM of its mean over the STILL_S before (>= 4 samples in each); else None."""
        rows = self.snapshot()
        if not rows.shape[0] or rows[0, 0] > now_ns - 2e9 * STILL_S:
            return None
        last = rows[rows[:, 0] >= now_ns - 1e9 * STILL_S, 3:6]
        before = rows[(rows[:, 0] < now_ns - 1e9 * STILL_S) & (rows[:, 0] >= now_ns - 2e9 * STILL_S), 3:6]
        if last.shape[0] < 4 or before.shape[0] < 4:
            return None
        m = last.mean(axis=0)
        return np.asarray(m, float) if np.linalg.norm(m - before.mean(axis=0)) <= STILL_MM / 1000 else None


def scored(t: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """The instants ``t`` [s] to score: while the device steered, after its first second, and not
    in its dropout nor the second after it."""
    inside = (t > ts[0] + SKIP_S) & (t < ts[-1])
    gaps = np.flatnonzero(np.diff(ts) > 0.1)
    for i in gaps:
        inside &= ~((t > ts[i]) & (t < ts[i + 1] + SKIP_S))
    return inside


def following(t: np.ndarray, p_true: np.ndarray, ts: np.ndarray, ps: np.ndarray) -> dict[str, Any]:
    """The true tip ``p_true`` [m] at ``t`` [s] against the device's target (``ts``, ``ps``) at the
    same instant and after the best constant delay (least mean error, 0-600 ms) [mm]."""

    def err(d: float) -> np.ndarray:
        dev = np.stack([np.interp(t - d, ts, ps[:, i]) for i in range(3)], axis=1)
        return 1000.0 * np.linalg.norm(p_true - dev, axis=1)

    delays = np.arange(0.0, 0.6, 0.005)
    best = float(delays[int(np.argmin([err(d).mean() for d in delays]))])
    return {"scored_samples": int(t.size), "error_mm": stats_ms(err(0.0)), "lag_ms": round(1000 * best, 1),
            "error_after_lag_mm": stats_ms(err(best))}


def read_line(stream: Any, timeout: float) -> str:
    """One line of a child's stdout, or '' after ``timeout`` [s]."""
    box: list[str] = []
    th = threading.Thread(target=lambda: box.append(stream.readline()), daemon=True)
    th.start()
    th.join(timeout)
    return box[0].strip() if box else ""


def first_image(dp: Any, lab_ns: str, timeout: float) -> bool:
    """Wait up to ``timeout`` [s] for the lab's first left image (its renderer starts slowly on a
    loaded host, and the loop allows a camera 2 s for its first frame)."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wristmark.rig.ros2.messages import CompressedImage, topic_name

    reader = DataReader(dp, Topic(dp, topic_name(f"{lab_ns}/left/image_raw/compressed"), CompressedImage),
                        Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1)))
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if any(hasattr(s, "data") for s in reader.take(N=4)):
            return True
        time.sleep(0.05)
    return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mode", choices=("lab", "inprocess"), default="lab",
                    help="lab: the virtual lab over ROS 2, vision in the loop (default); inprocess: the simulated "
                         "bench in the servo process")
    ap.add_argument("--duration", type=float, default=20.0, help="the loop's run [s]")
    ap.add_argument("--image-scale", type=float, default=0.35, help="frames at this fraction of 1920x1080")
    ap.add_argument("--fps", type=float, default=15.0, help="lab: the endoscope's frame rate [Hz]")
    ap.add_argument("--sensor", choices=("vision", "truth-noise"), default="vision",
                    help="inprocess: the tip sensor (default vision; truth-noise: no images)")
    ap.add_argument("--settle", type=float, default=None, help="the loop's approach to the start [s] "
                    "(default: lab 1.0, inprocess 0.3)")
    ap.add_argument("--rate", type=float, default=100.0, help="device rate [Hz]")
    ap.add_argument("--amplitude", type=float, default=6.0, help="hand motion per axis [mm]")
    ap.add_argument("--tremor", type=float, default=0.05, help="tremor amplitude [mm]")
    ap.add_argument("--dropout", type=float, default=0.6, help="device silent this long mid-run [s] (0: none)")
    ap.add_argument("--max-speed", type=float, default=0.03, help="the loop's target speed bound [m/s]")
    ap.add_argument("--lab-watchdog", type=float, default=0.25,
                    help="lab: the arm holds and disables after this long without servo_jp [s] (default 0.25, "
                         "the actuator box's)")
    ap.add_argument("--json", metavar="FILE", help="also write the JSON document here")
    args = ap.parse_args()
    if args.mode == "lab" and args.sensor != "vision":
        ap.error("--mode lab tracks the endoscope's frames: --sensor is for --mode inprocess")
    settle = args.settle if args.settle is not None else (1.0 if args.mode == "lab" else 0.3)

    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic

    from wristmark.rig.recording.run_log import read_log_csv
    from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG
    from wristmark.rig.ros2.messages import PoseStamped, pose_stamped, topic_name

    domain = random.randint(100, 199)
    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # benchmarks: always the loopback configuration
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    host = f"teleop_{os.getpid()}"
    lab_ns = f"teleop_lab_{os.getpid()}"
    tmp = Path(tempfile.mkdtemp(prefix="wristmark-teleop-"))
    controller = tmp / "controller.yaml"  # the shipped controller without its play probe: the walk starts at once
    controller.write_text((ROOT / "wristmark" / "configs" / "controller.yaml").read_text()
                          .replace("play_probe: true", "play_probe: false"))
    load_before = os.getloadavg()
    wall0 = time.monotonic()

    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(10))
    cp = CpListener(dp, Topic(dp, topic_name(f"{host}/measured_cp"), PoseStamped), qos)
    writer = DataWriter(dp, Topic(dp, topic_name(f"{host}/servo_cp"), PoseStamped), qos)

    lab: subprocess.Popen[str] | None = None
    servo: subprocess.Popen[str] | None = None
    truth = tmp / "truth.csv"
    common = ["--target", "ros2", "--ros2", host, "--image-scale", str(args.image_scale), "--duration",
              str(args.duration), "--settle", str(settle), "--max-speed", str(args.max_speed),
              "--controller-config", str(controller), "--no-progress", "--out", str(tmp / "run"),
              "--json", str(tmp / "res.json")]
    sent: list[tuple[float, list[float]]] = []
    stop = threading.Event()

    def device() -> None:
        start = None
        while start is None and not stop.is_set():  # the tip where the loop holds it: the device's origin
            start = cp.still_at(time.time_ns())
            time.sleep(0.02)
        if start is None:
            return
        t0 = time.monotonic()
        period = 1.0 / args.rate
        mid = 0.5 * args.duration
        k = 0
        while not stop.is_set():
            t = time.monotonic() - t0
            if not (args.dropout > 0 and mid <= t < mid + args.dropout):
                target = (start + hand_path(t, args.amplitude / 1000, args.tremor / 1000)).tolist()
                writer.write(pose_stamped(time.time(), "world", target))
                sent.append((time.monotonic(), target))
            k += 1
            time.sleep(max(0.0, t0 + k * period - time.monotonic()))

    th = threading.Thread(target=device, daemon=True)
    lab_err = servo_err = ""
    try:
        if args.mode == "lab":
            lab = subprocess.Popen(
                [sys.executable, "-m", "wristmark", "emulator", "--ros2", lab_ns, "--image-scale",
                 str(args.image_scale), "--fps", str(args.fps), "--watchdog", str(args.lab_watchdog), "--truth-out",
                 str(truth)], cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            actuator, camera = read_line(lab.stdout, 60), read_line(lab.stdout, 10)
            if not (actuator.startswith("ros2:") and camera.startswith("ros2:")):
                raise SystemExit(f"wristmark emulator --ros2 did not start: {actuator!r}")
            if not first_image(dp, lab_ns, 60.0):  # the endoscope is up before the loop waits for its frames
                raise SystemExit("the lab published no image in 60 s")
            cmd = ["--actuator", actuator, "--camera", camera, *common]
        else:
            cmd = ["--sensor", args.sensor, *common]
        servo = subprocess.Popen([sys.executable, "-m", "wristmark", "servo", *cmd], cwd=ROOT, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        th.start()
        _, servo_err = servo.communicate(timeout=120 + 3 * args.duration)
    finally:
        stop.set()
        if th.is_alive():
            th.join(timeout=5)
        if servo is not None:
            servo.kill()
        if lab is not None:
            lab.terminate()  # SIGTERM: the lab stops and prints its summary
            try:
                lab_err = lab.communicate(timeout=30)[1]
            except subprocess.TimeoutExpired:
                lab.kill()
                lab_err = lab.communicate()[1]
            if servo is None:
                print(lab_err.strip()[-2000:], file=sys.stderr)
        cp.close()
    wall_s = time.monotonic() - wall0
    load_after = os.getloadavg()
    assert servo is not None
    if servo.returncode != 0:
        sys.exit(f"wristmark servo failed ({servo.returncode}): {servo_err.strip()[-2000:]}")
    if len(sent) < 10:
        sys.exit(f"the device never started: measured_cp never stood still ({cp.snapshot().shape[0]} received)")
    res = json.loads((tmp / "res.json").read_text())
    log = read_log_csv(tmp / "run" / "log.csv")
    walk = np.array([ph == "servo" for ph in log["phase"]])
    t_cycles = np.asarray(log["t_wall"], float)[walk]
    ts = np.array([s[0] for s in sent])
    ps = np.array([s[1] for s in sent])

    lab_report: dict[str, Any] = {}
    if args.mode == "lab":
        from wristmark.sim.virtual_lab import read_truth_csv, true_tip_errors

        t_true, p_true = read_truth_csv(truth)
        keep = (t_true >= t_cycles[0]) & (t_true <= t_cycles[-1])  # the loop's walk only
        t_true, p_true = t_true[keep], p_true[keep]
        summary = [ln for ln in lab_err.splitlines() if "frames" in ln and "watchdog" in ln]
        vs_desired = 1000.0 * true_tip_errors(tmp / "run" / "log.csv", truth)
        counts = {k: int(v) for v, k in re.findall(r"(\d+) (frames|targets|watchdog trips|malformed)",
                                                  summary[-1] if summary else "")}
        lab_report = {"summary": summary[-1] if summary else lab_err.strip()[-300:],
                      "frames": counts.get("frames"), "targets_obeyed": counts.get("targets"),
                      "watchdog_trips": counts.get("watchdog trips"),
                      "true_vs_loop_desired_mm": stats_ms(vs_desired),
                      "capture_to_command_ms": res["latency"]["capture_to_command"],
                      "link": {k: res["link"].get(k) for k in ("sent", "malformed_measured_js")},
                      "camera": {k: res["frames"].get(k) for k in ("received", "dropped")}}
        truth_from = "the lab's --truth-out (each frame's instant)"
    else:
        t_true = t_cycles
        p_true = np.stack([np.asarray(log[f"p_true_{c}"], float) for c in "xyz"], axis=1)[walk]
        truth_from = "the simulated bench's log (p_true at t_wall)"
    inside = scored(t_true, ts)
    speed = np.linalg.norm(np.diff(ps, axis=0), axis=1) / np.maximum(np.diff(ts), 1e-9)
    c = res["closed_loop"]
    out = {
        "mode": args.mode,
        "settings": {"sensor": res["sensor"], "image_scale": args.image_scale,
                     "fps": args.fps if args.mode == "lab" else None,
                     "lab_watchdog_s": args.lab_watchdog if args.mode == "lab" else None,
                     "control_dt_s": res["control_dt_s"],
                     "controller": res["controller"] + " (play probe off)", "settle_s": settle,
                     "max_speed_mps": args.max_speed, "duration_s": args.duration, "dds": "loopback",
                     "ros_domain_id": domain},
        "device": {"rate_hz": args.rate, "amplitude_mm": args.amplitude, "tremor_mm": args.tremor,
                   "sent": len(sent), "peak_speed_mm_s": round(1000 * float(np.percentile(speed, 99)), 1),
                   "dropout_s": args.dropout},
        "truth": truth_from,
        "following": following(t_true[inside], p_true[inside], ts, ps),
        "measured_cp_latency_ms": {**cp.latency(), "clock": "system clock (time.time_ns vs DDS source timestamp)",
                                   "stamp_is": "the frame's capture" if args.mode == "lab" else "the cycle's start"},
        "loop": {"cycles": int(walk.sum()),
                 "longest_cycle_gap_ms": round(1000 * float(np.diff(t_cycles).max()), 1),
                 "targets": {k: res["targets"][k] for k in ("received", "dropped", "clamped", "holds", "timeout_s")},
                 "estimate_vs_asked_mm": {"mean": c["mean_mm"], "max": c["max_mm"], "lost": c.get("lost"),
                                          "rejected": c.get("rejected")},
                 "ros2_hook_ms": res["ros2"]["hook_ms"], "cycles_published": res["ros2"]["cycles_published"],
                 "publish_errors": res["ros2"]["publish_errors"]},
        "lab": lab_report or None,
        "host": {"wall_s": round(wall_s, 1), "load_before": [round(x, 2) for x in load_before],
                 "load_after": [round(x, 2) for x in load_after], "cpus": os.cpu_count()},
        "run_dir": str(tmp / "run"),
    }
    text = json.dumps(out, indent=1)
    if args.json:
        Path(args.json).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
