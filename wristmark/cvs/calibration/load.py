"""Stereo calibration files: every form of docs/design.md "Calibration files", one reader per format.

``load_calibration(SPEC)`` picks the reader from SPEC and the file's content:

- ``LEFT.yaml,RIGHT.yaml`` -> a ROS camera_info pair (:mod:`cvs.calibration.ros_files`);
- OpenCV FileStorage (``%YAML:1.0`` header, XML, or opencv-matrix nodes) -> :mod:`cvs.calibration.opencv_files`;
- a YAML mapping with ``cam0`` -> a Kalibr camchain (:mod:`cvs.calibration.kalibr_files`);
- otherwise docs/design.md's YAML (:mod:`cvs.calibration.yaml_files`).

Every loaded calibration is validated (:func:`cvs.calibration.checks.validated`); errors are one-line
:class:`ConfigError` messages naming the file, the key and the fix. Units: metres, pixels.
"""

from __future__ import annotations

from pathlib import Path

from wristmark.cvs.calibration.checks import validated
from wristmark.cvs.calibration.kalibr_files import from_camchain, is_camchain
from wristmark.cvs.calibration.opencv_files import is_opencv_storage, load_opencv
from wristmark.cvs.calibration.ros_files import is_camera_info, load_ros_pair
from wristmark.cvs.calibration.yaml_files import calibration_mapping, from_yaml_mapping, save_calibration
from wristmark.cvs.camera import StereoCamera
from wristmark.models.config_io import EXTENDS, check_file_size, load_layered, load_yaml
from wristmark.models.errors import ConfigError

__all__ = ["load_calibration", "calibration_mapping", "calibration_from_mapping", "save_calibration", "validated"]

calibration_from_mapping = from_yaml_mapping  # docs/design.md's calibration mapping -> validated StereoCamera


def _existing(path: Path) -> Path:
    """The file, checked to exist and to be small enough before YAML or cv2.FileStorage reads it."""
    return check_file_size(path, what="calibration file")


def load_calibration(spec: str | Path) -> StereoCamera:
    """Load and validate a stereo calibration named by ``spec`` (a file, or ``LEFT,RIGHT`` ROS pair)."""
    text_spec = str(spec)
    if "," in text_spec and not Path(text_spec).is_file():
        parts = [s.strip() for s in text_spec.split(",")]
        if len(parts) != 2 or not all(parts):
            raise ConfigError(f"{text_spec}: a ROS camera_info pair is written LEFT.yaml,RIGHT.yaml")
        return load_ros_pair(_existing(Path(parts[0])), _existing(Path(parts[1])))
    p = _existing(Path(text_spec))
    try:
        text = p.read_text(errors="replace")
    except OSError as e:
        raise ConfigError(f"{p}: cannot read the calibration file ({e.strerror})") from e
    if is_opencv_storage(text):
        return load_opencv(p)
    data = load_yaml(p)
    if EXTENDS in data:  # a variant of another calibration (docs/configuration.md)
        data = load_layered(p)
    if is_camchain(data):
        return from_camchain(data, str(p))
    if is_camera_info(data):
        raise ConfigError(f"{p}: this is one ROS camera_info file: give the pair as LEFT.yaml,RIGHT.yaml")
    return from_yaml_mapping(data, str(p))
