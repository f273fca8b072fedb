"""The virtual lab's camera runs on a fixed frame clock: frame k is captured k periods after the
first (a wake-up's lateness does not accumulate), so a host can lock its cycle to the frames."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from test_serial_link import PARAMS, PLANT

from wristmark.sim.setup import load_setup
from wristmark.sim.virtual_lab import LabCamera, VirtualLab, read_truth_csv

FPS = 20.0


def test_the_labs_frames_are_captured_on_a_fixed_clock(tmp_path: Path) -> None:
    setup = load_setup()
    truth = tmp_path / "truth.csv"
    lab = VirtualLab(PARAMS, PLANT, setup.camera, setup.marker, LabCamera(fps=FPS, image_scale=0.25), truth_out=truth)
    lab.start()
    try:
        time.sleep(2.5)
    finally:
        lab.stop()
    t, _ = read_truth_csv(truth)
    t = t[1:]  # the first frame (the render process's first call) is slow: the clock starts after it
    assert len(t) >= 25, len(t)  # a 0.25-scale frame renders well within the 50 ms period
    k = np.arange(len(t))
    late = (t - t[0]) - k / FPS  # each capture's lateness on the frame clock [s]
    assert np.all(late > -0.002), late  # never early
    assert np.median(late) < 0.003, late  # on the clock, not drifting away from it
    assert np.all(late < 0.025), late
    # the period between frames is the clock's (the old camera loop added each frame's wake-up
    # lateness, 0.1-1 ms, to the next period)
    assert abs(np.median(np.diff(t)) - 1.0 / FPS) < 2e-5, np.diff(t)
