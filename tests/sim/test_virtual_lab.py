"""The virtual lab end to end: `wristmark emulator --pty --camera-port 0` in one process, the
hardware path `wristmark servo --serial PTY --camera URL` in another (which never imports the
simulated bench), the true tip from --truth-out against the in-process run of the same plant;
a stream that stalls mid-run holds the arm and stops safely."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.rig.link.test_serial_link import PARAMS, PLANT
from wristmark.cli import servo as S
from wristmark.rig.loop.metrics import error_stats
from wristmark.rig.loop.realtime_priority import realtime_priority_allowed
from wristmark.rig.loop.servo_summary import summarize
from wristmark.sim.servo_bench import open_sim_session
from wristmark.sim.setup import SimSetup, load_setup
from wristmark.sim.virtual_lab import LabCamera, VirtualLab, true_tip_errors
from wristmark_testing.lab_process import read_lines, stop

ROOT = Path(__file__).resolve().parents[2]
# Image scale of the lab's endoscope and of the in-process reference. Measured on the loaded
# 2-core machine: at 0.25 the tracker's pose-dependent bias makes a held point's mean error vary
# by about +-0.1 mm from run to run (0.09..0.30 mm in the lab, 0.12..0.24 in process over seeds);
# at 0.5 the lab renders only ~18 fps with ~44 ms per frame, so its frames reach the host ~40 ms
# later than the in-process model's 45 ms latency and the cube error doubles; 0.35 renders at
# ~24 fps in ~28 ms and keeps both within the 0.1 mm of the issue.
SCALE = 0.35
FPS = 30.0
POINT_S, CUBE_S = 4.0, 6.0  # [s] trajectories of the end-to-end test


# The lab's actuator box and camera, and the host's loop, run in real time where the host
# allows it (as firmware, a camera and a real-time loop would): on this shared machine other
# work otherwise delays them by up to seconds (see rig/loop/realtime_priority.py).
RT_LAB = ["--rt-priority", "10"] if realtime_priority_allowed(20) else []
RT_HOST = ["--rt-priority", "20"] if realtime_priority_allowed(20) else []

# Runs the wristmark command line with every import of the simulated bench refused, and checks
# at the end that no module of it was loaded: the hardware path must not need it.
NO_SIM = """
import importlib.abc, sys
class NoSim(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "wristmark.sim" or name.startswith("wristmark.sim."):
            raise ImportError("the hardware path imported " + name)
        return None
sys.meta_path.insert(0, NoSim())
from wristmark.cli.main import main
rc = main(sys.argv[1:])
loaded = sorted(m for m in sys.modules if m == "wristmark.sim" or m.startswith("wristmark.sim."))
if loaded:
    print("simulated bench imported: " + ", ".join(loaded), file=sys.stderr)
    rc = rc or 99
sys.exit(rc)
"""


def hardware_servo(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """`wristmark servo ARGS` as its own process, with the simulated bench unimportable."""
    return subprocess.run([sys.executable, "-c", NO_SIM, "servo", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def setup() -> SimSetup:
    s = load_setup()
    return s.with_changes(rig=dataclasses.replace(s.rig, image_scale=SCALE))


@pytest.fixture(scope="module")
def lab_process(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str, Path, Path]]:
    """`wristmark emulator --pty --camera-port 0` as its own process: (pty, url, truth CSV of the
    frames, dense truth CSV)."""
    folder = tmp_path_factory.mktemp("lab")
    truth, dense = folder / "truth.csv", folder / "truth_dense.csv"
    proc = subprocess.Popen(
        [sys.executable, "-m", "wristmark", "emulator", "--pty", "--camera-port", "0", "--fps", str(FPS),
         "--image-scale", str(SCALE), "--jpeg-quality", "95", "--truth-out", str(truth),
         "--truth-dense-out", str(dense), *RT_LAB],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        pty, url = read_lines(proc, 2, timeout=60)
        assert pty.startswith("/dev/") and url.startswith("http://127.0.0.1:")
        yield pty, url, truth, dense
    finally:
        rc, err = stop(proc)
        assert rc == 0, err


def in_process(setup: SimSetup, kind: str, duration: float) -> dict:
    """The same plant and trajectory on the in-process bench (pty emulator, simulated clock)."""
    traj = S.build_trajectory(setup, kind, None, duration)
    psi0 = S.start_configuration(setup, traj)
    session = open_sim_session(setup, psi0, S.LinkOptions(kind="emulator"), seed=setup.rig.seed)
    out = S.run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time)
    return summarize(setup, traj, session, out)


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
@pytest.mark.parametrize(("kind", "duration"), [("point", POINT_S), ("cube", CUBE_S)])
def test_virtual_lab_reaches_the_in_process_accuracy(lab_process: tuple[str, str, Path, Path], setup: SimSetup,
                                                     tmp_path: Path, kind: str, duration: float) -> None:
    pty, url, truth, dense = lab_process
    record = ["--record", str(tmp_path / "run.mcap"), "--record-jpeg"] if kind == "point" else []
    r = hardware_servo("--serial", pty, "--camera", url, "--image-scale", str(SCALE), *RT_HOST,
                       "--trajectory", kind,
                       "--duration", str(duration), "--no-progress", "--out", str(tmp_path / "run"),
                       "--json", str(tmp_path / "res.json"), *record)
    assert r.returncode == 0, r.stderr
    if record:
        check_recording(tmp_path / "run.mcap", json.loads((tmp_path / "res.json").read_text()))
    res = json.loads((tmp_path / "res.json").read_text())
    assert res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    assert res["closed_loop"]["errors_from"] == "vision estimate"  # the host knows no truth
    lab = error_stats(true_tip_errors(tmp_path / "run" / "log.csv", dense))  # at the cycles' nominal instants
    at_frames = true_tip_errors(tmp_path / "run" / "log.csv", truth)  # the frames' truth, interpolated
    assert np.all(np.isfinite(at_frames)) and abs(float(np.mean(at_frames)) * 1e3 - lab.mean_mm) < 0.05
    ref = in_process(setup, kind, duration)["closed_loop"]["noise_free"]
    latency = res["latency"]["capture_to_command"]
    transport, host = res["latency"]["transport"], res["latency"]["arrival_to_command"]
    print(f"\n{kind} (real-time priority: {bool(RT_HOST)}): virtual lab true tip {lab.mean_mm:.3f} mm mean, "
          f"{lab.max_mm:.3f} mm max over {lab.n} cycles; "
          f"in process {ref['mean_mm']:.3f} / {ref['max_mm']:.3f} mm; capture -> command median "
          f"{latency['median_ms']:.1f} ms, p95 {latency['p95_ms']:.1f} ms, max {latency['max_ms']:.1f} ms (transport "
          f"median {transport['median_ms']:.1f} ms, then the host {host['median_ms']:.1f} ms); cycle "
          f"jitter max {res['timing']['jitter_ms']['max_ms']:.1f} ms, {res['closed_loop']['skipped']} skipped; "
          f"link {res['link']['overruns']} overruns, "
          f"latest {1000 * res['link']['max_late_s']:.0f} ms late")
    c = res["closed_loop"]
    assert lab.n == c["cycles"]  # the truth covers every cycle
    n_traj = int(np.floor(duration / setup.rig.control_dt)) + 1  # skipped counts the settling cycles too
    assert n_traj - c["skipped"] <= c["cycles"] <= n_traj
    assert abs(lab.mean_mm - ref["mean_mm"]) < 0.1
    # the delay compensation learnt its map of the model's motion from the frames, within its bounds
    learnt = c["motion_map"]
    assert learnt["updates"] >= 0.5 * c["cycles"] and np.abs(np.array(learnt["matrix"]) - np.eye(3)).max() <= 0.3
    # the lab stamps its frames (one machine's monotonic clock): the latency includes the transport
    assert latency["n"] >= lab.n and transport["n"] == latency["n"]
    assert 0 < transport["median_ms"] < latency["median_ms"] < 1000 * setup.rig.control_dt
    assert 0 < host["median_ms"] < 1000 * setup.rig.control_dt


def bag_messages(path: Path, res: dict) -> dict[str, list]:
    """A servo run's bag (``--record``), its messages by topic; the run says it wrote it whole."""
    from rosbags.highlevel import AnyReader

    from wristmark.cvs.sources.ros_image_msgs import typestore

    rec = res["recording"]
    assert rec["problem"] == "" and rec["dropped_cycles"] == 0
    with AnyReader([path], default_typestore=typestore()) as reader:
        by_topic: dict[str, list] = {}
        for conn, _, raw in reader.messages():
            by_topic.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    return by_topic


def check_recording(path: Path, res: dict) -> None:
    """The servo run's bag: every cycle's actuators (commanded and measured), its frames and poses."""
    by_topic = bag_messages(path, res)
    rec = res["recording"]
    joints = by_topic["/wristmark/actuators"]
    assert len(joints) == 2 * rec["cycles"] and rec["cycles"] >= res["closed_loop"]["cycles"]
    assert [j.header.frame_id for j in joints[:2]] == ["commanded", "measured"]
    assert list(joints[0].name) == ["phi", "d", "s1a", "s1b", "s2a", "s2b"]
    commanded, measured = np.asarray(joints[-2].position), np.asarray(joints[-1].position)
    assert np.all(np.isfinite(measured)) and np.abs(commanded - measured).max() < 2e-3  # it held the point
    assert len(by_topic["/stereo/left/image_raw"]) == len(by_topic["/stereo/right/image_raw"]) >= res[
        "closed_loop"]["cycles"]
    assert by_topic["/stereo/left/image_raw"][0].format == "jpeg"
    assert len(by_topic["/wristmark/tip"]) == 2 * len(by_topic["/wristmark/marker_pose"]) // 2 > 0


@pytest.mark.slow
def test_hardware_path_modules_never_import_the_simulated_bench() -> None:
    code = """
import sys
import wristmark.cli.servo as servo, wristmark.rig.loop.hardware_session, wristmark.rig.loop.servo_loop
import wristmark.rig.link.actuator_driver, wristmark.rig.link.serial_link, wristmark.rig.link.protocol
import wristmark.rig.loop.frame_feed, wristmark.rig.loop.tip_sensors, wristmark.rig.loop.servo_summary
import wristmark.cvs.tracking.tracker, wristmark.cvs.sources.open_source
import wristmark.cvs.sources.stream, wristmark.cvs.sources.v4l2, wristmark.solvers.controller
from wristmark.cli.main import build_parser
args = build_parser("servo").parse_args(["servo", "--serial", "/dev/null", "--camera", "http://127.0.0.1:1/x"])
servo.check_link_options(args)
setup = servo.build_setup(args)
traj = servo.build_trajectory(setup, "cube", None, 1.0)
servo.start_configuration(setup, traj)
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.loop.tip_sensors import VisionTipSensor
VisionTipSensor(setup.scaled_camera, setup.marker)
# several arms (servo --scene): the scene file, the boxes per arm, the walks, the shared tracking
import wristmark.cli.servo_scene as servo_scene, wristmark.rig.loop.arm_clearance
from wristmark.rig.loop import arm_set_session as A
from wristmark.rig.loop.scene_file import Scene
args = build_parser("servo").parse_args(["servo", "--scene", "configs/scenes/two_arms.yaml", "--serial", "a=/dev/null",
                                         "--serial", "b=/dev/zero", "--camera", "http://127.0.0.1:1/x",
                                         "--calib", "configs/camera.yaml"])
servo_scene.check_scene_options(args)
scene = Scene.load(args.scene)
A.parse_serial_specs(args.serials, scene.names)
setups, cam = A.load_scene_setups(scene, args.calib)
trajs = A.arm_trajectories({n: s.params for n, s in setups.items()}, scene.cube_size)
psi0 = {n: servo.start_configuration(s, trajs[n]) for n, s in setups.items()}
assert A.start_gap(setups, psi0, {a.name: a.base for a in scene.arms}) > scene.clearance
A.BudgetedArmSetSensor(setups["a"].scaled_camera, [s.marker for s in setups.values()], 0.15).close()
print(sorted(m for m in sys.modules if m == "wristmark.sim" or m.startswith("wristmark.sim.")))
"""
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


@pytest.mark.network
@pytest.mark.parametrize("render_rt", [True, False])
def test_the_box_runs_above_the_lab_and_rendering_can_stay_at_normal_priority(setup: SimSetup,
                                                                              render_rt: bool) -> None:
    """With --rt-priority N the actuator box's thread runs at N + 1 and the camera and stream at N;
    the rendering, in a process of its own, at N, or at normal priority (--render-normal-priority)."""
    from wristmark.models.errors import InputError

    if not realtime_priority_allowed(11):  # then the lab refuses at once, naming what is missing
        with pytest.raises(InputError, match="real-time priority"):
            VirtualLab(PARAMS, PLANT, setup.camera, setup.marker, LabCamera(image_scale=0.25), rt_priority=10)
        return
    caller = os.sched_getscheduler(0)  # the policy this process was started with (SCHED_OTHER, or an idle one)
    lab = VirtualLab(PARAMS, PLANT, setup.camera, setup.marker, LabCamera(fps=10.0, image_scale=0.25),
                     rt_priority=10, render_rt=render_rt)
    lab.start()
    try:
        def policy(thread: object) -> tuple[int, int]:
            tid = thread.native_id  # type: ignore[attr-defined]
            return os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority

        assert policy(lab.emulator._thread) == (os.SCHED_FIFO, 11)
        assert lab.server is not None and policy(lab.server._thread) == (os.SCHED_FIFO, 10)
        assert policy(lab._thread) == (os.SCHED_FIFO, 10)
        render = lab._render
        assert render is not None and render.pid is not None and render.pid != os.getpid()
        rendering = os.sched_getscheduler(render.pid), os.sched_getparam(render.pid).sched_priority
        assert rendering == ((os.SCHED_FIFO, 10) if render_rt else (os.SCHED_OTHER, 0))
        others = {int(t) for t in os.listdir(f"/proc/{render.pid}/task")} - {render.pid}
        assert others and all(os.sched_getscheduler(t) == os.SCHED_OTHER for t in others)  # never both cores
        assert os.sched_getscheduler(0) == caller  # the caller's thread keeps its scheduling
    finally:
        lab.stop()


def test_the_lab_never_overwrites_a_truth_file_without_force(tmp_path: Path) -> None:
    truth = tmp_path / "truth.csv"
    truth.write_text("a user's data\n")
    base = [sys.executable, "-m", "wristmark", "emulator", "--pty", "--camera-port", "0"]
    for option in ("--truth-out", "--truth-dense-out"):
        r = subprocess.run([*base, option, str(truth)], capture_output=True, text=True, timeout=60)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2 and len(lines) == 1 and "--force" in lines[0], r.stderr
        assert r.stdout == "" and truth.read_text() == "a user's data\n"  # nothing served, nothing written
