"""RTSP streams through OpenCV's FFmpeg backend, from a real RTSP server (GStreamer's, run by
Debian's Python: wristmark_testing/rtsp_server.py; scripts/ensure-rtsp-server.sh installs it).

Rendered marker pairs served side by side as RTP/JPEG at 30 fps: `wristmark track --source
rtsp://...` tracks them; a slow reader gets the newest frame; a stream that ends, a mount that
does not exist and a frame size the calibration does not have are one-line errors naming the URL.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.cvs.calibration.load import load_calibration, save_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.cvs.sources.frames import FrameSourceError
from wristmark.cvs.sources.layout import join_stereo
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source
from wristmark.models.config_files import CONFIG_DIR
from wristmark.sim.render.motion_video import render_motion

pytestmark = [pytest.mark.network, pytest.mark.wallclock]

ROOT = Path(__file__).resolve().parents[3]
SERVER = ROOT / "wristmark_testing" / "rtsp_server.py"
SYSTEM_PYTHON = "/usr/bin/python3"  # Debian's, with GStreamer's RTSP server (python3-gi)
FPS = 30
SCALE = 1 / 3  # 640 x 360 views: RTP/JPEG carries sizes in multiples of 8 px, at most 2040


def _write_frames(folder: Path, views: list[tuple[np.ndarray, np.ndarray]]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for k, (left, right) in enumerate(views):
        cv2.imwrite(str(folder / f"frame_{k:05d}.jpg"), join_stereo(left, right), [cv2.IMWRITE_JPEG_QUALITY, 95])
    return folder


class RtspServer:
    """The test server in a subprocess: its URL, stopped on exit."""

    def __init__(self, folder: Path, once: bool = False) -> None:
        cmd = [SYSTEM_PYTHON, str(SERVER), str(folder), str(FPS)] + (["--once"] if once else [])
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline().strip()
        if not line.startswith("rtsp://"):
            self.proc.kill()
            why = self.proc.stderr.read() if self.proc.stderr else ""
            raise RuntimeError(f"the RTSP test server did not start: {line} {why} (scripts/ensure-rtsp-server.sh)")
        self.url = line

    def __enter__(self) -> RtspServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


@pytest.fixture(scope="module")
def marker_stream(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    d = tmp_path_factory.mktemp("rtsp")
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    pairs = render_motion(cam, 6, scale=SCALE, seed=3)
    save_calibration(d / "calib.yaml", scaled_stereo_camera(cam, SCALE))
    folder = _write_frames(d / "frames", [(p.left, p.right) for p in pairs])
    with RtspServer(folder) as srv:
        yield {"url": srv.url, "calib": str(d / "calib.yaml"), "pairs": pairs, "dir": d}


def test_track_an_rtsp_stream(marker_stream: dict, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    rc = main(["track", "--source", marker_stream["url"], "--calib", marker_stream["calib"], "--frames", "12",
               "--json", "--axis-hint", "1", "0", "0"])
    out, err = capsys.readouterr()
    lines = [json.loads(s) for s in out.splitlines() if s.startswith("{")]
    assert rc == 0 and len(lines) == 12, err
    assert all(o["ok"] for o in lines), err
    tips = np.array([p.tip_left for p in marker_stream["pairs"]])
    # the stream loops over the rendered poses: each tracked tip is one of them
    worst = max(float(np.min(np.linalg.norm(tips - np.array(o["tip"]), axis=1))) for o in lines)
    assert worst < 5e-4, f"tracked tip {1e3 * worst:.3f} mm from every rendered pose"
    idx = [o["frame"] for o in lines]
    assert idx == sorted(set(idx))
    assert all(o["t_capture"] > 0 for o in lines)


def test_slow_reader_gets_the_newest_frame(tmp_path: Path, frame_ids: tuple) -> None:
    id_view, read_id = frame_ids
    views = [(id_view(k, 0, 320, 184), id_view(k, 1, 320, 184)) for k in range(90)]
    with RtspServer(_write_frames(tmp_path / "ids", views)) as srv:
        src = open_stereo_source(srv.url, SourceOptions(timeout=3.0))
        try:
            first = src.read()
            assert first is not None
            k0 = read_id(first.left) // 2
            assert read_id(first.right) == 2 * k0 + 1  # left and right of one frame, split right
            time.sleep(0.5)  # a slow consumer: 15 frames go by
            late = src.read()
            assert late is not None
            k1 = read_id(late.left) // 2
        finally:
            src.close()
    # the newest frame, not the next one in a queue (the JPEG ids survive RTP/JPEG)
    assert k1 - k0 >= 10, (k0, k1)
    assert src.dropped >= 5


def test_stream_that_ends_is_one_line_error(tmp_path: Path, frame_ids: tuple) -> None:
    id_view = frame_ids[0]
    views = [(id_view(k, 0, 320, 184), id_view(k, 1, 320, 184)) for k in range(45)]
    with RtspServer(_write_frames(tmp_path / "short", views), once=True) as srv:
        src = open_stereo_source(srv.url, SourceOptions(timeout=1.5))
        got = 0
        t0 = time.monotonic()
        try:
            with pytest.raises(FrameSourceError) as e:
                while True:
                    assert src.read() is not None
                    got += 1
        finally:
            src.close()
    assert got >= 5 and time.monotonic() - t0 < 8.0, str(e.value)
    assert srv.url in str(e.value) and "\n" not in str(e.value) and "ended" in str(e.value)


def test_unknown_mount_and_wrong_size(marker_stream: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    wrong_mount = marker_stream["url"].rsplit("/", 1)[0] + "/nothing"
    t0 = time.monotonic()
    with pytest.raises(FrameSourceError, match="cannot open the stream") as e:
        open_stereo_source(wrong_mount, SourceOptions(timeout=1.0))
    assert wrong_mount in str(e.value) and time.monotonic() - t0 < 4.0
    # the command line, in a process of its own: FFmpeg's "DESCRIBE failed: 404" is not printed
    cli = subprocess.run([sys.executable, "-m", "wristmark", "track", "--source", wrong_mount, "--calib",
                          marker_stream["calib"], "--timeout", "1", "--frames", "2"],
                         capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert cli.returncode == 2 and cli.stderr.strip().splitlines() == [
        f"wristmark track: error: {wrong_mount}: cannot open the stream (no video within 1 s, or not reachable)"]
    assert cli.stdout == ""
    small = tmp_path / "small.yaml"  # a calibration for other views than the stream's
    save_calibration(small, scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 1 / 6))
    capsys.readouterr()
    rc = main(["track", "--source", marker_stream["url"], "--calib", str(small), "--frames", "3", "--json"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and marker_stream["url"] in err
    assert "640" in err and "320" in err  # names both sizes
