"""`wristmark servo --robot configs/robots/tendon3.yaml` through the emulator on a pty (the default
servo path, no --direct): protocol v2 with n = 10 on the wire, and the loop closes (closed-loop
error below the same cube walked open loop)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from wristmark.cli import servo as servo_cli
from wristmark.cli.main import main
from wristmark.models.config_files import CONFIG_DIR
from wristmark.rig.link import protocol as P
from wristmark.sim import servo_bench
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.setup import load_setup
from wristmark.sim.trajectory_run import run_trajectory

TENDON3 = CONFIG_DIR / "robots" / "tendon3.yaml"
DURATION_S = 3.0


class WireTap(ActuatorEmulator):
    """The real emulator, also keeping every byte it received and sent."""

    taps: list[WireTap] = []

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.rx = bytearray()
        self.tx = bytearray()
        WireTap.taps.append(self)

    def receive(self, data: bytes) -> bytes:
        out = super().receive(data)
        self.rx += data
        self.tx += out
        return out


@pytest.mark.slow
def test_servo_tendon3_through_the_pty_speaks_v2_with_10_actuators_and_closes_the_loop(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    WireTap.taps = []
    monkeypatch.setattr(servo_bench, "ActuatorEmulator", WireTap)
    rc = main(["servo", "--robot", str(TENDON3), "--sensor", "truth-noise", "--duration", str(DURATION_S),
               "--no-progress", "--json", str(tmp_path / "res.json")])
    assert rc == 0
    res = json.loads((tmp_path / "res.json").read_text())
    c = res["closed_loop"]
    assert res["link"]["kind"] == "emulator" and res["stopped"] == "" and res["safe_stop"]["held_and_disabled"]
    assert res["link"]["protocol"] == {"version": 2, "actuators": 10}

    (tap,) = WireTap.taps
    sent = P.StreamParser(count=10).feed(bytes(tap.rx))  # host -> device, decoded independently
    answered = P.StreamParser(count=10).feed(bytes(tap.tx))
    assert not [p for p in sent + answered if isinstance(p, P.ParseError)]
    assert isinstance(sent[0], P.Ping) and answered[0] == P.Pong(2, 10, seq=sent[0].seq)
    targets = [p for p in sent if isinstance(p, P.SetTarget)]
    states = [p for p in answered if isinstance(p, P.State)]
    assert len(targets) >= c["cycles"] and all(len(t.targets_micro) == 10 for t in targets)
    assert states and all(len(s.positions_micro) == 10 for s in states)
    v1 = P.StreamParser().feed(bytes(tap.rx))  # a v1 (6-actuator) device could not read one of them
    assert all(isinstance(p, P.ParseError) for p in v1 if not isinstance(p, P.Ping | P.GetState | P.Enable
                                                                          | P.Disable))

    setup = load_setup(robot=TENDON3)
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))
    traj = servo_cli.build_trajectory(setup, "cube", None, DURATION_S)
    open_loop = run_trajectory(setup, traj, closed_loop=False).summary
    assert c["cycles"] >= 40 and c["mean_mm"] < open_loop["mean_mm"]
