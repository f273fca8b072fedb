"""``wristmark track --source`` end to end on rendered frames written as real video files:
JSON lines with frame and t_capture, --frames, --annotate, --record then replay, errors."""

from __future__ import annotations

import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.cvs.calibration.load import load_calibration, save_calibration
from wristmark.cvs.camera import scaled_stereo_camera
from wristmark.models.config_files import CONFIG_DIR
from wristmark.sim.render.motion_video import render_motion, write_stereo_video

ROOT = Path(__file__).resolve().parents[2]
N = 8


@pytest.fixture(scope="module")
def material(tmp_path_factory: pytest.TempPathFactory) -> dict:
    d = tmp_path_factory.mktemp("track_source")
    cam = load_calibration(CONFIG_DIR / "camera.yaml")
    pairs = render_motion(cam, N, scale=0.5, seed=2)
    save_calibration(d / "calib.yaml", scaled_stereo_camera(cam, 0.5))
    return {
        "dir": d,
        "calib": str(d / "calib.yaml"),
        "pairs": pairs,
        "avi": str(write_stereo_video(d / "sbs.avi", pairs, fps=30)),
        "mkv": str(write_stereo_video(d / "tb.mkv", pairs, fps=30, layout="tb")),
    }


# The reference sleeve looks the same turned end for end and `wristmark track` never guesses: the
# arm enters these rendered scenes from the left, so the tip points along +x of the left camera.
AXIS_HINT = ["--axis-hint", "1", "0", "0"]


def _track(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[dict], str]:
    capsys.readouterr()
    rc = main(["track", *argv, *AXIS_HINT])
    out, err = capsys.readouterr()
    return rc, [json.loads(line) for line in out.splitlines() if line.startswith("{")], err


def _tip_errors(lines: list[dict], pairs: list) -> list[float]:
    return [float(np.linalg.norm(np.array(o["tip"]) - pairs[o["frame"]].tip_left)) for o in lines]


@pytest.mark.parametrize(("video", "layout"), [("avi", "sbs"), ("mkv", "tb")])
def test_video_json_lines(material: dict, capsys: pytest.CaptureFixture[str], video: str, layout: str) -> None:
    rc, lines, err = _track(["--source", material[video], "--layout", layout, "--calib", material["calib"],
                             "--json"], capsys)
    assert rc == 0 and len(lines) == N
    assert [o["frame"] for o in lines] == list(range(N))
    assert all(o["ok"] for o in lines), [o.get("reason") for o in lines]
    assert list(lines[0])[:10] == ["left", "right", "ok", "tip", "R", "t", "corners_left", "corners_right",
                                   "rms_px", "time_ms"]
    assert "frame" in lines[0] and "t_capture" in lines[0]
    assert max(_tip_errors(lines, material["pairs"])) < 0.4e-3  # [m]
    t = [o["t_capture"] for o in lines]
    assert all(b > a for a, b in zip(t, t[1:]))
    summary = err.strip().splitlines()
    assert len(summary) == 1 and f"{N} frames" in summary[0] and "latency median" in summary[0]
    assert "dropped 0" in summary[0]


def test_frames_limit_and_text_output(material: dict, capsys: pytest.CaptureFixture[str]) -> None:
    rc, lines, _ = _track(["--source", material["avi"], "--calib", material["calib"], "--frames", "3",
                           "--json"], capsys)
    assert rc == 0 and len(lines) == 3
    capsys.readouterr()
    assert main(["track", "--source", material["avi"], "--calib", material["calib"], "--frames", "2", *AXIS_HINT]) == 0
    text = capsys.readouterr().out.strip().splitlines()
    assert len(text) == 2 and "tip in {ll}" in text[0]


