"""A stereo camera on ROS 2 that knows only the message types (Cyclone DDS and
wristmark.rig.ros2.messages): publishes the PNG pairs DIR/pair_NN_{left,right}.png in a loop at
RATE Hz, both images of a pair with the same stamp (the system clock), as sensor_msgs/Image bgr8
on NS/left/image_raw, NS/right/image_raw and as JPEG CompressedImage on .../image_raw/compressed.
Run by tests/rig/ros2/test_image_source.py (CYCLONEDDS_URI and ROS_DOMAIN_ID from the test) until
killed. Usage: image_publisher.py DIR NS RATE"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import cv2
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic

from wristmark.rig.ros2.messages import CompressedImage, Header, Image, Time, topic_name


def main() -> None:
    folder, ns, rate = Path(sys.argv[1]), sys.argv[2], float(sys.argv[3])
    assert "127.0.0.1" in os.environ["CYCLONEDDS_URI"]
    dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
    qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(2))
    raw = {s: DataWriter(dp, Topic(dp, topic_name(f"{ns}/{s}/image_raw"), Image), qos) for s in ("left", "right")}
    jpg = {s: DataWriter(dp, Topic(dp, topic_name(f"{ns}/{s}/image_raw/compressed"), CompressedImage), qos)
           for s in ("left", "right")}
    pairs = []
    for left in sorted(folder.glob("pair_*_left.png")):
        imgs = {"left": cv2.imread(str(left)), "right": cv2.imread(str(left).replace("_left", "_right"))}
        enc = {s: cv2.imencode(".jpg", im, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes() for s, im in imgs.items()}
        pairs.append((imgs, enc))
    k = 0
    while True:
        imgs, enc = pairs[k % len(pairs)]
        ns_now = time.time_ns()
        stamp = Time(ns_now // 1_000_000_000, ns_now % 1_000_000_000)
        for s in ("left", "right"):
            im = imgs[s]
            raw[s].write(Image(Header(stamp, f"{s}_camera"), im.shape[0], im.shape[1], "bgr8", 0, 3 * im.shape[1],
                               im.tobytes()))
            jpg[s].write(CompressedImage(Header(stamp, f"{s}_camera"), "jpeg", enc[s]))
        k += 1
        time.sleep(1.0 / rate)


if __name__ == "__main__":
    main()
