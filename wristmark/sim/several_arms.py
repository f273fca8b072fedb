"""Several arms in one view on the simulated bench, each in its own servo loop, in lockstep.

Every arm of a scene (sim.scene_setup) gets a fresh true arm, its own controller and its own
trajectory (in its own {w}); one simulated endoscope renders them all into each frame
(sim.render.scene_source), and every sleeve is tracked once per frame (rig.loop.arm_set_sensor).
Per cycle all arms' clocks advance to the cycle's start, then each arm's loop runs its cycle
(rig.loop.servo_loop.ServoLoop.step): one frame, every arm's own measurement, control and
command. One arm's lost marker holds that arm only (the others walk on).

Clearance: before each cycle every arm's controller gets the other arms' bodies (capsules along
their commanded configurations, moved into its {w}, each shifted by what vision says its tip is
off the model's: rig.loop.arm_clearance, shared with the hardware path) and keeps its own body ``scene.clearance`` (plus
``clearance_margin``) away from them; the run reports the least distance between the true bodies over every cycle.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import ConfigError
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.loop.arm_clearance import least_distance, model_offsets, set_obstacles
from wristmark.rig.loop.arm_set_sensor import ArmSetSensor
from wristmark.rig.loop.metrics import error_stats, tracking_errors
from wristmark.rig.loop.servo_cycle import MarkerLostError, PhaseStats, TrackingMemory, cycle_target
from wristmark.rig.loop.servo_loop import ServoLoop
from wristmark.rig.recording.run_log import CycleRecord, RunLog
from wristmark.rig.targets.orientation_path import start_configuration
from wristmark.rig.targets.trajectories import Trajectory
from wristmark.sim.render.scene_source import SceneFrames
from wristmark.sim.scene_setup import SceneSetup
from wristmark.sim.setup import make_plant, make_truth
from wristmark.sim.trajectory_run import check_reach, phase_summary
from wristmark.solvers.clearance import Capsules, shape_capsules
from wristmark.solvers.clearance import transformed as moved_capsules
from wristmark.solvers.controller_registry import make_controller

Array = NDArray[np.float64]

__all__ = ["ArmWalk", "SceneWalk", "walk_scene", "least_distance"]


@dataclass
class ArmWalk:
    """One arm's walk in a scene: its log (every cycle, its {w} [m]), the phase's statistics, the
    result.json fields of the phase (sim.trajectory_run.phase_summary) and why it stopped ('')."""

    log: RunLog
    stats: PhaseStats
    summary: dict[str, Any]
    stopped: str = ""


@dataclass
class SceneWalk:
    """Every arm's walk, and the least distance between any two arms' true bodies [m] over the
    cycles (``least_distance_m``; inf with one arm) with the cycle's time [s] where it was least."""

    arms: dict[str, ArmWalk]
    least_distance_m: float = float("inf")
    least_at_s: float = float("nan")
    tracking_ms: list[float] = field(default_factory=list)


def _true_bodies(setup: SceneSetup, plants: Mapping[str, Any]) -> dict[str, Capsules]:
    """Each arm's true body now in the scene's {w}."""
    return {n: moved_capsules(shape_capsules(p.true_shape()), setup.base(n)) for n, p in plants.items()}


def _set_obstacles(setup: SceneSetup, loops: Mapping[str, ServoLoop], offsets: Mapping[str, Array]) -> None:
    """Each arm's controller gets the other arms' bodies (rig.loop.arm_clearance.set_obstacles:
    shifted by their vision-measured tip offsets; two moving arms each close half the damper's
    share of the gap per cycle)."""
    set_obstacles({n: setup.base(n) for n in loops}, loops, offsets,
                  setup.scene.clearance + setup.scene.clearance_margin)


def _clock_of(link: DirectLink) -> Callable[[], float]:
    """The link's time [s] as a clock."""
    return lambda: float(link.time)


