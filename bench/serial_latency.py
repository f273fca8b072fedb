"""Benchmark: protocol-v1 round trip over a real pseudo-terminal (driver <-> emulator thread).

Prints one JSON object on stdout: median / p99 / max round trip [µs] for GET_STATE and
SET_TARGET through :class:`rig.link.actuator_driver.ActuatorDriver`, against the in-process
emulator serving the simulated true arm (configs/plant.yaml) on a pty.
Usage: .venv/bin/python bench/serial_latency.py [--calls 2000] [--ideal]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from wristmark.models.actuation import actuators_from_psi  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.robot_params import HOME_PSI, RobotParams  # noqa: E402
from wristmark.rig.link.actuator_driver import ActuatorDriver  # noqa: E402
from wristmark.sim.actuator_emulator import ActuatorEmulator  # noqa: E402
from wristmark.sim.plant import TruePlant  # noqa: E402
from wristmark.sim.plant_params import PlantParams  # noqa: E402


def _stats(samples: list[float]) -> dict[str, float]:
    us = np.array(samples) * 1e6
    return {"median_us": round(float(np.median(us)), 1), "p99_us": round(float(np.percentile(us, 99)), 1),
            "max_us": round(float(us.max()), 1), "calls": len(samples)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--ideal", action="store_true", help="ideal plant (no lag) instead of configs/plant.yaml")
    args = ap.parse_args()
    params = RobotParams()
    plant = PlantParams() if args.ideal else PlantParams.load(CONFIG_DIR / "plant.yaml")
    arm = TruePlant(params, plant, psi0=np.array(HOME_PSI))
    emu = ActuatorEmulator(arm, params)
    path = emu.serve_pty()
    a0 = actuators_from_psi(params, HOME_PSI)
    out: dict[str, object] = {"transport": "pty", "python": platform.python_version(), "plant": plant.__dict__}
    try:
        with ActuatorDriver(path, timeout=0.2, params=params) as drv:
            drv.ping()
            drv.enable()
            for name, call in (("get_state", drv.get_state),
                               ("set_target", lambda: drv.set_target(a0 + 1e-4 * np.sin(time.perf_counter())))):
                for _ in range(50):
                    call()
                samples = []
                for _ in range(args.calls):
                    t = time.perf_counter()
                    call()
                    samples.append(time.perf_counter() - t)
                out[name] = _stats(samples)
            out["driver_stats"] = dict(drv.stats)
    finally:
        emu.stop()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
