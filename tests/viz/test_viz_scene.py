"""The Meshcat scene without a browser: poses against the kinematics and the simulated true arm,
framing, the snapshot page, replay loading and its errors, the live view's rate and that its
hook never blocks the loop."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import umsgpack
from meshcat.commands import SetTransform
from meshcat.path import Path as MeshcatPath

from wristmark.cli.main import main
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.errors import ConfigError
from wristmark.models.kinematics import forward_kinematics
from wristmark.models.robot_params import HOME_PSI
from wristmark.rig.recording.run_log import CycleRecord, RunLog, write_json
from wristmark.sim.plant import TruePlant
from wristmark.sim.setup import load_setup
from wristmark.viz import command_tree, record_wire
from wristmark.viz.framing import DEFAULT_DIRECTION, frame_points
from wristmark.viz.replay import _animation, _frame_indices, build_replay, load_run
from wristmark.viz.scene import HIDDEN_SCALE, ROOT, ArmScene, SceneConfig, SceneState
from wristmark.viz.snapshot import recording_visualizer
from wristmark.viz.style import LEGEND, TIP_KINDS

OFFSET = 0.006  # [m] tip spheres of the fake run are this far apart on screen


def screen_axes() -> tuple[np.ndarray, np.ndarray]:
    """Right and up unit vectors in {w} of the default view (see viz.framing)."""
    fwd = -np.asarray(DEFAULT_DIRECTION, float)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return right, np.cross(right, fwd)


def fake_records(cycles: int = 40) -> list[CycleRecord]:
    """Open then closed loop around home, the clock restarting per phase as in the
    experiments; true arm = psi_true through the simulated plant's stem coupling; the four
    tips apart on screen; no vision estimate in the open loop."""
    setup = load_setup()
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig.from_setup(setup))
    right, up = screen_axes()
    home = np.asarray(HOME_PSI, float)
    out = []
    for phase in ("open_loop", "closed_loop"):
        for k in range(cycles):
            s = k / cycles
            psi_cmd = home + np.array([0.15 * np.sin(2 * np.pi * s), 0.004 * s, 0.1 * s, 0.3 * s, 0.0, 0.0])
            psi_true = psi_cmd + np.array([0.0, 0.0, 0.04, 0.0, 0.05, 0.0])
            T_tip = scene.stem_correction(psi_true) @ forward_kinematics(setup.params, psi_true).T_world_tip
            tip = T_tip[:3, 3]
            out.append(CycleRecord(
                t=2.0 + 0.06 * k, phase=phase, p_des=tip + OFFSET * up, p_cmd=tip - OFFSET * up,
                p_est=tip + OFFSET * right if phase == "closed_loop" else None, p_true=tip, p_trk=tip,
                psi_cmd=psi_cmd, psi_true=psi_true, meas_ok=True, rejected=False, vision_ms=5.0, ctrl_us=20.0))
    return out


def make_fake_run(out: Path, cycles: int = 40) -> Path:
    """A small run folder written with rig.recording.run_log (log.csv, config.json, result.json)."""
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "config.json", {"experiment": "cube", **load_setup().describe()})
    RunLog(fake_records(cycles)).write_csv(out / "log.csv")
    write_json(out / "result.json", {"experiment": "cube", "open_loop": {"mean_mm": 3.2, "max_mm": 8.1},
                                     "closed_loop": {"mean_mm": 0.8, "max_mm": 2.5}})
    return out


def poses_of(scene: ArmScene, state: SceneState) -> dict[str, np.ndarray]:
    return dict(scene.node_poses(state))


# -- scene ---------------------------------------------------------------------------------------
def test_set_transform_packing_matches_umsgpack() -> None:
    rng = np.random.default_rng(3)
    for name in ("a", "x" * 40, "y" * 300):
        cmd = SetTransform(rng.normal(size=(4, 4)), MeshcatPath(("meshcat", "wristmark", name)))
        assert command_tree.pack(cmd)[2] == umsgpack.packb(cmd.lower())


def test_true_arm_matches_the_simulated_plant_with_stem_coupling() -> None:
    setup = load_setup()
    assert setup.plant.stem_coupling > 0  # the default plant bends the stem
    plant = TruePlant(setup.params, setup.plant, psi0=np.asarray(HOME_PSI), dt_internal=0.001)
    psi_cmd = np.asarray(HOME_PSI) + np.array([0.2, 0.01, 0.3, 0.5, -0.2, 0.4])
    plant.command(actuators_from_psi(setup.params, psi_cmd))
    plant.advance(1.0)
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig.from_setup(setup))
    state = SceneState(plant.true_psi, psi_cmd, {"true": plant.true_tip()})
    poses = poses_of(scene, state)
    truth = plant.true_shape().frames
    np.testing.assert_allclose(poses[f"{ROOT}/marker"], truth.T_world_marker, atol=1e-9)
    # the ghost's sleeve sits on the commanded (model) marker, 18 % wider
    T_ghost = poses[f"{ROOT}/ghost/visuals/marker_0"]
    T_model = forward_kinematics(setup.params, psi_cmd).T_world_marker
    np.testing.assert_allclose(T_ghost[:3, 3], T_model[:3, 3], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(T_ghost[:3, :3], axis=0), [1.18, 1.18, 1.0], atol=1e-9)
    assert f"{ROOT}/arm/visuals/marker_0" not in poses  # the checker sleeve replaces the URDF's


def test_viewer_poses_are_the_models_chain_on_random_psi() -> None:
    """The drawn marker and the stem correction come from the model's chain with the stem bent as
    the simulated arm bends it (models.kinematics), to 1e-12 m, and agree with the plant's frames."""
    setup = load_setup()
    zeta = setup.plant.stem_coupling
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig.from_setup(setup))
    rng = np.random.default_rng(11)
    plant = TruePlant(setup.params, setup.plant, psi0=np.asarray(HOME_PSI))
    for _ in range(5):
        psi_cmd = np.asarray(HOME_PSI) + rng.uniform(-1, 1, 6) * [0.5, 0.01, 0.3, 2.0, 0.4, 2.0]
        plant.command(actuators_from_psi(setup.params, psi_cmd))
        plant.advance(0.5)
        psi = plant.true_psi
        bent = forward_kinematics(setup.params, psi, stem_bend=zeta * psi[2])
        poses = poses_of(scene, SceneState(psi, psi_cmd, {}))
        np.testing.assert_allclose(poses[f"{ROOT}/marker"], bent.T_world_marker, rtol=0, atol=1e-12)
        np.testing.assert_allclose(poses[f"{ROOT}/marker"], plant.true_shape().frames.T_world_marker, rtol=0,
                                   atol=1e-12)
        straight = forward_kinematics(setup.params, psi)
        np.testing.assert_allclose(scene.stem_correction(psi) @ straight.T_world_tip, bent.T_world_tip, rtol=0,
                                   atol=1e-12)


