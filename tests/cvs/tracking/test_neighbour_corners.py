"""Which corners another arm's edges may reach (cvs.tracking.neighbour_corners): only corners near
another arm's outline, and nearer the camera there, or with a foreign edge in their window; the
check touches nothing when no other arm is near."""

from __future__ import annotations

import cv2
import numpy as np

from wristmark.cvs.tracking.neighbour_corners import Outline, foreign_edge, outlines, reached
from wristmark.sim.scene_setup import load_scene_setup

SETUP = load_scene_setup("scenes/two_arms.yaml")


def _box(u0: float, v0: float, u1: float, v1: float, depth: float) -> Outline:
    """A rectangular outline with its axis along u at one depth [m]."""
    hull = np.array([[[u0, v0]], [[u1, v0]], [[u1, v1]], [[u0, v1]]], np.float32)
    axis = np.column_stack([np.linspace(u0, u1, 5), np.full(5, (v0 + v1) / 2)])
    return Outline(hull, axis, np.full(5, depth))


FLAT = np.full((200, 300), 120, np.uint8)  # no edges anywhere: (b) never fires
OWN = _box(50, 50, 250, 150, 0.10)
CORNERS = np.array([[100.0, 60.0], [100.0, 100.0], [200.0, 146.0]])


def test_nothing_is_reached_without_a_neighbour_near() -> None:
    far = _box(50, 400, 250, 500, 0.05)  # nearer the camera but far below
    assert not reached(FLAT, CORNERS, OWN, [], 6.0, 0.3).any()
    assert not reached(FLAT, CORNERS, OWN, [far], 6.0, 0.3).any()


def test_a_corner_near_a_nearer_arms_outline_is_reached_not_one_near_a_farther_arm() -> None:
    below = (150.0, 250.0)  # an arm whose outline starts 4 px below the third corner
    nearer, farther = _box(150, below[0], 250, below[1], 0.05), _box(150, below[0], 250, below[1], 0.2)
    assert reached(FLAT, CORNERS, OWN, [nearer], 6.0, 0.3).tolist() == [False, False, True]
    assert not reached(FLAT, CORNERS, OWN, [farther], 6.0, 0.3).any()


def test_an_edge_beside_the_outline_is_foreign_one_inside_it_is_not() -> None:
    img = FLAT.copy()
    cv2.rectangle(img, (96, 30), (140, 46), 250, -1)  # a bright bar 4 px above the outline's top edge
    hit = np.array([[100.0, 52.0]])
    assert foreign_edge(img, hit[0], OWN.hull, 6.0, 0.3)
    assert reached(img, hit, OWN, [], 6.0, 0.3).tolist() == [True]
    assert not reached(img, np.array([[100.0, 100.0]]), OWN, [], 6.0, 0.3).any()  # deep inside: not tested


def test_outlines_of_several_arms_project_as_each_alone() -> None:
    marker = SETUP.markers[0]
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    T[:3, 3] = [0.0, 0.0, 0.09]
    T2 = T.copy()
    T2[:3, 3] = [0.02, 0.005, 0.1]
    both = outlines(SETUP.camera, marker, {"a": T, "b": T2}, -0.01, 0.02)
    for a, pose in (("a", T), ("b", T2)):
        alone = outlines(SETUP.camera, marker, {a: pose}, -0.01, 0.02)[a]
        for x, y in zip(both[a], alone):
            assert x is not None and y is not None
            assert np.array_equal(x.hull, y.hull) and np.array_equal(x.axis_px, y.axis_px)
    behind = T.copy()
    behind[:3, 3] = [0.0, 0.0, -0.05]
    assert outlines(SETUP.camera, marker, {"a": behind}, -0.01, 0.02)["a"] == [None, None]
