"""`wristmark servo --target stdin | tcp:127.0.0.1:PORT`: a device script steers the simulated
bench (real subprocess, real pipe, real socket on loopback). The tip follows the newest target,
bounded in speed, clamped to the workspace, held while the stream is silent; malformed lines
are counted and dropped with a warning, and the result JSON reports the counts."""

from __future__ import annotations

import json
import math
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

import numpy as np
import pytest

from wristmark.rig.recording.run_log import read_log_csv
from wristmark.rig.targets.trajectories import workspace_centre
from wristmark.sim.setup import load_setup

pytestmark = [pytest.mark.network, pytest.mark.slow, pytest.mark.wallclock]

ROOT = Path(__file__).resolve().parents[2]
CENTRE = workspace_centre(load_setup().params)
RADIUS = 0.005  # [m] of the circle the device draws (x_w, z_w)
PERIOD = 5.0  # [s]: 6.3 mm/s, within the speed bound
MAX_SPEED = 0.015  # [m/s]
BAD_LINES = [b"garbage\n", b"[1, 2, 3]\n", b'{"t": 0, "p": [0, NaN, 0]}\n',
             b'{"t": 0, "p": [0.08, 0, 0.15], "q": [0, 0, 0, 0]}\n']


def no_probe_controller(tmp: Path) -> Path:
    """The default controller file without the play probe (the walk starts at once: fast)."""
    text = (ROOT / "wristmark" / "configs" / "controller.yaml").read_text()
    out = tmp / "controller.yaml"
    out.write_text(re.sub(r"play_probe: true", "play_probe: false", text))
    return out


def servo(tmp: Path, target: str, duration: float) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-m", "wristmark", "servo", "--target", target, "--sensor", "truth-noise",
         "--duration", str(duration), "--settle", "0.3", "--controller-config", str(no_probe_controller(tmp)),
         "--max-speed", str(MAX_SPEED), "--no-progress", "--out", str(tmp / "run"), "--json", str(tmp / "res.json")],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)


def circle(t: float) -> list[float]:
    a = 2 * math.pi * t / PERIOD
    return (CENTRE + RADIUS * np.array([math.cos(a) - 1, 0.0, math.sin(a)])).tolist()


def feed(out: IO[bytes], stop: threading.Event, gaps: bool) -> list[tuple[float, list[float]]]:
    """Write the bad lines, one target far outside the workspace, then the circle at 25 Hz
    (with ``gaps``: silent 0.6 s of every 2 s) until ``stop``; returns (monotonic time, p) sent."""
    sent: list[tuple[float, list[float]]] = []
    try:
        for line in BAD_LINES:
            out.write(line)
        out.write(json.dumps({"t": 0.0, "p": [1.0, 0.0, 0.0]}).encode() + b"\n")
        out.flush()
        t0 = time.monotonic()
        while not stop.is_set():
            t = time.monotonic() - t0
            if not (gaps and t % 2.0 > 1.4):
                p = circle(t)
                out.write(json.dumps({"t": t, "p": p}).encode() + b"\n")
                out.flush()
                sent.append((time.monotonic(), p))
            time.sleep(0.04)
    except (BrokenPipeError, OSError):
        pass
    return sent


def check_run(tmp: Path, proc: subprocess.Popen[bytes], sent: list[tuple[float, list[float]]], gaps: bool) -> None:
    stdout, stderr = proc.communicate(timeout=10)
    assert proc.returncode == 0, stderr.decode()
    res = json.loads((tmp / "res.json").read_text())
    tg = res["targets"]
    assert tg["dropped"] == len(BAD_LINES) and tg["clamped"] >= 1 and tg["received"] > 50, tg
    warnings = [ln for ln in stderr.decode().splitlines() if "dropped" in ln]
    assert len(warnings) == len(BAD_LINES), stderr.decode()
    assert res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    log = read_log_csv(tmp / "run" / "log.csv")
    walk = np.array([ph == "servo" for ph in log["phase"]])
    p_des = np.stack([log[f"p_des_{a}"] for a in "xyz"], axis=1)[walk]
    p_true = np.stack([log[f"p_true_{a}"] for a in "xyz"], axis=1)[walk]
    t_wall = np.asarray(log["t_wall"])[walk]
    assert walk.sum() > 40
    # the asked tip stays in the workspace and never outruns the speed bound
    assert np.all(np.abs(p_des - CENTRE) <= [0.025 + 1e-9, 0.015 + 1e-9, 0.025 + 1e-9])
    dt = res["control_dt_s"]
    assert np.linalg.norm(np.diff(p_des, axis=0), axis=1).max() <= MAX_SPEED * dt * 1.001
    # it follows the device: the asked tip near the newest sent target, the true tip near the asked one
    times = np.array([s[0] for s in sent])
    pts = np.array([s[1] for s in sent])
    lag = []
    for tw, p in zip(t_wall, p_des):
        i = np.searchsorted(times, tw) - 1
        if i >= 0 and tw - times[i] < 0.1:
            lag.append(np.linalg.norm(p - pts[i]))
    assert len(lag) > 20 and np.median(lag) < 1.5e-3, np.median(lag)
    assert np.median(np.linalg.norm(p_true - p_des, axis=1)) < 0.6e-3
    assert np.ptp(p_true[:, 0]) > 0.004  # the true tip really moved along the circle
    if gaps:
        assert tg["holds"] >= 1
        silent = np.array([tw - times[max(np.searchsorted(times, tw) - 1, 0)] > 0.35 for tw in t_wall])
        still = np.linalg.norm(np.diff(p_des, axis=0), axis=1)[silent[1:] & silent[:-1]]
        assert still.size > 0 and still.max() == 0.0  # silent: the arm held where its target stood


def test_a_script_on_stdin_steers_the_simulated_arm(tmp_path: Path) -> None:
    proc = servo(tmp_path, "stdin", 5.0)
    stop = threading.Event()
    result: list[list[tuple[float, list[float]]]] = []
    assert proc.stdin is not None
    th = threading.Thread(target=lambda: result.append(feed(proc.stdin, stop, gaps=False)))  # type: ignore[arg-type]
    th.start()
    try:
        proc.wait(timeout=240)
    finally:
        stop.set()
        th.join()
        proc.kill()
    check_run(tmp_path, proc, result[0], gaps=False)


def test_a_device_on_a_loopback_socket_steers_and_silence_holds(tmp_path: Path) -> None:
    proc = servo(tmp_path, "tcp:127.0.0.1:0", 6.0)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline().decode()  # "wristmark servo: taking targets on tcp:127.0.0.1:PORT"
        port = int(line.strip().rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port), timeout=30) as conn, conn.makefile("wb", buffering=0) as out:
            stop = threading.Event()
            result: list[list[tuple[float, list[float]]]] = []
            th = threading.Thread(target=lambda: result.append(feed(out, stop, gaps=True)))
            th.start()
            try:
                proc.wait(timeout=240)
            finally:
                stop.set()
                th.join()
    finally:
        proc.kill()
    check_run(tmp_path, proc, result[0], gaps=True)
