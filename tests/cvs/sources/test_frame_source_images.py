"""Dataset folders and LEFT RIGHT lists through cvs.sources.open_source; V4L2 specs without hardware."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import pytest

from wristmark.cvs.sources.frames import FrameSourceError, StereoSource, frames
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source, source_length
from wristmark.models.errors import InputError


def _folder(tmp_path: Path, frame_ids: tuple, n: int, ext: str = ".png") -> Path:
    id_view = frame_ids[0]
    root = tmp_path / "ds"
    root.mkdir()
    for k in range(n):
        cv2.imwrite(str(root / f"pair_{k:02d}_left{ext}"), id_view(k, 0))
        cv2.imwrite(str(root / f"pair_{k:02d}_right{ext}"), id_view(k, 1))
    (root / "calib.yaml").write_text("not an image\n")
    return root


def test_folder_in_nn_order(tmp_path: Path, frame_ids: tuple) -> None:
    root = _folder(tmp_path, frame_ids, 12)  # pair_10 sorts after pair_09
    src = open_stereo_source(str(root), SourceOptions(image_size=(320, 180)))
    assert isinstance(src, StereoSource) and source_length(src) == 12
    t0 = time.monotonic()
    got = list(frames(src))
    assert [frame_ids[1](f.left) for f in got] == [2 * k for k in range(12)]
    assert [frame_ids[1](f.right) for f in got] == [2 * k + 1 for k in range(12)]
    assert [f.index for f in got] == list(range(12)) and got[3].name_left.endswith("pair_03_left.png")
    assert t0 <= got[0].t_capture <= got[-1].t_capture <= time.monotonic()
    assert src.dropped == 0


def test_pair_list_and_its_errors(tmp_path: Path, frame_ids: tuple) -> None:
    root = _folder(tmp_path, frame_ids, 2, ".jpg")
    paths = [str(root / "pair_01_left.jpg"), str(root / "pair_01_right.jpg"), str(root / "pair_00_left.jpg"),
             str(root / "pair_00_right.jpg")]
    got = list(frames(open_stereo_source(paths)))
    assert [frame_ids[1](f.left) for f in got] == [2, 0]
    with pytest.raises(InputError, match="pairs"):
        open_stereo_source(paths[:3])
    with pytest.raises(InputError, match="not found"):
        open_stereo_source(paths[:1] + [str(root / "nope.png")])


def test_folder_errors(tmp_path: Path, frame_ids: tuple) -> None:
    root = _folder(tmp_path, frame_ids, 2)
    (root / "pair_01_right.png").unlink()
    with pytest.raises(FrameSourceError, match="pair 01 has no right image"):
        open_stereo_source(str(root))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FrameSourceError, match="no stereo pairs"):
        open_stereo_source(str(empty))
    (tmp_path / "x").mkdir()
    src = open_stereo_source(str(_folder(tmp_path / "x", frame_ids, 1)), SourceOptions(image_size=(640, 480)))
    with pytest.raises(FrameSourceError, match="320x180 px but the calibration's image_size is 640x480"):
        src.read()


@pytest.mark.parametrize("spec", ["/dev/video97", "device:97"])
def test_missing_camera_is_one_line(spec: str) -> None:
    with pytest.raises(FrameSourceError) as e:
        open_stereo_source(spec, SourceOptions(size=(640, 240), fps=30))
    msg = str(e.value)
    assert spec in msg and "/dev/video97" in msg and "\n" not in msg


def test_bad_options() -> None:
    for bad, word in [(SourceOptions(layout="lr"), "layout"), (SourceOptions(timeout=0), "timeout"),
                      (SourceOptions(fps=-1), "fps"), (SourceOptions(topics=("a", "/b")), "topics")]:
        with pytest.raises(FrameSourceError, match=word):
            open_stereo_source("device:0", bad)
