"""A closed-loop servo session: the link to the actuators and the frames the loop sees, the run
with its safe stops, and its summary. Nothing here knows whether the arm is real: the sessions
are opened by :mod:`rig.loop.hardware_session` (a serial port and a camera) or by
:mod:`sim.servo_bench` (the simulated bench in process).

Safe stops (the arm held, then DISABLE) are reported in :class:`ServoOutcome`, never raised:
marker lost too long, the camera stalled or its stream failed, the device silent or gone, an
emergency stop, a watchdog trip, Ctrl-C.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import WristmarkError
from wristmark.rig.link.actuator_link import ActuatorLink
from wristmark.rig.loop.frame_feed import FrameFeed
from wristmark.rig.loop.ground_truth import GroundTruth
from wristmark.rig.loop.loop_setup import LoopSetup
from wristmark.rig.loop.play_probe import probe_report
from wristmark.rig.loop.tip_sensors import TipSensor
from wristmark.rig.recording.run_log import CycleRecord, RunLog
from wristmark.rig.targets.trajectories import Trajectory

Array = NDArray[np.float64]
LINK_KINDS = ("emulator", "serial", "direct", "ros2")
SIM_TIMEOUT_S = 0.5  # [s] per attempt with the in-process emulator (it integrates the arm before replying)
HW_TIMEOUT_S = 0.05  # [s] per attempt on hardware / an external emulator
POINT_HOLD_S = 5.0  # [s] default duration of a held point


@dataclass(frozen=True)
class LinkOptions:
    """How the loop reaches the actuators. kind: emulator | serial | direct | ros2; port: device
    path or pyserial URL (serial), the namespace (ros2); timeout: per attempt [s] (None: by kind);
    realtime: the emulator on the wall clock (serial, ros2: always); pace: simulated time never
    ahead of the wall clock; operating_state (ros2): refuse an arm that publishes no
    operating_state (False: ``--no-operating-state``, unsafe)."""

    kind: str = "emulator"
    port: str | None = None
    baudrate: int = 115200
    timeout: float | None = None
    retries: int = 2
    realtime: bool = False
    pace: bool = False
    operating_state: bool = True


@dataclass(frozen=True)
class PointHold(Trajectory):
    """Hold ``waypoints[0]`` for ``hold`` seconds."""

    hold: float = POINT_HOLD_S

    @property
    def times(self) -> Array:
        """Start and end [s]."""
        return np.array([0.0, self.hold])

    @property
    def duration(self) -> float:
        """Hold time [s]."""
        return float(self.hold)

    def sample(self, t: float) -> tuple[Array, Array]:
        """The point [m], at rest."""
        return np.asarray(self.waypoints[0], float).copy(), np.zeros(3)

    def truncated(self, duration: float) -> PointHold:
        """Hold for ``duration`` [s] instead."""
        return dataclasses.replace(self, hold=float(duration))


@dataclass
class ServoSession:
    """An open link to the actuators and the loop's frames and tip sensor.

    truth: ground-truth observer (the simulated bench only); wall_clock: frames stamped on
    ``time.monotonic()``, commands sent when computed (hardware, the virtual lab); arm,
    emulator: the simulated arm and actuator-box emulator when they run in this process."""

    link: ActuatorLink
    options: LinkOptions
    frames: FrameFeed
    sensor: TipSensor
    port: str = ""
    camera: str = ""
    truth: GroundTruth | None = None
    wall_clock: bool = False
    arm: Any = None
    emulator: Any = None
    closed: bool = False
    close_error: str = ""
    on_close: list[Callable[[], None]] = dataclasses.field(default_factory=list)

    def start(self) -> None:
        """ENABLE the device (serial links); call right before the first command. On the wall
        clock the link's time is then the host's ``time.monotonic()``."""
        connect = getattr(self.link, "connect", None)
        if connect is not None:
            connect(t_now=time.monotonic() if self.wall_clock else self.link.time)

    def close(self) -> None:
        """Hold + DISABLE (through the link), stop the frames and an in-process emulator. Never raises."""
        if self.closed:
            return
        self.closed = True
        try:
            self.link.close()
        finally:
            self.close_error = str(getattr(self.link, "close_error", ""))
            for step in (self.frames.close, *(self.on_close), *((self.emulator.stop,) if self.emulator else ())):
                try:
                    step()
                except Exception as e:  # noqa: BLE001 - closing must go on; the cause is kept
                    self.close_error = self.close_error or f"closing: {type(e).__name__}: {e}"

    def __enter__(self) -> ServoSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class ServoOutcome:
    """A run's log and how it ended: stopped ("" when the trajectory completed), cause
    (marker-lost, camera, device, estop, watchdog, interrupted, error) and when, from the start [s];
    ready_after_arrival_ms: on the wall clock, each accepted cycle's frame arrival -> command
    computed [ms] (before the wait for the cycle's ``command_phase``); frame_lock_offsets_ms: with
    rig ``frame_phase_lock``, each frame's capture (or arrival) after its cycle's nominal start [ms], and
    phase_shift_ms the cycle grid's final shift [ms]."""

    log: RunLog
    cycles: int = 0
    lost: int = 0
    rejected: int = 0
    no_frame: int = 0
    reused: int = 0
    skipped: int = 0
    dithers: int = 0  # lost cycles that moved the held arm a little (rig lost_dither)
    stopped: str = ""
    cause: str = ""
    t_stop: float = float("nan")
    close_error: str = ""
    wall_time_s: float = 0.0
    ready_after_arrival_ms: list[float] = dataclasses.field(default_factory=list)
    frame_lock_offsets_ms: list[float] = dataclasses.field(default_factory=list)
    phase_shift_ms: float = float("nan")
    play_probe: list[dict[str, Any]] | str | None = None  # rig.loop.play_probe.probe_report (None: not asked for)
    play_shrinks: int = 0  # plays the dead-band inversion shrank for buzzing (Controller.play_shrinks)
    # the delay compensation's learnt map of the model's tip motion to the measured one (rig.loop.motion_correction)
    motion_map: dict[str, Any] | None = None


def _count(out: ServoOutcome, stats: Any) -> None:
    """Copy a phase's counters (rig.loop.servo_loop.PhaseStats) into the outcome."""
    for name in ("cycles", "lost", "rejected", "no_frame", "reused", "skipped", "dithers"):
        setattr(out, name, int(getattr(stats, name)))


def run_servo(setup: LoopSetup, traj: Trajectory, session: ServoSession, psi0: Array, settle: float,
              progress: bool = False, on_cycle: Callable[[CycleRecord], None] | None = None,
              sensor: TipSensor | None = None, recorder: Any = None, on_frame: Any = None) -> ServoOutcome:
    """Settle at ``psi0``, run ``traj`` closed loop, then close the session (hold + DISABLE).

    Safe stops and Ctrl-C are reported in the outcome, never raised; ``sensor`` replaces the
    session's tip sensor (tests); ``on_frame(frame, measurement)`` sees every measured frame
    (the live view); ``recorder`` (rig.recording.servo_recorder.ServoRecorder) records every
    cycle and is closed at the end."""
    from wristmark.rig.link.actuator_driver import ActuatorError, ActuatorEStopped, ActuatorNotEnabled
    from wristmark.rig.loop.servo_loop import CameraStalledError, MarkerLostError, ServoLoop
    from wristmark.solvers.controller_registry import make_controller

    opts = session.options
    rig = dataclasses.replace(setup.rig, realtime=(opts.realtime or opts.pace) and opts.kind == "direct")
    out = ServoOutcome(RunLog.for_arm(setup.params))
    wall0 = time.perf_counter()
    loop: ServoLoop | None = None
    t_start = 0.0
    try:
        # the slow parts first: an enabled device wants a command every 250 ms from ENABLE on
        controller = make_controller(setup.params, setup.controller)
        session.start()
        hook = on_cycle
        if recorder is not None:
            def hook(rec: CycleRecord) -> None:
                recorder.record(rec, loop, session.link)
                if on_cycle is not None:
                    on_cycle(rec)

        link = session.link
        if setup.model is not None:  # --model: command the identified arm (docs/identification.md)
            from wristmark.rig.loop.model_loop import model_rig, use_model

            link = use_model(link, setup.params, setup.model, controller, rig.control_dt)
            rig = model_rig(rig, setup.model)
        loop = ServoLoop(setup.params, rig, link, frames=session.frames,
                         sensor=sensor if sensor is not None else session.sensor, controller=controller,
                         truth=session.truth, wall_clock=session.wall_clock, frame_wait=rig.frame_wait,
                         on_cycle=hook, on_frame=on_frame)
        t_start = loop.t
        loop.start_at(psi0)
        stats = loop.run(traj, "servo", True, out.log, settle=settle, progress=progress)
        _count(out, stats)
    except MarkerLostError as e:
        out.stopped, out.cause = str(e), "camera" if isinstance(e, CameraStalledError) else "marker-lost"
        if e.stats is not None:
            _count(out, e.stats)
    except ActuatorEStopped as e:
        out.stopped, out.cause = f"emergency stop: {e}", "estop"
    except ActuatorNotEnabled as e:
        out.stopped, out.cause = str(e), "watchdog" if "watchdog" in str(e) else "device"
    except ActuatorError as e:
        out.stopped, out.cause = f"actuator box not answering: {e}", "device"
    except WristmarkError as e:
        out.stopped, out.cause = str(e), "error"
    except KeyboardInterrupt:
        out.stopped, out.cause = "interrupted (Ctrl-C / SIGTERM)", "interrupted"
    finally:
        if out.stopped:
            out.t_stop = loop.t - t_start if loop is not None else float("nan")
            out.cycles = out.cycles or len(out.log.phase("servo"))
        if loop is not None:
            out.ready_after_arrival_ms = list(loop.ready_after_arrival_ms)
            out.play_probe = probe_report(loop.play_fits, loop.play_probe_note)
            out.play_shrinks = loop.controller.play_shrinks if loop.controller is not None else 0
            correction = loop.delay.correction if loop.delay is not None else None
            if correction is not None:
                out.motion_map = {"matrix": np.round(correction.matrix, 4).tolist(), "updates": correction.updates}
            if loop.phase_lock is not None:
                out.frame_lock_offsets_ms = [1000.0 * x for x in loop.phase_lock.offsets]
                out.phase_shift_ms = 1000.0 * loop.phase_lock.shift
        session.close()
        out.close_error = session.close_error
        if recorder is not None:
            recorder.close()
        out.wall_time_s = time.perf_counter() - wall0
    return out
