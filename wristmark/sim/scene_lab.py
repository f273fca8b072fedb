"""The virtual lab of a scene: several arms in one endoscope view, each behind its own actuator box
(docs/design.md "The virtual lab", "Several arms").

:class:`SceneLab` plays one actuator box per arm of a scene (sim.scene_setup), each on its own new
pty (protocol v1 or v2 as the one-arm lab, its own watchdog and emergency stop), each driving its
own simulated true arm (its plant file, at its base pose in the scene's {w}), and one stereo
endoscope that renders every arm into each frame (the arms hide one another where they cross) and
serves it as an MJPEG stream on loopback, as :class:`sim.virtual_lab.VirtualLab` does for one arm.
``truth_out`` logs each frame's capture instant and every arm's true tip in the scene's {w} [m]
(header ``t,NAME_tip_x,NAME_tip_y,NAME_tip_z,...`` in the scene's order).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.models.arm_shape import transformed
from wristmark.models.arm_spec import home_psi
from wristmark.models.errors import InputError
from wristmark.sim.actuator_emulator import ActuatorEmulator
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.plant import TruePlant
from wristmark.sim.scene_setup import SceneSetup
from wristmark.sim.virtual_lab import LabCamera, StreamingLab, tip_errors

Array = NDArray[np.float64]

__all__ = ["SceneLab", "scene_truth_header", "read_scene_truth_csv", "scene_true_tip_errors"]


def scene_truth_header(names: list[str]) -> str:
    """The truth CSV's header of a scene: ``t`` then ``NAME_tip_x,NAME_tip_y,NAME_tip_z`` per arm."""
    return ",".join(["t", *(f"{n}_tip_{a}" for n in names for a in "xyz")])


class SceneLab(StreamingLab):
    """One actuator box per arm on its own pty and one endoscope on an MJPEG stream (module docstring).

    setup: the scene (its camera's ``world_T_left`` in the scene's {w}, the arms' plants); camera:
    the endoscope's rate, image scale, noise, port; psi0: each arm's start configuration (default
    its home); rt_priority, render_rt: as :class:`sim.virtual_lab.VirtualLab` (the boxes' threads
    one priority above the rest)."""

    def __init__(self, setup: SceneSetup, camera: LabCamera | None = None, watchdog_s: float = 0.25,
                 truth_out: str | Path | None = None, rt_priority: int | None = None, render_rt: bool = True,
                 psi0: Mapping[str, Array] | None = None) -> None:
        super().__init__(camera, truth_out, rt_priority, render_rt)
        self.setup = setup
        self.names = setup.names
        cam = setup.camera
        self.camera: StereoCamera = cam if self.options.image_scale == 1.0 else scaled_stereo_camera(
            cam, self.options.image_scale)
        self.bases = [np.asarray(setup.base(n), float) for n in self.names]
        self.arms: dict[str, LockedArm] = {}
        self.emulators: dict[str, ActuatorEmulator] = {}
        for n in self.names:
            s = setup.arms[n]
            start = np.asarray(psi0[n], float) if psi0 is not None and n in psi0 else home_psi(s.params)
            self.arms[n] = LockedArm(TruePlant(s.params, s.plant, psi0=start))
            self.emulators[n] = ActuatorEmulator(self.arms[n], s.params, watchdog_s=watchdog_s)
        self.ptys: dict[str, str] = {}

    def start(self) -> tuple[dict[str, str], str]:
        """Open every arm's pty and the stream, start the camera; returns ({arm: pty path} in the
        scene's order, stream URL). The first frame is published before this returns."""
        self._start_stream(self.camera, self.setup.markers, scene_truth_header(self.names))
        return dict(self.ptys), self.url

    def _serve_boxes(self) -> None:
        for n in self.names:
            self.ptys[n] = self.emulators[n].serve_pty()

    def _frame(self) -> float:
        """Sample every arm, render them together, publish, log the truth; returns the capture instant [s]."""
        samples = [self.emulators[n].sample_arm() for n in self.names]
        t = samples[0][0]
        shapes = [transformed(shape, B) for (_, shape), B in zip(samples, self.bases)]  # into the scene's {w}
        out = self._publish(shapes)
        assert self.server is not None
        self.server.publish(out.jpeg, t_capture=t)
        self._log_truth(t, [s.tip for s in shapes])
        return t

    def _stop_boxes(self) -> None:
        for em in self.emulators.values():
            em.stop()

    def __enter__(self) -> SceneLab:
        return self


def read_scene_truth_csv(path: str | Path) -> tuple[Array, dict[str, Array]]:
    """(t (N,) [s], {arm: tip (N, 3) in the scene's {w} [m]}) from a scene lab's ``--truth-out``."""
    with open(path) as f:
        cols = f.readline().strip().split(",")
        names = [c[: -len("_tip_x")] for c in cols[1::3]]
        if cols[0] != "t" or len(cols) < 4 or cols != scene_truth_header(names).split(","):
            raise InputError(f"{path}: not a scene lab's truth file (header {','.join(cols)!r})")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    if data.size == 0:
        return np.zeros(0), {n: np.zeros((0, 3)) for n in names}
    return data[:, 0], {n: data[:, 1 + 3 * i: 4 + 3 * i] for i, n in enumerate(names)}


def scene_true_tip_errors(log_csv: str | Path, truth_csv: str | Path, arm: str, base: Array,
                          phase: str = "servo", at: str = "t") -> Array:
    """|true tip - desired tip| [m] of each cycle of ``phase`` in arm ``arm``'s log (its desired
    tip in its own {w}), the true tip from a scene lab's truth CSV (scene {w}) moved into that {w}
    by ``base`` (the arm's {w} in the scene's, 4x4) and interpolated at the log's column ``at``
    (as :func:`sim.virtual_lab.true_tip_errors`)."""
    t, tips = read_scene_truth_csv(truth_csv)
    if arm not in tips:
        raise InputError(f"{truth_csv}: no arm '{arm}' (arms: {', '.join(tips)})")
    inv = np.linalg.inv(np.asarray(base, float))
    return tip_errors(log_csv, t, tips[arm] @ inv[:3, :3].T + inv[:3, 3], phase, at)
