"""The hardware path of ``wristmark servo``: an actuator box on a serial port (protocol v1) and a
stereo camera named by a frame-source SPEC. Nothing here (or below) imports the simulated
bench: the virtual lab (``wristmark emulator --pty --camera-port``) is reached exactly like a lab.

Frames come only from the camera, read by :class:`rig.loop.frame_feed.LatestFrameFeed` (newest frame,
never blocking the loop); the tip comes only from tracking them (:class:`rig.loop.tip_sensors.VisionTipSensor`);
time is the host's ``time.monotonic()``, on which the frames are stamped.
"""

from __future__ import annotations

import time
from typing import Any

from wristmark.cvs.camera import StereoCamera
from wristmark.cvs.sources.frames import StereoFrame
from wristmark.rig.link.actuator_driver import ActuatorDriver, ActuatorError
from wristmark.rig.link.serial_link import SerialLink
from wristmark.rig.loop.frame_feed import LatestFrameFeed
from wristmark.rig.loop.loop_setup import LoopSetup
from wristmark.rig.loop.servo_session import HW_TIMEOUT_S, LinkOptions, ServoSession
from wristmark.rig.loop.tip_sensors import DeadlineTipSensor, VisionTipSensor

FIRST_FRAME_TIMEOUT_S = 10.0  # [s] longest wait for the camera's first frame before any motion


def open_hardware_session(setup: LoopSetup, options: LinkOptions, camera: str, camera_timeout: float = 2.0,
                          layout: str = "sbs") -> ServoSession:
    """Open the actuator box (PING, GET_STATE: not yet enabled) and the camera, and check the
    camera's first frame against the calibration's image size (at the rig's image scale) and track
    it once (the tracker's first, slow call), all before any motion command.
    camera_timeout: no new frame for this long ends the camera's stream [s] (the loop holds the
    arm well before, after ``max_lost_cycles`` cycles without a frame)."""
    from wristmark.cvs.sources.open_source import SourceOptions
    from wristmark.rig.ros2.image_source import open_frame_source

    if not options.port:
        raise ActuatorError("--serial needs a device path or pyserial URL")
    link: SerialLink | Any
    if options.kind == "ros2":  # an arm on a ROS 2 graph (rig/ros2/actuator_link.py)
        from wristmark.models.arm_spec import actuator_names
        from wristmark.rig.ros2.actuator_link import Ros2ActuatorLink

        link = Ros2ActuatorLink(options.port, require_operating_state=options.operating_state,
                                names=actuator_names(setup.params))
    else:
        timeout = options.timeout if options.timeout is not None else HW_TIMEOUT_S
        driver = ActuatorDriver(options.port, options.baudrate, timeout, options.retries, params=setup.params)
        link = SerialLink(driver)
    try:
        link.probe()
        cam = setup.scaled_camera
        source = open_frame_source(camera, SourceOptions(layout=layout, timeout=camera_timeout))  # also ros2:L,R
    except BaseException:
        link.close()
        raise
    feed = LatestFrameFeed(source)
    vision = VisionTipSensor(cam, setup.marker, magnify=setup.rig.tracker_magnify)
    sensor = DeadlineTipSensor(vision, setup.rig.tracking_budget)  # no cycle outlasts the box's watchdog
    session = ServoSession(link, options, feed, sensor, port=getattr(link, "port", options.port), camera=camera,
                           wall_clock=True)
    session.on_close.append(sensor.close)
    try:
        first = first_frame(feed, cam, camera)
        vision.measure(first)  # loads the tracker's compiled kernels before any motion (no budget)
    except BaseException:
        session.close()
        raise
    return session


def first_frame(feed: LatestFrameFeed, camera: StereoCamera, spec: str) -> StereoFrame:
    """The camera's first frame (within FIRST_FRAME_TIMEOUT_S), its views checked against
    ``camera``'s image size (FrameSourceError, one line naming both)."""
    from wristmark.cvs.sources.frames import FrameSourceError, check_frame_size

    first = feed.take(wait_until=time.monotonic() + FIRST_FRAME_TIMEOUT_S)
    if first is None:
        raise FrameSourceError(f"{spec}: no frame within {FIRST_FRAME_TIMEOUT_S:g} s")
    check_frame_size(first, camera.image_size, spec)
    return first
