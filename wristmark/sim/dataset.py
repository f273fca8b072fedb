"""The stereo dataset folder of docs/design.md: calib.yaml, marker.yaml, pair_NN_left.png,
pair_NN_right.png and truth.json (pose of {wm} and tip in the left camera frame, metres;
corners in raw pixels with cos_view)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.calibration.load import load_calibration, save_calibration
from wristmark.cvs.camera import StereoCamera
from wristmark.models.config_io import save_yaml, to_mapping
from wristmark.models.errors import InputError
from wristmark.models.marker import MarkerModel
from wristmark.sim.render.stereo_renderer import CornerTruth, RenderedPair, RenderedScene

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PairTruth:
    """Ground truth of one pair: R, t of {wm} in {ll} [m], tip in {ll} [m], corners per camera."""

    pair: int
    R: Array
    t: Array
    tip: Array
    corners_left: tuple[CornerTruth, ...]
    corners_right: tuple[CornerTruth, ...]


@dataclass(frozen=True)
class StereoDataset:
    """A loaded dataset: calibration, marker, image paths per pair and truth."""

    root: Path
    camera: StereoCamera
    marker: MarkerModel
    pairs: tuple[tuple[Path, Path], ...]
    truth: tuple[PairTruth, ...]


def pair_paths(root: str | Path, n: int) -> tuple[Path, Path]:
    """Paths of pair ``n``'s left and right PNG images."""
    r = Path(root)
    return r / f"pair_{n:02d}_left.png", r / f"pair_{n:02d}_right.png"


def _corners_json(cs: tuple[CornerTruth, ...], occluded: bool = False) -> list[dict[str, Any]]:
    """Corners as truth.json objects (``occluded``: with each corner's flag, for scenes)."""
    return [{"index": c.index, "uv": [c.uv[0], c.uv[1]], "cos_view": c.cos_view}
            | ({"occluded": bool(c.occluded)} if occluded else {}) for c in cs]


def truth_entry(n: int, frame: RenderedPair) -> dict[str, Any]:
    """The truth.json object of pair ``n`` (docs/design.md)."""
    return {
        "pair": n,
        "R": frame.T_left_marker[:3, :3].tolist(),
        "t": frame.T_left_marker[:3, 3].tolist(),
        "tip": np.asarray(frame.tip_left, float).tolist(),
        "corners_left": _corners_json(frame.corners_left),
        "corners_right": _corners_json(frame.corners_right),
    }


def scene_truth_entry(n: int, scene: RenderedScene, names: list[str]) -> dict[str, Any]:
    """The truth.json object of pair ``n`` of a scene (several arms): per arm, in the order of
    ``names``, the fields of :func:`truth_entry` and each corner's ``occluded`` (another arm
    hides it)."""
    arms = {}
    for name, a in zip(names, scene.arms):
        arms[name] = {"R": a.T_left_marker[:3, :3].tolist(), "t": a.T_left_marker[:3, 3].tolist(),
                      "tip": np.asarray(a.tip_left, float).tolist(),
                      "corners_left": _corners_json(a.corners_left, True),
                      "corners_right": _corners_json(a.corners_right, True)}
    return {"pair": n, "arms": arms}


def write_pair_images(root: Path, n: int, left: NDArray[np.uint8], right: NDArray[np.uint8]) -> None:
    """Write pair ``n``'s two images (InputError naming a path that cannot be written)."""
    for path, img in zip(pair_paths(root, n), (left, right)):
        if not cv2.imwrite(str(path), img):
            raise InputError(f"{path}: could not write the image (check the folder)")


class DatasetWriter:
    """Writes a stereo dataset folder pair by pair; truth.json is rewritten after each pair."""

    def __init__(self, root: str | Path, camera: StereoCamera, marker: MarkerModel) -> None:
        self.root = Path(root)
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise InputError(f"{self.root}: cannot create the dataset folder ({e.strerror})") from e
        save_calibration(self.root / "calib.yaml", camera)
        mk = {k: v for k, v in to_mapping(marker).items() if v not in (None, [], ())}  # a plain sleeve: 4 keys
        save_yaml(self.root / "marker.yaml", mk)
        self.entries: list[dict[str, Any]] = []

    def add(self, frame: RenderedPair) -> int:
        """Write the next pair's images and truth; returns its index NN."""
        n = len(self.entries)
        write_pair_images(self.root, n, frame.left, frame.right)
        self.entries.append(truth_entry(n, frame))
        (self.root / "truth.json").write_text(json.dumps(self.entries, indent=1))
        return n


def _corners(data: Any, src: str) -> tuple[CornerTruth, ...]:
    return tuple(
        CornerTruth(int(c["index"]), (float(c["uv"][0]), float(c["uv"][1])), float(c["cos_view"])) for c in data
    )


def load_dataset(root: str | Path) -> StereoDataset:
    """Read a dataset folder; raise InputError/ConfigError naming the missing or bad file."""
    r = Path(root)
    if not r.is_dir():
        raise InputError(f"{r}: dataset folder not found")
    camera = load_calibration(r / "calib.yaml")
    marker = MarkerModel.load(r / "marker.yaml")
    tpath = r / "truth.json"
    if not tpath.is_file():
        raise InputError(f"{tpath}: file not found")
    try:
        raw = json.loads(tpath.read_text())
        truth = tuple(
            PairTruth(
                int(e["pair"]),
                np.asarray(e["R"], float).reshape(3, 3),
                np.asarray(e["t"], float).reshape(3),
                np.asarray(e["tip"], float).reshape(3),
                _corners(e["corners_left"], str(tpath)),
                _corners(e["corners_right"], str(tpath)),
            )
            for e in raw
        )
    except (ValueError, KeyError, TypeError, IndexError) as e:
        raise InputError(f"{tpath}: malformed truth ({type(e).__name__}: {e})") from e
    pairs = tuple(pair_paths(r, t.pair) for t in truth)
    for lp, rp in pairs:
        for p in (lp, rp):
            if not p.is_file():
                raise InputError(f"{p}: image listed in truth.json is missing")
    return StereoDataset(r, camera, marker, pairs, truth)
