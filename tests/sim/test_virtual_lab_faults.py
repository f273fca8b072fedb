"""A stream that stalls mid-run (sim/virtual_lab.py's freeze_camera): the hardware path holds the
arm, then stops safely in one line.

Apart from tests/sim/test_virtual_lab.py because that module's lab (a module-scoped fixture)
keeps rendering until the module ends: this wall-clock test runs a lab of its own and must not
share the cores with an idle one (tests/sim/test_scene_lab_faults.py says why)."""

from __future__ import annotations

import dataclasses
import gc
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.rig.link.test_serial_link import PARAMS, PLANT
from tests.sim.test_virtual_lab import FPS, ROOT, RT_HOST, RT_LAB, SCALE
from wristmark.rig.link import protocol as P
from wristmark.rig.loop.heap_freeze import freeze_heap
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.setup import SimSetup, load_setup
from wristmark.sim.virtual_lab import LabCamera, VirtualLab


@pytest.fixture(scope="module")
def setup() -> SimSetup:
    s = load_setup()
    return s.with_changes(rig=dataclasses.replace(s.rig, image_scale=SCALE))


class TargetRecorder(ActuatorEmulator):
    """The emulator, recording each packet's type and, for SET_TARGET, its targets and the
    wall-clock time it came."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.received: list[tuple[str, float, tuple[int, ...] | None]] = []
        self._spy = P.StreamParser()

    def receive(self, data: bytes) -> bytes:
        for item in self._spy.feed(data):
            if not isinstance(item, P.ParseError):
                targets = tuple(item.targets_micro) if isinstance(item, P.SetTarget) else None
                self.received.append((type(item).__name__, time.monotonic(), targets))
        return super().receive(data)


@pytest.mark.slow
@pytest.mark.network
@pytest.mark.wallclock
def test_a_stream_stalling_mid_run_holds_the_arm_then_stops_safely(setup: SimSetup) -> None:
    lab = VirtualLab(PARAMS, PLANT, setup.camera, setup.marker, LabCamera(fps=FPS, image_scale=SCALE),
                     rt_priority=10 if RT_LAB else None, emulator_factory=TargetRecorder)
    pty, url = lab.start()
    emu = lab.emulator
    assert isinstance(emu, TargetRecorder)
    freeze_heap()  # as `wristmark emulator` does: the box shares this (large) process's GIL with its collector
    try:
        proc = subprocess.Popen([sys.executable, "-m", "wristmark", "servo", "--serial", pty, "--camera", url,
                                 "--image-scale", str(SCALE), *RT_HOST, "--duration", "30", "--no-progress"],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        deadline = time.monotonic() + 60
        while sum(p[0] == "SetTarget" for p in emu.received) < 150 and time.monotonic() < deadline:
            time.sleep(0.05)  # ramp, 2 s at the start, settle, then the cube: well into the closed loop
        lab.freeze_camera()
        t_freeze = time.monotonic()
        _, err = proc.communicate(timeout=30)
        t_end = time.monotonic()
        held_at = emu.arm.measured_actuators()
        time.sleep(0.5)
        moved = np.abs(emu.arm.measured_actuators() - held_at).max()
    finally:
        lab.stop()
        gc.unfreeze()
    assert proc.returncode == 3, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "stopped safely" in lines[0] and "camera stalled" in lines[0] and url in lines[0]
    assert "arm held and disabled" in lines[0]
    assert emu.received[-1][0] == "Disable" and not emu.enabled and not emu.watchdog_tripped
    # after the last frame in flight (one cycle), the commands only hold: the same target every
    # cycle, then the final holds at the measured position
    after = [p for p in emu.received if p[0] == "SetTarget" and p[1] > t_freeze + 0.2]
    distinct = {p[2] for p in after}
    assert len(after) >= 20 and len(distinct) <= 3, distinct
    assert t_end - t_freeze < 5.0  # stopped within the loop's lost-frame budget (25 cycles) and margin
    assert moved < 1e-5  # held