def test_tips_are_placed_or_hidden() -> None:
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig(camera=None))
    state = SceneState.at_rest(scene.config.params)
    state.tips["desired"] = np.array([0.01, 0.02, 0.03])
    state.tips["estimated"] = np.array([np.nan, 0.0, 0.0])
    poses = poses_of(scene, state)
    np.testing.assert_allclose(poses[f"{ROOT}/tips/desired"][:3, 3], [0.01, 0.02, 0.03])
    np.testing.assert_allclose(np.diag(poses[f"{ROOT}/tips/estimated"])[:3], HIDDEN_SCALE)
    np.testing.assert_allclose(poses[f"{ROOT}/tips/true"][:3, 3], forward_kinematics(scene.config.params, HOME_PSI).tip)


def test_framing_keeps_the_arm_in_view_and_centres_the_target() -> None:
    setup = load_setup()
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig.from_setup(setup))
    view = scene.view
    w, h = 1200, 800
    np.testing.assert_allclose(view.project(view.target[None], w, h)[0], [w / 2, h / 2], atol=1e-9)
    tip = forward_kinematics(setup.params, HOME_PSI).tip
    uv = view.project(np.array([[0.0, 0.0, 0.0], tip, setup.camera.T_world_left[:3, 3]]), w, h)
    assert np.all((uv >= 0) & (uv <= [w, h])), uv
    # the arm is centimetres long: the camera sits a few decimetres away, not metres
    assert 0.08 < view.distance < 0.4
    # a point behind the eye is not projected
    behind = view.target + 2 * view.eye_offset
    assert np.all(np.isnan(view.project(behind[None], w, h)))
    with pytest.raises(ValueError, match="non-vertical"):
        frame_points(np.zeros((2, 3)), direction=(0.0, 0.0, 1.0))


