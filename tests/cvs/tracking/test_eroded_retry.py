"""A sleeve close to the lens whose white squares clip over its corners: the views searched
eroded, the corners fitted with the clipping (MarkerTracker._retry_eroded,
cvs.tracking.corner_refit.refit_corners_clipped)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tests.cvs.tracking.pbr_pairs import load_pbr_pair
from wristmark.cvs.calibration.load import load_calibration
from wristmark.cvs.tracking.settings import TrackerSettings
from wristmark.cvs.tracking.tracker import MarkerTracker
from wristmark.models.config_files import default_config
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray, dict]:
    return load_pbr_pair("coded_clipped")


def test_the_clipped_sleeve_is_tracked_from_its_eroded_views_and_its_roll_read(pair) -> None:
    """Path-traced seed 303 pair 55: every other search finds no marker. Eroded, the views give
    4 stereo pairs; fitted with the clipping, the corners are 0.02-0.48 px off the truth and the
    tip 0.11 mm (the eroded corners alone: 0.2-0.8 px)."""
    left, right, truth = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    tracker = MarkerTracker(cam, marker, TrackerSettings(reduced_scales=()))  # the reduced search comes first
    r = tracker.track(left, right)
    assert r.ok and r.tip_left is not None and r.T_left_marker is not None, r.reason
    assert "eroded" in r.timings and "eroded_refit" in r.timings
    assert r.roll_known
    assert 1e3 * np.linalg.norm(r.tip_left - np.asarray(truth["tip_left"])) < 0.2
    T = np.asarray(truth["T_left_marker"])
    C = marker.corners() @ T[:3, :3].T + T[:3, 3]
    for uv, project in ((r.corners_left, cam.project_left), (r.corners_right, cam.project_right)):
        off = [float(np.min(np.linalg.norm(project(C) - c, axis=1))) for c in uv]
        assert len(off) >= 3 and max(off) < 0.6, off
    R_err = T[:3, :3].T @ r.T_left_marker[:3, :3]
    assert np.degrees(np.arccos(np.clip((np.trace(R_err) - 1) / 2, -1, 1))) < 1.5


def test_the_size_that_worked_is_tried_first_on_the_next_pair(pair, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sizes tried largest first: the first pair erodes each view at 11, 9 and 7 px (7 tracks
    it), the next pair at 7 px alone."""
    left, right, _ = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    tracker = MarkerTracker(cam, marker, TrackerSettings(eroded_sizes=(11, 9, 7, 5, 3), reduced_scales=()))
    sizes: list[int] = []
    real_erode = cv2.erode

    def erode(img: np.ndarray, kernel: np.ndarray, *args: object, **kwargs: object) -> np.ndarray:
        sizes.append(int(kernel.shape[0]))
        return real_erode(img, kernel, *args, **kwargs)

    monkeypatch.setattr(cv2, "erode", erode)
    assert tracker.track(left, right).ok
    assert sizes == [11, 11, 9, 9, 7, 7], sizes
    sizes.clear()
    assert tracker.track(left, right).ok
    assert sizes == [7, 7], sizes


def test_without_the_eroded_search_the_pair_is_lost(pair) -> None:
    left, right, _ = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    r = MarkerTracker(cam, marker, TrackerSettings(eroded_sizes=(), reduced_scales=())).track(left, right)
    assert not r.ok and r.reason.startswith("no marker found") and "eroded" not in r.timings


def test_the_reduced_search_tracks_the_clipped_sleeve_first(pair) -> None:
    """The search of the views reduced (MarkerTracker._retry_reduced), cheaper, runs before the
    eroded one and tracks this pair as accurately (0.11 mm): the eroded search does not run."""
    left, right, truth = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    r = MarkerTracker(cam, marker).track(left, right)
    assert r.ok and r.tip_left is not None, r.reason
    assert "eroded" not in r.timings and "reduced_refit" in r.timings
    assert 1e3 * np.linalg.norm(r.tip_left - np.asarray(truth["tip_left"])) < 0.2


def test_unclipped_views_are_not_searched_eroded(pair) -> None:
    """Where a view has fewer than eroded_min_clipped_px clipped pixels, a lost pair is not
    searched eroded (the reduced search, which would track it, off)."""
    left, right, _ = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    dim = [(v.astype(np.float32) * 0.9).astype(np.uint8) for v in (left, right)]
    r = MarkerTracker(cam, marker, TrackerSettings(reduced_scales=())).track(dim[0], dim[1])
    assert not r.ok and "eroded" not in r.timings


def test_eroded_sizes_given_as_a_list_are_kept_as_a_tuple() -> None:
    settings = TrackerSettings(eroded_sizes=[5, 3])  # type: ignore[arg-type]
    assert settings.eroded_sizes == (5, 3) and hash(settings) == hash(TrackerSettings(eroded_sizes=(5, 3)))


@pytest.mark.parametrize("bad", [{"eroded_sizes": (1,)}, {"eroded_sizes": (3.5,)}, {"eroded_min_clipped_px": -1}])
def test_bad_eroded_settings_are_refused(bad) -> None:
    with pytest.raises(InputError):
        TrackerSettings(**bad)


def test_one_view_that_does_not_clip_is_enough_to_skip_the_eroded_search(pair) -> None:
    left, right, _ = pair
    cam = load_calibration(str(default_config("camera.yaml")))
    marker = MarkerModel.load(default_config("marker_coded.yaml"))
    r = MarkerTracker(cam, marker).track(np.full_like(left, 90), right)
    assert not r.ok and "eroded" not in r.timings
