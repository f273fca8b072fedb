"""Close the loop in the virtual lab, through the public API: two processes, as in a lab.

Process 1 is ``wristmark emulator --pty --camera-port 0``: the actuator box of a simulated arm
on a pseudo-terminal (protocol v1, bytes) and its stereo endoscope on an MJPEG stream (HTTP on
127.0.0.1). Process 2 is this script, the host, exactly as with hardware: it opens the box on
the pty and the camera on the stream URL (``open_hardware_session``), and runs the cube
trajectory closed loop on the tip tracked in the frames (``run_servo``); nothing of the
simulated bench is imported while the loop runs. Afterwards the lab's ``--truth-out`` CSV gives
the true tip on the same clock (``wristmark.sim.true_tip_errors``; an offline evaluation only).

Run: ``python examples/virtual_lab.py [--fast]`` (``--fast``: 2 s of the cube at 0.3 x 1080p;
else 20 s at 0.35 x). Prints one JSON line with the closed-loop errors.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from wristmark import HOME_PSI, load_loop_setup, open_hardware_session, run_servo, solve_tip_ik, warm_up
from wristmark.rig import LinkOptions, cube_trajectory, summarize_servo, workspace_centre

LAB_START_TIMEOUT_S = 120.0  # [s] for the lab's first two lines (it renders its first frame first)


def start_lab(scale: float, truth_csv: Path, realtime: bool) -> tuple[subprocess.Popen[str], str, str]:
    """``wristmark emulator --pty --camera-port 0`` as its own process: (process, pty, stream URL);
    realtime: its actuator box, camera and stream under SCHED_FIFO (as firmware and a camera are)."""
    lab = subprocess.Popen([sys.executable, "-m", "wristmark", "emulator", "--pty", "--camera-port", "0",
                            "--fps", "30", "--image-scale", str(scale), "--truth-out", str(truth_csv),
                            *(["--rt-priority", "10"] if realtime else [])],
                           stdout=subprocess.PIPE, text=True)
    assert lab.stdout is not None
    pty, url = lab.stdout.readline().strip(), lab.stdout.readline().strip()  # line 1: the pty; line 2: the URL
    if not (pty.startswith("/dev/") and url.startswith("http://")):
        lab.terminate()
        raise SystemExit(f"the virtual lab did not start (got {pty!r}, {url!r})")
    return lab, pty, url


def realtime_scheduling(priority: int, keep: bool = True) -> bool:
    """Put this thread under SCHED_FIFO at ``priority`` if the host allows it (root, CAP_SYS_NICE
    or an rtprio limit); whether it could. keep False: only try, and go back to normal scheduling."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):  # not Linux, or not allowed: normal scheduling
        return False
    if not keep:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", help="CI mode: 2 s of the cube, small images")
    parser.add_argument("--rig", default="configs/rig.yaml",
                        help="the loop's rig file (default the shipped configs/rig.yaml)")
    args = parser.parse_args()
    duration, scale = (2.0, 0.3) if args.fast else (20.0, 0.35)

    setup = load_loop_setup(rig=args.rig)  # robot, marker, calibration, controller: the shipped files
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, image_scale=scale))  # the camera's resolution
    traj = cube_trajectory(workspace_centre(setup.params)).truncated(duration)
    psi0 = solve_tip_ik(setup.params, traj.sample(0.0)[0], np.asarray(HOME_PSI, float)).psi
    warm_up()  # one OpenCV thread, the tracker's numba kernels loaded: before the lab and its watchdog start

    with tempfile.TemporaryDirectory() as tmp:
        truth_csv, log_csv = Path(tmp) / "truth.csv", Path(tmp) / "log.csv"
        # Real-time scheduling where the host allows it, for the lab and this loop alike: on a
        # loaded machine at normal priority the loop loses whole cycles and the lab's frames come
        # late, and the arm holds while the cube moves on (measured: docs/notes/virtual-lab-timing.md).
        realtime = realtime_scheduling(20, keep=False)
        lab, pty, url = start_lab(scale, truth_csv, realtime)  # the lab asks for its own priorities
        try:
            if realtime:
                realtime_scheduling(20)  # before the session starts its threads: they inherit it
            session = open_hardware_session(setup, LinkOptions(kind="serial", port=pty), url)
            outcome = run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time)
            result = summarize_servo(setup, traj, session, outcome)
        finally:
            lab.terminate()
            lab.wait(timeout=30)
        outcome.log.write_csv(log_csv)
        from wristmark.sim import true_tip_errors  # offline, after the run: the lab's ground truth

        true_mm = 1000 * true_tip_errors(log_csv, truth_csv)
    closed = result["closed_loop"]
    print(json.dumps({
        "stopped": outcome.stopped, "cycles": outcome.cycles, "duration_s": duration, "link": pty, "camera": url,
        "vision_error_mean_mm": closed["mean_mm"], "vision_error_max_mm": closed["max_mm"],
        "true_error_mean_mm": float(np.nanmean(true_mm)), "true_error_max_mm": float(np.nanmax(true_mm)),
        "latency_median_ms": result["latency"]["capture_to_command"]["median_ms"],
        "cycles_lost": closed["lost"], "cycles_rejected": closed["rejected"],
        "cycles_without_frame": closed["no_frame"], "cycles_reused": outcome.reused,
        "cycles_skipped": outcome.skipped, "realtime_priority": realtime,
    }))


if __name__ == "__main__":
    main()
