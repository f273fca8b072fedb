"""The registration log: what ``wristmark register`` records and ``register --from-log DIR`` reads.

``DIR/registration_log.csv``, one row per visit, header::

    pose,approach,psi_cmd_0..psi_cmd_5,psi_meas_0..psi_meas_5,ok,rms_px,R_00..R_22,t_x,t_y,t_z,reason

pose: index of the chosen configuration; approach: -1 or +1 (the side it was approached from);
psi_cmd / psi_meas: commanded and encoder configuration [rad, m, rad, rad, rad, rad]. Any other arm
(a format-2 robot file) names them after its configuration, as the run log does
(models.arm_spec.log_psi_names): ``psi_cmd_d, psi_cmd_theta1, ..., psi_meas_d, ...`` (n each); ok: 1 when
the marker was tracked, then R (row-major) and t: the pose of {wm} in {ll} [m] and rms_px its
reprojection RMS [px]; otherwise empty fields and a reason. Any recorder of a lab run can write
this file (the marker pose from ``wristmark track``'s R and t, psi from the encoders).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from wristmark.models.errors import InputError
from wristmark.rig.registration.run import Observation

LOG_NAME = "registration_log.csv"


def log_header(psi_names: tuple[str, ...] | None = None) -> list[str]:
    """The log's columns; ``psi_names``: the names of psi's entries (None: the reference arm's
    ``psi_cmd_0..5``; models.arm_spec.log_psi_names gives an arm's)."""
    tags = [str(i) for i in range(6)] if psi_names is None else list(psi_names)
    return (["pose", "approach"] + [f"psi_cmd_{i}" for i in tags] + [f"psi_meas_{i}" for i in tags]
            + ["ok", "rms_px"] + [f"R_{i}{j}" for i in range(3) for j in range(3)] + ["t_x", "t_y", "t_z", "reason"])


HEADER = log_header()  # the reference arm's


def write_log(folder: str | Path, observations: list[Observation], psi_names: tuple[str, ...] | None = None) -> Path:
    """Write DIR/registration_log.csv (``psi_names``: as :func:`log_header`); returns its path."""
    path = Path(folder) / LOG_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    header = log_header(psi_names)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for o in observations:
            T = o.T_left_marker
            pose = [f"{v:.12g}" for v in np.r_[T[:3, :3].ravel(), T[:3, 3]]] if T is not None else [""] * 12
            w.writerow([o.pose, o.approach, *(f"{v:.12g}" for v in o.psi_cmd), *(f"{v:.12g}" for v in o.psi_meas),
                        int(o.ok), "" if math.isnan(o.rms_px) else f"{o.rms_px:.6g}", *pose, o.reason])
    return path


def _floats(row: dict[str, str], keys: list[str], where: str) -> np.ndarray:
    try:
        a = np.array([float(row[k]) for k in keys])
    except (KeyError, ValueError) as e:
        raise InputError(f"{where}: bad or missing value in {keys[0]}..{keys[-1]} ({e})") from None
    if not np.all(np.isfinite(a)):
        raise InputError(f"{where}: non-finite value in {keys[0]}..{keys[-1]}")
    return a


def read_log(folder: str | Path, psi_names: tuple[str, ...] | None = None) -> list[Observation]:
    """Read DIR/registration_log.csv (or the CSV file itself) of the arm whose psi entries are
    ``psi_names`` (as :func:`log_header`); InputError naming the row, or the columns when the log
    is of another arm."""
    path = Path(folder)
    path = path / LOG_NAME if path.is_dir() else path
    if not path.is_file():
        raise InputError(f"{path}: registration log not found (wristmark register --log DIR writes one)")
    out = []
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = log_header(psi_names)
        fields = list(reader.fieldnames or [])
        missing = [k for k in header if k not in fields]
        if missing:
            given = [k[len("psi_cmd_"):] for k in fields if k.startswith("psi_cmd_")]
            if given and "pose" in fields:  # a registration log, of another arm
                want = [k[len("psi_cmd_"):] for k in header if k.startswith("psi_cmd_")]
                raise InputError(f"{path}: the log's configuration ({', '.join(given)}) is not this arm's "
                                 f"({', '.join(want)}): pass the --robot it was recorded with")
            raise InputError(f"{path}: not a registration log (missing column '{missing[0]}')")
        tags = [k[len("psi_cmd_"):] for k in header if k.startswith("psi_cmd_")]
        for n, row in enumerate(reader, start=2):
            where = f"{path}:{n}"
            ok = row["ok"].strip() == "1"
            T = None
            if ok:
                T = np.eye(4)
                T[:3, :3] = _floats(row, [f"R_{i}{j}" for i in range(3) for j in range(3)], where).reshape(3, 3)
                T[:3, 3] = _floats(row, ["t_x", "t_y", "t_z"], where)
                if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5):
                    raise InputError(f"{where}: R is not a rotation")
            try:
                pose, side = int(row["pose"]), int(row["approach"])
            except ValueError:
                raise InputError(f"{where}: 'pose' and 'approach' must be integers") from None
            rms = float(row["rms_px"]) if row["rms_px"].strip() else float("nan")
            out.append(Observation(pose, side, _floats(row, [f"psi_cmd_{i}" for i in tags], where),
                                   _floats(row, [f"psi_meas_{i}" for i in tags], where), T, rms,
                                   row.get("reason", "")))
    return out
