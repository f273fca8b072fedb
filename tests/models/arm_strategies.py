"""Hypothesis strategies for random format-2 robot files and configurations (tests only).

``robot_files()`` draws a plain mapping as a user would write it (1-4 segments, a random stem of
0-3 joints, every actuation type, planar or not); ``spec_of`` loads it through the YAML loader;
``psis(spec)`` draws configurations within the limits, with thetas at and near 0 (the series).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from hypothesis import strategies as st

from wristmark.models.arm_spec import ArmSpec, load_arm

TWO_PI = 2.0 * math.pi


@st.composite
def _stem(draw: st.DrawFn) -> list[dict[str, Any]]:
    kinds = draw(st.lists(st.sampled_from(["revolute_z", "prismatic_z"]), min_size=0, max_size=3))
    out = []
    for i, kind in enumerate(kinds):
        rng = [-math.pi, math.pi] if kind == "revolute_z" else [0.0, draw(st.floats(0.01, 0.2))]
        out.append({"joint": kind, "name": f"q{i}", "range": rng, "max_velocity": draw(st.floats(0.01, 2.0))})
    return out


@st.composite
def _actuation(draw: st.DrawFn, planar: float | None, radius: float) -> dict[str, Any]:
    kind = draw(st.sampled_from(["push_pull", "tendons", "direct"]))
    if kind == "direct":
        return {"type": "direct"}
    count = draw(st.integers(3 if kind == "tendons" else 2, 5))
    offset = draw(st.floats(0.0, TWO_PI))
    step = TWO_PI / count if count > 2 else math.pi / 2  # two backbones 90 deg apart, as the paper's
    angles = [offset + k * step + draw(st.floats(-0.2, 0.2)) for k in range(count)]
    if planar is not None and kind == "push_pull":
        angles[0] = -planar  # one backbone in the bending plane
    return {"type": kind, "pitch_radius": draw(st.floats(0.2, 1.0)) * radius, "angles": angles}


@st.composite
def robot_files(draw: st.DrawFn) -> dict[str, Any]:
    """A random, valid format-2 robot mapping."""
    outer = draw(st.floats(0.004, 0.010))
    segments = []
    for t in range(draw(st.integers(1, 4))):
        planar = draw(st.one_of(st.none(), st.floats(-math.pi, math.pi)))
        seg: dict[str, Any] = {"length": draw(st.floats(0.005, 0.12)), "theta_max": draw(st.floats(0.2, math.pi)),
                               "max_velocity": [1.0] if planar is not None else [1.0, 3.0],
                               "actuation": draw(_actuation(planar, outer / 2))}
        if t:
            seg["spacer"] = draw(st.sampled_from([0.0, 0.002, 0.01]))
        if planar is not None:
            seg["planar"] = planar
        segments.append(seg)
    return {"format": 2, "name": "random", "stem": draw(_stem()), "segments": segments,
            "marker_offset": draw(st.floats(0.0, 0.01)), "outer_diameter": outer}


def spec_of(data: dict[str, Any], folder: Path) -> ArmSpec:
    """Write ``data`` as a robot file in ``folder`` and load it."""
    path = folder / "random_arm.yaml"
    path.write_text(yaml.safe_dump(json.loads(json.dumps(data))))
    return load_arm(path)


def _theta(lo: float, hi: float) -> st.SearchStrategy[float]:
    special = [v for v in (0.0, 1e-10, -1e-10, 0.1, -0.1, 0.2, lo, hi) if lo <= v <= hi]
    return st.one_of(st.floats(lo, hi), st.sampled_from(special))


def psis(spec: ArmSpec) -> st.SearchStrategy[np.ndarray]:
    """Configurations of ``spec`` within its limits (delta in [-pi, pi])."""
    lo, hi = spec.bounds()
    parts = []
    thetas = set(spec.theta_index)
    for i, (a, b) in enumerate(zip(lo.tolist(), hi.tolist())):
        if i in thetas:
            parts.append(_theta(a, b))
        else:
            parts.append(st.floats(max(a, -math.pi), min(b, math.pi)))
    return st.tuples(*parts).map(np.array)
