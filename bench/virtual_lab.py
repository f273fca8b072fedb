"""Benchmark: frames in, and the loop on the virtual lab against the in-process bench.

(a) bench/video_tracking.py's ``run()``: a 1080p side-by-side MJPG video played at 60 fps.
(b) For each image scale (1: 1080p, and 0.5): the renderer's frame rate on this machine alone
(median time of a render plus JPEG encode), then the virtual lab (its camera at the loop's rate,
below; with ``--phase-lock none`` as fast as it can up to ``--max-fps``; the achieved rate is
reported): the emulator (`wristmark emulator --pty --camera-port 0 --fps F`) in one process, the hardware path
(`wristmark servo --serial PTY --camera URL`) in another, a cube of ``--duration`` s (default 20):
capture-to-command latency (median, p95, max; split into the frame's transport and what the
host adds; ``arrival_to_ready``: the host's own work before the cycle's command instant), frames
dropped, cycle jitter, and the true-tip error from ``--truth-dense-out`` at each cycle's nominal
instant (beside it, ``true_tip_mm_variants``: the frames' truth interpolated at the nominal
instant and at ``t_wall``, the evaluation before); beside it the in-process run of the same plant,
scale, rig file (default configs/rig.yaml) and trajectory (simulated clock, 45 ms latency).
``--camera-matched``: where the lab's camera (``--lab-share`` x the renderer's rate alone) is
slower than the loop, both loops run at the camera's period (``control_dt_s`` in the JSON).
By default the lab's camera runs at the loop's rate (one frame every ``--cycles-per-frame`` cycles on
the lab's fixed frame clock) and the host's cycle is locked to the frames' arrival at
``--lock-phase`` 0.038 s after its start (rig ``frame_phase_lock: arrival``, ``frame_lock_phase``,
``frame_wait`` from ``--frame-wait``; ``phase_lock`` in the JSON): every command then goes out
~45 ms after its cycle's start, the in-process instant, at once after its frame's tracking.
``--phase-lock none``: a free-running camera rendering as fast as it can, the shipped rig.yaml's
setting (its commands go out at a different instant of every cycle).
Both processes run under SCHED_FIFO where the host allows it (rig/loop/realtime_priority.py): the
host's loop, the lab's actuator box and stream, and the lab's rendering where the renderer
alone sustains 1.5 x ``--max-fps-rt``.
Prints one JSON object. Targets (issue 11): host latency beyond the transport <= 10 ms
(median); lab true-tip error within 20 % of the in-process run.
``--plant``, ``--marker``, ``--controller-config``, ``--orientation``: another arm, marker, controller
or orientation mode for both loops (e.g. the unseen arm with the coded marker, orientation held).
``--reference-seeds S ...``: the in-process run again with each seed of the rig's noise (render,
tracker): its spread, and the lab against the mean of those runs (``in_process_seeds``).
``in_process_latency_matched``: the in-process run once more at the lab's own timing, measured
from its log: frames that show the arm as it was the lab's median capture age before each
cycle's start (rig ``frame_age``; 0 where the lab's frames are captured after it) and commands
the lab's median delay after that start (``vision_latency``), so that where the lab's camera
is slow (1080p here) the in-process reference has the same capture-to-command latency; the
lab against it in ``targets.true_tip_ratio_latency_matched``.
``--lab-start``: where both arms rest before the run. ``start`` (default): at the cube's start
configuration, the lab's through the emulator's ``--psi0`` (the in-process bench's arm always
began there); ``home``: at the emulator's home, from where the loop's start ramps it, in the lab
and (``open_sim_session(rest=...)``) in process alike. The two differ in where each motor sits in
its play when the walk begins, which at 1080p's timing changes the error by more than the lab's
transport does (docs/notes/virtual-lab-timing.md).
``true_tip_along_path``: the lab's error along the path (a loop that trails its path shows a lag
[ms]) and across it. ``--keep DIR`` keeps the lab's files (its run folder, truth, calibration,
the host's stderr).
``--scene SCENE``: several arms instead (docs/hardware.md "Several arms"): `wristmark emulator --scene`
(one box per arm, one endoscope at the loop's rate) and `wristmark servo --scene` for each scale,
per arm the true tip error from the lab's truth CSV, lost and skipped cycles and the latency,
beside the in-process walk of the same scene, scale and cubes (sim.several_arms.walk_scene).
Usage: .venv/bin/python bench/virtual_lab.py [--duration S] [--scales 1 0.5] [--skip-video] [--camera-matched]
       [--phase-lock none]
       [--plant configs/plant_unseen.yaml --marker configs/marker_coded.yaml --orientation hold]
       [--model MODEL.yaml]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import select
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from wristmark.cli.option_types import float_in, int_in, positive_float  # noqa: E402
from wristmark.cvs.tracking.warmup import warm_up  # noqa: E402
from wristmark.models.config_files import default_config  # noqa: E402
from wristmark.rig.loop.realtime_priority import realtime_priority_allowed  # noqa: E402
from wristmark.rig.loop.rig_config import RigConfig  # noqa: E402

WRISTMARK = [sys.executable, "-m", "wristmark"]


def sustained_fps(scale: float, n: int = 12, robot: str | None = None) -> dict[str, float]:
    """Median render + JPEG-encode time of the lab's camera at ``scale`` and the rate it allows."""
    import cv2

    from wristmark.cvs.camera import scaled_stereo_camera
    from wristmark.models.arm_spec import home_psi
    from wristmark.sim.render.settings import noise_preset
    from wristmark.sim.render.stereo_renderer import StereoRenderer
    from wristmark.sim.setup import load_setup, make_plant

    setup = load_setup(robot=robot)
    cam = setup.camera if scale == 1.0 else scaled_stereo_camera(setup.camera, scale)
    renderer = StereoRenderer(cam, setup.marker, noise_preset("default"))
    plant = make_plant(setup, home_psi(setup.params))
    times = []
    for k in range(n + 2):
        t0 = time.perf_counter()
        pair = renderer.render(plant.true_shape())
        cv2.imencode(".jpg", np.hstack([pair.left, pair.right]), [cv2.IMWRITE_JPEG_QUALITY, 95])
        if k >= 2:
            times.append(time.perf_counter() - t0)
        plant.advance(0.05)
    ms = 1000 * float(np.median(times))
    return {"frame_ms_median": round(ms, 1), "fps": round(1000.0 / ms, 1)}


