"""Meshcat views of the arm (live during a run, replay of a finished run, the home pose) and
the plots of the experiments.

Frames: everything is drawn in {w} (the robot base) [m]. The view listens on 127.0.0.1 unless a
host is given.

The names below are imported on first use (``wristmark/_lazy.py``): ``import wristmark.viz``
does not import Meshcat.
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.viz.live import LiveView, start_live_view
    from wristmark.viz.plots import plot_accuracy, plot_cube
    from wristmark.viz.replay import build_replay, home_scene, load_run
    from wristmark.viz.scene import ArmScene, SceneConfig
    from wristmark.viz.snapshot import write_html
    from wristmark.viz.viewer_client import MeshcatServer
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
