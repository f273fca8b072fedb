"""ActuatorDriver against scripted devices on a pty: resend on corruption, late replies, decoding."""

from __future__ import annotations

import os
import select
import threading
import tty

import numpy as np
import pytest

from wristmark.models.actuation import actuators_from_psi
from wristmark.models.robot_params import HOME_PSI, RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorProtocolError, DeviceState


class ScriptedDevice:
    """Answers each request frame with ``script(request) -> bytes`` on a raw pty."""

    def __init__(self, script) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.script = script
        self.requests: list[P.Packet] = []
        self._parser = P.StreamParser()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def path(self) -> str:
        return os.ttyname(self.slave)

    def _run(self) -> None:
        # never a blocking read: close() joins this thread before it closes the fds, whose numbers
        # the next test's pty reuses (a read still pending on the old number then stole and answered
        # the next emulator's requests: "expected PONG, got State" in test_actuator_emulator)
        while not self._stop.is_set():
            if not select.select([self.master], [], [], 0.02)[0]:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            for item in self._parser.feed(data):
                if not isinstance(item, P.ParseError):
                    self.requests.append(item)
                    os.write(self.master, self.script(item, len(self.requests)))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        assert not self._thread.is_alive(), "the scripted device's reader did not stop"
        os.close(self.slave)
        os.close(self.master)


def _state(seq: int, flags: int = P.FLAG_ENABLED) -> bytes:
    return P.encode(P.State((1000, 2000, -3, 0, 4, 5), flags, 77, seq=seq))


def test_resends_at_once_when_device_reports_corruption() -> None:
    def script(req: P.Packet, n: int) -> bytes:
        return P.encode(P.Error(P.ERR_BAD_CRC, seq=0)) if n == 1 else _state(req.seq)

    dev = ScriptedDevice(script)
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, retries=2)
        st = drv.get_state()
        assert len(dev.requests) == 2 and dev.requests[0].seq != dev.requests[1].seq
        assert drv.stats["retries"] == 1
        assert np.allclose(st.positions, [1e-3, 2e-3, -3e-6, 0, 4e-6, 5e-6])
        assert st.enabled and not st.estopped and st.clock_ms == 77
        drv.close()
    finally:
        dev.close()


def test_stale_replies_are_skipped_and_wrong_type_is_a_protocol_error() -> None:
    def script(req: P.Packet, n: int) -> bytes:
        stale = _state((req.seq - 1) % 256, flags=P.FLAG_ESTOPPED)
        if isinstance(req, P.Ping):
            return stale + P.encode(P.Pong(3, 6, seq=req.seq))  # v2 with 6 now fits a 6-actuator arm: v3 does not
        return stale + P.encode(P.Pong(1, 6, seq=req.seq))

    dev = ScriptedDevice(script)
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, retries=0)
        with pytest.raises(ActuatorProtocolError, match="v3"):
            drv.ping()
        with pytest.raises(ActuatorProtocolError, match="expected STATE"):
            drv.get_state()
        assert drv.stats["dropped"] == 2
        drv.close()
    finally:
        dev.close()


def test_device_state_flags() -> None:
    s = DeviceState.from_packet(P.State((0,) * 6, P.FLAG_WATCHDOG | P.FLAG_REJECTED | P.FLAG_FAULT, 1500))
    assert (s.enabled, s.estopped, s.watchdog_tripped, s.target_rejected, s.fault) == (False, False, True, True, True)
    assert s.clock_s == 1.5


def test_set_psi_sends_the_actuation_map() -> None:
    params = RobotParams()
    dev = ScriptedDevice(lambda req, n: _state(req.seq))
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, params=params)
        drv.set_psi(HOME_PSI)
        sent = dev.requests[-1]
        assert isinstance(sent, P.SetTarget)
        assert sent.targets_micro == P.micro_from_si(actuators_from_psi(params, HOME_PSI))
        drv.close()
    finally:
        dev.close()


def test_a_device_end_closing_between_write_and_flush_is_a_disconnect() -> None:
    """pyserial's flush (tcdrain) on a pty whose other end has gone raises termios.error, which
    is no OSError: it must still become the typed disconnect (servo then stops safely, exit 3),
    not an internal error."""
    import termios

    from wristmark.rig.link.actuator_driver import ActuatorDisconnected

    dev = ScriptedDevice(lambda req, n: _state(req.seq))
    try:
        drv = ActuatorDriver(dev.path, timeout=0.05, retries=0)
        assert drv.get_state().enabled  # the pty answers

        def gone() -> None:
            raise termios.error(5, "Input/output error")

        assert drv._port is not None
        drv._port.flush = gone  # type: ignore[method-assign]
        with pytest.raises(ActuatorDisconnected, match="failed on write"):
            drv.get_state()
        assert not drv.is_open
    finally:
        dev.close()