def _read_lines(proc: subprocess.Popen[bytes], n: int, timeout: float) -> list[str]:
    assert proc.stdout is not None
    fd, got, deadline = proc.stdout.fileno(), b"", time.monotonic() + timeout
    while got.count(b"\n") < n:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready or not (chunk := os.read(fd, 4096)):
            raise RuntimeError(f"the emulator printed only {got!r}")
        got += chunk
    return [ln.strip() for ln in got.decode().splitlines()[:n]]


@dataclass(frozen=True)
class Scenario:
    """What both loops run: plant and marker files (None: the shipped ones), the controller file
    (None: configs/controller.yaml), the trajectory's orientation mode (none | hold | follow) and
    the identified arm the loops command (``--model``, None: the robot file's)."""

    plant: str | None = None
    marker: str | None = None
    controller: str | None = None
    orientation: str = "none"
    robot: str | None = None
    model: str | None = None

    def lab_args(self) -> list[str]:
        """The emulator's options for it (its true arm and its marker)."""
        return [*(["--plant", self.plant] if self.plant else []), *(["--marker", self.marker] if self.marker else []),
                *(["--robot", self.robot] if self.robot else [])]

    def host_args(self) -> list[str]:
        """The hardware path's options for it (no plant: the host never knows the true arm)."""
        return [*(["--marker", self.marker] if self.marker else []), *(["--robot", self.robot] if self.robot else []),
                *(["--controller-config", self.controller] if self.controller else []),
                *(["--orientation", self.orientation] if self.orientation != "none" else []),
                *(["--model", self.model] if self.model else [])]


