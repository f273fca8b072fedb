"""Video files through every SPEC form: written with cv2.VideoWriter (MJPG .avi, lossless FFV1
.mkv), read back by cvs.sources.open_source; split, size check, truncation, pacing."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError, frames
from wristmark.cvs.sources.layout import join_stereo, split_stereo
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source, source_length

N = 8
CODECS = {"mjpg": ("MJPG", ".avi"), "ffv1": ("FFV1", ".mkv")}


def _write(path: Path, images: list[NDArray[np.uint8]], fourcc: str, fps: float = 30.0) -> Path:
    h, w = images[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*fourcc), fps, (w, h))
    assert vw.isOpened(), f"{fourcc} writer"
    vw.set(cv2.VIDEOWRITER_PROP_QUALITY, 95)
    for img in images:
        vw.write(img)
    vw.release()
    return path


def _views(frame_ids: tuple[Callable[..., NDArray[np.uint8]], object], n: int = N) -> list[tuple]:
    id_view = frame_ids[0]
    return [(id_view(k, 0), id_view(k, 1)) for k in range(n)]


def _spec(tmp_path: Path, form: str, codec: str, views: list[tuple], fps: float = 30.0) -> tuple[str, str]:
    fourcc, ext = CODECS[codec]
    if form == "two":
        lp = _write(tmp_path / f"left{ext}", [v[0] for v in views], fourcc, fps)
        rp = _write(tmp_path / f"right{ext}", [v[1] for v in views], fourcc, fps)
        return f"{lp},{rp}", "sbs"
    layout = form
    path = _write(tmp_path / f"{form}{ext}", [join_stereo(left, right, layout) for left, right in views], fourcc, fps)
    return str(path), layout


@pytest.mark.parametrize("codec", list(CODECS))
@pytest.mark.parametrize("form", ["sbs", "tb", "two"])
def test_round_trip_every_form(tmp_path: Path, frame_ids: tuple, codec: str, form: str) -> None:
    views = _views(frame_ids)
    read_id = frame_ids[1]
    spec, layout = _spec(tmp_path, form, codec, views)
    src = open_stereo_source(spec, SourceOptions(layout=layout, image_size=(320, 180)))
    try:
        assert source_length(src) == N
        got = list(frames(src))
        assert src.dropped == 0
    finally:
        src.close()
    assert [f.index for f in got] == list(range(N))
    for k, f in enumerate(got):
        assert f.left.shape == f.right.shape == (180, 320, 3) and f.left.dtype == np.uint8
        # split: the left view carries id 2k, the right one 2k + 1
        assert (read_id(f.left), read_id(f.right)) == (2 * k, 2 * k + 1)
        err = np.abs(f.left.astype(int) - views[k][0]).mean()
        assert err == 0 if codec == "ffv1" else err < 2.0  # FFV1 is lossless
    t = [f.t_capture for f in got]
    assert all(b >= a for a, b in zip(t, t[1:])) and abs(t[-1] - time.monotonic()) < 5


def test_frames_limit(tmp_path: Path, frame_ids: tuple) -> None:
    spec, _ = _spec(tmp_path, "sbs", "mjpg", _views(frame_ids))
    src = open_stereo_source(spec)
    assert len(list(frames(src, limit=3))) == 3
    src.close()


@pytest.mark.parametrize("form", ["sbs", "two"])
def test_size_differs_from_calibration(tmp_path: Path, frame_ids: tuple, form: str) -> None:
    spec, layout = _spec(tmp_path, form, "mjpg", _views(frame_ids, 2))
    src = open_stereo_source(spec, SourceOptions(layout=layout, image_size=(1920, 1080)))
    with pytest.raises(FrameSourceError) as e:
        src.read()
    src.close()
    msg = str(e.value)
    assert "320x180" in msg and "1920x1080" in msg and "\n" not in msg


@pytest.mark.parametrize("codec", list(CODECS))
def test_truncated_file(tmp_path: Path, frame_ids: tuple, codec: str) -> None:
    spec, _ = _spec(tmp_path, "sbs", codec, _views(frame_ids, 30))
    data = Path(spec).read_bytes()
    cut = tmp_path / f"cut{Path(spec).suffix}"
    cut.write_bytes(data[: int(0.6 * len(data))])
    src = open_stereo_source(str(cut))
    n = 0
    with pytest.raises(FrameSourceError) as e:
        for _ in frames(src):
            n += 1
    src.close()
    assert 0 < n < 30
    assert str(cut) in str(e.value) and "truncated" in str(e.value) and "\n" not in str(e.value)


def test_unreadable_and_missing(tmp_path: Path) -> None:
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"RIFF not a video at all" * 10)
    with pytest.raises(FrameSourceError, match="cannot open the video"):
        open_stereo_source(str(junk))
    with pytest.raises(FrameSourceError, match="no such file"):
        open_stereo_source(str(tmp_path / "nope.avi"))
    with pytest.raises(FrameSourceError, match="not found"):
        open_stereo_source(f"{tmp_path / 'nope.avi'},{junk}")


def test_split_needs_equal_halves() -> None:
    img = np.arange(6 * 8 * 3, dtype=np.uint8).reshape(6, 8, 3)
    left, right = split_stereo(img, "sbs", "x")
    assert np.array_equal(join_stereo(left, right, "sbs"), img) and left.shape == (6, 4, 3)
    top, bottom = split_stereo(img, "tb", "x")
    assert np.array_equal(join_stereo(top, bottom, "tb"), img) and top.shape == (3, 8, 3)
    with pytest.raises(FrameSourceError, match="even width"):
        split_stereo(img[:, :7], "sbs", "cam")
    with pytest.raises(FrameSourceError, match="even height"):
        split_stereo(img[:5], "tb", "cam")
    with pytest.raises(FrameSourceError, match="valid: sbs, tb"):
        split_stereo(img, "lr", "cam")


@pytest.mark.wallclock
def test_paced_plays_in_real_time_and_drops_for_a_slow_consumer(tmp_path: Path, frame_ids: tuple) -> None:
    read_id = frame_ids[1]
    fps = 50.0
    spec, _ = _spec(tmp_path, "sbs", "mjpg", _views(frame_ids, 40), fps=fps)
    # a fast consumer gets every frame, each at its due time
    src = open_stereo_source(spec, SourceOptions(paced=True))
    t0 = time.monotonic()
    got = list(frames(src))
    wall = time.monotonic() - t0
    src.close()
    assert len(got) + src.dropped == 40 and src.dropped <= 2
    assert 0.7 * 39 / fps < wall < 39 / fps + 1.0
    assert all(read_id(f.left) == 2 * f.index for f in got)
    assert np.allclose(np.diff([f.t_capture for f in got if f.index < 40]).min(), 1 / fps, atol=1e-6)
    # a consumer taking 3 periods per frame gets the newest frame each time; the rest is dropped
    src = open_stereo_source(spec, SourceOptions(paced=True))
    slow = []
    while (f := src.read()) is not None:
        slow.append(f)
        assert time.monotonic() - f.t_capture < 1.5 / fps + 0.05  # never older than ~one period
        time.sleep(3 / fps)
    src.close()
    assert 8 <= len(slow) <= 16 and len(slow) + src.dropped == 40
    assert all(read_id(f.left) == 2 * f.index for f in slow)
