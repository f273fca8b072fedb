"""The public API surface: each package's ``__all__`` is pinned here, every name resolves and
is documented, and ``import wristmark`` stays cheap (no OpenCV, CasADi, Meshcat, dask or
simulated bench until a name that needs them is used).

Changing the public API means changing the lists below on purpose (and docs/api.md)."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

API = {
    "wristmark": [
        "ActuatorLink", "Controller", "ControllerConfig", "DirectLink", "HOME_PSI", "LiveView", "LoopSetup",
        "MarkerModel", "MarkerTracker", "RobotParams", "SerialLink", "ServoLoop", "SourceOptions",
        "StereoCamera", "StereoFrame", "StereoSource", "TrackResult", "WristmarkError", "__version__",
        "forward_kinematics", "load_calibration", "load_loop_setup", "load_registration", "make_controller",
        "open_hardware_session", "open_stereo_source", "run_servo", "save_calibration", "solve_tip_ik",
        "start_live_view", "tip_jacobian", "tip_position", "warm_up",
    ],
    "wristmark.models": [
        "Actuation", "Arm", "ArmFrames", "ArmPoses", "ArmShape", "ArmSpec", "ConfigError", "HOME_PSI",
        "IkResult", "InputError", "LimitError", "MarkerCode", "MarkerModel", "PinocchioAnyArm", "PinocchioArm",
        "RobotParams", "Segment", "StemJoint", "WristmarkError", "actuator_jacobian", "actuator_names",
        "actuator_units", "actuators_from_psi", "arm_actuator_jacobian", "arm_actuators", "arm_frames",
        "arm_names", "arm_psi_from_actuators", "arm_shape_of", "arm_size", "arm_tip_jacobian",
        "arm_tip_position", "check_psi", "clamp_psi", "clamp_velocity", "default_config",
        "find_config", "forward_kinematics", "from_mapping", "generate_arm_urdf", "generate_urdf", "home_psi",
        "load_arm",
        "load_yaml", "psi_bounds", "psi_from_actuators", "save_yaml", "shipped_configs", "solve_tip_ik",
        "tip_jacobian", "tip_position", "to_mapping", "within_limits", "write_urdf",
    ],
    "wristmark.cvs": [
        "AnnotationWriter", "BoardSpec", "Camera", "FrameSourceError", "ImagePairSource",
        "MarkerCornerDetector", "MarkerPose", "MarkerTracker", "PoseSettings", "Registration", "SourceOptions",
        "StereoCalibration", "StereoCamera", "StereoFrame", "StereoPoseSolver", "StereoSource", "TrackResult",
        "TrackerSettings", "annotate_pair",
        "apply_registration", "calibrate_stereo", "detect_views", "detect_xcorners", "iter_frames",
        "join_stereo", "load_calibration", "load_registration", "open_image_folder", "open_image_pairs",
        "open_stereo_source", "save_calibration", "save_registration", "scaled_stereo_camera", "split_stereo",
        "warm_up",
    ],
    "wristmark.solvers": [
        "Capsules", "ControlStep", "Controller", "ControllerConfig", "PaperController",
        "QpController", "RegistrationPose", "RegistrationResult", "body_capsules", "clearance_rows",
        "make_controller", "min_distance", "solve_registration", "transform_error", "transformed",
    ],
    "wristmark.rig": [
        "ActuatorDriver", "ActuatorError", "ActuatorLink", "CameraStalledError", "CycleRecord", "DirectLink",
        "ErrorStats", "LinkOptions", "LoopSetup", "MarkerLostError", "MjpegServer", "Observation",
        "RigConfig", "RunLog", "SerialLink", "ServoLoop", "ServoOutcome", "ServoSession", "SimClock",
        "TipMeasurement", "TipSensor", "Trajectory", "VisionTipSensor", "accuracy_targets", "choose_poses",
        "collect", "cube_trajectory", "error_stats", "load_loop_setup", "open_hardware_session",
        "read_log_csv", "registration_inputs", "run_servo", "summarize_servo", "workspace_centre",
    ],
    "wristmark.viz": [
        "ArmScene", "LiveView", "MeshcatServer", "SceneConfig", "build_replay", "home_scene", "load_run",
        "plot_accuracy", "plot_cube", "start_live_view", "write_html",
    ],
    "wristmark.sim": [
        "ActuatorEmulator", "OpticalTracker", "PlantParams", "RenderSettings", "RenderedPair",
        "SimRegistrationRig", "SimSetup", "StereoDataset", "StereoRenderer", "TrajectoryRun", "TruePlant",
        "VirtualLab", "load_dataset", "load_setup", "motion_psi", "noise_preset", "render_motion",
        "run_accuracy", "run_cube", "run_load", "run_point", "run_trajectory", "true_tip_errors",
        "write_stereo_video",
    ],
    "wristmark.cli": [
        "COMMANDS", "build_parser", "run_cli",
    ],
    "wristmark.sweep": [
        "load_spec", "run_sweep",
    ],
}
HEAVY = ("cv2", "casadi", "meshcat", "dask", "distributed", "numba", "pinocchio", "wristmark.sim")


@pytest.mark.parametrize("package", sorted(API))
def test_all_is_pinned(package: str) -> None:
    module = importlib.import_module(package)
    assert sorted(module.__all__) == API[package]
    assert len(set(module.__all__)) == len(module.__all__)


@pytest.mark.parametrize("package", sorted(API))
def test_every_name_resolves_and_is_documented(package: str) -> None:
    module = importlib.import_module(package)
    api_doc = (ROOT / "docs" / "api.md").read_text()
    for name in module.__all__:
        value = getattr(module, name)
        assert name in dir(module)
        assert f"`{name}`" in api_doc, f"{package}.{name} is not listed in docs/api.md"
        if not callable(value):  # constants: HOME_PSI, COMMANDS, __version__ (documented in docs/api.md)
            continue
        doc = inspect.getdoc(value) or ""
        own = "__doc__" in vars(value) if inspect.isclass(value) else bool(value.__doc__)
        assert own and doc.strip(), f"{package}.{name} has no docstring of its own"
        assert not doc.startswith(f"{name}("), f"{package}.{name}: only the dataclass's generated docstring"


@pytest.mark.parametrize("package", sorted(API))
def test_no_public_name_is_shadowed_by_a_submodule(package: str) -> None:
    """Importing ``package.X`` binds the module X on the package: a public name X would vanish."""
    module = importlib.import_module(package)
    for name in module.__all__:
        if package != "wristmark" or not name.startswith("__"):
            assert importlib.util.find_spec(f"{package}.{name}") is None, f"{package}.{name} is also a module"


def test_top_level_names_are_the_subpackages_objects() -> None:
    import wristmark
    from wristmark import cvs, models, rig

    assert wristmark.MarkerTracker is cvs.MarkerTracker
    assert wristmark.forward_kinematics is models.forward_kinematics
    assert wristmark.ServoLoop is rig.ServoLoop
    assert wristmark.__version__ == importlib.metadata.version("wristmark")


def test_unknown_name_is_an_attribute_error() -> None:
    import wristmark

    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        wristmark.no_such_name  # noqa: B018
    assert not hasattr(wristmark.models, "no_such_name")


def test_subpackage_reached_as_an_attribute() -> None:
    import wristmark

    assert wristmark.sim.__name__ == "wristmark.sim"  # imported on first use


def _modules_after(code: str) -> list[str]:
    out = subprocess.run([sys.executable, "-c", f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.splitlines()[-1])


@pytest.mark.parametrize("package", ["wristmark", "wristmark.models", "wristmark.cvs", "wristmark.solvers",
                                     "wristmark.rig", "wristmark.viz", "wristmark.sim", "wristmark.cli"])
def test_importing_a_package_is_cheap(package: str) -> None:
    loaded = _modules_after(f"import {package}")
    heavy = [m for m in loaded if m.split(".")[0] in HEAVY or m.startswith("wristmark.sim.")
             or (m == "wristmark.sim" and package != "wristmark.sim")]
    assert heavy == []
    assert "numpy" not in loaded


def test_kinematics_from_the_top_level_does_not_load_the_bench_or_vision() -> None:
    loaded = _modules_after("from wristmark import forward_kinematics, tip_jacobian, RobotParams\n"
                            "forward_kinematics(RobotParams(), [0, 0.04, 0.7, 0, 0.9, 0])")
    assert "wristmark.models.kinematics" in loaded
    assert not [m for m in loaded if m.split(".")[0] in HEAVY or m.startswith("wristmark.sim")]


def test_public_names_reads_only_the_type_checking_block(tmp_path: Path) -> None:
    from wristmark._lazy import public_names

    init = tmp_path / "__init__.py"
    init.write_text("import os\nTYPE_CHECKING = False\nif TYPE_CHECKING:\n"
                    "    from a.b import c, d as e\n    from f import (g,\n        h)\n")
    assert public_names(init) == {"c": ("a.b", "c"), "e": ("a.b", "d"), "g": ("f", "g"), "h": ("f", "h")}
    init.write_text("TYPE_CHECKING = False\nif TYPE_CHECKING:\n    from .b import c\n")
    with pytest.raises(ImportError, match="only 'from wristmark.x import y'"):
        public_names(init)
