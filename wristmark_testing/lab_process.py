"""Tests' helpers for the virtual lab (`wristmark emulator --pty --camera-port 0`) run as its own
process: read the lines it prints first (the pty path, the camera URL), and stop it."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time


def read_lines(proc: subprocess.Popen[bytes], n: int, timeout: float) -> list[str]:
    """The first ``n`` lines of a process's stdout (unbuffered reads), within ``timeout`` s."""
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    got = b""
    deadline = time.monotonic() + timeout
    while got.count(b"\n") < n:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            raise AssertionError(f"only {got!r} on stdout within {timeout} s")
        chunk = os.read(fd, 4096)
        if not chunk:
            raise AssertionError(f"stdout closed after {got!r}")
        got += chunk
    return [ln.strip() for ln in got.decode().splitlines()[:n]]


def stop(proc: subprocess.Popen[bytes], timeout: float = 20) -> tuple[int, str]:
    """SIGTERM, then (after ``timeout`` s) SIGKILL: the exit status and stderr."""
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return int(proc.returncode), err.decode(errors="replace")


def scene_lab_command(scene: str, scale: float, fps: float, truth: str, calib: str, *extra: str) -> list[str]:
    """The command line of a scene's virtual lab (`wristmark emulator --scene SCENE --pty
    --camera-port 0`) at ``scale`` and ``fps``, its truth CSV and calibration written to ``truth``
    and ``calib``; its stdout: one `NAME PTY` line per arm, then the stream URL."""
    return [sys.executable, "-m", "wristmark", "emulator", "--scene", scene, "--pty", "--camera-port", "0",
            "--fps", str(fps), "--image-scale", str(scale), "--truth-out", truth, "--calib-out", calib, *extra]
