"""Writes the held-out plant files tests/data/heldout_plants/heldout_<i>.yaml: random but plausible arms
(gains, plane offsets, backlash, actuator lag, stem coupling, load, stiffness) that no controller
setting was tuned on. Ranges bracket configs/plant.yaml and configs/plant_unseen.yaml.

    .venv/bin/python bench/heldout_plants.py [--n 4] [--seed 2026] [--out DIR]

A new seed into a new folder gives arms nobody has looked at (the 2026 set was looked at while
the compensation was developed; docs/notes/motor-lag-burst.md reports a
validation set drawn with --seed 31).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from wristmark.cli.option_types import int_in, seed_int  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "heldout_plants"


def draw(rng: np.random.Generator) -> dict[str, list[float] | float]:
    """One arm's plant parameters (SI units, the plant-file keys)."""
    u = rng.uniform
    return {
        "bend_gain": [u(0.88, 1.10), u(0.85, 1.08)],
        "plane_offset": [u(-0.09, 0.09), u(-0.09, 0.09)],
        "stem_coupling": u(0.030, 0.050),
        "backlash": [u(0.003, 0.010), u(4e-5, 1.2e-4), *[u(2e-5, 1.1e-4) for _ in range(4)]],
        "actuator_tau": u(0.03, 0.09),
        "tip_force": [u(-0.06, 0.06), u(-0.06, 0.06), u(-0.10, 0.0)],
        "segment_stiffness": [u(0.30, 0.45), u(0.10, 0.18)],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int_in(1, 20), default=4)
    ap.add_argument("--seed", type=seed_int(), default=2026)
    ap.add_argument("--out", type=Path, default=OUT, help="folder for the plant files")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    for i in range(args.n):
        p = draw(rng)
        lines = [f"# Held-out arm {i} (bench/heldout_plants.py, seed {args.seed}): never used for tuning."]
        for k, v in p.items():
            val = "[" + ", ".join(f"{x:.6g}" for x in v) + "]" if isinstance(v, list) else f"{v:.6g}"
            lines.append(f"{k}: {val}")
        (args.out / f"heldout_{i}.yaml").write_text("\n".join(lines) + "\n")
        print(args.out / f"heldout_{i}.yaml")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
