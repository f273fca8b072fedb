"""Actuator-box emulator end to end: over real ptys (in process and `wristmark emulator --pty`),
through the driver and through an independent hand-built client."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import serial

from wristmark.models.actuation import actuators_from_psi, psi_from_actuators
from wristmark.models.arm_shape import ArmShape, arm_shape
from wristmark.models.limits import actuator_bounds
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import (
    ActuatorDisconnected,
    ActuatorDriver,
    ActuatorEStopped,
    ActuatorNotEnabled,
    ActuatorRejected,
    ActuatorTimeout,
)
from wristmark.sim.actuator_emulator import ActuatorEmulator

PARAMS = RobotParams()
A_HOME = actuators_from_psi(PARAMS, HOME_PSI)


class IdealArm:
    """ActuatedArm test double: motors reach their targets at once; records every command."""

    def __init__(self, a0: np.ndarray) -> None:
        self.pos = np.array(a0, float)
        self.target = self.pos.copy()
        self.commands: list[np.ndarray] = []
        self._time = 0.0

    def command(self, actuators: np.ndarray) -> None:
        self.commands.append(np.array(actuators, float))
        self.target = np.array(actuators, float)

    def hold(self) -> None:
        self.target = self.pos.copy()

    def advance(self, dt: float) -> None:
        self._time += dt
        self.pos = self.target.copy()

    def measured_actuators(self) -> np.ndarray:
        return self.pos.copy()

    def true_shape(self) -> ArmShape:
        return arm_shape(PARAMS, psi_from_actuators(PARAMS, self.pos))

    @property
    def time(self) -> float:
        return self._time


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def rig() -> Iterator[tuple[ActuatorEmulator, IdealArm, ActuatorDriver]]:
    arm = IdealArm(A_HOME)
    emu = ActuatorEmulator(arm, PARAMS)
    path = emu.serve_pty()
    drv = ActuatorDriver(path, timeout=0.2, retries=1, params=PARAMS)
    yield emu, arm, drv
    drv.close()
    emu.stop()


# -- over a real pty, through the driver ------------------------------------------------------
def test_ping_pong(rig) -> None:
    _, _, drv = rig
    pong = drv.ping()
    assert (pong.version, pong.count) == (1, 6)


def test_set_target_needs_enable(rig) -> None:
    emu, arm, drv = rig
    with pytest.raises(ActuatorNotEnabled, match="enable"):
        drv.set_target(A_HOME + 0.001)
    assert arm.commands == []
    assert np.allclose(drv.get_state().positions, A_HOME, atol=1e-6)
    st = drv.enable()
    assert st.enabled and not st.watchdog_tripped
    goal = A_HOME + np.array([0.1, 0.002, 0.0001, -0.0002, 0.0003, 0.0])
    drv.set_target(goal)
    assert np.allclose(drv.get_state().positions, goal, atol=1e-6)
    psi = HOME_PSI + np.array([0.0, 0.0, 0.05, 0.1, -0.05, 0.2])
    drv.set_psi(psi)
    assert np.allclose(drv.measured_psi(), psi, atol=1e-3)


def test_out_of_limit_target_rejected_whole(rig) -> None:
    emu, arm, drv = rig
    drv.enable()
    lo, hi = actuator_bounds(PARAMS)
    bad = A_HOME.copy()
    bad[0] = 0.3  # a valid phi change ...
    bad[4] = hi[4] + 1e-4  # ... with one backbone beyond its limit: nothing may move
    with pytest.raises(ActuatorRejected, match="s2a"):
        drv.set_target(bad)
    st = drv.get_state()
    assert st.target_rejected and st.enabled
    assert arm.commands == []
    assert np.allclose(st.positions, A_HOME, atol=1e-6)
    assert not drv.set_target(A_HOME).target_rejected  # a good target clears bit3


@pytest.mark.wallclock
def test_watchdog_trips_after_silence(rig) -> None:
    emu, arm, drv = rig
    drv.enable()
    drv.set_target(A_HOME + 0.001)
    time.sleep(0.08)
    assert drv.get_state().enabled  # fed within 250 ms: still enabled
    time.sleep(0.40)
    st = drv.get_state()
    assert st.watchdog_tripped and not st.enabled
    with pytest.raises(ActuatorNotEnabled):
        drv.set_target(A_HOME)
    st = drv.enable()
    assert st.enabled and not st.watchdog_tripped


def test_estop_then_reset(rig) -> None:
    emu, arm, drv = rig
    drv.enable()
    drv.set_target(A_HOME + 0.001)
    n = len(arm.commands)
    st = drv.estop()
    assert st.estopped and not st.enabled
    with pytest.raises(ActuatorEStopped, match="reset"):
        drv.set_target(A_HOME)
    with pytest.raises(ActuatorEStopped):
        drv.enable()
    assert drv.ping().version == 1 and drv.get_state().estopped
    assert len(arm.commands) == n
    st = drv.reset()
    assert not st.estopped and not st.enabled
    assert drv.enable().enabled


def test_pty_closing_mid_run_raises_clearly(rig) -> None:
    emu, _, drv = rig
    drv.enable()
    emu.stop()
    with pytest.raises((ActuatorDisconnected, ActuatorTimeout)) as info:
        for _ in range(3):
            drv.get_state()
    assert "reconnect" in str(info.value) or "no valid reply" in str(info.value)


def test_context_manager_disables_on_interrupt(rig) -> None:
    emu, _, drv = rig
    with pytest.raises(KeyboardInterrupt), drv:
        drv.enable()
        assert emu.enabled
        raise KeyboardInterrupt
    assert not emu.enabled and not drv.is_open


def test_timeout_when_nobody_answers() -> None:
    master, slave = os.openpty()
    try:
        drv = ActuatorDriver(os.ttyname(slave), timeout=0.03, retries=2)
        with pytest.raises(ActuatorTimeout, match="3 attempts"):
            drv.ping()
        assert drv.stats["sent"] == 3
        drv.close()
    finally:
        os.close(master)
        os.close(slave)


def test_bad_port_is_one_clear_error() -> None:
    with pytest.raises(ActuatorDisconnected, match="cannot open"):
        ActuatorDriver("/dev/does-not-exist-wristmark")


def test_corrupted_packets_over_pty_move_nothing(rig) -> None:
    emu, arm, drv = rig
    drv.enable()
    rng = np.random.default_rng(1)
    port = serial.Serial(drv.url, 115200, timeout=0.05)
    try:
        for _ in range(200):
            wire = bytearray(P.encode(P.SetTarget(P.micro_from_si(A_HOME + 0.001), seq=3)))
            wire[rng.integers(len(wire) - 1)] ^= 1 << int(rng.integers(8))
            port.write(bytes(wire) + bytes(rng.integers(0, 256, 5, dtype=np.uint8)) + b"\x00")
            drv.get_state()  # keeps the watchdog fed and drains nothing of ours
    finally:
        port.close()
    assert arm.commands == []
    assert np.allclose(drv.get_state().positions, A_HOME, atol=1e-6)


# -- in process, byte level ---------------------------------------------------------------------
def test_thousands_of_corrupted_packets_leave_arm_unmoved() -> None:
    arm, clock = IdealArm(A_HOME), FakeClock()
    emu = ActuatorEmulator(arm, PARAMS, clock=clock)
    parser = P.StreamParser()
    assert isinstance(parser.feed(emu.receive(P.encode(P.Enable(seq=1))))[0], P.State)
    rng = np.random.default_rng(0)
    good = P.encode(P.SetTarget(P.micro_from_si(A_HOME + 0.001), seq=2))
    replies = []
    for i in range(5000):
        clock.t += 0.001
        if i % 2:
            bad = bytearray(good)
            bad[rng.integers(len(good) - 1)] ^= 1 << int(rng.integers(8))
            data = bytes(bad)
        else:
            data = bytes(rng.integers(0, 256, int(rng.integers(1, 80)), dtype=np.uint8)) + b"\x00"
        replies += parser.feed(emu.receive(data))
        replies += parser.feed(emu.receive(P.encode(P.GetState(seq=9))))
    assert arm.commands == []
    assert emu.enabled and not emu.watchdog_tripped
    assert all(isinstance(r, P.State | P.Error) for r in replies)
    assert any(isinstance(r, P.Error) and r.code == P.ERR_BAD_CRC and r.seq == 0 for r in replies)
    assert np.allclose(arm.pos, A_HOME)


def test_watchdog_holds_at_trip_time() -> None:
    arm, clock = IdealArm(A_HOME), FakeClock()
    emu = ActuatorEmulator(arm, PARAMS, clock=clock)
    emu.receive(P.encode(P.Enable(seq=1)))
    clock.t += 0.2
    emu.poll()
    assert emu.enabled
    clock.t += 0.06
    emu.poll()
    assert not emu.enabled and emu.watchdog_tripped
    assert emu.flags == P.FLAG_WATCHDOG
    out = P.StreamParser().feed(emu.receive(P.encode(P.SetTarget(P.micro_from_si(A_HOME), seq=4))))
    assert out == [P.Error(P.ERR_NOT_ENABLED, seq=4)]
    st = P.StreamParser().feed(emu.receive(P.encode(P.GetState(seq=5))))[0]
    assert isinstance(st, P.State) and st.clock_ms == 260


def test_device_to_host_types_are_unknown_to_the_device() -> None:
    emu = ActuatorEmulator(IdealArm(A_HOME), PARAMS, clock=FakeClock())
    out = P.StreamParser().feed(emu.receive(P.encode(P.Pong(1, 6, seq=8)) + P.encode_packet(0x99, 7)))
    assert out == [P.Error(P.ERR_UNKNOWN_TYPE, seq=8), P.Error(P.ERR_UNKNOWN_TYPE, seq=7)]


# -- an independent client: bytes built by hand from docs/design.md ---------------------------------
def _crc(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def _cobs(data: bytes) -> bytes:
    out, block = b"", b""
    for b in data + b"\x00":
        if b == 0 or len(block) == 254:
            out += bytes([len(block) + 1]) + block
            block = b"" if b == 0 else bytes([b])
        else:
            block += bytes([b])
    return out


def _uncobs(frame: bytes) -> bytes:
    out, i = b"", 0
    while i < len(frame):
        n = frame[i]
        out += frame[i + 1 : i + n]
        i += n
        if n < 255 and i < len(frame):
            out += b"\x00"
    return out


def _frame(t: int, seq: int, payload: bytes = b"") -> bytes:
    body = bytes([t, seq]) + payload
    return _cobs(body + struct.pack("<H", _crc(body))) + b"\x00"


def _transact(port: serial.Serial, t: int, seq: int, payload: bytes = b"") -> tuple[int, int, bytes]:
    port.write(_frame(t, seq, payload))
    buf = b""
    deadline = time.monotonic() + 2.0
    while b"\x00" not in buf and time.monotonic() < deadline:
        buf += port.read(port.in_waiting or 1)
    body = _uncobs(buf[: buf.index(b"\x00")])
    assert struct.unpack("<H", body[-2:])[0] == _crc(body[:-2])
    return body[0], body[1], body[2:-2]


def _independent_session(path: str) -> None:
    port = serial.Serial(path, 115200, timeout=0.1)
    try:
        assert _transact(port, 0x01, 11) == (0x81, 11, b"\x01\x06")
        t, seq, payload = _transact(port, 0x04, 12, struct.pack("<6i", 0, 40000, 0, 0, 0, 0))
        assert (t, seq, payload) == (0xEE, 12, b"\x04")
        t, seq, payload = _transact(port, 0x02, 13)
        assert (t, seq, len(payload)) == (0x84, 13, 30)
        assert struct.unpack("<6iHI", payload)[6] & 1
        target = struct.pack("<6i", 100000, 40000, 1750, 0, 2430, 0)
        assert _transact(port, 0x04, 14, target)[:2] == (0x84, 14)
        assert _transact(port, 0x04, 15, struct.pack("<6i", 0, 10**7, 0, 0, 0, 0)) == (0xEE, 15, b"\x05")
        port.write(b"\x03\x04\x0f\x00")  # broken frame: ERROR 1 with seq 0
        assert _transact(port, 0x05, 16)[:2] == (0xEE, 0)
    finally:
        port.close()


def test_independent_client_in_process() -> None:
    emu = ActuatorEmulator(IdealArm(A_HOME), PARAMS)
    try:
        _independent_session(emu.serve_pty())
    finally:
        emu.stop()


def test_cli_emulator_subprocess_with_independent_client() -> None:
    exe = Path(sys.executable).parent / "wristmark"
    proc = subprocess.Popen([str(exe), "emulator", "--pty"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/")
        _independent_session(path)
    finally:
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=10)
    assert rc == 0