def test_snapshot_page_is_self_contained_with_legend(tmp_path: Path) -> None:
    out = tmp_path / "home.html"
    assert main(["view", "--snapshot", str(out), "--json"]) == 0
    text = out.read_text()
    assert "<script src=" not in text and "http://" not in text.split("<script>")[0]
    for label, _ in LEGEND:
        assert label.replace("(", "").split()[0] in text
    assert "wmCommands" in text and len(text) > 500_000  # the viewer bundle is inlined


def test_record_wire_round_trip() -> None:
    rec = CycleRecord(t=1.5, phase="closed_loop:settle", p_des=np.array([1.0, 2, 3]), p_cmd=np.array([4.0, 5, 6]),
                      p_est=None, p_true=np.array([7.0, 8, 9]), p_trk=np.zeros(3), psi_cmd=np.arange(6.0),
                      psi_true=np.arange(6.0) + 1, meas_ok=False, rejected=False, vision_ms=0.0, ctrl_us=0.0)
    data = record_wire.encode(rec)
    assert len(data) == record_wire.RECORD_SIZE <= 512
    back = record_wire.decode(data)
    assert back.t == 1.5 and back.phase == "closed_loop:settle" and back.p_est is None
    np.testing.assert_array_equal(back.psi_true, rec.psi_true)
    rec.p_est = np.array([0.1, 0.2, 0.3])
    np.testing.assert_array_equal(record_wire.decode(record_wire.encode(rec)).p_est, rec.p_est)


# -- replay --------------------------------------------------------------------------------------
def test_replay_loads_a_run_and_animates_every_node(tmp_path: Path) -> None:
    run = make_fake_run(tmp_path / "run", cycles=30)
    rep = load_run(run)
    assert len(rep.states) == 60
    assert np.all(np.diff(rep.times) > 0)  # the clock restart between phases is joined
    assert rep.summary["phases"] == "open_loop, closed_loop" and "mean 0.80 mm" in rep.summary["closed loop"]
    vis, window = recording_visualizer()
    scene = build_replay(vis, rep, max_frames=25, play=False)
    idx = _frame_indices(len(rep.states), 25)
    assert len(idx) == 25 and idx[0] == 0 and idx[-1] == 59
    anim = _animation(scene, rep, idx).lower()
    paths = {a["path"] for a in anim}
    assert f"/meshcat/{ROOT}/marker" in paths and all(f"/meshcat/{ROOT}/tips/{k}" in paths for k in TIP_KINDS)
    est = next(a for a in anim if a["path"].endswith("tips/estimated"))
    scale = next(t for t in est["clip"]["tracks"] if t["name"] == ".scale")
    assert scale["keys"][0]["value"][0] == HIDDEN_SCALE and scale["keys"][-1]["value"][0] == 1.0
    assert any(b"set_animation" in c for c in window.commands())


def test_replay_reads_the_recorded_camera_with_the_calibration_reader(tmp_path: Path) -> None:
    """A run's config.json camera goes through the calibration's own reader: a malformed one is
    refused in one line naming config.json and the key."""
    from wristmark.cvs.calibration.load import calibration_mapping
    from wristmark.viz.replay import scene_config_from_run

    run = make_fake_run(tmp_path / "run", cycles=2)
    camera = scene_config_from_run(run).camera
    assert camera is not None and calibration_mapping(camera) == calibration_mapping(load_setup().camera)
    cfg = json.loads((run / "config.json").read_text())
    del cfg["camera"]["left"]["dist"]
    (run / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(ConfigError, match=r"config.json 'camera': missing key 'left.dist'"):
        scene_config_from_run(run)


def test_accuracy_run_replays_its_positions(tmp_path: Path) -> None:
    run = tmp_path / "acc"
    run.mkdir()
    tip = forward_kinematics(load_setup().params, HOME_PSI).tip
    rows = [{"index": i, "target": (tip + [0.002 * i, 0, 0]).tolist(), "tracker": tip.tolist(),
             "true": tip.tolist(), "estimate": None if i == 1 else tip.tolist(), "ok": i != 1} for i in range(3)]
    (run / "result.json").write_text(json.dumps({"experiment": "accuracy", "mean_mm": 0.7, "max_mm": 1.2,
                                                 "positions_detail": rows}))
    rep = load_run(run)
    assert len(rep.states) == 3 and rep.states[1].tips["estimated"] is None
    np.testing.assert_allclose(forward_kinematics(rep.config.params, rep.states[2].psi_cmd).tip,
                               rows[2]["target"], atol=1e-6)


@pytest.mark.parametrize("case, message", [
    ("missing", "does not exist"),
    ("garbage", "corrupt log"),
    ("no_column", "missing column 'psi_cmd_0'"),
    ("empty_dir", "has no log.csv"),
])
def test_view_bad_input_is_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str,
                                          message: str) -> None:
    run = tmp_path / "run"
    if case == "garbage":
        run.mkdir()
        (run / "log.csv").write_bytes(b"t,phase,p_des_x\n1.0,open,abc\n\x00\xff")
    elif case == "no_column":
        make_fake_run(run, cycles=2)
        lines = (run / "log.csv").read_text().splitlines()
        head = lines[0].split(",")
        keep = [i for i, c in enumerate(head) if c != "psi_cmd_0"]
        (run / "log.csv").write_text("\n".join(",".join(r.split(",")[i] for i in keep) for r in lines) + "\n")
    elif case == "empty_dir":
        (run / "force_0.10N").mkdir(parents=True)
        (run / "force_0.10N" / "log.csv").write_text("t\n")
    code = main(["view", str(run), "--snapshot", str(tmp_path / "x.html")])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and message in err, err
    if case == "empty_dir":
        assert "force_0.10N" in err
    assert not (tmp_path / "x.html").exists()


