"""Replay of an experiment run folder as a Meshcat animation with a time slider.

A servo run folder (``wristmark experiment cube``/``load`` write one per run) holds
``log.csv`` (rig.recording.run_log.COLUMNS) and ``config.json`` (the robot, marker, plant and camera that
ran). Each logged cycle becomes a key frame: the true arm at psi_true, the ghost at psi_cmd,
the four tips; the full paths of each phase are drawn as lines. An accuracy run (no log.csv,
``result.json`` with ``positions_detail``) replays its positions one per second, the arm at the
commanded configuration (the model's IK of each target, as the experiment commanded it).
Frames: {w} world, metres; replay time in seconds.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import meshcat
import numpy as np
from meshcat.animation import Animation, AnimationClip, AnimationTrack
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from wristmark.models.arm_spec import Arm, ArmSpec, arm_size, home_psi, log_psi_names
from wristmark.models.config_io import from_mapping
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.rig.recording.run_log import log_columns, read_log_csv
from wristmark.viz import shapes
from wristmark.viz.scene import HIDDEN_SCALE, ArmScene, SceneConfig, SceneState
from wristmark.viz.style import TIP_KINDS

Array = NDArray[np.float64]

DEFAULT_MAX_FRAMES = 1000  # key frames of an animation (~4 kB each); longer runs are decimated
ACCURACY_STEP = 1.0  # [s] per position when replaying an accuracy run


def _needed(arm: Arm) -> tuple[str, ...]:
    """The log.csv columns a replay of ``arm``'s run reads (psi_cmd_<name> for a format-2 arm)."""
    cols = log_columns(log_psi_names(arm))
    return ("t", "phase", *(c for c in cols if c.startswith(("p_des", "p_cmd", "p_est", "p_true", "psi_"))))


def _robot_from_run(data: dict[str, Any], src: str, marker: MarkerModel) -> Arm:
    """The arm of config.json's ``robot`` mapping: an ArmSpec when it is a format-2 arm (it has
    ``segments``; its recorded tip offset [m], else ``marker``'s), else the reference arm's
    RobotParams."""
    robot = data["robot"]
    if "segments" in robot:
        tip = robot.get("tip_offset")
        spec = ArmSpec.from_mapping({k: v for k, v in robot.items() if k != "tip_offset"}, f"{src} 'robot'")
        try:
            spec = spec.with_marker(marker) if tip is None else replace(spec, tip_offset=float(tip))
            spec.validate()
        except ConfigError as e:
            raise ConfigError(f"{src} 'robot': {e}") from None
        except (TypeError, ValueError):
            raise ConfigError(f"{src} 'robot': tip_offset: expected a number [m], got {tip!r}") from None
        return spec
    return from_mapping(RobotParams, robot, src, "robot.")


@dataclass
class RunReplay:
    """A run folder ready to draw: scene configuration, one state per logged cycle (or
    position), their replay times [s] (monotone), and summary lines for the legend."""

    run_dir: Path
    config: SceneConfig
    states: list[SceneState]
    times: Array
    summary: dict[str, str] = field(default_factory=dict)


# -- loading ---------------------------------------------------------------------------------
def scene_config_from_run(run_dir: Path) -> SceneConfig:
    """The scene of the configuration recorded in ``run_dir/config.json`` (missing parts: the
    project's configs/)."""
    path = run_dir / "config.json"
    return scene_config_from_mapping(read_run_config(run_dir), str(path))


def read_run_config(run_dir: Path) -> dict[str, Any]:
    """``run_dir/config.json`` as a mapping (missing: empty); one-line InputError when unreadable."""
    path = run_dir / "config.json"
    data: dict[str, Any] = {}
    if path.exists():
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            raise InputError(f"{path}: not readable JSON ({e})") from None
        if not isinstance(data, dict):
            raise InputError(f"{path}: expected a JSON object")
    return data


def scene_config_from_mapping(data: dict[str, Any], src: str) -> SceneConfig:
    """The scene of one arm's recorded configuration (config.json's robot, marker, camera and
    plant; ``src`` names it in errors; missing parts: the project's configs/)."""
    from wristmark.cvs.calibration.load import calibration_from_mapping, load_calibration
    from wristmark.models.config_files import default_config

    marker = (from_mapping(MarkerModel, data["marker"], src, "marker.") if isinstance(data.get("marker"), dict)
              else MarkerModel.load(default_config("marker.yaml")))
    params = (_robot_from_run(data, src, marker) if isinstance(data.get("robot"), dict)
              else RobotParams.load(default_config("robot.yaml")))
    camera = (calibration_from_mapping(data["camera"], f"{src} 'camera'") if isinstance(data.get("camera"), dict)
              else load_calibration(default_config("camera.yaml")))
    plant: dict[str, Any] = data["plant"] if isinstance(data.get("plant"), dict) else {}
    try:
        zeta = float(plant.get("stem_coupling", 0.0) or 0.0)
    except (TypeError, ValueError):
        raise ConfigError(f"{src}: 'plant.stem_coupling' must be a number") from None
    return SceneConfig(params, marker, camera, zeta)


