"""What publishing on ROS 2 costs the servo loop (#30: at most 1 ms a cycle): one in-process run
of the simulated bench (its emulator on a pty, unpaced: the loop runs as fast as the host lets it,
so a cycle's wall time is its host time), publishing measured_cp / measured_js / setpoint_js
(rig/ros2/bridge.py) in alternate blocks of --block cycles, with a subscriber in another
process on loopback (the loopback configuration set here). Prints one JSON document: the median
host time of a cycle with publishing on and off (the first cycle of each block left out), their
difference, and the loop thread's median time in the bridge's hook [ms].

    .venv/bin/python bench/ros2_overhead.py [--duration 20] [--block 10] [--link emulator|direct]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
READER = """
import os, signal, sys, time
signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from wristmark.rig.ros2.messages import JointState, PoseStamped, topic_name
dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
ns = os.environ["NS"]
qos = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(64))
readers = [DataReader(dp, Topic(dp, topic_name(ns + "/" + n), c), qos) for n, c in
           (("measured_cp", PoseStamped), ("measured_js", JointState), ("setpoint_js", JointState))]
n = 0
t_end = time.monotonic() + float(os.environ["LIFE_S"])
try:
    while time.monotonic() < t_end:
        for r in readers:
            n += len(r.take(N=64))
        time.sleep(0.01)
finally:
    print(n, flush=True)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=20.0, help="trajectory time [s] (simulated)")
    ap.add_argument("--block", type=int, default=10, help="cycles per on / off block")
    ap.add_argument("--link", choices=("emulator", "direct"), default="emulator")
    args = ap.parse_args()
    from wristmark.rig.ros2.dds_config import LOOPBACK_CONFIG

    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # benchmarks: always the loopback configuration
    os.environ["ROS_DOMAIN_ID"] = str(random.randint(100, 199))
    ns = f"wm_bench_{os.getpid()}"
    from wristmark.cli import servo as S
    from wristmark.rig.ros2.bridge import Ros2Bridge
    from wristmark.sim.servo_bench import open_sim_session
    from wristmark.sim.setup import load_setup

    setup = load_setup()
    setup = setup.with_changes(rig=dataclasses.replace(setup.rig, sensor="truth-noise"))
    traj = S.build_trajectory(setup, "cube", None, args.duration)
    psi0 = S.start_configuration(setup, traj)
    reader = subprocess.Popen([sys.executable, "-c", READER], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(ROOT), "NS": ns,
                                   "LIFE_S": str(60 + 2 * args.duration)})
    bridge = Ros2Bridge(ns, setup.params)
    time.sleep(1.0)  # discovery
    session = open_sim_session(setup, psi0, S.LinkOptions(kind=args.link))
    stamps: list[tuple[float, bool]] = []

    def hook(rec: object) -> None:
        k = len(stamps)
        on = (k // args.block) % 2 == 0
        if on:
            bridge.on_cycle(rec, session.link)  # type: ignore[arg-type]
        stamps.append((time.perf_counter(), on))

    out = S.run_servo(setup, traj, session, psi0, settle=0.3, on_cycle=hook)
    time.sleep(0.5)
    bridge.close()
    reader.terminate()
    received = reader.communicate(timeout=10)[0].strip()
    t = np.array([s[0] for s in stamps])
    on = np.array([s[1] for s in stamps])
    dt_ms = 1000.0 * np.diff(t)
    same = on[1:] == on[:-1]  # the cycle ended in the same block it began (first of a block left out)
    cyc_on, cyc_off = dt_ms[same & on[1:]], dt_ms[same & ~on[1:]]
    hook_ms = 1000.0 * np.asarray(bridge.hook_s)
    print(json.dumps({
        "link": args.link, "cycles": int(len(t)), "stopped": out.stopped,
        "cycle_host_ms": {"on_median": float(np.median(cyc_on)), "off_median": float(np.median(cyc_off)),
                          "extra_median": float(np.median(cyc_on) - np.median(cyc_off)),
                          "on_p90": float(np.percentile(cyc_on, 90)), "off_p90": float(np.percentile(cyc_off, 90)),
                          "n_on": int(cyc_on.size), "n_off": int(cyc_off.size)},
        "hook_ms": {"median": float(np.median(hook_ms)), "p99": float(np.percentile(hook_ms, 99)),
                    "max": float(hook_ms.max())},
        "published": bridge.published, "replaced": bridge.skipped,
        "received_by_subscriber": int(received) if received.isdigit() else received,
    }, indent=1))


if __name__ == "__main__":
    main()
