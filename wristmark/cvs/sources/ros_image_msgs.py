"""Images and stamps as ROS 2 messages (rosbags' built-in types, no ROS install needed).

``sensor_msgs/msg/Image`` with encodings bgr8, rgb8, mono8 (and bgra8/rgba8 read as BGR), and
``sensor_msgs/msg/CompressedImage`` (JPEG or PNG) both ways; ``builtin_interfaces/msg/Time``
from and to integer nanoseconds.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from wristmark.cvs.sources.frames import FrameSourceError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE, COMPRESSED)


def typestore() -> Any:
    """rosbags' ROS 2 Humble typestore (the message types of docs/design.md "Recording")."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def time_msg(store: Any, t_ns: int) -> Any:
    """builtin_interfaces/msg/Time of ``t_ns`` [ns]."""
    return store.types["builtin_interfaces/msg/Time"](sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000))


def header_msg(store: Any, t_ns: int, frame_id: str) -> Any:
    """std_msgs/msg/Header stamped ``t_ns`` [ns] in ``frame_id``."""
    return store.types["std_msgs/msg/Header"](stamp=time_msg(store, t_ns), frame_id=frame_id)


def stamp_ns(msg: Any) -> int:
    """The message header's stamp [ns] (0 when unset)."""
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def image_msg(store: Any, image: NDArray[np.uint8], t_ns: int, frame_id: str, jpeg_quality: int | None = None) -> Any:
    """An Image (bgr8 or mono8) or, with ``jpeg_quality``, a CompressedImage (jpeg) of ``image``."""
    header = header_msg(store, t_ns, frame_id)
    a = np.ascontiguousarray(image)
    if jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", a, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        if not ok:
            raise FrameSourceError(f"cannot JPEG-encode an image of shape {a.shape}")
        return store.types[COMPRESSED](header=header, format="jpeg", data=buf.reshape(-1))
    if a.ndim == 2:
        encoding, step = "mono8", a.shape[1]
    elif a.ndim == 3 and a.shape[2] == 3:
        encoding, step = "bgr8", 3 * a.shape[1]
    else:
        raise FrameSourceError(f"cannot record an image of shape {a.shape} (grey or BGR uint8 only)")
    return store.types[IMAGE](header=header, height=a.shape[0], width=a.shape[1], encoding=encoding,
                              is_bigendian=0, step=step, data=a.reshape(-1))


def image_from_msg(msg: Any, msgtype: str, where: str) -> NDArray[np.uint8]:
    """The 8-bit image (BGR or grey) in an Image or CompressedImage message."""
    if msgtype == COMPRESSED:
        img = cv2.imdecode(np.asarray(msg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise FrameSourceError(f"{where}: a CompressedImage ({msg.format}) cannot be decoded")
        return np.asarray(img)
    if msgtype != IMAGE:
        raise FrameSourceError(f"{where}: {msgtype} is not an image type ({', '.join(IMAGE_TYPES)})")
    channels = {"bgr8": 3, "rgb8": 3, "mono8": 1, "bgra8": 4, "rgba8": 4}.get(msg.encoding)
    if channels is None:
        raise FrameSourceError(f"{where}: image encoding '{msg.encoding}' is not supported (bgr8, rgb8, mono8)")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, np.uint8)
    if step < w * channels or data.size < h * step:
        raise FrameSourceError(f"{where}: image data of {data.size} bytes does not fit {w}x{h} {msg.encoding}")
    rows = data[: h * step].reshape(h, step)[:, : w * channels]
    if channels == 1:
        return np.ascontiguousarray(rows)
    img = rows.reshape(h, w, channels)
    conversion = {"rgb8": cv2.COLOR_RGB2BGR, "bgra8": cv2.COLOR_BGRA2BGR, "rgba8": cv2.COLOR_RGBA2BGR}
    if msg.encoding in conversion:
        return np.asarray(cv2.cvtColor(img, conversion[msg.encoding]))
    return np.ascontiguousarray(img)