def _replay_times(t: Array) -> Array:
    """Monotone replay time [s]: the logged clock, with restarts (new phase, new plant) joined."""
    if len(t) == 0:
        return t
    d = np.diff(t)
    good = d[d > 0]
    step = float(np.median(good)) if good.size else 0.06
    return np.concatenate([[0.0], np.cumsum(np.where(d > 0, d, step))])


def _states_from_log(log_path: Path, arm: Arm) -> tuple[list[SceneState], Array, dict[str, str]]:
    try:
        cols = read_log_csv(log_path)
    except UnicodeDecodeError:
        raise InputError(f"{log_path}: corrupt log (not UTF-8 text)") from None
    except OSError as e:
        raise InputError(f"{log_path}: cannot read ({e.strerror or e})") from None
    except (ValueError, KeyError, TypeError, csv.Error) as e:
        raise InputError(f"{log_path}: corrupt log (not rig.recording.run_log's format: {e})") from None
    if not cols:
        raise InputError(f"{log_path}: no logged cycles")
    missing = [c for c in _needed(arm) if c not in cols]
    if missing:
        raise InputError(f"{log_path}: corrupt log, missing column '{missing[0]}'")

    def xyz(prefix: str) -> Array:
        return np.column_stack([np.asarray(cols[f"{prefix}_{a}"], float) for a in "xyz"])

    tags = log_psi_names(arm) or tuple(str(i) for i in range(6))

    def psi(prefix: str) -> Array:
        return np.column_stack([np.asarray(cols[f"{prefix}_{i}"], float) for i in tags])

    t = np.asarray(cols["t"], float)
    phase = [str(p) for p in cols["phase"]]
    P = {"desired": xyz("p_des"), "commanded": xyz("p_cmd"), "estimated": xyz("p_est"), "true": xyz("p_true")}
    psi_cmd, psi_true = psi("psi_cmd"), psi("psi_true")
    bad = ~np.all(np.isfinite(psi_cmd), axis=1) | ~np.isfinite(t)
    if np.any(bad):
        raise InputError(f"{log_path}: corrupt log, row {int(np.argmax(bad)) + 2} has no finite psi_cmd or t")
    states = [
        SceneState(psi_true[k], psi_cmd[k], {kind: P[kind][k] for kind in TIP_KINDS}, float(t[k]), phase[k])
        for k in range(len(t))
    ]
    summary = {"cycles": str(len(states)), "phases": ", ".join(dict.fromkeys(p.split(":")[0] for p in phase))}
    return states, _replay_times(t), summary


def _states_from_accuracy(run_dir: Path, result: dict[str, Any], config: SceneConfig) -> tuple[
        list[SceneState], Array, dict[str, str]]:
    from wristmark.models.ik import solve_tip_ik

    rows = result.get("positions_detail")
    if not isinstance(rows, list) or not rows:
        raise InputError(f"{run_dir}: result.json has no positions to replay")
    psi = home_psi(config.params)
    n = arm_size(config.params)[0]
    states: list[SceneState] = []
    try:
        for r in rows:
            target = np.asarray(r["target"], float)
            psi = solve_tip_ik(config.params, target, psi).psi
            est = r.get("estimate")
            tips: dict[str, Array | None] = {
                "desired": target, "commanded": target, "true": np.asarray(r["true"], float),
                "estimated": None if est is None else np.asarray(est, float),
            }
            states.append(SceneState(np.full(n, np.nan), psi.copy(), tips, ACCURACY_STEP * len(states), "accuracy"))
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"{run_dir}/result.json: malformed positions_detail ({e})") from None
    times = ACCURACY_STEP * np.arange(len(states), dtype=float)
    return states, times, {"positions": str(len(states))}


def _result_summary(run_dir: Path) -> tuple[dict[str, Any], dict[str, str]]:
    path = run_dir / "result.json"
    if not path.exists():
        return {}, {}
    try:
        res = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}, {"result.json": "unreadable"}
    if not isinstance(res, dict):
        return {}, {}
    lines: dict[str, str] = {}
    for key in ("open_loop", "closed_loop"):
        r = res.get(key)
        if isinstance(r, dict) and isinstance(r.get("mean_mm"), int | float):
            lines[key.replace("_", " ")] = f"mean {r['mean_mm']:.2f} mm, max {r.get('max_mm', math.nan):.2f} mm"
    if res.get("experiment") == "accuracy" and isinstance(res.get("mean_mm"), int | float):
        lines["estimate vs tracker"] = f"mean {res['mean_mm']:.2f} mm, max {res.get('max_mm', math.nan):.2f} mm"
    return res, lines


