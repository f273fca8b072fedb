"""The plant file's errors of the simulated true arm: :class:`PlantParams` lives in
models/plant_params.py (the identification's fit, solvers/identification.py, needs it below the
simulated bench); this module keeps its old import path."""

from __future__ import annotations

from wristmark.models.plant_params import PlantParams

__all__ = ["PlantParams"]
