"""The virtual lab over ROS 2 (wristmark/sim/ros2_lab.py) as its own process, with the shipped
robot, plant, calibration and marker: for tests/rig/ros2/test_ros2_lab.py (CYCLONEDDS_URI and
ROS_DOMAIN_ID from the test). Prints "ready" once its topics are up and "enabled" when a host
enabled the arm; runs until SIGTERM/SIGKILL. Usage: ros2_lab_main.py NS IMAGE_SCALE FPS TRUTH_CSV
[no-operating-state] (the last: an arm driver that publishes no NS/operating_state)"""

from __future__ import annotations

import os
import signal
import sys
import time

from wristmark.sim.ros2_lab import Ros2Lab
from wristmark.sim.setup import load_setup


def main() -> None:
    ns, scale, fps, truth = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    publish_state = sys.argv[5:] != ["no-operating-state"]
    assert "127.0.0.1" in os.environ["CYCLONEDDS_URI"]
    setup = load_setup()
    lab = Ros2Lab(setup.params, setup.plant, setup.camera, setup.marker, namespace=ns, fps=fps, image_scale=scale,
                  truth_out=truth, publish_state=publish_state)
    signal.signal(signal.SIGTERM, lambda *a: sys.exit(0))
    lab.start()
    print("ready", flush=True)
    said_enabled = False
    try:
        while True:
            time.sleep(0.1)
            if lab.enabled and not said_enabled:  # the host enabled the arm: motion from now on
                print("enabled", flush=True)
                said_enabled = True
            if lab.error:
                print(lab.error, file=sys.stderr, flush=True)
    finally:
        lab.stop()
        print(f"frames {lab.frames} targets {lab.targets} trips {lab.watchdog_trips} malformed {lab.malformed}",
              flush=True)


if __name__ == "__main__":
    main()