def load_run(run_dir: str | Path) -> RunReplay:
    """Read a run folder; one-line InputError when it is missing or not a run."""
    d = Path(run_dir)
    if not d.is_dir():
        raise InputError(f"run folder {d} does not exist" if not d.exists() else f"{d} is not a folder")
    result, summary = _result_summary(d)
    config = scene_config_from_run(d)
    log = d / "log.csv"
    if log.is_file():
        states, times, info = _states_from_log(log, config.params)
    elif isinstance(result.get("positions_detail"), list):
        states, times, info = _states_from_accuracy(d, result, config)
    else:
        subs = sorted(p.parent for p in d.glob("*/log.csv"))
        hint = f"; replay one of its runs: {', '.join(str(s) for s in subs[:4])}" if subs else ""
        raise InputError(f"{d} has no log.csv: not an experiment run folder{hint}")
    return RunReplay(d, config, states, times, {"run": d.name, **info, **summary})


# -- drawing ---------------------------------------------------------------------------------
def _frame_indices(n: int, max_frames: int) -> NDArray[np.int64]:
    if n <= max_frames:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_frames).round().astype(np.int64))


def _held(points: list[Array | None]) -> tuple[Array, NDArray[np.bool_]]:
    """(N, 3) positions with hidden entries holding the nearest shown one, and the shown mask."""
    shown = np.array([p is not None and bool(np.all(np.isfinite(p))) for p in points])
    out = np.zeros((len(points), 3))
    if not shown.any():
        return out, shown
    last = next(np.asarray(p, float) for p, s in zip(points, shown) if s)
    for i, (p, s) in enumerate(zip(points, shown)):
        if s:
            last = np.asarray(p, float)
        out[i] = last
    return out, shown


def _draw_paths(scene: ArmScene, replay: RunReplay) -> None:
    """Full tip paths per phase as lines (trails of the whole run)."""
    phases = [s.phase.split(":")[0] for s in replay.states]
    for ph in dict.fromkeys(phases):
        idx = [i for i, p in enumerate(phases) if p == ph]
        for kind in scene.tip_kinds:
            pts = [replay.states[i].tips.get(kind) for i in idx]
            P = np.array([p if p is not None else np.full(3, np.nan) for p in pts], float).reshape(-1, 3)
            P = P[np.all(np.isfinite(P), axis=1)]
            if len(P) >= 2:
                scene.vis[f"{scene.root}/trails/{kind}/{ph}"].set_object(
                    shapes.polyline(P, scene.tip_styles[kind].color, opacity=0.75))


def _animation(scene: ArmScene, replay: RunReplay, idx: NDArray[np.int64]) -> Animation:
    times = [float(replay.times[i]) for i in idx]
    per_node: dict[str, list[Array]] = {}
    for i in idx:
        for path, T in scene.node_poses(replay.states[i]):
            per_node.setdefault(path, []).append(T)
    anim = Animation(default_framerate=1)
    tip_paths = {f"{scene.root}/tips/{k}": k for k in scene.tip_kinds}
    for path, Ts in per_node.items():
        clip = AnimationClip(fps=1)  # key times are seconds
        if path in tip_paths:
            pos, shown = _held([replay.states[i].tips.get(tip_paths[path]) for i in idx])
            clip.tracks["position"] = AnimationTrack("position", "vector3", list(times), pos.tolist())
            if not shown.all():
                s = np.where(shown, 1.0, HIDDEN_SCALE)
                clip.tracks["scale"] = AnimationTrack("scale", "vector3", list(times), [[v, v, v] for v in s.tolist()])
        else:
            A = np.asarray(Ts)
            R = A[:, :3, :3] / np.linalg.norm(A[:, :3, :3], axis=1, keepdims=True)  # drop the ghost's scale
            quat = Rotation.from_matrix(R).as_quat()  # x, y, z, w (three.js order)
            clip.tracks["position"] = AnimationTrack("position", "vector3", list(times), A[:, :3, 3].tolist())
            clip.tracks["quaternion"] = AnimationTrack("quaternion", "quaternion", list(times), quat.tolist())
        anim.clips[scene.vis[path].path] = clip
    return anim


def build_replay(vis: meshcat.Visualizer, replay: RunReplay, max_frames: int = DEFAULT_MAX_FRAMES,
                 play: bool = True) -> ArmScene:
    """Draw ``replay`` into ``vis``: the scene framed on the whole run, its paths, the first
    frame, and an animation of up to ``max_frames`` key frames (``play``: start playing)."""
    if max_frames < 2:
        raise InputError(f"max frames must be >= 2, got {max_frames}")
    if not replay.states:
        raise InputError(f"{replay.run_dir}: nothing to replay")
    scene = ArmScene(vis, replay.config, view=None)
    scene.set_view(scene.frame_on(replay.states))
    _draw_paths(scene, replay)
    scene.show(replay.states[0])
    idx = _frame_indices(len(replay.states), max_frames)
    if len(idx) >= 2:
        vis.set_animation(_animation(scene, replay, idx), play=play, repetitions=1)
    return scene


def home_scene(vis: meshcat.Visualizer, config: SceneConfig | None = None) -> ArmScene:
    """The arm at its home configuration with marker, endoscope and the model's tip."""
    scene = ArmScene(vis, config)
    scene.show(SceneState.at_rest(scene.config.params))
    return scene

