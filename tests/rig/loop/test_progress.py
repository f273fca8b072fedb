"""Progress bars count what the summaries count, and the load sweep says which force runs
(issue 17, item 5)."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

from wristmark.cli import main as cli

BAR = re.compile(r"^(?P<desc>[^:|]+(?:: [^:|]+)*): +\d+%\|[^|]*\| (?P<n>\d+)/(?P<total>\d+)")


def renders(stderr: str) -> list[tuple[str, int, int]]:
    """(description, count, total) of every progress bar drawn on stderr."""
    out = []
    for piece in re.split(r"[\r\n]", stderr):
        m = BAR.match(piece.strip().replace("\x1b[A", ""))
        if m:
            out.append((m["desc"], int(m["n"]), int(m["total"])))
    return out


def test_load_bars_name_the_force_and_end_on_the_summary_count(tmp_path: Path) -> None:
    out_dir = tmp_path / "load"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        assert cli.main(["experiment", "load", "--forces", "0", "0.1", "--sensor", "truth-noise", "--duration", "0.3",
                         "--out", str(out_dir)]) == 0
    bars = renders(err.getvalue())
    descs = {d for d, _, _ in bars}
    assert "load: force 1 of 2 (0.00 N)" in descs and "load: force 2 of 2 (0.10 N)" in descs, descs
    for force in ("0.00", "0.10"):
        res = json.loads((out_dir / f"force_{force}N" / "result.json").read_text())
        cfg = json.loads((out_dir / f"force_{force}N" / "config.json").read_text())
        n_settle = round(cfg["rig"]["settle_time"] / cfg["rig"]["control_dt"])
        for phase in ("open_loop", "closed_loop"):
            cycles = res[phase]["cycles"]
            totals = {t for d, _, t in bars if d == phase}
            assert totals == {cycles}, (phase, totals, cycles)  # the summary's count, settling apart
            assert (phase, cycles, cycles) in bars  # and the bar ends on it
            assert {t for d, _, t in bars if d == f"{phase}: settling"} == {n_settle}
    table = (out_dir / "force_0.00N" / "results.md").read_text()
    assert f"{res['closed_loop']['cycles']} closed-loop cycles" in table
