"""The live view's drawing of several arms (viz.live_worker.ArmsDrawer) without a server: records
that name their arm (record_wire.encode_arm) move that arm's tips and trails, the status block
has every arm's errors."""

from __future__ import annotations

import numpy as np
import pytest

from tests.viz.test_arms_scene import TWO_ARMS, node, transform_of
from wristmark.models.kinematics import forward_kinematics
from wristmark.rig.recording.run_log import CycleRecord
from wristmark.sim.scene_setup import load_scene_setup
from wristmark.viz import record_wire
from wristmark.viz.arms_scene import ArmsScene, ArmsSceneConfig, arm_root
from wristmark.viz.live_worker import ArmsDrawer, arms_status_lines
from wristmark.viz.snapshot import RecordingWindow, recording_visualizer


class StatusWindow(RecordingWindow):
    """A recording window that also keeps the status block sent to it."""

    status: dict[str, str] = {}

    def send_status(self, status: dict[str, str]) -> None:
        self.status = dict(status)


def records(params: object, n: int, shift: float, phase: str = "closed_loop") -> list[CycleRecord]:
    """``n`` cycles of an arm near home; the estimate ``shift`` [m] off the true tip along x."""
    from wristmark.models.arm_spec import home_psi

    out = []
    for k in range(n):
        psi = home_psi(params) + 0.002 * k  # type: ignore[arg-type]
        tip = forward_kinematics(params, psi).tip  # type: ignore[arg-type]
        out.append(CycleRecord(t=2.0 + 0.06 * k, phase=phase, p_des=tip + [0, 0, 0.001], p_cmd=tip,
                               p_est=tip + [shift, 0, 0], p_true=tip, p_trk=tip, psi_cmd=psi, psi_true=psi,
                               meas_ok=True, rejected=False, vision_ms=5.0, ctrl_us=20.0))
    return out


def test_arm_records_round_trip_with_their_arm() -> None:
    rec = records(load_scene_setup(TWO_ARMS).arms["a"].params, 1, 0.0)[0]
    data = record_wire.encode_arm(3, rec)
    assert len(data) == record_wire.ARM_RECORD_SIZE == record_wire.RECORD_SIZE + 8 <= 512
    index, back = record_wire.decode_arm(data)
    assert index == 3 and back.t == rec.t
    np.testing.assert_array_equal(back.p_est, rec.p_est)


def test_drawer_moves_each_arm_from_its_own_records() -> None:
    setup = load_scene_setup(TWO_ARMS)
    window = StatusWindow()
    import meshcat

    vis = meshcat.Visualizer(window=window)
    scene = ArmsScene(vis, ArmsSceneConfig.from_scene_setup(setup))
    drawer = ArmsDrawer(scene, window, period=0.0, trail_seconds=10.0)  # type: ignore[arg-type]
    recs = {"a": records(setup.arms["a"].params, 5, 0.001), "b": records(setup.arms["b"].params, 5, 0.002)}
    for k in range(5):
        for i, name in enumerate(("a", "b")):
            drawer.take(record_wire.encode_arm(i, recs[name][k]))
    drawer.take(record_wire.encode_arm(7, recs["a"][0]))  # an arm the scene does not have: ignored
    assert drawer.records == 10 and drawer.pending
    drawer.draw()
    assert drawer.frames == 1 and not drawer.pending
    for name in ("a", "b"):
        last = recs[name][-1]
        for kind, p in (("estimated", last.p_est), ("desired", last.p_des), ("true", last.p_true)):
            np.testing.assert_allclose(transform_of(window, f"{arm_root(name)}/tips/{kind}")[:3, 3], p)
        assert node(window, f"{arm_root(name)}/trails/estimated").object is not None  # type: ignore[attr-defined]
    assert window.status["a: |estimate - true|"].strip() == "1.00 mm"
    assert window.status["b: |estimate - true|"].strip() == "2.00 mm"
    assert window.status["phase"] == "closed_loop"


def test_status_lines_name_every_arm() -> None:
    setup = load_scene_setup(TWO_ARMS)
    recs = [records(setup.arms[n].params, 1, 0.0, "open_loop")[0] for n in ("a", "b")]
    wire = {n: record_wire.decode(record_wire.encode(r)) for n, r in zip(("x", "y"), recs)}
    wire["x"].p_est = None
    lines = arms_status_lines(wire)
    assert lines["x: |true - desired|"].strip() == "1.00 mm" and "x: |estimate - true|" not in lines
    assert lines["y: |estimate - true|"].strip() == "0.00 mm"


@pytest.mark.network
def test_scene_live_view_draws_both_arms() -> None:
    from wristmark.viz.live import start_scene_live_view

    setup = load_scene_setup(TWO_ARMS)
    view = start_scene_live_view(setup, stream=None)
    assert view.url.startswith("http://127.0.0.1:")
    recs = {n: records(setup.arms[n].params, 20, 0.0) for n in ("a", "b")}
    try:
        for k in range(20):
            for n in ("a", "b"):
                view.on_arm_cycle(n, recs[n][k])
            view.on_arm_cycle("nobody", recs["a"][k])  # not an arm of the scene: not sent
    finally:
        view.close()
    st = view.stats
    assert st.error == "" and st.sent == 40 and st.received == 40 and st.frames >= 1


def test_recording_visualizer_is_unchanged_for_one_arm() -> None:
    """The one-arm scene keeps its nodes at the root (no arms/ subtree)."""
    from wristmark.viz.replay import home_scene

    vis, window = recording_visualizer()
    home_scene(vis)
    assert "arms" not in node(window, "wristmark")  # type: ignore[operator]
    assert node(window, "wristmark/tips/commanded").object is not None  # type: ignore[attr-defined]
