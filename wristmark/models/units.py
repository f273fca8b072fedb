"""Unit constants shared by the layers: the actuator wire's resolution (DESIGN.md, the serial
protocol) is one micro-unit of the SI unit (1 urad, 1 um)."""

from __future__ import annotations

MICRO = 1e6  # micro-units per SI unit (urad per rad, um per m)
