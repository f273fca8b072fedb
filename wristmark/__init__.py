"""wristmark: closed-loop control of a continuum surgical manipulator from stereo-endoscope
tracking of a marker on its wrist.

Subpackages, lowest first (each imports only those before it): ``models`` (kinematics, robot
parameters, limits, configuration files), ``cvs`` (cameras, calibration, the marker and its
tracker, frame sources), ``solvers`` (the stereo pose solve, the controllers), ``rig`` (the servo
loop, the actuator link, the command line), ``viz`` (the Meshcat views) and ``sim`` (the
simulated bench: true plant, renderer, emulator, experiments).
"""

__version__ = "0.1.0"
