"""The simulated bench: everything that stands in for the lab.

The true arm (``TruePlant`` with a ``PlantParams`` file), its stereo endoscope images
(``StereoRenderer``), the optical tracker that measures ground truth, the actuator-box emulator,
the virtual lab (emulator + MJPEG camera), the experiments, your own trajectory walked in
process (``run_trajectory``), and the setup that wires them together (``load_setup``). Frames:
{w} the robot base, {ll} the left camera; units SI. The hardware path (``wristmark servo
--serial --camera``) never imports this package.

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.sim.actuator_emulator import ActuatorEmulator
    from wristmark.sim.dataset import StereoDataset, load_dataset
    from wristmark.sim.experiments import run_accuracy, run_cube, run_load, run_point
    from wristmark.sim.optical_tracker import OpticalTracker
    from wristmark.sim.plant import TruePlant
    from wristmark.sim.plant_params import PlantParams
    from wristmark.sim.registration_bench import SimRegistrationRig
    from wristmark.sim.render.motion_video import motion_psi, render_motion, write_stereo_video
    from wristmark.sim.render.settings import RenderSettings, noise_preset
    from wristmark.sim.render.stereo_renderer import RenderedPair, StereoRenderer
    from wristmark.sim.setup import SimSetup, load_setup
    from wristmark.sim.trajectory_run import TrajectoryRun, run_trajectory
    from wristmark.sim.virtual_lab import VirtualLab, true_tip_errors
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
