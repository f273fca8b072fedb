"""``wristmark marker print``: the unrolled sleeve at 1:1. The SVG, rasterised here (its rectangles,
pure Python) and wrapped back onto the cylinder, shows the colours the renderer's sleeve kernel
(sim.render.raycast.sleeve_dark) gives at sampled (angle, z) points; the PDF has the same physical size."""

from __future__ import annotations

import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from wristmark.cli.main import main
from wristmark.cvs.marker.print_sheet import page_size
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.arm import Sleeve, pack_sleeves
from wristmark.sim.render.raycast import sleeve_dark

ROOT = Path(__file__).resolve().parents[3]
CODED_FILE = CONFIG_DIR / "marker_coded.yaml"
PX_PER_MM = 20.0


def _rasterise_svg(path: Path) -> tuple[np.ndarray, float, float]:
    """Black (True) / white raster of the SVG's filled rectangles at PX_PER_MM, and its size [mm]."""
    text = path.read_text()
    w = float(re.search(r'<svg[^>]* width="([0-9.]+)mm"', text).group(1))  # type: ignore[union-attr]
    h = float(re.search(r'<svg[^>]* height="([0-9.]+)mm"', text).group(1))  # type: ignore[union-attr]
    img = np.zeros((int(round(h * PX_PER_MM)), int(round(w * PX_PER_MM))), bool)
    for m in re.finditer(r'<rect [^>]*x="([-0-9.]+)" y="([-0-9.]+)" width="([0-9.]+)" height="([0-9.]+)" '
                         r'fill="(\w+)"', text):
        x, y, rw, rh = (float(v) * PX_PER_MM for v in m.groups()[:4])
        img[int(round(y)):int(round(y + rh)), int(round(x)):int(round(x + rw))] = m.group(5) == "black"
    return img, w, h


@pytest.mark.parametrize("marker_file", [CODED_FILE, CONFIG_DIR / "marker.yaml"])
def test_printed_svg_wrapped_back_matches_the_renderers_sleeve(marker_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "sleeve.svg"
    assert main(["marker", "print", "--marker", str(marker_file), "--out", str(out)]) == 0
    marker = MarkerModel.load(marker_file)
    img, w, h = _rasterise_svg(out)
    W, H = page_size(marker)
    assert (w, h) == pytest.approx((1e3 * W, 1e3 * H), abs=1e-3)
    assert marker_file.name in out.read_text() and 'class="scalebar"' in out.read_text()
    bar = re.search(r'class="scalebar" [^>]*width="([0-9.]+)"', out.read_text())
    assert bar is not None and float(bar.group(1)) == pytest.approx(10.0)
    rows, pat = pack_sleeves([Sleeve(np.eye(4), marker)])
    z_lo, z_hi = marker.z_extent
    rng = np.random.default_rng(0)
    eps = 0.05e-3  # points this close to a colour boundary (in angle or z) are not compared
    compared = 0
    for a, z in zip(rng.uniform(0, 2 * math.pi, 4000), rng.uniform(z_lo, z_hi, 4000)):
        da = eps / marker.radius
        near = {sleeve_dark(rows, 0, pat, (a + sa) % (2 * math.pi), z + sz)
                for sa in (-da, 0, da) for sz in (-eps, 0, eps)}
        if len(near) > 1:
            continue
        x_mm = 5.0 + 1e3 * marker.radius * a  # the page margin, then the unrolled arc
        y_mm = 5.0 + 1e3 * (z_hi - z)
        assert img[int(y_mm * PX_PER_MM), int(x_mm * PX_PER_MM)] == near.pop(), (a, z)
        compared += 1
    assert compared > 3000


@pytest.mark.slow
def test_pdf_has_the_physical_size_and_overwrite_needs_force(tmp_path: Path) -> None:
    out = tmp_path / "sleeve.pdf"
    exe = [str(ROOT / ".venv" / "bin" / "wristmark")]
    args = [*exe, "marker", "print", "--marker", str(CODED_FILE), "--out", str(out)]
    assert subprocess.run(args, capture_output=True, text=True).returncode == 0
    box = re.search(rb"/MediaBox \[ ?0 0 ([0-9.]+) ([0-9.]+) ?\]", out.read_bytes())
    assert box is not None
    W, H = page_size(MarkerModel.load(CODED_FILE))
    assert float(box.group(1)) == pytest.approx(W / 0.0254 * 72, abs=0.01)
    assert float(box.group(2)) == pytest.approx(H / 0.0254 * 72, abs=0.01)
    again = subprocess.run(args, capture_output=True, text=True)
    assert again.returncode == 2 and "--force" in again.stderr and len(again.stderr.strip().splitlines()) == 1
    assert subprocess.run([*args, "--force"], capture_output=True, text=True).returncode == 0
    bad = subprocess.run([*exe, "marker", "print", "--marker", str(CODED_FILE), "--out", str(tmp_path / "x.png")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and ".svg or .pdf" in bad.stderr
