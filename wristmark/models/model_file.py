"""The identified-arm file (``wristmark identify --out MODEL.yaml``, read by ``--model``): the
plant file's keys with the fitted values, plus ``rms_m`` (the fit's tip residual [m]), ``poses``
(the measured tips it used) and the fit's report (``std_errors`` per parameter, ``not_separable``,
``excitation_s``, and with ``--register-out`` the ``registration`` file the model is fitted in),
which :func:`load_model` reads past (docs/identification.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from wristmark.models.config_io import from_mapping, load_yaml, save_yaml, to_mapping
from wristmark.models.errors import ConfigError
from wristmark.models.plant_params import PlantParams

__all__ = ["REPORT_KEYS", "load_model", "save_model"]

REPORT_KEYS = ("rms_m", "poses", "std_errors", "not_separable", "excitation_s", "lag_per_actuator",
               "registration")


def save_model(path: str | Path, plant: PlantParams, report: dict[str, Any]) -> None:
    """Write ``plant`` (the plant-file keys, SI units) and the fit's ``report`` (REPORT_KEYS)."""
    extra = sorted(set(report) - set(REPORT_KEYS))
    if extra:
        raise ConfigError(f"model file: unknown report keys {extra}")
    data = to_mapping(plant)
    save_yaml(path, {**data, **{k: report[k] for k in REPORT_KEYS if k in report}})


def load_model(path: str | Path) -> PlantParams:
    """The identified plant of a model file (validated as a plant file; the report keys skipped)."""
    raw = load_yaml(path)
    data = {k: v for k, v in raw.items() if k not in REPORT_KEYS}
    if "rms_m" not in raw:
        raise ConfigError(f"{path}: not a model file from 'wristmark identify' (no 'rms_m'); a plant file is "
                          "--plant's")
    return from_mapping(PlantParams, data, str(path))
