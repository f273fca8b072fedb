"""The driver's version negotiation: PING first; v1 (6 actuators) or v2 (n actuators, checked
against the host's arm); a mismatch is one line naming both counts and nothing is moved."""

from __future__ import annotations

import numpy as np
import pytest

from tests.rig.link.test_actuator_driver import ScriptedDevice
from wristmark.models.actuation import actuators_from_psi
from wristmark.models.arm_spec import home_psi, load_loop_arm
from wristmark.models.config_files import CONFIG_DIR, default_config
from wristmark.models.errors import ConfigError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.rig.link import protocol as P
from wristmark.rig.link.actuator_driver import (
    ActuatorDriver,
    ActuatorProtocolError,
    actuator_units,
    check_device_arm,
    check_protocol_arm,
)
from wristmark.rig.link.serial_link import SerialLink

MARKER = MarkerModel.load(default_config("marker.yaml"))
TENDON3 = load_loop_arm(CONFIG_DIR / "robots" / "tendon3.yaml", MARKER)


def _device(version: int, count: int) -> ScriptedDevice:
    """A device answering PONG (version, count) and STATE with ``count`` positions."""
    def script(req: P.Packet, n: int) -> bytes:
        if isinstance(req, P.Ping):
            return P.encode(P.Pong(version, count, seq=req.seq))
        pos = req.targets_micro if isinstance(req, P.SetTarget) else tuple(range(count))
        return P.encode(P.State(pos, P.FLAG_ENABLED, 5, seq=req.seq))

    dev = ScriptedDevice(script)
    dev._parser.set_count(count)  # before any byte arrives
    return dev


def test_a_v2_device_with_the_arms_count_speaks_v2_with_n_actuators() -> None:
    dev = _device(2, 10)
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, retries=0, params=TENDON3)
        assert drv.ping() == P.Pong(2, 10, seq=1) and (drv.version, drv.count) == (2, 10)
        st = drv.get_state()
        assert np.allclose(st.positions, np.arange(10) * 1e-6)
        a = actuators_from_psi(TENDON3, home_psi(TENDON3))
        st = drv.set_target(a)
        assert dev.requests[-1].targets_micro == P.micro_from_si(a, 10) and len(st.positions) == 10
        drv.close()
    finally:
        dev.close()


@pytest.mark.parametrize(("version", "count", "params", "words"), [
    (2, 6, TENDON3, r"protocol v2 with 6 actuators; this arm \(tendon3\) has 10"),
    (2, 12, RobotParams(), r"protocol v2 with 12 actuators; this arm has 6"),
    (1, 6, TENDON3, r"protocol v1 with 6 actuators; this arm \(tendon3\) has 10"),
    (1, 10, TENDON3, r"claims protocol v1 with 10 actuators; v1 carries exactly 6"),
    (3, 10, TENDON3, r"protocol v3 with 10 actuators; this host speaks v1 \(6 actuators\) and v2"),
])
def test_a_device_that_does_not_fit_the_arm_is_refused_in_one_line_and_nothing_moves(
        version: int, count: int, params: object, words: str) -> None:
    dev = _device(version, count)
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, retries=0, params=params)  # type: ignore[arg-type]
        link = SerialLink(drv)
        with pytest.raises(ActuatorProtocolError, match=words) as e:
            link.connect()
        assert "\n" not in str(e.value) and "nothing was moved" in str(e.value)
        assert [type(r) for r in dev.requests] == [P.Ping]  # no ENABLE, no SET_TARGET
        drv.close()
    finally:
        dev.close()


def test_a_v1_device_still_drives_the_paper_arm() -> None:
    dev = _device(1, 6)
    try:
        drv = ActuatorDriver(dev.path, timeout=1.0, retries=0)
        assert drv.ping().version == 1 and (drv.version, drv.count) == (1, 6)
        drv.close()
    finally:
        dev.close()


def test_check_device_arm_and_v1_check() -> None:
    check_device_arm(1, 6, RobotParams())
    check_device_arm(2, 6, RobotParams())
    check_device_arm(2, 10, TENDON3)
    check_protocol_arm(RobotParams())
    with pytest.raises(ConfigError, match="this arm has 10"):
        check_protocol_arm(TENDON3)


def test_actuator_units_per_arm() -> None:
    assert actuator_units(RobotParams()) == ("rad", "m", "m", "m", "m", "m")
    assert actuator_units(TENDON3) == ("m",) * 10
    for name in ("planar", "single_tendon", "paper"):
        arm = load_loop_arm(CONFIG_DIR / "robots" / f"{name}.yaml", MARKER)
        assert len(actuator_units(arm)) == len(actuators_from_psi(arm, home_psi(arm)))
