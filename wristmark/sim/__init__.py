"""The simulated bench: everything that stands in for the lab.

The true arm (``plant``), its stereo endoscope images (``render*``), the optical tracker that
measures ground truth (``optical_tracker``), the actuator-box emulator, the experiments and the
setup that wires them together. The hardware path (``wristmark servo --serial --camera``) never
imports this package.
"""