# -- live ----------------------------------------------------------------------------------------
def _records(n: int) -> list[CycleRecord]:
    params = load_setup().params
    out = []
    for k in range(n):
        psi = np.asarray(HOME_PSI) + np.array([0.2 * np.sin(k / 50), 0.0, 0.1 * np.sin(k / 70), 0.0, 0.0, 0.0])
        tip = forward_kinematics(params, psi).tip
        out.append(CycleRecord(t=0.005 * k, phase="closed_loop", p_des=tip, p_cmd=tip, p_est=tip, p_true=tip,
                               p_trk=tip, psi_cmd=psi, psi_true=psi, meas_ok=True, rejected=False,
                               vision_ms=0.0, ctrl_us=0.0))
    return out


@pytest.mark.network
@pytest.mark.wallclock
def test_live_view_draws_at_least_20_hz_without_blocking_the_loop() -> None:
    from wristmark.viz.live import start_live_view

    recs = _records(400)
    view = start_live_view(stream=None)
    try:
        worst = 0.0
        t0 = time.perf_counter()
        for k, rec in enumerate(recs):  # a 200 Hz loop for 2 s
            c = time.perf_counter()
            view.on_cycle(rec)
            worst = max(worst, time.perf_counter() - c)
            delay = t0 + 0.005 * (k + 1) - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
    finally:
        view.close()
    st = view.stats
    print(f"live view: {st.frames} frames at {st.frame_rate_hz:.1f} Hz, {st.mean_draw_ms:.1f} ms per frame, "
          f"on_cycle mean {st.mean_on_cycle_us:.1f} us, worst {1e6 * worst:.0f} us")
    assert st.error == "" and st.sent == 400 and st.received == 400 and st.dropped == 0
    assert st.frame_rate_hz >= 20.0 and st.frames >= 30
    assert st.mean_on_cycle_us < 500.0


@pytest.mark.network
@pytest.mark.wallclock
def test_live_view_drops_records_instead_of_blocking_when_the_drawer_stalls() -> None:
    from wristmark.viz.live import start_live_view

    rec = _records(1)[0]
    view = start_live_view(stream=None)
    pid = view._worker.pid
    try:
        os.kill(pid, signal.SIGSTOP)
        worst = 0.0
        for _ in range(8000):  # more than the pipe holds
            c = time.perf_counter()
            view.on_cycle(rec)
            worst = max(worst, time.perf_counter() - c)
        os.kill(pid, signal.SIGCONT)
    finally:
        os.kill(pid, signal.SIGCONT)
        view.close()
    assert view.stats.dropped > 0 and view.stats.sent + view.stats.dropped == 8000
    assert worst < 0.05  # never waits for the stalled drawer


# -- any arm (format-2 robot file) ---------------------------------------------------------------
TENDON3 = Path(__file__).resolve().parents[2] / "configs" / "robots" / "tendon3.yaml"


