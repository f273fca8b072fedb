"""The virtual lab over ROS 2: one simulated arm whose actuators and stereo endoscope are reached
only through ROS 2 topics (Cyclone DDS, no ROS; loopback unless ``CYCLONEDDS_URI`` says
otherwise), the way a lab's arm driver and camera driver would expose them.

Topics under ``NS`` (CRTK names, as rig/ros2/actuator_link.py speaks them): in ``NS/servo_jp``
(sensor_msgs/JointState: actuator targets by the robot file's actuator names, [rad] or [m] each:
phi, d, s1a, s1b, s2a, s2b for the reference arm; obeyed only while enabled) and
``NS/crtk_command`` (std_msgs/String enable | disable); out ``NS/measured_js``
(the encoders, every ``js_period`` s) and the endoscope, ``NS/left/image_raw/compressed`` and
``NS/right/image_raw/compressed`` (sensor_msgs/CompressedImage, JPEG, both images of a frame
stamped alike with the instant the arm was sampled, on the system clock), up to ``fps`` frames a
second, and ``NS/operating_state`` (crtk_msgs/OperatingState: ENABLED, DISABLED or FAULT) at each
change and every ``state_period`` s. Like the actuator box: enabled and no ``servo_jp`` for
``watchdog_s`` -> hold and disable (counted in ``watchdog_trips``), which ``operating_state`` says
(the host's link stops on it); a malformed target is counted and ignored.

``operating_state`` QoS: reliable, transient local, keep last 1: the writer keeps the current state
and hands it to a subscriber that joins late at once (a transient-local reader, as ROS 2 latched
topics), a volatile subscriber has it within ``state_period``; reliable so that no change is lost,
keep last 1 because only the current state matters. ``publish_state=False`` plays an arm driver
that publishes no ``operating_state`` (tests).

``truth_out`` logs each frame's capture instant (``time.monotonic()``) with the true tip in {w}
[m] (the virtual lab's CSV: ``t,tip_x,tip_y,tip_z``).

Its parts, shared with the scene's lab over ROS 2 (sim.ros2_scene_lab): :class:`Ros2Arm` (one
arm's topics, its watchdog and state) and :class:`Ros2Endoscope` (the images of one arm or several).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import cv2
import numpy as np

from wristmark.cvs.camera import StereoCamera, scaled_stereo_camera
from wristmark.models.arm_spec import Arm, actuator_names, home_psi
from wristmark.models.errors import InputError, WristmarkError
from wristmark.models.marker import MarkerModel
from wristmark.rig.ros2.bridge import clean_namespace
from wristmark.rig.ros2.dds_config import open_participant, require_cyclonedds
from wristmark.sim.dense_truth import TRUTH_HEADER
from wristmark.sim.locked_arm import LockedArm
from wristmark.sim.plant import TruePlant
from wristmark.sim.plant_params import PlantParams


class Ros2Arm:
    """One simulated arm behind ``NS/servo_jp``, ``NS/crtk_command``, ``NS/measured_js`` and
    ``NS/operating_state`` (the module docstring's arm; :class:`Ros2Lab` adds its endoscope,
    sim.ros2_scene_lab puts several under one)."""

    def __init__(self, params: Arm, plant: PlantParams, namespace: str = "lab", watchdog_s: float = 0.25,
                 js_period: float = 0.01, psi0: Any = None, state_period: float = 0.1,
                 publish_state: bool = True) -> None:
        self.namespace = clean_namespace(namespace)
        self.params = params
        self.names = actuator_names(params)
        self.watchdog_s = float(watchdog_s)
        self.js_period = float(js_period)
        self.state_period = float(state_period)
        self.publish_state = bool(publish_state)
        self.arm = LockedArm(TruePlant(params, plant, psi0=np.asarray(psi0, float) if psi0 is not None
                                       else home_psi(params)))
        self.enabled = False
        self.watchdog_trips = 0
        self.malformed = 0
        self.targets = 0
        self.error = ""
        self.fault = False
        self._published_state = ""
        self._t_arm = time.monotonic()
        self._last_target = -np.inf
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._state_writer: Any = None
        self._readers: list[Any] = []

    # -- the arm -------------------------------------------------------------------------------
    def advance(self) -> tuple[float, Any]:
        """Advance the arm to now (the watchdog runs); returns (now [s], the true shape)."""
        with self.arm.lock:
            now = time.monotonic()
            if self.enabled and now - self._last_target > self.watchdog_s:
                self.arm.hold()
                self.enabled = False
                self.watchdog_trips += 1
            dt = now - self._t_arm
            if dt > 0:
                try:
                    self.arm.advance(dt)
                except WristmarkError as e:  # the plant refused (a limit): the lab holds and says so
                    self.arm.hold()
                    self.enabled = False
                    self.fault = True
                    self.error = f"arm fault: {e}"
                self._t_arm = now
            if self.operating_state != self._published_state:
                self._write_state()
            return now, self.arm.true_shape()

    @property
    def operating_state(self) -> str:
        """CRTK's operating state: FAULT after a plant fault, else ENABLED or DISABLED."""
        return "FAULT" if self.fault else "ENABLED" if self.enabled else "DISABLED"

    def _write_state(self) -> None:
        """Publish the operating state now (the caller holds the arm's lock)."""
        writer = self._state_writer
        if writer is None:
            return
        M = self._M
        state = self.operating_state
        ns = time.time_ns()
        writer.write(M.OperatingState(M.Header(M.Time(ns // 1_000_000_000, ns % 1_000_000_000), ""), state,
                                      True, False))
        self._published_state = state

    def _on_servo_jp(self, reader: Any) -> None:
        for msg in reader.take(N=8):
            if not hasattr(msg, "position"):
                continue  # an InvalidSample: the writer left (no data)
            names, pos = list(msg.name), list(msg.position)
            if len(names) != len(pos) or not set(self.names) <= set(names):
                self.malformed += 1
                continue
            a = np.array([pos[names.index(n)] for n in self.names], float)
            if not np.all(np.isfinite(a)):
                self.malformed += 1
                continue
            with self.arm.lock:
                self.advance()
                if self.enabled:
                    self.arm.command(a)
                    self._last_target = time.monotonic()
                    self.targets += 1

    def _on_command(self, reader: Any) -> None:
        for msg in reader.take(N=8):
            if not hasattr(msg, "data"):
                continue  # an InvalidSample
            with self.arm.lock:
                self.advance()
                if msg.data == "enable":
                    self.enabled = not self.fault  # a faulted arm stays down (FAULT)
                    self._last_target = time.monotonic()  # the watchdog counts from ENABLE
                elif msg.data == "disable":
                    self.arm.hold()
                    self.enabled = False
                else:
                    self.malformed += 1
                if self.operating_state != self._published_state:
                    self._write_state()

    # -- threads -------------------------------------------------------------------------------
    def _run_js(self) -> None:
        M = self._M
        while not self._stop.wait(self.js_period):
            self.advance()
            q = self.arm.measured_actuators()
            ns = time.time_ns()
            self._js.write(M.JointState(M.Header(M.Time(ns // 1_000_000_000, ns % 1_000_000_000), ""),
                                        list(self.names), [float(x) for x in q], [], []))

    def _run_state(self) -> None:
        while not self._stop.wait(self.state_period):
            with self.arm.lock:
                self.advance()
                self._write_state()

    def join(self, dp: Any) -> None:
        """Join the graph on participant ``dp``: the arm's writers and readers, its threads started."""
        from cyclonedds.core import Listener, Policy, Qos
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2 import messages as M

        self._M = M

        def topic(name: str, cls: type) -> Any:
            return Topic(dp, M.topic_name(f"{self.namespace}/{name}"), cls)

        reliable = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(1))
        self._js = DataWriter(dp, topic("measured_js", M.JointState), sensor_qos())
        if self.publish_state:  # reliable, transient local, keep last 1 (module docstring)
            latched = Qos(Policy.Reliability.Reliable(100_000_000), Policy.History.KeepLast(1),
                          Policy.Durability.TransientLocal)
            with self.arm.lock:
                self._state_writer = DataWriter(dp, topic("operating_state", M.OperatingState), latched)
                self._write_state()
        self._readers = [
            DataReader(dp, topic("servo_jp", M.JointState), reliable,
                       listener=Listener(on_data_available=self._on_servo_jp)),
            DataReader(dp, topic("crtk_command", M.String), reliable,
                       listener=Listener(on_data_available=self._on_command)),
        ]
        threads = [(self._run_js, "ros2-lab-arm")]
        if self.publish_state:
            threads.append((self._run_state, "ros2-lab-state"))
        self._spawn(threads)

    def _spawn(self, threads: list[tuple[Any, str]]) -> None:
        for fn, name in threads:
            th = threading.Thread(target=fn, name=name, daemon=True)
            self._threads.append(th)
            th.start()

    def leave(self) -> None:
        """Stop the threads, hold the arm and say DISABLED, drop the readers (idempotent)."""
        self._stop.set()
        for th in self._threads:
            th.join(5.0)
        self._threads = []
        for r in self._readers:
            r.set_listener(None)
        self._readers = []
        with self.arm.lock:
            self.arm.hold()
            self.enabled = False
            try:
                self._write_state()  # DISABLED: a host still subscribed knows at once
            except Exception:  # noqa: BLE001 - leaving the graph goes on
                pass
            self._state_writer = None


def sensor_qos() -> Any:
    """Best effort, keep last 2: the encoders' and the images' QoS."""
    from cyclonedds.core import Policy, Qos

    return Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(2))


class Ros2Endoscope:
    """A stereo endoscope on ``NS/left/image_raw/compressed`` and ``NS/right/image_raw/compressed``
    rendering what ``sample()`` returns ((instant [s], [shape in {w}, ...]): one arm, or every arm
    of a scene, one marker each) at up to ``fps``; each frame's instant and tips to ``truth``."""

    def __init__(self, camera: StereoCamera, markers: list[MarkerModel], namespace: str, fps: float,
                 sample: Callable[[], tuple[float, list[Any]]], noise: str = "default", seed: int = 0,
                 jpeg_quality: int = 90) -> None:
        self.camera, self.markers, self.namespace = camera, markers, clean_namespace(namespace)
        self.fps, self.sample = float(fps), sample
        self.noise, self.seed, self.jpeg_quality = noise, int(seed), int(jpeg_quality)
        self.frames = 0
        self.error = ""
        self.truth: IO[str] | None = None
        self._epoch_minus_mono = time.time() - time.monotonic()

    def join(self, dp: Any) -> None:
        """The two image writers on participant ``dp``."""
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        from wristmark.rig.ros2 import messages as M

        self._M = M
        self._writers = [(side, DataWriter(dp, Topic(dp, M.topic_name(f"{self.namespace}/{side}/image_raw/compressed"),
                                                     M.CompressedImage), sensor_qos())) for side in ("left", "right")]

    def run(self, stop: threading.Event) -> None:
        """Render and publish until ``stop``; a failure ends it with one line in ``error``."""
        from wristmark.sim.render.settings import noise_preset
        from wristmark.sim.render.stereo_renderer import StereoRenderer

        M = self._M
        one = len(self.markers) == 1
        renderer = StereoRenderer(self.camera, self.markers[0] if one else self.markers, noise_preset(self.noise),
                                  seed=self.seed)
        period = 1.0 / self.fps
        t_next = time.monotonic()
        while not stop.is_set():
            wait = t_next - time.monotonic()
            if wait > 0 and stop.wait(wait):
                return
            try:
                t, shapes = self.sample()
                pair = renderer.render(shapes[0]) if one else renderer.render_arms(shapes)
                ns = int(round((t + self._epoch_minus_mono) * 1e9))
                stamp = M.Time(ns // 1_000_000_000, ns % 1_000_000_000)
                for (side, writer), img in zip(self._writers, (pair.left, pair.right)):
                    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
                    if not ok:
                        raise WristmarkError(f"cannot JPEG-encode the {side} image")
                    writer.write(M.CompressedImage(M.Header(stamp, f"{side}_camera"), "jpeg", buf.tobytes()))
                if self.truth is not None:
                    self.truth.write(",".join([f"{t:.6f}", *(f"{float(v):.9g}" for s in shapes for v in s.tip)]) + "\n")
                self.frames += 1
            except Exception as e:  # noqa: BLE001 - the camera dies with one line; the topics then stall
                self.error = f"virtual endoscope stopped: {type(e).__name__}: {e}"
                return
            t_next = max(t_next + period, time.monotonic())


def open_truth(path: Path | None, header: str) -> IO[str] | None:
    """The truth CSV at ``path`` (line buffered, ``header`` written), or None."""
    if path is None:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    f = open(path, "w", buffering=1)
    f.write(header + "\n")
    return f


class Ros2Lab(Ros2Arm):
    """The simulated arm behind ROS 2 topics and its endoscope (module docstring)."""

    def __init__(self, params: Arm, plant: PlantParams, calibration: StereoCamera, marker: MarkerModel,
                 namespace: str = "lab", fps: float = 15.0, image_scale: float = 0.35, noise: str = "default",
                 seed: int = 0, jpeg_quality: int = 90, watchdog_s: float = 0.25, js_period: float = 0.01,
                 truth_out: str | Path | None = None, psi0: Any = None, state_period: float = 0.1,
                 publish_state: bool = True) -> None:
        require_cyclonedds("the virtual lab over ROS 2")
        if calibration.T_world_left is None:
            raise InputError("the virtual lab's calibration needs 'world_T_left' (camera pose in {w})")
        check_camera(fps, image_scale)
        if any(plant.camera_offset):  # the endoscope truly sits at world_T_left @ T(camera_offset)
            W = np.asarray(calibration.T_world_left, float) @ plant.camera_offset_transform()
            calibration = dataclasses.replace(calibration, T_world_left=W)
        super().__init__(params, plant, namespace, watchdog_s, js_period, psi0, state_period, publish_state)
        self.camera = calibration if image_scale == 1.0 else scaled_stereo_camera(calibration, image_scale)
        self.marker = marker
        self.fps = float(fps)
        self.endoscope = Ros2Endoscope(self.camera, [marker], namespace, fps, self._sample, noise, seed, jpeg_quality)
        self.truth_path = Path(truth_out) if truth_out else None
        self.participant: Any = None

    def _sample(self) -> tuple[float, list[Any]]:
        t, shape = self.advance()
        return t, [shape]

    @property
    def frames(self) -> int:
        """Frames published."""
        return self.endoscope.frames

    def start(self) -> None:
        """Join the graph and start the arm's and the camera's threads."""
        self.endoscope.truth = open_truth(self.truth_path, TRUTH_HEADER)
        self.participant = dp = open_participant()
        self.endoscope.join(dp)
        self.join(dp)
        self._spawn([(self._run_camera, "ros2-lab-camera")])

    def _run_camera(self) -> None:
        self.endoscope.run(self._stop)
        if self.endoscope.error:
            self.error = self.endoscope.error

    def stop(self) -> None:
        """Stop the threads, hold the arm, leave the graph, close the truth file (idempotent)."""
        self.leave()
        self.participant = None
        if self.endoscope.truth is not None:
            self.endoscope.truth.close()
            self.endoscope.truth = None

    def __enter__(self) -> Ros2Lab:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def check_camera(fps: float, image_scale: float) -> None:
    """InputError unless ``fps`` > 0 and ``image_scale`` in (0, 1]."""
    if not (np.isfinite(fps) and fps > 0) or not 0 < image_scale <= 1:
        raise InputError(f"fps must be > 0 and image_scale in (0, 1], got {fps}, {image_scale}")
