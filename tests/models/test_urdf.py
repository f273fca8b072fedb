"""URDF generator: loads in Pinocchio, named frames present, link/joint counts, geometry."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wristmark.models.errors import ConfigError, InputError
from wristmark.models.marker import MarkerModel
from wristmark.models.robot_params import RobotParams
from wristmark.models.urdf import FRAME_NAMES, MATERIALS, chord_length, generate_urdf, write_urdf

PARAMS = RobotParams()


@pytest.mark.parametrize("n", [1, 3, 8])
def test_urdf_loads_with_frames_and_counts(n: int) -> None:
    text = generate_urdf(PARAMS, n)
    root = ET.fromstring(text)
    links = root.findall("link")
    joints = root.findall("joint")
    # per segment: plane, N link_k, tilted, N rings, end; plus incision, stem, seg1_base,
    # seg2_base, marker, tip
    assert len(links) == 2 * (2 * n + 3) + 6
    assert len(joints) == len(links) - 1
    kinds = [j.get("type") for j in joints]
    assert kinds.count("prismatic") == 2 * n + 1  # chords + d
    assert kinds.count("revolute") == 2 * (n + 3) + 1  # bends, plane in/out + phi
    assert kinds.count("fixed") == 3
    model = pin.buildModelFromXML(text)
    assert model.nq == model.nv == 4 * n + 8
    for name in (*FRAME_NAMES, "incision"):
        assert model.existFrame(name), name
    visual = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    # stem, N per segment, rigid link, {2e}->{wm} piece, sleeve, gripper body + 2 jaws
    assert visual.ngeoms == 2 * n + 7


def test_file_path_loader_and_write(tmp_path: Path) -> None:
    path = write_urdf(tmp_path / "arm.urdf", PARAMS, 2)
    model, collision, visual = pin.buildModelsFromUrdf(
        str(path), geometry_types=[pin.GeometryType.COLLISION, pin.GeometryType.VISUAL]
    )
    assert model.existFrame("tip") and visual.ngeoms > collision.ngeoms > 0
    assert path.read_text() == generate_urdf(PARAMS, 2)


def test_write_to_bad_path_is_one_line_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot write URDF"):
        write_urdf(tmp_path / "missing" / "arm.urdf", PARAMS)


@pytest.mark.parametrize("bad", [0, -1, 2.5, True, "8"])
def test_bad_link_count(bad: object) -> None:
    with pytest.raises(InputError, match="links per segment"):
        generate_urdf(PARAMS, bad)  # type: ignore[arg-type]


def test_invalid_params_are_rejected() -> None:
    with pytest.raises(ConfigError, match="segment_lengths"):
        generate_urdf(RobotParams(segment_lengths=(0.1, -0.02)))


def test_geometry_sizes_follow_params_and_marker() -> None:
    mk = MarkerModel(radius=0.006, row_height=0.003)
    root = ET.fromstring(generate_urdf(PARAMS, 4, mk))
    sleeve = root.find("link[@name='marker']/visual/geometry/cylinder")
    assert sleeve is not None
    assert float(sleeve.get("radius", "0")) == 0.006
    assert float(sleeve.get("length", "0")) == pytest.approx(0.006)
    link = root.find("link[@name='seg2_link_0']/visual/geometry/cylinder")
    assert link is not None
    assert float(link.get("radius", "0")) == PARAMS.outer_diameter / 2
    assert float(link.get("length", "0")) == pytest.approx(PARAMS.segment_lengths[1] / 4)
    tip = root.find("joint[@name='tip_mount']/origin")
    assert tip is not None and tip.get("xyz") == f"0.0 0.0 {PARAMS.tip_offset!r}"


def test_materials_are_distinct_and_used() -> None:
    root = ET.fromstring(generate_urdf(PARAMS, 2))
    colours = {m.get("name"): m.find("color").get("rgba") for m in root.findall("material")}  # type: ignore[union-attr]
    assert set(colours) == set(MATERIALS)
    assert len(set(colours.values())) == len(colours)
    used = {m.get("name") for m in root.iter("material") if m.find("color") is None}
    assert used == set(MATERIALS)


def test_chord_length_is_exact_and_smooth_at_zero() -> None:
    L, n = 0.1, 4
    assert chord_length(L, 0.0, n) == L / n
    th = 1.3
    assert chord_length(L, th, n) == pytest.approx(2 * L / th * math.sin(th / (2 * n)), rel=1e-15)
    # continuity across the series switch
    x = np.array([chord_length(L, t, n) for t in (8e-4 * (1 - 1e-9), 8e-4, 8e-4 * (1 + 1e-9))])
    assert np.all(np.abs(np.diff(x)) < 1e-15)
    assert chord_length(L, 1e-10, n) == pytest.approx(L / n, rel=1e-18)
