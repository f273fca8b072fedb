"""Replay of a run folder of several arms in one view (``wristmark experiment cube --scene``).

Such a folder holds config.json (``arms``: per arm its base pose in the scene's {w} and its robot,
marker, camera and plant: sim.scene_setup.SceneSetup.describe), result.json (per arm) and
``log_<arm>.csv`` per arm (rig.recording.run_log's columns, in the arm's own {w}). Every arm's
cycles become key frames of one animation on a common clock: the arms ran in lockstep, each
phase restarting the clock on fresh arms, so the phases are laid end to end as in a one-arm
replay (viz.replay). Frames: the scene's {w} (each arm's nodes under its base pose); seconds.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import meshcat
import numpy as np
from meshcat.animation import Animation
from numpy.typing import NDArray

from wristmark.models.errors import InputError
from wristmark.viz.arms_scene import ArmsScene, ArmsSceneConfig
from wristmark.viz.replay import (
    DEFAULT_MAX_FRAMES,
    RunReplay,
    _animation,
    _draw_paths,
    _frame_indices,
    _result_summary,
    _states_from_log,
    read_run_config,
    scene_config_from_mapping,
)
from wristmark.viz.style import LegendRow, arms_legend

Array = NDArray[np.float64]

__all__ = ["SceneRunReplay", "is_scene_run", "load_scene_run", "build_scene_replay"]


@dataclass
class SceneRunReplay:
    """A scene run folder ready to draw: the scene, per arm a :class:`viz.replay.RunReplay` (its
    states and their replay times [s] on the common clock), and summary lines per arm."""

    run_dir: Path
    config: ArmsSceneConfig
    arms: dict[str, RunReplay]
    summary: dict[str, str] = field(default_factory=dict)

    @property
    def legend(self) -> tuple[LegendRow, ...]:
        """The page's legend rows: each arm's name and colours, then the shared items."""
        return arms_legend(self.config.names)


def is_scene_run(run_dir: str | Path) -> bool:
    """Whether ``run_dir`` is a run folder of several arms: no log.csv, and config.json lists
    ``arms`` (an unreadable config.json is left to the loader's error)."""
    d = Path(run_dir)
    if not d.is_dir() or (d / "log.csv").is_file() or not (d / "config.json").is_file():
        return False
    try:
        data = read_run_config(d)
    except InputError:
        return False
    return isinstance(data.get("arms"), dict)


def _base(value: Any, where: str) -> Array:
    """A 4x4 rigid pose from config.json; one-line InputError otherwise."""
    try:
        B = np.asarray(value, float)
    except (TypeError, ValueError):
        B = np.zeros(0)
    if B.shape != (4, 4) or not np.all(np.isfinite(B)) or not np.allclose(B[3], [0, 0, 0, 1]) \
            or not np.allclose(B[:3, :3] @ B[:3, :3].T, np.eye(3), atol=1e-6):
        raise InputError(f"{where}: expected a 4x4 rigid pose (the arm's base in the scene's {{w}})")
    return B


def _common_times(ts: dict[str, Array]) -> dict[str, Array]:
    """Replay times [s] of every arm's logged clock: the clock restarts (a new phase on fresh
    arms) split the run into segments that every arm shares; segment i starts where segment i-1
    ended (plus one cycle), at the earliest clock of any arm in it. Strictly increasing per arm."""
    seg = {n: np.concatenate([[0], np.cumsum(np.diff(t) < 0)]).astype(int) for n, t in ts.items()}
    n_seg = max(int(s.max()) + 1 for s in seg.values())
    diffs = np.concatenate([np.diff(t) for t in ts.values()])
    good = diffs[diffs > 0]
    step = float(np.median(good)) if good.size else 0.06
    starts = np.full(n_seg, np.inf)
    ends = np.full(n_seg, -np.inf)
    for n, t in ts.items():
        for i in range(n_seg):
            if np.any(seg[n] == i):
                starts[i] = min(starts[i], float(t[seg[n] == i].min()))
                ends[i] = max(ends[i], float(t[seg[n] == i].max()))
    starts[~np.isfinite(starts)] = 0.0
    ends = np.maximum(ends, starts)
    offset = np.concatenate([[0.0], np.cumsum(ends - starts + step)])
    out = {}
    for n, t in ts.items():
        r = offset[seg[n]] + t - starts[seg[n]]
        for k in range(1, len(r)):  # equal clocks in one arm's log: keep the key frames ordered
            r[k] = max(r[k], r[k - 1] + 1e-6)
        out[n] = r
    return out


def _summary(run_dir: Path, result: dict[str, Any], names: list[str], cycles: dict[str, int]) -> dict[str, str]:
    """Status lines: the run, and per arm its cycles and its open- and closed-loop errors."""
    out = {"run": run_dir.name, "arms": ", ".join(names)}
    per_arm = result.get("arms") if isinstance(result.get("arms"), dict) else {}
    for n in names:
        res = per_arm.get(n) if isinstance(per_arm, dict) else None
        out[f"{n}: cycles"] = str(cycles[n])
        if not isinstance(res, dict):
            continue
        for key in ("open_loop", "closed_loop"):
            r = res.get(key)
            if isinstance(r, dict) and isinstance(r.get("mean_mm"), int | float):
                out[f"{n}: {key.replace('_', ' ')}"] = (f"mean {r['mean_mm']:.2f} mm, "
                                                         f"max {r.get('max_mm', math.nan):.2f} mm")
            if isinstance(r, dict) and r.get("stopped"):
                out[f"{n}: stopped"] = str(r["stopped"])
    cl = result.get("clearance")
    if isinstance(cl, dict) and isinstance(cl.get("least_true_mm"), dict):
        least = ", ".join(f"{v:.1f} mm {k.split('_')[0]}" for k, v in cl["least_true_mm"].items()
                          if isinstance(v, int | float))
        out["least gap"] = least
        if isinstance(cl.get("required_mm"), int | float):
            out["clearance"] = f"{cl['required_mm']:.1f} mm, {'kept' if cl.get('kept') else 'VIOLATED'}"
    return out


def load_scene_run(run_dir: str | Path) -> SceneRunReplay:
    """Read a run folder of several arms; one-line InputError/ConfigError naming the file and
    the cause (a missing or corrupt log_<arm>.csv, a malformed config.json entry)."""
    d = Path(run_dir)
    if not d.is_dir():
        raise InputError(f"run folder {d} does not exist" if not d.exists() else f"{d} is not a folder")
    data = read_run_config(d)
    src = str(d / "config.json")
    arms_data = data.get("arms")
    if not isinstance(arms_data, dict) or not arms_data:
        raise InputError(f"{src}: 'arms' must map each arm's name to its configuration")
    configs, bases = {}, {}
    camera = None
    for name, a in arms_data.items():
        where = f"{src} 'arms.{name}'"
        if not isinstance(name, str) or not name or "/" in name or not isinstance(a, dict):
            raise InputError(f"{where}: expected an arm name (no '/') mapping to its configuration")
        bases[name] = _base(a.get("base"), f"{where}.base")
        cfg = scene_config_from_mapping(a, where)
        if camera is None and cfg.camera is not None and cfg.camera.T_world_left is not None:
            # each arm recorded the scene camera seen from its base: back into the scene's {w}
            camera = dataclasses.replace(cfg.camera, T_world_left=bases[name] @ np.asarray(cfg.camera.T_world_left))
        configs[name] = dataclasses.replace(cfg, camera=None)
    config = ArmsSceneConfig(configs, bases, camera)
    result, _ = _result_summary(d)
    arms: dict[str, RunReplay] = {}
    for name in config.names:
        log = d / f"log_{name}.csv"
        if not log.is_file():
            raise InputError(f"{d}: no log_{name}.csv for arm '{name}' of config.json: not a complete scene run folder")
        states, _, _ = _states_from_log(log, configs[name].params)
        arms[name] = RunReplay(d, configs[name], states, np.zeros(0))
    times = _common_times({n: np.array([s.t for s in r.states]) for n, r in arms.items()})
    for n, r in arms.items():
        r.times = times[n]
    summary = _summary(d, result, config.names, {n: len(r.states) for n, r in arms.items()})
    return SceneRunReplay(d, config, arms, summary)


def build_scene_replay(vis: meshcat.Visualizer, replay: SceneRunReplay, max_frames: int = DEFAULT_MAX_FRAMES,
                       play: bool = True) -> ArmsScene:
    """Draw ``replay`` into ``vis``: every arm, the scene framed on the whole run, each arm's
    paths per phase, the first frame, and one animation of up to ``max_frames`` key frames per
    arm (``play``: start playing)."""
    if max_frames < 2:
        raise InputError(f"max frames must be >= 2, got {max_frames}")
    if not any(r.states for r in replay.arms.values()):
        raise InputError(f"{replay.run_dir}: nothing to replay")
    scene = ArmsScene(vis, replay.config)
    scene.set_view(scene.frame_on({n: r.states for n, r in replay.arms.items()}))
    anim = Animation(default_framerate=1)
    for name, r in replay.arms.items():
        part = scene.parts[name]
        _draw_paths(part, r)
        part.show(r.states[0])
        idx = _frame_indices(len(r.states), max_frames)
        if len(idx) >= 2:
            anim.clips.update(_animation(part, r, idx).clips)
    if anim.clips:
        vis.set_animation(anim, play=play, repetitions=1)
    return scene