def lab_run(scale: float, fps: float, duration: float, tmp: Path, rt: bool, rt_render: bool,
            rig: str | None = None, dt: float | None = None, scenario: Scenario = Scenario(),
            psi_rest: np.ndarray | None = None) -> dict[str, Any]:
    """The virtual lab at up to ``fps`` and ``scale``: a cube of ``duration`` s on the hardware
    path (rt: the host loop and the lab's actuator box and stream under SCHED_FIFO; rt_render:
    the lab's rendering too; rig: the host's rig file, default the shipped one; dt: the host's
    control cycle [s], default the rig file's; scenario: plant, marker, controller, orientation;
    psi_rest: where the lab's arm rests at the start, default the emulator's home)."""
    from wristmark.rig.loop.metrics import error_stats
    from wristmark.sim.virtual_lab import read_truth_csv, true_tip_errors

    truth = tmp / f"truth_{scale}.csv"
    dense = tmp / f"truth_dense_{scale}.csv"
    emu = subprocess.Popen([*WRISTMARK, "emulator", "--pty", "--camera-port", "0", "--fps", f"{fps:.6g}",
                            "--image-scale", str(scale), "--jpeg-quality", "95", "--truth-out", str(truth),
                            "--truth-dense-out", str(dense), "--calib-out", str(tmp / f"calib_{scale}.yaml"),
                            *scenario.lab_args(),
                            *(["--psi0", *(f"{x:.17g}" for x in psi_rest)] if psi_rest is not None else []),
                            *(["--rt-priority", "10"] if rt else []),
                            *(["--render-normal-priority"] if rt and not rt_render else [])],
                           cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        pty, url = _read_lines(emu, 2, timeout=120)
        run_dir = tmp / f"run_{scale}"
        r = subprocess.run([*WRISTMARK, "servo", "--serial", pty, "--camera", url, "--image-scale", str(scale),
                            "--duration", str(duration), "--no-progress", "--out", str(run_dir),
                            "--json", str(tmp / f"res_{scale}.json"), "--calib", str(tmp / f"calib_{scale}.yaml"),
                            *(["--rt-priority", "20"] if rt else []),
                            *(["--rig", rig] if rig else []), *(["--dt", f"{dt:g}"] if dt else []),
                            *scenario.host_args()],
                           cwd=ROOT, capture_output=True, text=True, timeout=600)
    finally:
        emu.send_signal(signal.SIGTERM)
        _, emu_err = emu.communicate(timeout=60)
    (tmp / f"servo_stderr_{scale}.txt").write_text(r.stderr)
    if r.returncode != 0:
        return {"error": r.stderr.strip()}
    res = json.loads((tmp / f"res_{scale}.json").read_text())
    err = error_stats(true_tip_errors(run_dir / "log.csv", dense))  # at the cycles' nominal instants
    err_frames = error_stats(true_tip_errors(run_dir / "log.csv", truth))
    err_wall = error_stats(true_tip_errors(run_dir / "log.csv", truth, at="t_wall"))
    t, _ = read_truth_csv(truth)
    lat = res["latency"]
    return {
        "timing_in_cycle_ms": cycle_timing(run_dir / "log.csv"),
        "fps_requested": round(fps, 1),
        "fps_rendered": round((len(t) - 1) / (t[-1] - t[0]), 1) if len(t) > 1 else None,
        "latency_ms": {k: {q: lat[k][q] for q in ("median_ms", "p95_ms", "max_ms")} for k in
                       ("capture_to_command", "transport", "arrival_to_command", "arrival_to_ready", "tracking")},
        "command_phase_ms": lat["command_phase_ms"],
        "frames": {"received": res["frames"]["received"], "dropped": res["frames"]["dropped"],
                   "cycles_without_a_new_frame": res["closed_loop"]["no_frame"]},
        "cycle_jitter_ms": res["timing"]["jitter_ms"], "cycles_skipped": res["closed_loop"]["skipped"],
        "link_overruns": res["link"]["overruns"],
        "phase_lock": res["timing"].get("phase_lock"),
        "true_tip_mm": {"mean": err.mean_mm, "max": err.max_mm, "cycles": err.n},
        "true_tip_along_path": path_lag(run_dir / "log.csv", dense),
        "stopped": res["stopped"],  # why the loop stopped early ("" when it walked the whole cube)
        "true_tip_mm_variants": {  # the same run's error evaluated the earlier ways (decomposition)
            "interpolated_between_frames": {"mean": err_frames.mean_mm, "max": err_frames.max_mm},
            "between_frames_at_t_wall": {"mean": err_wall.mean_mm, "max": err_wall.max_mm}},
        "closed_loop_reused": res["closed_loop"].get("reused"),
        **({"orientation_deg_vision": {"mean": res["closed_loop"]["orientation_mean_deg"],
                                       "max": res["closed_loop"]["orientation_max_deg"]}}
           if res["closed_loop"].get("orientation_mean_deg") is not None else {}),
        **({"play_probe": res["closed_loop"]["play_probe"]} if res["closed_loop"].get("play_probe") else {}),
        "emulator": emu_err.decode(errors="replace").strip().splitlines()[-1:],
    }


def path_lag(log_csv: Path, truth_csv: Path) -> dict[str, float]:
    """The true tip's error along the desired path's direction, averaged over the walk's cycles
    [mm] (negative: behind), and as a lag [ms] at the median speed; the rest, across the path [mm]."""
    from wristmark.rig.recording.run_log import read_log_csv
    from wristmark.sim.virtual_lab import read_truth_csv

    log = read_log_csv(log_csv)
    sel = np.array([p == "servo" for p in log["phase"]], bool)
    t = np.asarray(log["t"], float)[sel]
    p_des = np.stack([np.asarray(log[f"p_des_{a}"], float)[sel] for a in "xyz"], axis=1)
    tt, tip = read_truth_csv(truth_csv)
    keep = (t >= tt[0]) & (t <= tt[-1])
    t, p_des = t[keep], p_des[keep]
    err = np.stack([np.interp(t, tt, tip[:, i]) for i in range(3)], axis=1) - p_des
    v = np.gradient(p_des, t, axis=0)
    speed = np.linalg.norm(v, axis=1)
    moving = speed > 1e-4
    along = np.sum(err * v, axis=1)[moving] / speed[moving]
    across = np.linalg.norm(err[moving] - along[:, None] * v[moving] / speed[moving][:, None], axis=1)
    return {"along_mean_mm": round(1000 * float(np.mean(along)), 4),
            "lag_ms": round(-1000 * float(np.mean(along)) / float(np.median(speed[moving])), 2),
            "across_mean_mm": round(1000 * float(np.mean(across)), 4)}


def cycle_timing(log_csv: Path) -> dict[str, float]:
    """Medians over a run's measured walk cycles [ms]: a frame's capture before its cycle's
    nominal start (negative: after it) and the command after that start."""
    from wristmark.rig.recording.run_log import read_log_csv

    log = read_log_csv(log_csv)
    sel = np.array([p == "servo" and ok == 1 for p, ok in zip(log["phase"], log["meas_ok"])], bool)
    t, t_cap = np.asarray(log["t"], float)[sel], np.asarray(log["t_capture"], float)[sel]
    cmd = t_cap + 1e-3 * np.asarray(log["latency_ms"], float)[sel]
    return {"capture_before_start_median": round(1000 * float(np.median(t - t_cap)), 2),
            "command_after_start_median": round(1000 * float(np.median(cmd - t)), 2)}


def _setup_and_cube(scale: float, duration: float, rig: str | None, dt: float | None, scenario: Scenario,
                    changes: dict[str, Any] | None = None) -> tuple[Any, Any]:
    """Both loops' setup (the rig file with ``image_scale``, ``control_dt`` and ``changes``) and cube."""
    from wristmark.cli import servo as S
    from wristmark.sim.setup import load_setup

    setup = load_setup(robot=scenario.robot, plant=scenario.plant, marker=scenario.marker,
                       controller=scenario.controller)
    base = RigConfig.load(rig) if rig else setup.rig
    every: dict[str, Any] = {"image_scale": scale, **({"control_dt": dt} if dt else {}), **(changes or {})}
    setup = setup.with_changes(rig=dataclasses.replace(base, **every))
    if scenario.model:
        from wristmark.models.model_file import load_model

        setup = setup.with_changes(model=load_model(scenario.model))
    traj = S.build_trajectory(setup, "cube", None, duration)
    if scenario.orientation != "none":
        traj = traj.with_orientation(scenario.orientation, setup.params)
    return setup, traj


def start_configuration(scale: float, duration: float, rig: str | None, dt: float | None,
                        scenario: Scenario) -> np.ndarray:
    """The cube's start configuration [rad, m, ...], the host's (and the in-process loop's) first target."""
    from wristmark.cli import servo as S

    return np.asarray(S.start_configuration(*_setup_and_cube(scale, duration, rig, dt, scenario)), float)


def in_process_run(scale: float, duration: float, rig: str | None = None, dt: float | None = None,
                   scenario: Scenario = Scenario(), seed: int | None = None,
                   timing: dict[str, float] | None = None, from_home: bool = False) -> dict[str, Any]:
    """The same cube on the in-process bench (pty emulator, simulated clock; rig: the rig file,
    default the shipped one; dt: the control cycle [s], default the rig file's; scenario: plant,
    marker, controller, orientation; seed: the rig's seed, default the rig file's; timing: a lab
    run's ``timing_in_cycle_ms``, whose capture age and command delay the frames and commands get;
    from_home: the arm rests at the home configuration and the loop ramps it to the start, as the
    lab's with ``--lab-start home``; else it rests at the start)."""
    from wristmark.cli import servo as S
    from wristmark.models.arm_spec import home_psi
    from wristmark.rig.loop.servo_summary import summarize
    from wristmark.sim.servo_bench import open_sim_session

    setup, traj = _setup_and_cube(scale, duration, rig, dt, scenario, {"seed": seed} if seed is not None else None)
    if timing is not None:  # the lab's: frames that old at the cycle's start, commands that late after it
        age = max(0.0, 1e-3 * timing["capture_before_start_median"])
        delay = min(0.95 * setup.rig.control_dt, max(0.0, 1e-3 * timing["command_after_start_median"]))
        setup = setup.with_changes(rig=dataclasses.replace(setup.rig, frame_age=age, vision_latency=delay))
    psi0 = S.start_configuration(setup, traj)
    session = open_sim_session(setup, psi0, S.LinkOptions(kind="emulator"), seed=setup.rig.seed,
                               rest=home_psi(setup.params) if from_home else None)
    out = S.run_servo(setup, traj, session, psi0, settle=setup.rig.settle_time)
    summary = summarize(setup, traj, session, out)
    c = summary["closed_loop"]
    return {"true_tip_mm": {"mean": c["noise_free"]["mean_mm"], "max": c["noise_free"]["max_mm"],
                            "cycles": c["cycles"]},
            "stopped": summary["stopped"],
            **({"orientation_deg": {"mean": c["orientation_mean_deg"], "max": c["orientation_max_deg"]}}
               if "orientation_mean_deg" in c else {}),
            "latency_ms_modelled": round(1000 * (setup.rig.frame_age + setup.rig.vision_latency), 2),
            "frame_age_ms": round(1000 * setup.rig.frame_age, 2),
            "command_after_start_ms": round(1000 * setup.rig.vision_latency, 2),
            "control_dt_s": setup.rig.control_dt}


def camera_matched_cycle(renderer_fps: float, dt: float, share: float) -> float | None:
    """The control cycle [s] for a camera slower than the loop: None when the lab, rendering at
    ``share`` x its rate alone (the host's tracking takes the rest of the 2 cores), still gives
    a frame every ``dt``; else the camera's period rounded up to 10 ms, so that the loop (as a
    lab's loop on such an endoscope would) runs at the camera's rate."""
    period = 1.0 / (share * renderer_fps)
    return None if period <= dt else 0.01 * float(np.ceil(period / 0.01 - 1e-9))


def scene_lab_run(scene: str, scale: float, duration: float, tmp: Path, rt: bool) -> dict[str, Any]:
    """`wristmark emulator --scene` and `wristmark servo --scene` (a cube of ``duration`` s per arm at
    ``scale``, the camera at the loop's rate): per arm the true tip error [mm], lost and skipped
    cycles, capture-to-command latency [ms]; the least distance between the model bodies [mm]."""
    from wristmark.rig.loop.scene_file import Scene
    from wristmark.sim.scene_lab import scene_true_tip_errors

    sc = Scene.load(scene)
    fps = 1.0 / RigConfig.load(default_config("rig.yaml")).control_dt
    truth, calib, run = tmp / f"scene_truth_{scale}.csv", tmp / f"scene_calib_{scale}.yaml", tmp / f"scene_run_{scale}"
    lab = subprocess.Popen([*WRISTMARK, "emulator", "--scene", scene, "--pty", "--camera-port", "0", "--fps",
                            f"{fps:.4f}", "--image-scale", str(scale), "--truth-out", str(truth), "--calib-out",
                            str(calib), "--force", *(["--rt-priority", "10"] if rt else [])],
                           cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lines = _read_lines(lab, len(sc.arms) + 1, 120)
        serial = [x for line in lines[:-1] for x in ("--serial", "=".join(line.split(" ", 1)))]
        host = subprocess.run([*WRISTMARK, "servo", "--scene", scene, *serial, "--camera", lines[-1], "--calib",
                               str(calib), "--image-scale", str(scale), "--duration", str(duration), "--out", str(run),
                               "--force", "--no-progress", *(["--rt-priority", "20"] if rt else [])],
                              cwd=ROOT, capture_output=True, text=True, timeout=120 + 3 * duration)
    finally:
        lab.send_signal(signal.SIGTERM)
        lab.communicate(timeout=30)
    if not (run / "result.json").is_file():
        return {"error": host.stderr.strip()}
    res = json.loads((run / "result.json").read_text())
    arms = {}
    for a in sc.arms:
        r = res["arms"][a.name]
        err = scene_true_tip_errors(run / f"log_{a.name}.csv", truth, a.name, a.base)
        err = 1000 * err[np.isfinite(err)]
        arms[a.name] = {"true_tip_mm": {"mean": float(err.mean()), "max": float(err.max()), "n": int(err.size)}
                        if err.size else None, "lost": r["closed_loop"]["lost"],
                        "skipped": r["closed_loop"]["skipped"], "stopped": r["stopped"],
                        "capture_to_command_ms": r["latency"]["capture_to_command"]["median_ms"],
                        "period_median_ms": r["timing"]["period_median_ms"]}
    return {"arms": arms, "least_model_mm": res["clearance"]["least_model_mm"], "exit": host.returncode,
            "tracking_ms_median": res["tracking_ms_median"], "tracking_late": res["tracking_late"]}


def scene_in_process(scene: str, scale: float, duration: float) -> dict[str, Any]:
    """The same scene's cubes walked closed loop in process (sim.several_arms.walk_scene) at
    ``scale``: per arm the true tip error [mm] and lost cycles."""
    from wristmark.sim.scene_experiments import scene_trajectories
    from wristmark.sim.scene_setup import load_scene_setup
    from wristmark.sim.several_arms import walk_errors, walk_scene

    setup = load_scene_setup(scene)
    for n, s in setup.arms.items():
        setup.arms[n] = s.with_changes(rig=dataclasses.replace(s.rig, image_scale=scale))
    walk = walk_scene(setup, scene_trajectories(setup, duration), True, "closed_loop")
    return {"arms": {n: {"true_tip_mm": {"mean": m, "max": x}, "lost": walk.arms[n].stats.lost}
                     for n, (m, x) in walk_errors(walk, "closed_loop").items()},
            "least_true_mm": 1000 * walk.least_distance_m}


def scene_bench(scene: str, scales: list[float], duration: float, skip_in_process: bool,
                keep: str | None) -> dict[str, Any]:
    """``--scene``: the lab and the in-process walk at each scale (see the module docstring)."""
    rt = realtime_priority_allowed(20)
    out: dict[str, Any] = {"scene": scene, "duration_s": duration, "realtime_priority": rt,
                           "load_avg_1min_at_start": os.getloadavg()[0], "runs": []}
    with tempfile.TemporaryDirectory(prefix="wristmark-scene-bench-") as tmp_dir:
        tmp = Path(keep or tmp_dir)
        tmp.mkdir(parents=True, exist_ok=True)
        for scale in scales:
            out["runs"].append({"image_scale": scale, "lab": scene_lab_run(scene, scale, duration, tmp, rt),
                                "in_process": None if skip_in_process else scene_in_process(scene, scale, duration)})
    out["load_avg_1min_at_end"] = os.getloadavg()[0]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=positive_float(600.0), default=20.0, help="cube duration [s] (default 20)")
    ap.add_argument("--scales", type=positive_float(1.0), nargs="+", default=[1.0, 0.5, 0.35], help="image scales")
    ap.add_argument("--skip-video", action="store_true", help="skip part (a), the video tracking bench")
    ap.add_argument("--max-fps", type=positive_float(240.0), default=60.0,
                    help="the lab renders at most this rate (default 60: as fast as it can here)")
    ap.add_argument("--max-fps-rt", type=positive_float(240.0), default=10.0,
                    help="the lab's rendering gets real-time priority only if the renderer alone sustains 1.5 x this")
    ap.add_argument("--rig", metavar="YAML", default=str(default_config("rig.yaml")),
                    help="rig file of both loops (default the shipped configs/rig.yaml)")
    ap.add_argument("--skip-in-process", action="store_true", help="run the lab only (no in-process reference)")
    ap.add_argument("--camera-matched", action="store_true",
                    help="where the lab's camera is slower than the loop, run both loops at the camera's rate "
                         "(default: the rig's cycle)")
    ap.add_argument("--phase-lock", choices=("none", "capture", "arrival"), default="arrival",
                    help="the lab's camera renders a frame every --cycles-per-frame control cycles on a fixed clock "
                         "and the host locks its cycle to their arrival (default) or capture (rig frame_phase_lock); "
                         "none: a free-running camera, the lab rendering as fast as it can")
    ap.add_argument("--lock-phase", type=float_in(-0.06, 0.06), default=0.038, metavar="S",
                    help="with --phase-lock: frames arriving / captured S s after the host cycle's start "
                         "(rig frame_lock_phase; default 0.038: commands ~45 ms after it, the in-process instant)")
    ap.add_argument("--frame-wait", type=float_in(0.0, 0.05), default=0.05, metavar="S",
                    help="with --phase-lock: the host's rig frame_wait (default 0.05)")
    ap.add_argument("--cycles-per-frame", type=int_in(1, 4), default=1,
                    help="with --phase-lock: the lab's camera period in control cycles (default 1)")
    ap.add_argument("--lab-share", type=positive_float(1.0), default=0.7,
                    help="the lab's frame rate beside the host, as a share of the renderer's alone (default 0.7)")
    ap.add_argument("--plant", metavar="YAML",
                    help="the lab's true arm (and the in-process one; default configs/plant.yaml)")
    ap.add_argument("--marker", metavar="YAML", help="marker file of both loops (default configs/marker.yaml)")
    ap.add_argument("--robot", metavar="YAML",
                    help="robot file of both loops (default configs/robot.yaml); a format-2 arm's lab frames it "
                         "(its plant: NAME_plant.yaml beside it unless --plant), the host gets the lab's calibration")
    ap.add_argument("--controller-config", metavar="YAML", help="controller file of both loops "
                                                                "(default configs/controller.yaml)")
    ap.add_argument("--orientation", choices=("none", "hold", "follow"), default="none",
                    help="the cube's orientation mode (default none: position only)")
    ap.add_argument("--model", metavar="MODEL.yaml",
                    help="identified arm both loops command (wristmark identify; default the robot file's)")
    ap.add_argument("--reference-seeds", type=int_in(0, 2**31 - 1), nargs="+", metavar="S",
                    help="also run the in-process reference with these seeds (the rig's noise) and report "
                         "the lab against their mean (the target's ratio stays against the rig file's seed)")
    ap.add_argument("--lab-start", choices=("start", "home"), default="start",
                    help="where both arms rest before the run: start (default): at the cube's start configuration, "
                         "as the in-process bench's always did (the lab's emulator gets --psi0); home: at the "
                         "emulator's home, ramped to the start by the loop, in the lab and in process alike")
    ap.add_argument("--scene", metavar="SCENE.yaml", help="several arms in one view (see the module docstring)")
    ap.add_argument("--keep", metavar="DIR", help="keep the lab's files (run folders, truth, calibration) in DIR")
    a = ap.parse_args()
    warm_up()  # OpenCV threads and the tracker's kernels, explicitly (building a tracker changes nothing)
    if a.scene:
        print(json.dumps(scene_bench(a.scene, a.scales, a.duration, a.skip_in_process, a.keep), indent=1,
                         default=float))
        return 0
    scenario = Scenario(a.plant, a.marker, a.controller_config, a.orientation, a.robot, a.model)
    rt = realtime_priority_allowed(20)
    out: dict[str, Any] = {"machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                                       "load_avg_1min_at_start": os.getloadavg()[0]},
                           "realtime_priority": rt}
    if not a.skip_video:
        import video_tracking

        out["video_tracking"] = video_tracking.run()
    out["virtual_lab"] = []
    with tempfile.TemporaryDirectory(prefix="wristmark-lab-bench-") as tmp_dir:
        tmp = a.keep or tmp_dir
        Path(tmp).mkdir(parents=True, exist_ok=True)
        rig_file = a.rig
        if a.phase_lock != "none":  # the host's rig file with the lock (the in-process run ignores it)
            rig_file = str(Path(tmp) / "rig_phase_locked.yaml")
            import yaml  # the rig file's sections (loop, bench): the lock belongs to the loop

            data = yaml.safe_load(Path(a.rig).read_text())
            loop = data["loop"] if "loop" in data else data
            loop.update(frame_phase_lock=a.phase_lock, frame_lock_phase=a.lock_phase, frame_wait=a.frame_wait)
            Path(rig_file).write_text(yaml.safe_dump(data, sort_keys=False))
            RigConfig.load(rig_file)
        for scale in a.scales:
            sustained = sustained_fps(scale, robot=a.robot)
            base_dt = RigConfig.load(a.rig).control_dt
            dt = camera_matched_cycle(sustained["fps"], base_dt, a.lab_share) if a.camera_matched else None
            fps = a.max_fps if dt is None else min(a.max_fps, 1.25 / dt)  # a little faster than the loop
            if a.phase_lock != "none":
                fps = 1.0 / (a.cycles_per_frame * (dt or base_dt))
            # the lab's box and stream run in real time, its rendering only where the renderer
            # leaves most of the machine to spare: at 1.5 x --max-fps-rt alone and, for a camera
            # at a fixed rate, 2 x that rate (in real time a renderer that needs most of both
            # cores eats the machine's real-time budget and starves the host's loop: at 1080p,
            # locked at 16.7 fps, the host skipped 55 cycles with 18.5 fps alone and 34 with 26.1)
            rt_render = rt and sustained["fps"] >= 1.5 * a.max_fps_rt and (
                a.phase_lock == "none" or sustained["fps"] >= 2.0 * fps)
            home = a.lab_start == "home"
            rest = None if home else start_configuration(scale, a.duration, a.rig, dt, scenario)
            lab = lab_run(scale, fps, a.duration, Path(tmp), rt, rt_render, rig_file, dt, scenario, rest)
            lab["lab_realtime_priority"] = {"box_and_stream": rt, "rendering": rt_render}
            ref = None if a.skip_in_process else in_process_run(scale, a.duration, a.rig, dt, scenario,
                                                                    from_home=home)
            row: dict[str, Any] = {"image_scale": scale, "renderer": sustained,
                                   "control_dt_s": dt or base_dt, "camera_matched_cycle": dt is not None,
                                   "lab": lab, "in_process": ref}
            if "true_tip_mm" in lab and ref is not None:
                ratio = lab["true_tip_mm"]["mean"] / ref["true_tip_mm"]["mean"]
                host = lab["latency_ms"]["arrival_to_command"]["median_ms"]
                work = lab["latency_ms"]["arrival_to_ready"]["median_ms"]
                # the command then waits for its cycle's command instant (rig command_phase): the
                # literal target (capture -> command <= transport + 10 ms) counts that wait too
                row["targets"] = {"true_tip_ratio": round(ratio, 3), "true_tip_within_20_percent": bool(ratio <= 1.2),
                                  "host_latency_beyond_transport_ms": host, "host_latency_met": bool(host <= 10.0),
                                  "host_work_after_arrival_ms": work, "host_work_met": bool(work <= 10.0)}
            if "timing_in_cycle_ms" in lab and not a.skip_in_process:  # the in-process run at the lab's timing
                matched = in_process_run(scale, a.duration, a.rig, dt, scenario, timing=lab["timing_in_cycle_ms"],
                                         from_home=home)
                row["in_process_latency_matched"] = matched
                if "targets" in row:
                    r = lab["true_tip_mm"]["mean"] / matched["true_tip_mm"]["mean"]
                    row["targets"]["true_tip_ratio_latency_matched"] = round(r, 3)
                    row["targets"]["latency_matched_within_20_percent"] = bool(r <= 1.2)
            if a.reference_seeds and ref is not None:  # the in-process run's spread over its noise's seeds
                means = {s: in_process_run(scale, a.duration, a.rig, dt, scenario, s,
                                           from_home=home)["true_tip_mm"]["mean"] for s in a.reference_seeds}
                mean = float(np.mean(list(means.values())))
                row["in_process_seeds"] = {"mean_mm": {str(s): m for s, m in means.items()}, "mean_of_means_mm": mean,
                                           **({"lab_ratio": round(lab["true_tip_mm"]["mean"] / mean, 3)}
                                              if "true_tip_mm" in lab else {})}
            out["virtual_lab"].append(row)
    out["rig"] = a.rig
    out["lab_start"] = a.lab_start
    out["scenario"] = dataclasses.asdict(scenario)
    out["phase_lock"] = {"on": a.phase_lock, "lock_phase_s": a.lock_phase, "frame_wait_s": a.frame_wait,
                         "cycles_per_frame": a.cycles_per_frame} if a.phase_lock != "none" else None
    out["machine"]["load_avg_1min_at_end"] = os.getloadavg()[0]
    print(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