def make_fake_arm_run(out: Path, cycles: int = 10) -> Path:
    """A tendon3 run folder as rig.recording.run_log writes it: psi_cmd_<name> columns."""
    setup = load_setup(robot=TENDON3)
    arm = setup.params
    home = arm.home_psi()
    recs = []
    for phase in ("open_loop", "closed_loop"):
        for k in range(cycles):
            psi = home + 0.02 * k / cycles
            tip = forward_kinematics(arm, psi).tip
            recs.append(CycleRecord(
                t=0.06 * k, phase=phase, p_des=tip, p_cmd=tip, p_est=tip if phase == "closed_loop" else None,
                p_true=tip, p_trk=tip, psi_cmd=psi, psi_true=psi + 0.01, meas_ok=True, rejected=False,
                vision_ms=5.0, ctrl_us=20.0))
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "config.json", {"experiment": "cube", **setup.describe()})
    RunLog(recs, psi_names=arm.names).write_csv(out / "log.csv")
    return out


def test_scene_draws_any_arm_from_its_spec() -> None:
    setup = load_setup(robot=TENDON3)
    arm = setup.params
    vis, _ = recording_visualizer()
    scene = ArmScene(vis, SceneConfig.from_setup(setup))
    psi = arm.home_psi() + 0.05
    poses = poses_of(scene, SceneState(psi, psi, {k: None for k in TIP_KINDS}))
    for t in (1, 2, 3):  # every segment's links, for the true arm and its ghost
        assert any(p.startswith(f"{ROOT}/arm/visuals/seg{t}_link_") for p in poses)
        assert any(p.startswith(f"{ROOT}/ghost/visuals/seg{t}_link_") for p in poses)
    bent = scene.stem_correction(psi) @ forward_kinematics(arm, psi).T_world_marker
    np.testing.assert_allclose(poses[f"{ROOT}/marker"], bent, atol=1e-9)
    assert scene.config.stem_coupling > 0  # tendon3's plant bends the stem: the view follows it


def test_replay_of_a_format2_arm_run(tmp_path: Path) -> None:
    run = make_fake_arm_run(tmp_path / "run")
    rep = load_run(run)
    assert rep.config.params.name == "tendon3" and len(rep.states) == 20
    assert rep.states[-1].psi_cmd.shape == (rep.config.params.n,)
    vis, _ = recording_visualizer()
    scene = build_replay(vis, rep, max_frames=10, play=False)
    clips = _animation(scene, rep, _frame_indices(len(rep.states), 10)).clips
    assert any("seg3_link_" in p.lower() for p in clips)  # the last segment moves with the replay
    out = tmp_path / "replay.html"
    assert main(["view", str(run), "--snapshot", str(out)]) == 0 and out.stat().st_size > 500_000


def test_replay_of_a_format2_run_names_a_missing_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = make_fake_arm_run(tmp_path / "run")
    log = run / "log.csv"
    log.write_text(log.read_text().replace("psi_cmd_theta3", "psi_cmd_x"))
    assert main(["view", str(run), "--snapshot", str(tmp_path / "o.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing column 'psi_cmd_theta3'" in err[0], err


def test_record_wire_carries_any_arms_psi() -> None:
    psi = np.arange(7.0)
    rec = CycleRecord(t=0.0, phase="x", p_des=np.zeros(3), p_cmd=np.zeros(3), p_est=None, p_true=np.zeros(3),
                      p_trk=np.zeros(3), psi_cmd=psi, psi_true=psi + 1, meas_ok=True, rejected=False,
                      vision_ms=0.0, ctrl_us=0.0)
    back = record_wire.decode(record_wire.encode(rec))
    np.testing.assert_array_equal(back.psi_cmd, psi)
    np.testing.assert_array_equal(back.psi_true, psi + 1)
    rec.psi_cmd = np.zeros(record_wire.MAX_PSI + 1)
    with pytest.raises(ValueError, match="malformed psi"):
        record_wire.encode(rec)


@pytest.mark.network
def test_live_view_draws_a_format2_arm_run() -> None:
    from wristmark.viz.live import start_live_view

    setup = load_setup(robot=TENDON3)
    psi = setup.params.home_psi()
    tip = forward_kinematics(setup.params, psi).tip
    view = start_live_view(setup, stream=None)
    try:
        for k in range(40):
            q = psi + 0.01 * k / 40
            view.on_cycle(CycleRecord(t=0.02 * k, phase="closed_loop", p_des=tip, p_cmd=tip, p_est=tip, p_true=tip,
                                      p_trk=tip, psi_cmd=q, psi_true=q, meas_ok=True, rejected=False,
                                      vision_ms=5.0, ctrl_us=20.0))
            time.sleep(0.01)
    finally:
        view.close()
    assert view.stats.error == "" and view.stats.frames >= 1 and view.stats.sent == 40
