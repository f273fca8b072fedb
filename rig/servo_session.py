"""A closed-loop servo session: the link to the actuators (in-process emulator on a pty, an
external box on a serial port, or the plant directly), the run with its safe stops, and its summary.

Safe stops (the arm held, then DISABLE) are reported in :class:`ServoOutcome`, never raised:
marker lost too long, the device silent or gone, an emergency stop, a watchdog trip, Ctrl-C.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from models.errors import ConfigError, InputError, WristmarkError
from models.plant_interface import ActuatedArm
from rig.actuator_link import ActuatorLink
from rig.run_log import CycleRecord, RunLog
from rig.tip_sensors import TipSensor
from rig.trajectories import Trajectory

if TYPE_CHECKING:
    from sim.actuator_emulator import ActuatorEmulator
    from sim.setup import SimSetup

Array = NDArray[np.float64]
LINK_KINDS = ("emulator", "serial", "direct")
SIM_TIMEOUT_S = 0.5  # [s] per attempt with the in-process emulator (it integrates the arm before replying)
HW_TIMEOUT_S = 0.05  # [s] per attempt on hardware / an external emulator
POINT_HOLD_S = 5.0  # [s] default duration of a held point


@dataclass(frozen=True)
class LinkOptions:
    """How the loop reaches the actuators. kind: emulator | serial | direct; port: device path or
    pyserial URL (serial); timeout: per attempt [s] (None: by kind); realtime: the emulator on the
    wall clock (serial: always); pace: simulated time never ahead of the wall clock."""

    kind: str = "emulator"
    port: str | None = None
    baudrate: int = 115200
    timeout: float | None = None
    retries: int = 2
    realtime: bool = False
    pace: bool = False


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
    """An open link with the arm the loop's cameras look at (and the emulator, if in process)."""

    link: ActuatorLink
    arm: ActuatedArm
    options: LinkOptions
    port: str = ""
    emulator: ActuatorEmulator | None = None
    closed: bool = False
    close_error: str = ""

    def start(self) -> None:
        """ENABLE the device (serial links); call right before the first command."""
        connect = getattr(self.link, "connect", None)
        if connect is not None:
            connect(t_now=self.arm.time)

    def close(self) -> None:
        """Hold + DISABLE (through the link), stop the in-process emulator. Never raises."""
        if self.closed:
            return
        self.closed = True
        try:
            self.link.close()
        finally:
            self.close_error = str(getattr(self.link, "close_error", ""))
            if self.emulator is not None:
                self.emulator.stop()

    def __enter__(self) -> ServoSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_session(setup: SimSetup, psi0: Array, options: LinkOptions,
                 emulator_factory: Callable[..., ActuatorEmulator] | None = None) -> ServoSession:
    """Open the link to a device that answers and is not stopped (not yet enabled: see
    :meth:`ServoSession.start`), the simulated arm resting at ``psi0``.

    emulator_factory: ``(arm, params, clock=...) -> ActuatorEmulator`` (tests record packets).
    """
    from rig.actuator_driver import ActuatorDriver
    from rig.actuator_link import DirectLink
    from rig.serial_link import EncoderArm, LockedArm, SerialLink, SimClock
    from sim.actuator_emulator import ActuatorEmulator
    from sim.setup import make_plant

    if options.kind not in LINK_KINDS:
        raise ConfigError(f"link kind must be one of {', '.join(LINK_KINDS)}, got {options.kind!r}")
    if options.kind == "direct":
        plant = make_plant(setup, psi0)
        return ServoSession(DirectLink(plant), plant, options, port="(in process)")
    realtime = options.realtime or options.kind == "serial"
    timeout = options.timeout if options.timeout is not None else (HW_TIMEOUT_S if realtime else SIM_TIMEOUT_S)
    if options.kind == "serial":
        if not options.port:
            raise InputError("--serial needs a device path or pyserial URL")
        driver = ActuatorDriver(options.port, options.baudrate, timeout, options.retries, params=setup.params)
        link = SerialLink(driver)
        session = ServoSession(link, EncoderArm(link, setup.params, setup.plant), options, port=options.port)
    else:
        arm = LockedArm(make_plant(setup, psi0))
        clock = None if realtime else SimClock(arm.time)
        factory = emulator_factory or ActuatorEmulator
        emulator = factory(arm, setup.params, clock=clock if clock is not None else time.monotonic)
        path = emulator.serve_pty()
        try:
            driver = ActuatorDriver(path, options.baudrate, timeout, options.retries, params=setup.params)
        except BaseException:
            emulator.stop()
            raise
        link = SerialLink(driver, clock=clock, pace=options.pace)
        session = ServoSession(link, arm, options, port=path, emulator=emulator)
    try:
        link.probe()
    except BaseException:
        session.close()
        raise
    return session


