"""``wristmark experiment cube --scene S --view``: the live view of every arm while the loops run
(short: 0.3 s of cube, the default controller without its play probe)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from wristmark.cli.main import main
from wristmark.rig.recording.run_log import read_log_csv

pytestmark = [pytest.mark.network, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]


def test_scene_experiment_with_the_live_view_sends_every_arms_cycles(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import wristmark.viz.live as live

    views: list[Any] = []
    start = live.start_scene_live_view

    def keep(*args: Any, **kwargs: Any) -> Any:
        views.append(start(*args, **kwargs))
        return views[-1]

    monkeypatch.setattr(live, "start_scene_live_view", keep)
    monkeypatch.chdir(ROOT)
    run = tmp_path / "run"
    code = main(["experiment", "cube", "--scene", "configs/scenes/two_arms.yaml", "--controller-config",
                 "configs/controller_encoders.yaml", "--duration", "0.3", "--view", "--no-progress", "--out", str(run)])
    err = capsys.readouterr().err
    assert code == 0, err
    assert len(views) == 1
    view = views[0]
    assert view.url.startswith("http://127.0.0.1:") and f"live 3D view: open {view.url}" in err
    assert f"replay in the browser: wristmark view {run}" in err
    rows = sum(len(read_log_csv(run / f"log_{n}.csv")["t"]) for n in ("a", "b"))
    st = view.stats
    assert st.error == "" and st.sent == rows and st.received == rows and st.frames >= 1  # every arm's every cycle
    assert view.names == ["a", "b"]