@pytest.mark.slow
def test_annotate_folder_and_video(material: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ann"
    rc, lines, _ = _track(["--source", material["avi"], "--calib", material["calib"], "--frames", "4",
                           "--annotate", str(out), "--json"], capsys)
    assert rc == 0
    files = sorted(out.glob("frame_*.png"))
    assert [f.name for f in files] == [f"frame_{k:06d}.png" for k in range(4)]
    img = cv2.imread(str(files[1]))
    assert img.shape == (540, 1920, 3)
    # the corners are drawn (yellow circles) where they were detected in the left view
    u, v = np.round(lines[1]["corners_left"][0]).astype(int)
    patch = img[v - 8 : v + 9, u - 8 : u + 9].reshape(-1, 3).astype(int)
    assert np.any((patch[:, 1] > 200) & (patch[:, 2] > 200) & (patch[:, 0] < 80))
    video = tmp_path / "ann.avi"
    rc, _, _ = _track(["--source", material["mkv"], "--layout", "tb", "--calib", material["calib"],
                       "--annotate", str(video), "--json"], capsys)
    cap = cv2.VideoCapture(str(video))
    assert rc == 0 and int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N and int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == 1920
    cap.release()


@pytest.mark.slow
def test_record_then_replay_identical(material: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "run.mcap"
    rc, live, _ = _track(["--source", material["avi"], "--calib", material["calib"], "--record", str(bag),
                          "--json"], capsys)
    assert rc == 0 and bag.is_file()
    rc, replay, err = _track(["--source", str(bag), "--calib", material["calib"], "--json"], capsys)
    assert rc == 0 and len(replay) == len(live) == N
    keys = ["ok", "tip", "R", "t", "corners_left", "corners_right", "rms_px", "axis_source"]
    for a, b in zip(live, replay):
        assert {k: a[k] for k in keys} == {k: b[k] for k in keys}
    assert np.allclose(np.diff([o["t_capture"] for o in replay]), np.diff([o["t_capture"] for o in live]),
                       atol=1e-6)  # the recorded capture times, mapped to this run's clock
    # the same recording again: refused, one line, the bag untouched
    size = bag.stat().st_size
    rc, _, err = _track(["--source", material["avi"], "--calib", material["calib"], "--record", str(bag)], capsys)
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "exists already" in err and bag.stat().st_size == size
    # JPEG recording replays too (lossy: close, not identical)
    jbag = tmp_path / "run_jpeg.mcap"
    rc, _, _ = _track(["--source", material["avi"], "--calib", material["calib"], "--frames", "3", "--record",
                       str(jbag), "--record-jpeg"], capsys)
    rc2, jl, _ = _track(["--source", str(jbag), "--calib", material["calib"], "--json"], capsys)
    assert rc == rc2 == 0 and len(jl) == 3 and all(o["ok"] for o in jl)
    assert jbag.stat().st_size < 0.3 * size


def test_dataset_folder_source(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds = tmp_path / "ds"
    assert main(["render", "--out", str(ds), "--pairs", "2", "--seed", "4", "--scale", "0.5"]) == 0
    rc, lines, _ = _track(["--source", str(ds), "--calib", str(ds / "calib.yaml"), "--json"], capsys)
    truth = json.loads((ds / "truth.json").read_text())
    assert rc == 0 and [o["left"] for o in lines] == [str(ds / f"pair_{k:02d}_left.png") for k in range(2)]
    assert all(np.linalg.norm(np.array(o["tip"]) - t["tip"]) < 1e-3 for o, t in zip(lines, truth))
    # the same results as the LEFT RIGHT form on the same files
    paths = [str(ds / f"pair_{k:02d}_{side}.png") for k in range(2) for side in ("left", "right")]
    rc, positional, _ = _track(["--calib", str(ds / "calib.yaml"), *paths, "--json"], capsys)
    assert rc == 0 and [{k: v for k, v in o.items() if k not in ("frame", "t_capture", "time_ms")} for o in lines] == [
        {k: v for k, v in o.items() if k != "time_ms"} for o in positional]
    assert "frame" not in positional[0]


@pytest.mark.parametrize("case", ["size", "missing", "both", "truncated", "annotate_bad", "topics"])
def test_errors_exit_2_one_line(material: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                case: str) -> None:
    full = str(CONFIG_DIR / "camera.yaml")
    cut = tmp_path / "cut.avi"
    data = Path(material["avi"]).read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    argv = {
        "size": ["--source", material["avi"], "--calib", full],
        "missing": ["--source", str(tmp_path / "none.avi"), "--calib", material["calib"]],
        "both": ["--source", material["avi"], "--calib", material["calib"], "a.png", "b.png"],
        "truncated": ["--source", str(cut), "--calib", material["calib"], "--json"],
        "annotate_bad": ["--source", material["avi"], "--calib", material["calib"],
                         "--annotate", str(tmp_path / "x.gif")],
        "topics": ["--source", material["avi"], "--calib", material["calib"], "--topics", "/a"],
    }[case]
    rc, lines, err = _track(argv, capsys)
    expected = {"size": "960x540 px but the calibration's image_size is 1920x1080", "missing": "no such file",
                "both": "not both", "truncated": "truncated", "annotate_bad": "a folder or a .mp4",
                "topics": "LEFT,RIGHT"}[case]
    assert rc == 2 and len(err.strip().splitlines()) == 1 and expected in err and "Traceback" not in err
    if case == "truncated":
        assert 0 < len(lines) < N and all(o["ok"] for o in lines)  # the frames before the cut were tracked


def test_grayscale_and_paced(material: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, colour, _ = _track(["--source", material["avi"], "--calib", material["calib"], "--json"], capsys)
    rc2, grey, err = _track(["--source", material["avi"], "--calib", material["calib"], "--grayscale", "--paced",
                             "--json"], capsys)
    assert rc == rc2 == 0 and len(grey) + int(err.split("dropped ")[1]) == N
    assert all(g["ok"] for g in grey) and all(c["ok"] for c in colour)
    assert max(_tip_errors(grey, material["pairs"])) < 0.4e-3  # the luma plane tracks as well as BGR
    ann = tmp_path / "grey"
    assert main(["track", "--source", material["avi"], "--calib", material["calib"], "--grayscale", "--frames", "1",
                 "--annotate", str(ann)]) == 0
    assert cv2.imread(str(ann / "frame_000000.png")).shape == (540, 1920, 3)  # drawn in colour on grey


@pytest.mark.network
@pytest.mark.wallclock
def test_live_stream_that_stalls_keeps_the_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                      frame_ids: tuple) -> None:
    """A live HTTP stream through the CLI: lines while it flows, then one error line when it
    stalls; the recording holds exactly the frames that were printed."""
    import threading

    from wristmark.cvs.sources.frames import frames
    from wristmark.cvs.sources.layout import join_stereo
    from wristmark.cvs.sources.mjpeg_server import MjpegServer
    from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source

    id_view = frame_ids[0]
    calib = tmp_path / "small.yaml"
    save_calibration(calib, scaled_stereo_camera(load_calibration(CONFIG_DIR / "camera.yaml"), 1 / 6))
    bag = tmp_path / "live.mcap"
    with MjpegServer() as srv:
        def publish() -> None:
            while srv.clients == 0:  # until the command has opened the stream
                time.sleep(0.01)
            for k in range(15):
                srv.publish_image(join_stereo(id_view(k, 0), id_view(k, 1)), 85)
                time.sleep(0.05)

        th = threading.Thread(target=publish, daemon=True)
        th.start()
        rc, lines, err = _track(["--source", srv.url, "--calib", str(calib), "--timeout", "1", "--record", str(bag),
                                 "--json"], capsys)
        th.join()
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "stalled" in err and srv.url in err
    assert len(lines) >= 3 and all(o["ok"] is False for o in lines)  # no marker in these frames
    idx = [o["frame"] for o in lines]
    assert idx == sorted(set(idx)) and all(o["t_capture"] > 0 for o in lines)
    replay = open_stereo_source(str(bag), SourceOptions())
    assert len(list(frames(replay))) == len(lines)
    replay.close()
