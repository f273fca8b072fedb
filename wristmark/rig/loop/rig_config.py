"""Configuration of the servo loop and of the simulated bench it runs on (configs/rig.yaml); SI units.

A rig file has two sections: ``loop:``, what the servo loop needs on hardware as on the bench
(the cycle, gates, feed-forward, delay compensation, frame handling on the wall clock), and
``bench:``, what only the simulated bench uses (its latency, plant step, sensor, rendering
noise, optical tracker, seed, pacing, frame age: :data:`BENCH_KEYS`). A flat file (every key at
the top, the format before the sections) loads the same. One dataclass holds both, flat, so
``rig.control_dt`` and a sweep's ``rig.sensor`` name a key as they always did.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wristmark.models.config_io import flatten_sections, from_mapping, load_layered, sectioned, to_mapping
from wristmark.models.errors import ConfigError

SENSOR_KINDS = ("vision", "truth-noise")
NOISE_LEVELS = ("none", "default", "strong")
PHASE_LOCKS = ("none", "capture", "arrival")  # rig frame_phase_lock
# the keys only the simulated bench uses (rig.yaml's 'bench:'); every other key is the loop's
BENCH_KEYS = ("vision_latency", "plant_dt", "sensor", "truth_noise_rms", "render_noise", "tracker_rms", "seed",
              "realtime", "frame_age", "sleeve_specular", "sleeve_roughness")
SECTIONS = {"loop": "the servo loop, on hardware as on the bench", "bench": "the simulated bench only"}


@dataclass(frozen=True)
class RigConfig:
    """How the servo loop and the simulated bench run (configs/rig.yaml's ``loop:`` and ``bench:``,
    or a flat file: module doc). The defaults are configs/rig.yaml's
    (tests/models/test_config_defaults.py); a key no file states takes that default.

    control_dt: servo cycle [s] (paper: 60 ms). vision_latency: capture -> command applied [s]
    (paper: ~45 ms of image processing). plant_dt: plant integration step [s].
    sensor: "vision" renders stereo images and tracks the marker (default, the real pipeline);
    "truth-noise" is an explicit fast option: the true tip plus Gaussian noise.
    gate: largest accepted jump between consecutive measurements [m]; model_gate: largest
    accepted distance between a measurement and the model's commanded tip [m].
    max_lost_cycles: consecutive cycles without a measurement after which the loop stops.
    lost_dither: when frames show no marker for ``lost_dither_after`` cycles or more while the arm
    holds, each further lost cycle moves the command by a step of one configuration entry that
    moves the nominal model's tip this far [m] from the held command (entries and signs in turn,
    never adding up; 0: the arm just holds): a view the tracker cannot read (a highlight over the
    marker's corners, docs/notes/highlight-stripe.md) changes before the loop gives up.
    open_loop_on_lost: while the marker is lost, the loop walks on along the target open loop
    (the model's IK: with ``--model`` the identified arm's inverse, docs/identification.md) for
    this long [s], then holds the arm (0: it holds at once; the stop after max_lost_cycles stays).
    settle_time: closed-loop approach to the trajectory's start before logging metrics [s].
    feedforward_preview, feedforward_lead: the feed-forward tip velocity takes the desired path
    ``preview`` [s] ahead plus a first-order lead of ``lead`` [s] (rig.targets.trajectories.feedforward_velocity).
    frame_wait: on the wall clock (a camera), how long a cycle waits for a frame that arrived
    after it began (after its nominal start when it began over half this late) before it takes
    the newest older one [s] (0: never wait); a cycle without any new frame holds the arm like a
    lost marker. image_scale: the simulated bench renders at this
    fraction of the calibrated resolution; on hardware, the camera delivers it (the calibration
    is scaled to match). delay_compensation: the controller gets the measured tip moved on by
    the nominal model's predicted motion from the frame's capture to the command
    (rig.loop.delay_compensation; the model: the commands sent, through a first-order lag of
    ``delay_compensation_tau`` [s] per actuator, 0 = at once, or each command reached
    ``delay_compensation_reach`` [s] after its send along that lag, 0 = by the lag alone, as the
    ``--model`` link makes it; the model's motion mapped by a
    3x3 matrix fitted to the measured motion between consecutive frames, forgetting with the
    time constant ``delay_compensation_learn_window`` [s], 0 = the model as it is:
    rig.loop.motion_correction). tracking_budget: on the wall
    clock, how long a cycle waits for its frame's tracking before it holds the arm for that
    cycle (rig.loop.tip_sensors.DeadlineTipSensor; with ``frame_wait`` it keeps every cycle under the
    actuator box's 250 ms watchdog). command_phase: on the wall clock, a closed-loop cycle's
    command goes out this long after the cycle began [s] (at once when it is ready later; 0: always
    at once): a fixed instant in every cycle, so the arm's response to the command is the same in
    each cycle whatever the frame's arrival and tracking time (the simulated bench sends it
    ``vision_latency`` after the capture). reuse_measurement_age: on the wall clock, a cycle
    without a new frame steps the controller with the last accepted measurement moved on by the
    delay compensation when that is at most this old at the cycle's start [s] (0: such a cycle
    holds the arm). reuse_lost: a frame that shows no marker, or whose measurement the gates
    reject, does the same, on either clock (the simulated bench's too), before the lost marker's
    dither (false, the default: such a cycle holds the arm, the safe rule; true is a bounded open
    loop like ``open_loop_on_lost``, for the user to choose): a held arm falls behind
    the path by its speed x the cycle each lost cycle (0.6 mm at the cube's 10 mm/s), the walk's
    largest error on the shipped arms at 0.35 x image scale. frame_phase_lock: on the wall
    clock, shift the cycle grid (a bounded step per cycle, rig.loop.frame_phase_lock) so that each
    frame is captured ('capture', from the frames' capture stamps) or arrives ('arrival') at the
    host ``frame_lock_phase`` [s] after a cycle's nominal start (negative: before it); 'none': the
    grid stays where the run started. For a camera whose period equals or divides ``control_dt``
    (frames must arrive within ``frame_wait`` of a cycle's start). frame_age: the simulated
    bench's frames show the arm this long [s] before the cycle's start and are stamped so (a
    camera whose frames reach the host that late, e.g. the virtual lab's at 1080p); capture to
    command is then ``frame_age + vision_latency`` (vision sensor only; at most 1 s).
    sleeve_specular, sleeve_roughness: the simulated bench renders the sleeve under a glossy
    laminate of this Fresnel F0 (0: matte, as always before) and GGX roughness
    (sim.render.settings.RenderSettings; configs/rig_glossy.yaml). tracker_magnify: the
    tracker's ``magnify`` (cvs.tracking.settings.TrackerSettings; 1, the default: off): a pair
    lost for too few corners is searched once more enlarged this many times around the last
    good corners, which keeps a small marker (image scale 0.35) in view more often at the cost
    of more wrong tips in steep views (docs/notes/steep-views.md); 1 to 4.
    vision_latency, frame_age, plant_dt, sensor, truth_noise_rms, render_noise, tracker_rms, seed,
    realtime and the sleeve's gloss concern the simulated bench only (:data:`BENCH_KEYS`, rig.yaml's ``bench:``).
    """

    control_dt: float = 0.060
    vision_latency: float = 0.045
    plant_dt: float = 0.001
    sensor: str = "vision"
    truth_noise_rms: float = 0.0002  # [m] 3D RMS of the truth-noise sensor
    image_scale: float = 1.0  # render at this fraction of the calibrated resolution
    render_noise: str = "default"
    tracker_rms: float = 0.00012  # [m] optical tracker (Polaris Vega: 0.12 mm RMS)
    gate: float = 0.004  # [m]
    model_gate: float = 0.025  # [m]
    max_lost_cycles: int = 25
    lost_dither: float = 0.001  # [m] a lost marker's dither: tip move of each step around the held arm (0: off)
    lost_dither_after: int = 3  # lost cycles (a frame without the marker) before the dither starts
    settle_time: float = 1.5  # [s]
    feedforward_preview: float = 0.035  # [s] desired path previewed this far ahead (loop delay)
    feedforward_lead: float = 0.06  # [s] first-order lead on the feed-forward (actuator lag)
    seed: int = 0
    realtime: bool = False
    frame_wait: float = 0.04  # [s] wall clock: longest wait of a cycle for a fresh frame
    delay_compensation: bool = True
    delay_compensation_tau: float = 0.04  # [s] actuator lag assumed by the compensation's model
    delay_compensation_reach: float = 0.0  # [s] each command reached this long after its send (0: by the lag)
    delay_compensation_learn_window: float = 5.0  # [s] memory of the compensation's learnt motion map (0: off)
    tracking_budget: float = 0.15  # [s] wall clock: longest wait of a cycle for its frame's tracking
    command_phase: float = 0.0  # [s] wall clock: a cycle's command goes out this long after its start
    reuse_measurement_age: float = 0.3  # [s] wall clock: a cycle without a frame reuses a measurement this old
    reuse_lost: bool = False  # a frame without the marker (or rejected) steps on the last measurement (either clock)
    frame_phase_lock: str = "none"  # wall clock: lock the cycle grid to the frames' capture or arrival
    frame_lock_phase: float = 0.0  # [s] with the lock: frames captured / arriving this long after a cycle's start
    frame_age: float = 0.0  # [s] simulated bench: its frames show the arm this long before the cycle's start
    sleeve_specular: float = 0.0  # simulated bench: the sleeve's glossy laminate, Fresnel F0 (0: matte)
    sleeve_roughness: float = 0.1  # simulated bench: the laminate's GGX roughness alpha
    open_loop_on_lost: float = 0.0  # [s] marker lost: walk on open loop this long, then hold (0: hold at once)
    tracker_magnify: float = 1.0  # a lost pair searched again enlarged this many times (1: off)

    def validate(self) -> None:
        """Raise ConfigError naming the offending key."""
        for k in ("control_dt", "plant_dt", "image_scale", "gate", "model_gate", "tracking_budget"):
            if getattr(self, k) <= 0:
                raise ConfigError(f"'{k}' must be > 0, got {getattr(self, k)}")
        for k in ("vision_latency", "truth_noise_rms", "tracker_rms", "settle_time", "feedforward_preview",
                  "feedforward_lead", "frame_wait", "delay_compensation_tau", "delay_compensation_reach",
                  "delay_compensation_learn_window",
                  "command_phase", "reuse_measurement_age", "frame_age", "open_loop_on_lost"):
            if getattr(self, k) < 0:
                raise ConfigError(f"'{k}' must be >= 0, got {getattr(self, k)}")
        if self.vision_latency >= self.control_dt:
            raise ConfigError(
                f"'vision_latency' ({self.vision_latency} s) must be shorter than 'control_dt' "
                f"({self.control_dt} s): the paper sets the cycle longer than the processing time"
            )
        if self.delay_compensation_learn_window > 600.0:
            raise ConfigError(f"'delay_compensation_learn_window' must be at most 600 s, "
                              f"got {self.delay_compensation_learn_window}")
        if self.frame_age > 1.0:
            raise ConfigError(f"'frame_age' must be at most 1 s, got {self.frame_age}")
        if self.frame_age > 0 and self.sensor != "vision":
            raise ConfigError("'frame_age' needs 'sensor: vision' (it ages rendered frames)")
        if self.frame_wait >= self.control_dt:
            raise ConfigError(f"'frame_wait' ({self.frame_wait} s) must be shorter than 'control_dt' "
                              f"({self.control_dt} s)")
        if self.command_phase >= self.control_dt:
            raise ConfigError(f"'command_phase' ({self.command_phase} s) must be shorter than 'control_dt' "
                              f"({self.control_dt} s)")
        if self.frame_phase_lock not in PHASE_LOCKS:
            raise ConfigError(f"'frame_phase_lock' must be one of {', '.join(PHASE_LOCKS)}, "
                              f"got {self.frame_phase_lock!r}")
        if not -self.control_dt < self.frame_lock_phase < self.frame_wait:
            raise ConfigError(f"'frame_lock_phase' ({self.frame_lock_phase} s) must be within "
                              f"(-control_dt, frame_wait) = ({-self.control_dt:g}, {self.frame_wait:g}) s")
        if self.frame_wait + self.tracking_budget > 0.2:
            raise ConfigError(f"'frame_wait' + 'tracking_budget' ({self.frame_wait + self.tracking_budget:g} s) must "
                              "not exceed 0.2 s: a cycle must stay well within the actuator box's 250 ms watchdog")
        if self.plant_dt > self.control_dt:
            raise ConfigError("'plant_dt' must not exceed 'control_dt'")
        if self.sensor not in SENSOR_KINDS:
            raise ConfigError(f"'sensor' must be one of {', '.join(SENSOR_KINDS)}, got {self.sensor!r}")
        if self.render_noise not in NOISE_LEVELS:
            raise ConfigError(
                f"'render_noise' must be one of {', '.join(NOISE_LEVELS)}, got {self.render_noise!r}"
            )
        if not 0 <= self.sleeve_specular <= 1:
            raise ConfigError(f"'sleeve_specular' must be in [0, 1], got {self.sleeve_specular}")
        if not 0.01 <= self.sleeve_roughness <= 1:
            raise ConfigError(f"'sleeve_roughness' must be in [0.01, 1], got {self.sleeve_roughness}")
        if not 0 <= self.lost_dither <= 0.005:
            raise ConfigError(f"'lost_dither' must be in [0, 0.005] m, got {self.lost_dither}")
        if not 1.0 <= self.tracker_magnify <= 4.0:
            raise ConfigError(f"'tracker_magnify' must be in 1..4, got {self.tracker_magnify}")
        if self.lost_dither_after < 1:
            raise ConfigError(f"'lost_dither_after' must be >= 1, got {self.lost_dither_after}")
        if self.max_lost_cycles < 1:
            raise ConfigError(f"'max_lost_cycles' must be >= 1, got {self.max_lost_cycles}")

    @classmethod
    def load(cls, path: str | Path) -> RigConfig:
        """Load configs/rig.yaml-style files: ``loop:`` and ``bench:`` sections or a flat mapping,
        either under a 'rig' key or not (``extends`` resolved: docs/configuration.md)."""
        return from_mapping(cls, load_layered(path, "rig", flat_rig_mapping), str(path))

    def sections(self) -> dict[str, Any]:
        """The settings as rig.yaml lays them out: {'loop': {...}, 'bench': {...}}."""
        return sectioned(to_mapping(self), RIG_LAYOUT, SECTIONS)


# each key -> its section of rig.yaml
RIG_LAYOUT: dict[str, str] = {f.name: "bench" if f.name in BENCH_KEYS else "loop"
                              for f in dataclasses.fields(RigConfig)}


def flat_rig_mapping(data: dict[str, Any], source: str) -> dict[str, Any]:
    """One rig file's mapping, flat: the keys of its ``loop:`` and ``bench:`` sections (each in
    its own), or the flat mapping as it is (config_io.flatten_sections)."""
    if any(k in SECTIONS for k in data):
        loose = next((k for k in data if k not in SECTIONS and k not in RIG_LAYOUT), None)
        if loose is not None:
            raise ConfigError(f"{source}: '{loose}' is outside the 'loop:' and 'bench:' sections (not a rig key)")
    return flatten_sections(data, source, RIG_LAYOUT, SECTIONS)