def walk_scene(setup: SceneSetup, trajectories: Mapping[str, Trajectory], closed_loop: bool, phase: str,
               logs: Mapping[str, RunLog] | None = None, seed: int | None = None,
               on_cycle: Callable[[str, CycleRecord], None] | None = None, processes: bool = False) -> SceneWalk:
    """Walk each arm's trajectory (in its own {w}, after the rig's settle time at its start) on
    fresh simulated arms, all in lockstep, open loop or closed loop on the one camera; log each
    arm's cycles under ``phase`` into ``logs`` (default new logs). An arm whose marker stays lost
    is held and stops; the others go on. ConfigError before anything runs: a trajectory missing
    for an arm or out of its reach, arms that overlap at their start. A controller that probes its
    play (rig/loop/play_probe.py) probes it first, one arm at a time, the others holding.
    ``on_cycle(arm, record)`` is called after every logged cycle (e.g. a live view's);
    ``processes``: the tracker's arms but the first in worker processes (stopped at the end)."""
    names = setup.names
    missing = [n for n in names if n not in trajectories]
    if missing:
        raise ConfigError(f"no trajectory for arm '{missing[0]}'")
    for n in names:
        check_reach(setup.arms[n], trajectories[n].waypoints)
    rig = next(iter(setup.arms.values())).rig
    seed = rig.seed if seed is None else int(seed)
    psi0 = {n: start_configuration(setup.arms[n].params, trajectories[n].sample(0.0)[0]) for n in names}
    plants = {n: make_plant(setup.arms[n], psi0[n]) for n in names}
    start_gap = least_distance(_true_bodies(setup, plants))
    if start_gap < setup.scene.clearance:
        raise ConfigError(f"{setup.scene.source}: the arms' bodies come {1000 * start_gap:.1f} mm close at the start "
                          f"of their paths, under the clearance {1000 * setup.scene.clearance:.1f} mm")
    links = {n: DirectLink(plants[n]) for n in names}
    frames = sensor = None
    if closed_loop:
        frames = SceneFrames(list(plants.values()), [setup.base(n) for n in names], setup.render_camera,
                             setup.markers, noise=rig.render_noise, seed=seed, age=rig.frame_age,
                             gloss=(rig.sleeve_specular, rig.sleeve_roughness))
        sensor = ArmSetSensor(setup.render_camera, setup.markers, magnify=rig.tracker_magnify, processes=processes)
    try:
        loops: dict[str, ServoLoop] = {}
        for i, n in enumerate(names):
            s = setup.arms[n]
            controller = make_controller(s.params, s.controller) if closed_loop else None
            if controller is not None and setup.scene.clearance > 0 and not controller.supports_obstacles:
                raise ConfigError(f"several arms: controller '{s.controller.kind}' cannot keep a clearance; use kind "
                                  "qp or set the scene's clearance to 0")
            link = links[n]
            W = np.asarray(s.camera.T_world_left, float)
            loops[n] = ServoLoop(s.params, rig, link,
                                 frames=None if frames is None else frames.feed(_clock_of(link)),
                                 sensor=None if sensor is None else sensor.view(n, W),
                                 truth=make_truth(s, plants[n], seed + 100 * i), controller=controller,
                                 on_cycle=None if on_cycle is None else functools.partial(on_cycle, n))
            loops[n].start_at(psi0[n])
        logs = dict(logs) if logs is not None else {n: RunLog.for_arm(setup.arms[n].params) for n in names}
        stats = {n: PhaseStats() for n in names}
        memory = {n: TrackingMemory() for n in names}
        stopped = {n: "" for n in names}
        dt = rig.control_dt
        settle = {n: int(round(rig.settle_time / dt)) for n in names}
        for n in names:  # a controller that probes its play: settle and probe, one arm at a time
            ctrl = loops[n].controller
            if ctrl is not None and ctrl.wants_play_probe:
                settle[n] = loops[n].probe_play(trajectories[n], phase, logs[n], stats[n], memory[n], settle[n])
        n_cycles = max(settle[n] + int(np.floor(trajectories[n].duration / dt)) + 1 for n in names)
        t0 = max(loop.t for loop in loops.values())  # one clock again: the arms that did not probe held
        walk = SceneWalk({})
        offsets: dict[str, Array] = {}
        active = list(names)
        for k in range(n_cycles):
            if not active:
                break
            targets = {n: cycle_target(trajectories[n], rig, k, t0 + k * dt, settle[n]) for n in active}
            for n in active:
                loops[n].advance_to(targets[n].t)
            if closed_loop and setup.scene.clearance > 0:
                model_offsets(loops, offsets)
                _set_obstacles(setup, loops, offsets)
            gap = least_distance(_true_bodies(setup, plants))
            if gap < walk.least_distance_m:
                walk.least_distance_m, walk.least_at_s = gap, loops[names[0]].elapsed(t0 + k * dt)
            for n in list(active):
                try:
                    rec = loops[n].step(targets[n], phase, closed_loop, memory[n], stats[n])
                except MarkerLostError as e:  # that arm held; the others walk on
                    if e.record is not None:
                        logs[n].add(e.record)
                        if on_cycle is not None:
                            on_cycle(n, e.record)
                    stopped[n] = stats[n].stopped or str(e)
                    active.remove(n)
                    if sensor is not None:  # as on the hardware path (rig.loop.arm_set_session)
                        sensor.retire(n)
                    continue
                logs[n].add(rec)
                if on_cycle is not None:
                    on_cycle(n, rec)
            if sensor is not None:
                walk.tracking_ms.append(sensor.last_ms)
        for n in names:
            summary = phase_summary(logs[n], phase, trajectories[n])
            walk.arms[n] = ArmWalk(logs[n], stats[n], summary, stopped[n])
        return walk
    finally:
        if sensor is not None:  # its worker processes, if any
            sensor.close()


def walk_errors(walk: SceneWalk, phase: str) -> dict[str, tuple[float, float]]:
    """Per arm the true tip's (mean, max) error against the desired tip [mm] over ``phase``."""
    out = {}
    for n, w in walk.arms.items():
        st = error_stats(tracking_errors(w.log.phase(phase), "p_true"))
        out[n] = (st.mean_mm, st.max_mm)
    return out
