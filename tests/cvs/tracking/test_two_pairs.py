"""A coded sleeve whose views each show only two X-corners (path-traced, seen 35 deg from square,
dim): tracked from the two stereo pairs and the print's bars in every roll hypothesis
(cvs.tracking.two_pairs, MarkerTracker._retry_two_pairs), its roll read; refused where the
path is off or the code cells are blanked."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.cvs.tracking.pbr_pairs import load_pbr_pair
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.corners.detector import MarkerCornerDetector
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.stereo_match import StereoRectifier
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.cvs.tracking.two_pairs import axis_from_edges, stereo_chords
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel

MARKER = MarkerModel.load(default_config("marker_coded.yaml"))
CHORD_M = 2.0 * MARKER.radius * np.sin(0.5 * MARKER.beta)


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray, dict]:
    return load_pbr_pair("coded_two_corners")


@pytest.fixture(scope="module")
def camera():
    return load_calibration(str(default_config("camera.yaml")))


def _rot_deg(R_est: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R_true.T @ R_est) - 1) / 2, -1, 1))))


def test_the_pair_is_tracked_from_two_stereo_pairs_with_its_roll(pair, camera) -> None:
    left, right, truth = pair
    r = MarkerTracker(camera, MARKER).track(left, right)
    assert r.ok and r.roll_known and r.tip_left is not None and r.T_left_marker is not None, r.reason
    assert "two_pairs" in r.timings and r.match is not None and r.match.n_pairs == 2
    assert r.code is not None and r.code.ok and r.axis_source == "code"
    assert 1e3 * np.linalg.norm(r.tip_left - np.asarray(truth["tip_left"])) < 0.2
    assert _rot_deg(r.T_left_marker[:3, :3], np.asarray(truth["T_left_marker"])[:3, :3]) < 1.0
    assert r.ids_left is not None and sorted(r.ids_left.tolist()) == [10, 11]


def test_without_the_two_pair_path_the_pair_is_lost(pair, camera) -> None:
    left, right, _ = pair
    r = MarkerTracker(camera, MARKER, TrackerSettings(two_pairs_min_bars=0)).track(left, right)
    assert not r.ok and "two_pairs" not in r.timings


def test_each_view_shows_a_chain_of_two_on_the_sleeve_and_the_axis_is_seen(pair, camera) -> None:
    left, right, truth = pair
    det = MarkerCornerDetector()
    chords = stereo_chords(StereoRectifier(camera), det.chains_of_two(left), det.chains_of_two(right), CHORD_M, 2.5)
    T = np.asarray(truth["T_left_marker"])
    X = MARKER.corners()[[10, 11]] @ T[:3, :3].T + T[:3, 3]
    seen = (camera.project_left(X), camera.project_right(X))  # corners 10 and 11 in each view [px]
    on_sleeve = [c for c in chords
                 if np.abs(c.uv_left - seen[0]).max() < 1.5 and np.abs(c.uv_right - seen[1]).max() < 1.5]
    assert len(on_sleeve) == 1
    axis = axis_from_edges(camera, on_sleeve[0], MARKER)
    assert axis is not None and np.degrees(np.arccos(min(1.0, abs(float(axis @ T[:3, 2]))))) < 15.0


def test_with_the_code_cells_blanked_the_two_pair_path_keeps_nothing(pair, camera) -> None:
    """The roll comes from the code cells' bars and the code: without them no hypothesis wins."""
    left, right, truth = pair
    T = np.asarray(truth["T_left_marker"])
    views = []
    for img, project in ((left, camera.project_left), (right, camera.project_right)):
        out = img.copy()
        for z0 in (MARKER.row_height + 2e-4, -MARKER.z_extent[1]):  # the bands above and below the checker rows
            a = np.linspace(0, 2 * np.pi, 90)
            for zz in np.linspace(z0, z0 + MARKER.z_extent[1] - MARKER.row_height - 2e-4, 12):
                P = np.column_stack([MARKER.radius * np.cos(a), MARKER.radius * np.sin(a), np.full_like(a, zz)])
                X = P @ T[:3, :3].T + T[:3, 3]
                normal = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)]) @ T[:3, :3].T
                X = X[np.einsum("ij,ij->i", normal, -X) > 0]  # the side facing the left camera only
                uv = np.rint(project(X)).astype(int)
                for u, v in uv:
                    out[v - 2:v + 3, u - 2:u + 3] = int(np.median(img[v - 6:v + 7, u - 6:u + 7]))
        views.append(out)
    det = MarkerCornerDetector()
    chords = stereo_chords(StereoRectifier(camera), det.chains_of_two(views[0]), det.chains_of_two(views[1]),
                           CHORD_M, 2.5)
    assert len(chords) >= 1  # the two corners are still there
    r = MarkerTracker(camera, MARKER).track(views[0], views[1])
    assert not r.ok and "two_pairs" in r.timings
    # a lost pair's time is the whole call's, its last try (the two-pair path) and the searches before it
    assert r.time_ms >= r.timings["detect"] + r.timings["two_pairs"], (r.time_ms, r.timings)


def test_bad_two_pair_settings_are_refused() -> None:
    with pytest.raises(InputError, match="two_pairs_min_bars"):
        TrackerSettings(two_pairs_min_bars=-1)
    with pytest.raises(InputError, match="two_pairs_margin"):
        TrackerSettings(two_pairs_margin=float("nan"))
    assert replace(TrackerSettings(), two_pairs_margin=1.0).two_pairs_margin == 1.0
