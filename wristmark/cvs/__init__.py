"""Computer vision for stereo: cameras and calibration files, calibration, registration files,
the marker tracker and its corner detector, stereo frame sources.

Frames: {ll} the left camera (x right, y down, z forward), {rr} the right one; image pixels
(u right, v down, origin at the centre of the top-left pixel). Units SI ([m], [rad]); image
sizes (width, height) [px].

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.cvs.calibration.board import BoardSpec
    from wristmark.cvs.calibration.load import load_calibration
    from wristmark.cvs.calibration.registration_file import (
        Registration,
        apply_registration,
        load_registration,
        save_registration,
    )
    from wristmark.cvs.calibration.stereo import StereoCalibration, calibrate_stereo, detect_views
    from wristmark.cvs.calibration.yaml_files import save_calibration
    from wristmark.cvs.camera import Camera, StereoCamera, scaled_stereo_camera
    from wristmark.cvs.corners.detector import MarkerCornerDetector, detect_xcorners
    from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame, StereoSource
    from wristmark.cvs.sources.frames import frames as iter_frames
    from wristmark.cvs.sources.images import ImagePairSource, open_image_folder, open_image_pairs
    from wristmark.cvs.sources.layout import join_stereo, split_stereo
    from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source
    from wristmark.cvs.tracking.annotate import AnnotationWriter, annotate_pair
    from wristmark.cvs.tracking.stereo_pose import MarkerPose, PoseSettings, StereoPoseSolver
    from wristmark.cvs.tracking.tracker import MarkerTracker, TrackerSettings, TrackResult
    from wristmark.cvs.tracking.warmup import warm_up
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
