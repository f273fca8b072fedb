"""Open-loop cube tracking on the simulated true arm: nominal IK commands, true tip vs desired.

Follows the paper's cube (IV.C) with IK commands sent every control cycle to a TruePlant and
prints JSON: mean/max/rms error [mm], IK reachability and the psi range used.

    .venv/bin/python bench/open_loop_plant.py [--plant configs/plant.yaml] [--dt 0.06]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from wristmark.models.actuation import actuators_from_psi  # noqa: E402
from wristmark.models.config_files import CONFIG_DIR
from wristmark.models.ik import solve_tip_ik  # noqa: E402
from wristmark.models.kinematics import tip_position  # noqa: E402
from wristmark.models.limits import within_limits  # noqa: E402
from wristmark.models.robot_params import HOME_PSI, RobotParams  # noqa: E402
from wristmark.rig.targets.trajectories import cube_trajectory  # noqa: E402
from wristmark.sim.plant import TruePlant  # noqa: E402
from wristmark.sim.plant_params import PlantParams  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def run(plant_path: Path, dt: float, size: tuple[float, float, float], speed: float) -> dict[str, object]:
    """Open-loop cube run; errors are |true tip - desired tip| at each cycle."""
    params = RobotParams.load(CONFIG_DIR / "robot.yaml")
    plant_params = PlantParams.load(plant_path)
    centre = tip_position(params, np.asarray(HOME_PSI))
    traj = cube_trajectory(centre, size, speed)
    q = solve_tip_ik(params, traj.sample(0.0)[0], np.asarray(HOME_PSI)).psi
    plant = TruePlant(params, plant_params, psi0=q)
    plant.advance(2.0)
    errs, qs, ik_ok = [], [], True
    for t in np.arange(0.0, traj.duration + 1e-9, dt):
        errs.append(float(np.linalg.norm(plant.true_tip() - traj.sample(float(t))[0])))
        res = solve_tip_ik(params, traj.sample(float(t) + dt)[0], q)
        ik_ok &= res.converged and within_limits(params, res.psi)
        q = res.psi
        qs.append(q)
        plant.command(actuators_from_psi(params, q))
        plant.advance(dt)
    e = np.asarray(errs) * 1e3
    Q = np.asarray(qs)
    return {
        "plant": str(plant_path),
        "control_dt_s": dt,
        "size_m": list(size),
        "speed_m_s": speed,
        "cycles": len(errs),
        "mean_mm": round(float(e.mean()), 3),
        "max_mm": round(float(e.max()), 3),
        "rms_mm": round(float(np.sqrt(np.mean(e**2))), 3),
        "paper_mm": {"mean": 3.25, "max": 8.40},
        "ik_all_converged_within_limits": bool(ik_ok),
        "psi_min": [round(float(v), 4) for v in Q.min(axis=0)],
        "psi_max": [round(float(v), 4) for v in Q.max(axis=0)],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plant", type=Path, default=CONFIG_DIR / "plant.yaml")
    ap.add_argument("--dt", type=float, default=0.06, help="control cycle [s]")
    ap.add_argument("--size", type=float, nargs=3, default=(0.040, 0.020, 0.040), help="edges x y z [m]")
    ap.add_argument("--speed", type=float, default=0.010, help="[m/s]")
    a = ap.parse_args()
    print(json.dumps(run(a.plant, a.dt, tuple(a.size), a.speed), indent=1))


if __name__ == "__main__":
    main()