@dataclass
class ServoOutcome:
    """A run's log and how it ended: stopped ("" when the trajectory completed), cause
    (marker-lost, device, estop, watchdog, interrupted, error) and when, from the start [s]."""

    log: RunLog
    cycles: int = 0
    lost: int = 0
    rejected: int = 0
    stopped: str = ""
    cause: str = ""
    t_stop: float = float("nan")
    close_error: str = ""
    wall_time_s: float = 0.0


def run_servo(setup: SimSetup, traj: Trajectory, session: ServoSession, psi0: Array, settle: float,
              seed: int = 0, progress: bool = False, on_cycle: Callable[[CycleRecord], None] | None = None,
              sensor: TipSensor | None = None) -> ServoOutcome:
    """Settle at ``psi0``, run ``traj`` closed loop, then close the session (hold + DISABLE).

    Safe stops and Ctrl-C are reported in the outcome, never raised; ``sensor`` replaces the
    rig's tip sensor (tests)."""
    from rig.actuator_driver import ActuatorError, ActuatorEStopped, ActuatorNotEnabled
    from rig.servo_loop import MarkerLostError, ServoLoop
    from sim.optical_tracker import OpticalTracker
    from sim.setup import make_sensor
    from solvers.controller import make_controller

    opts = session.options
    rig = dataclasses.replace(setup.rig, realtime=(opts.realtime or opts.pace) and opts.kind == "direct")
    out = ServoOutcome(RunLog())
    wall0 = time.perf_counter()
    loop: ServoLoop | None = None
    t_start = 0.0
    try:
        # the slow parts first: an enabled device wants a command every 250 ms from ENABLE on
        tracker = OpticalTracker(setup.rig.tracker_rms, seed=seed + 7)
        sensor = sensor if sensor is not None else make_sensor(setup, seed)
        controller = make_controller(setup.params, setup.controller)
        session.start()
        loop = ServoLoop(setup.params, rig, session.link, session.arm, tracker, sensor=sensor,
                         controller=controller, on_cycle=on_cycle)
        t_start = loop.t
        loop.start_at(psi0)
        stats = loop.run(traj, "servo", True, out.log, settle=settle, progress=progress)
        out.cycles, out.lost, out.rejected = stats.cycles, stats.lost, stats.rejected
    except MarkerLostError as e:
        out.stopped, out.cause = str(e), "marker-lost"
        if e.stats is not None:
            out.cycles, out.lost, out.rejected = e.stats.cycles, e.stats.lost, e.stats.rejected
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
        session.close()
        out.close_error = session.close_error
        out.wall_time_s = time.perf_counter() - wall0
    return out


def summarize(setup: SimSetup, traj: Trajectory, session: ServoSession, out: ServoOutcome) -> dict[str, Any]:
    """The result JSON: tip errors of the logged cycles (optical tracker vs desired) and the link."""
    from rig.metrics import error_stats, estimate_errors, tracking_errors

    recs = out.log.phase("servo")
    trk = error_stats(tracking_errors(recs, "p_trk"))
    true = error_stats(tracking_errors(recs, "p_true"))
    closed: dict[str, Any] = {**trk.as_dict(), "cycles": trk.n,
                              "noise_free": {"mean_mm": true.mean_mm, "max_mm": true.max_mm},
                              "lost": out.lost, "rejected": out.rejected}
    est = error_stats(estimate_errors(recs))
    if est.n:
        closed["vision_vs_true"] = {"mean_mm": est.mean_mm, "max_mm": est.max_mm}
    link: dict[str, Any] = {"kind": session.options.kind, "port": session.port,
                            "realtime": session.options.realtime or session.options.kind == "serial"}
    driver = getattr(session.link, "driver", None)
    if driver is not None:
        link.update(driver.stats)
        st = getattr(session.link, "state", None)
        if st is not None:
            link["device"] = {"flags": st.flags, "enabled": st.enabled, "estopped": st.estopped,
                              "watchdog_tripped": st.watchdog_tripped, "clock_ms": st.clock_ms}
        link.update(dataclasses.asdict(session.link.stats))  # type: ignore[attr-defined]
    kind = "point" if isinstance(traj, PointHold) else "cube"
    return {
        "command": "servo", "trajectory": {"kind": kind, "duration_s": traj.duration,
                                           "waypoints_m": np.asarray(traj.waypoints).tolist()},
        "controller": setup.controller.kind, "control_dt_s": setup.rig.control_dt, "sensor": setup.rig.sensor,
        "closed_loop": closed, "stopped": out.stopped, "cause": out.cause,
        "t_stop_s": out.t_stop if out.stopped else None,
        "safe_stop": {"held_and_disabled": not out.close_error, "problem": out.close_error},
        "link": link, "wall_time_s": out.wall_time_s,
    }


