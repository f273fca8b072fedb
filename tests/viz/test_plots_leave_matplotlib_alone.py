"""The run folder's figures (viz.plots, viz.sweep_plots) and the marker's PDF page
(cvs.marker.print_sheet) draw on their own figures: the process's matplotlib backend and pyplot's
figures are left as the user set them (they used to switch the backend to Agg on import)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_SCRIPT = textwrap.dedent("""
    import json, sys
    from pathlib import Path
    import matplotlib
    matplotlib.use("svg")  # the user's choice
    out = Path(sys.argv[1])
    from wristmark.cvs.marker.print_sheet import write_pdf
    from wristmark.models.marker import MarkerModel
    from wristmark.viz.plots import plot_accuracy
    from wristmark.viz.sweep_plots import plot_metrics_vs_key
    rows = [{"index": 0, "ok": True, "tracker": [0.0, 0.0, 0.1], "estimate": [0.0, 0.0, 0.1001], "error_mm": 0.1}]
    written = [plot_accuracy(rows, out)]
    sweep = [{"status": "ok", "dt": "0.06", "closed_mean_mm": "0.5"},
             {"status": "ok", "dt": "0.03", "closed_mean_mm": "0.4"}]
    written.append(plot_metrics_vs_key(sweep, "dt", [("closed_mean_mm", "mean [mm]")], out / "sweep.png"))
    write_pdf(MarkerModel(), out / "marker.pdf", "test")
    written.append(out / "marker.pdf")
    print(json.dumps({"backend": matplotlib.get_backend(), "pyplot": "matplotlib.pyplot" in sys.modules,
                      "sizes": [Path(p).stat().st_size for p in written]}))
""")


def test_figures_leave_the_backend_and_pyplot_alone(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-c", _SCRIPT, str(tmp_path)], capture_output=True, text=True, timeout=300,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["backend"] == "svg" and not out["pyplot"]
    assert all(n > 1000 for n in out["sizes"]), out  # the PNGs and the PDF were written
    assert (tmp_path / "marker.pdf").read_bytes().startswith(b"%PDF")
    assert (tmp_path / "sweep.png").read_bytes().startswith(b"\x89PNG")
