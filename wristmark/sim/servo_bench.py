"""The simulated bench behind a servo session, all in this process: the true arm, the actuator
box emulated on a pty (or the plant called directly), the rendered frames and the ground truth.

With the emulator the loop and the emulator share a simulated clock (faster than real time,
deterministic) unless ``realtime`` asks for the wall clock; every command crosses the pty as
protocol-v1 bytes either way.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from wristmark.models.errors import ConfigError
from wristmark.rig.link.actuator_driver import ActuatorDriver
from wristmark.rig.link.actuator_link import DirectLink
from wristmark.rig.link.serial_link import SerialLink, SimClock
from wristmark.rig.loop.servo_session import HW_TIMEOUT_S, SIM_TIMEOUT_S, LinkOptions, ServoSession
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.setup import SimSetup, make_measurement, make_plant, make_truth

Array = NDArray[np.float64]
SIM_LINK_KINDS = ("emulator", "direct")


def open_sim_session(setup: SimSetup, psi0: Array, options: LinkOptions, seed: int = 0,
                     emulator_factory: Callable[..., ActuatorEmulator] | None = None,
                     rest: Array | None = None) -> ServoSession:
    """Open the link to the in-process bench (not yet enabled: see :meth:`ServoSession.start`),
    the simulated arm resting at ``psi0`` (or at ``rest`` [rad, m, ...], from where the loop's
    start ramps it to ``psi0``, as the virtual lab's and a real arm); frames are rendered from the
    true arm at the loop's time (seeded ``seed``).

    emulator_factory: ``(arm, params, clock=...) -> ActuatorEmulator`` (tests record packets).
    """
    born = np.asarray(psi0 if rest is None else rest, float)
    if options.kind not in SIM_LINK_KINDS:
        raise ConfigError(f"simulated link kind must be one of {', '.join(SIM_LINK_KINDS)}, got {options.kind!r}")
    if options.kind == "direct":
        plant = make_plant(setup, born)
        direct = DirectLink(plant)
        frames, sensor = make_measurement(setup, plant, lambda: direct.time, seed)
        return ServoSession(direct, options, frames, sensor, port="(in process)", truth=make_truth(setup, plant, seed),
                            arm=plant)
    arm = LockedArm(make_plant(setup, born))
    clock = None if options.realtime else SimClock(arm.time)
    timeout = options.timeout if options.timeout is not None else (HW_TIMEOUT_S if options.realtime else SIM_TIMEOUT_S)
    factory = emulator_factory or ActuatorEmulator
    emulator = factory(arm, setup.params, clock=clock if clock is not None else time.monotonic)
    path = emulator.serve_pty()
    try:
        driver = ActuatorDriver(path, options.baudrate, timeout, options.retries, params=setup.params)
    except BaseException:
        emulator.stop()
        raise
    link = SerialLink(driver, clock=clock, pace=options.pace)
    frames, sensor = make_measurement(setup, arm, lambda: link.time, seed)
    session = ServoSession(link, options, frames, sensor, port=path, truth=make_truth(setup, arm, seed), arm=arm,
                           emulator=emulator)
    try:
        link.probe()
    except BaseException:
        session.close()
        raise
    return session
