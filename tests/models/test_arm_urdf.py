"""models.arm_urdf and models.arm_pinocchio: any arm's pseudo-rigid URDF through Pinocchio equals
the closed form (models.arm_kinematics) to 1e-9 for every number of links."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from functools import cache

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.models.arm_strategies import psis
from wristmark.models.arm_kinematics import arm_frames, arm_tip_jacobian
from wristmark.models.arm_pinocchio import PinocchioAnyArm
from wristmark.models.arm_spec import ArmSpec, load_arm, shipped_robot_files
from wristmark.models.arm_urdf import arm_frame_names, generate_arm_urdf
from wristmark.models.errors import ConfigError, InputError
from wristmark.models.pinocchio_model import PinocchioArm
from wristmark.models.robot_params import HOME_PSI, RobotParams

ROBOTS = {p.name: load_arm(p) for p in shipped_robot_files()}
SEEDED = settings(max_examples=25, derandomize=True, deadline=None)
LINKS = [1, 3, 8]


@cache
def model(name: str, links: int) -> PinocchioAnyArm:
    return PinocchioAnyArm(ROBOTS[name], links)


def _assert_same(spec: ArmSpec, arm: PinocchioAnyArm, psi: np.ndarray, atol: float = 1e-9) -> None:
    got, ref = arm.forward(psi), arm_frames(spec, psi)
    for name in ("T_world_base", "T_world_end", "T_world_marker", "T_world_tip"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=0, atol=atol)  # [m], rotations
    np.testing.assert_allclose(arm.tip_jacobian(psi), arm_tip_jacobian(spec, psi), rtol=0, atol=atol)


@pytest.mark.parametrize("links", LINKS)
@pytest.mark.parametrize("name", sorted(ROBOTS))
@SEEDED
@given(data=st.data())
def test_shipped_arms_agree_with_the_closed_form(name: str, links: int, data: st.DataObject) -> None:
    spec = ROBOTS[name]
    _assert_same(spec, model(name, links), data.draw(psis(spec)))


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_dq_dpsi_vs_central_differences(name: str) -> None:
    arm, spec = model(name, 3), ROBOTS[name]
    rng = np.random.default_rng(5)
    lo, hi = spec.bounds()
    for psi in rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), (5, spec.n)):
        h = 1e-6
        D = arm.dq_dpsi(psi)
        fd = np.column_stack([(arm.q_from_psi(psi + h * e) - arm.q_from_psi(psi - h * e)) / (2 * h)
                              for e in np.eye(spec.n)])
        np.testing.assert_allclose(D, fd, rtol=0, atol=1e-9)


def test_the_paper_arm_is_todays_pinocchio_model() -> None:
    ours, today = model("paper.yaml", 4), PinocchioArm(RobotParams(), 4)
    for psi in (HOME_PSI, (0.3, 0.1, 1.2, -2.0, 0.0, 0.5)):
        a, b = ours.forward(psi), today.forward(psi)
        np.testing.assert_allclose(a.T_world_tip, b.T_world_tip, rtol=0, atol=1e-15)
        np.testing.assert_allclose(a.T_world_base[1], b.T_world_2b, rtol=0, atol=1e-15)
        np.testing.assert_allclose(ours.tip_jacobian(psi), today.tip_jacobian(psi), rtol=0, atol=1e-15)
    assert ours.model.nq == today.model.nq


def test_structure_of_a_planar_arm() -> None:
    root = ET.fromstring(generate_arm_urdf(ROBOTS["planar.yaml"], 2))
    kinds = {j.get("name"): j.get("type") for j in root.findall("joint")}
    assert kinds["seg1_plane_in"] == kinds["seg2_plane_out"] == "fixed"
    assert kinds["phi"] == "revolute" and kinds["d"] == "prismatic"
    rpy = root.find("joint[@name='seg2_plane_out']/origin")
    assert rpy is not None and float(rpy.get("rpy", "").split()[2]) == pytest.approx(math.pi / 2)
    lim = root.find("joint[@name='seg1_bend_1']/limit")
    assert lim is not None and float(lim.get("lower", "0")) == -float(lim.get("upper", "0")) < 0
    assert model("planar.yaml", 2).model.nq == 2 + 2 * (2 * 2 + 1)


def test_four_segments_and_no_stem() -> None:
    tendon3 = ROBOTS["tendon3.yaml"]
    spec = replace(tendon3, stem=(), segments=(*tendon3.segments, replace(tendon3.segments[2], planar=0.5,
                                                                           max_velocity=(1.0,))))
    spec.validate()
    arm = PinocchioAnyArm(spec, 2)
    assert arm.frame_names == arm_frame_names(spec) and arm.frame_names[-4:] == ("seg4_base", "seg4_end",
                                                                                  "marker", "tip")
    assert "stem_mount" in [str(n) for n in arm.model.names] or arm.model.existFrame("stem_mount")
    rng = np.random.default_rng(7)
    for psi in rng.uniform(-1.5, 1.5, (10, spec.n)):
        psi[[0, 2, 4]] = np.abs(psi[[0, 2, 4]])
        _assert_same(spec, arm, psi)
    materials = {m.get("name") for m in ET.fromstring(arm.urdf).findall("material")}
    assert {"segment1", "segment2", "segment3", "segment4"} <= materials


def test_the_sleeve_sits_on_the_marker_frame() -> None:
    arm, spec = model("tendon3.yaml", 3), ROBOTS["tendon3.yaml"]
    psi = np.array([0.05, 0.7, 0.2, 0.9, -1.0, 1.1, 2.0])
    vdata = pin.GeometryData(arm.visual_model)
    pin.updateGeometryPlacements(arm.model, arm.data, arm.visual_model, vdata, arm.q_from_psi(psi))
    gid = arm.visual_model.getGeometryId("marker_0")
    np.testing.assert_allclose(vdata.oMg[gid].translation, arm_frames(spec, psi).T_world_marker[:3, 3], atol=1e-12)
    np.testing.assert_allclose(arm.frame_pose("tip", psi), arm_frames(spec, psi).T_world_tip, atol=1e-12)


def test_errors() -> None:
    with pytest.raises(InputError, match="links per segment"):
        generate_arm_urdf(ROBOTS["paper.yaml"], 0)
    with pytest.raises(ConfigError, match="segments\\[0\\].length"):
        generate_arm_urdf(replace(ROBOTS["paper.yaml"], segments=(replace(ROBOTS["paper.yaml"].segments[0],
                                                                          length=-1.0),)))
    with pytest.raises(InputError, match="unknown frame 'wrist'"):
        model("paper.yaml", 1).frame_pose("wrist", HOME_PSI)
    with pytest.raises(InputError, match="finite"):
        model("paper.yaml", 1).tip_jacobian([0, 0, math.nan, 0, 0, 0])
