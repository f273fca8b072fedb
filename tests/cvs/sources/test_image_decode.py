"""A truncated image is one line of ours on stderr, not OpenCV's codec warning first (issue 17, item 5)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from wristmark.cvs.sources.image_decode import decode_image

ROOT = Path(__file__).resolve().parents[3]
CALIB = ROOT / "docs" / "example" / "calib.yaml"


def _images(tmp_path: Path) -> tuple[Path, Path]:
    img = (np.random.default_rng(0).integers(0, 255, (270, 480, 3))).astype(np.uint8)
    ok, png = cv2.imencode(".png", img)
    assert ok
    full, cut = tmp_path / "full.png", tmp_path / "cut.png"
    full.write_bytes(png.tobytes())
    cut.write_bytes(png.tobytes()[: len(png) // 2])
    return full, cut


def test_truncated_png_is_one_line_of_ours(tmp_path: Path) -> None:
    full, cut = _images(tmp_path)
    p = subprocess.run([sys.executable, "-m", "wristmark", "track", "--calib", str(CALIB), str(cut), str(full)],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert lines[0].startswith("wristmark track: error:") and "cut.png" in lines[0]
    assert "PNG input buffer is incomplete" in lines[0]  # the codec's words, inside our line


def test_decode_image_returns_the_codec_message_and_leaves_stderr_working(tmp_path: Path, capfd) -> None:
    full, cut = _images(tmp_path)
    img, said = decode_image(np.fromfile(str(cut), np.uint8))
    assert img is None and "libpng" in said
    img, said = decode_image(np.fromfile(str(full), np.uint8))
    assert img is not None and img.shape == (270, 480, 3) and said == ""
    print("after", file=sys.stderr, flush=True)
    err = capfd.readouterr().err
    assert err == "after\n"  # nothing of the codec's leaked, and stderr was restored
