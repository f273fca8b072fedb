"""ROS 2 bags: rig.recording.bag_recorder writes MCAP that rosbags reads back (topics, types, frames,
stamps); cvs.sources.bag reads MCAP files and sqlite3 bag directories, Image (bgr8,
rgb8, mono8) and CompressedImage, pairing left/right by nearest stamp."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer

from wristmark.cvs.sources.bag import mutual_nearest_pairs
from wristmark.cvs.sources.frames import FrameSourceError, StereoFrame, frames
from wristmark.cvs.sources.open_source import SourceOptions, open_stereo_source
from wristmark.cvs.sources.ros_image_msgs import image_msg, stamp_ns, typestore
from wristmark.models.errors import InputError
from wristmark.rig.recording.bag_recorder import ACTUATOR_NAMES, BagRecorder

W_T_L = np.array([[0, 0, 1, 0.01], [-1, 0, 0, 0.02], [0, -1, 0, 0.03], [0, 0, 0, 1.0]])


def _record(path: Path, frame_ids: tuple, n: int = 4, jpeg: bool = False) -> list[StereoFrame]:
    id_view = frame_ids[0]
    t0 = time.monotonic()
    written = [StereoFrame(id_view(k, 0), id_view(k, 1), t0 + k / 30.0, k) for k in range(n)]
    T = np.eye(4)
    T[:3, 3] = [0.001, 0.002, 0.08]
    with BagRecorder(path, jpeg=jpeg, world_T_left=W_T_L) as rec:
        for f in written:
            rec.write_frame(f)
            rec.write_pose(f.t_capture, T, T[:3, 3] + [0.015, 0, 0])
            rec.write_actuators(f.t_capture, np.arange(6) * 0.1, np.arange(6) * 0.1 + 0.001)
    return written


def test_recording_topics_types_and_stamps(tmp_path: Path, frame_ids: tuple) -> None:
    path = tmp_path / "run.mcap"
    written = _record(path, frame_ids)
    assert path.is_file() and not (tmp_path / "run.mcap.partial").exists()
    with AnyReader([path], default_typestore=typestore()) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {
            "/stereo/left/image_raw": "sensor_msgs/msg/Image",
            "/stereo/right/image_raw": "sensor_msgs/msg/Image",
            "/wristmark/marker_pose": "geometry_msgs/msg/PoseStamped",
            "/wristmark/tip": "geometry_msgs/msg/PoseStamped",
            "/wristmark/actuators": "sensor_msgs/msg/JointState",
        }
        by_topic: dict[str, list] = {}
        for conn, log_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            assert stamp_ns(msg) == log_ns  # stamped with the capture time
            by_topic.setdefault(conn.topic, []).append(msg)
    left = by_topic["/stereo/left/image_raw"]
    assert [m.encoding for m in left] == ["bgr8"] * 4 and left[0].header.frame_id == "left_camera"
    assert np.array_equal(np.asarray(left[2].data).reshape(180, 320, 3), written[2].left)
    dt = np.diff([stamp_ns(m) for m in left]) * 1e-9
    assert np.allclose(dt, 1 / 30.0, atol=1e-6)  # capture times kept (mapped to the wall clock)
    assert abs(stamp_ns(left[0]) * 1e-9 - time.time()) < 60
    poses = by_topic["/wristmark/marker_pose"]
    assert [m.header.frame_id for m in poses[:2]] == ["left_camera", "world"]
    p_world = W_T_L[:3, :3] @ [0.001, 0.002, 0.08] + W_T_L[:3, 3]
    assert np.allclose([poses[1].pose.position.x, poses[1].pose.position.y, poses[1].pose.position.z], p_world)
    tip = by_topic["/wristmark/tip"][0].pose.position
    assert np.allclose([tip.x, tip.y, tip.z], [0.016, 0.002, 0.08])
    joints = by_topic["/wristmark/actuators"]
    assert [m.header.frame_id for m in joints[:2]] == ["commanded", "measured"]
    assert tuple(joints[0].name) == ACTUATOR_NAMES and np.allclose(joints[1].position, np.arange(6) * 0.1 + 0.001)


def test_record_then_read_back(tmp_path: Path, frame_ids: tuple) -> None:
    read_id = frame_ids[1]
    for jpeg in (False, True):
        path = tmp_path / f"run_{jpeg}.mcap"
        written = _record(path, frame_ids, n=5, jpeg=jpeg)
        src = open_stereo_source(str(path), SourceOptions(image_size=(320, 180)))
        t_before = time.monotonic()
        got = list(frames(src))
        src.close()
        assert [f.index for f in got] == list(range(5)) and src.dropped == 0
        assert [(read_id(f.left), read_id(f.right)) for f in got] == [(2 * k, 2 * k + 1) for k in range(5)]
        if not jpeg:
            assert all(np.array_equal(f.left, w.left) and np.array_equal(f.right, w.right)
                       for f, w in zip(got, written))
        # stamps mapped to the host's monotonic clock from the first read
        assert np.allclose(np.diff([f.t_capture for f in got]), 1 / 30.0, atol=1e-6)
        assert abs(got[0].t_capture - t_before) < 0.5


def test_recorder_refuses_to_overwrite(tmp_path: Path, frame_ids: tuple) -> None:
    path = tmp_path / "run.mcap"
    _record(path, frame_ids, n=1)
    size = path.stat().st_size
    with pytest.raises(InputError, match="exists already") as e:
        BagRecorder(path)
    assert "\n" not in str(e.value) and path.stat().st_size == size
    with pytest.raises(InputError, match=".mcap"):
        BagRecorder(tmp_path / "run.bag")


def _sqlite_bag(path: Path, frame_ids: tuple, left_stamps: list[int], right_stamps: list[int]) -> None:
    """A sqlite3 bag directory: rgb8 left images and JPEG right images on custom topics."""
    id_view = frame_ids[0]
    store = typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        cl = w.add_connection("/cam/left", "sensor_msgs/msg/Image", typestore=store)
        cr = w.add_connection("/cam/right", "sensor_msgs/msg/CompressedImage", typestore=store)
        for k, t in enumerate(left_stamps):
            rgb = cv2.cvtColor(id_view(k, 0), cv2.COLOR_BGR2RGB)
            msg = image_msg(store, rgb, t, "left")
            msg.encoding = "rgb8"
            w.write(cl, t, store.serialize_cdr(msg, "sensor_msgs/msg/Image"))
        for k, t in enumerate(right_stamps):
            msg = image_msg(store, id_view(k, 1), t, "right", jpeg_quality=90)
            w.write(cr, t + 3_000_000, store.serialize_cdr(msg, "sensor_msgs/msg/CompressedImage"))  # logged later


def test_sqlite3_bag_nearest_stamp_pairs(tmp_path: Path, frame_ids: tuple) -> None:
    read_id = frame_ids[1]
    period = 33_000_000
    left = [10**18 + k * period for k in range(6)]
    right = [t + (2_000_000 if k % 2 else -1_500_000) for k, t in enumerate(left)]  # a few ms of skew
    del right[3]  # left 3 has no partner
    bag = tmp_path / "bagdir"
    _sqlite_bag(bag, frame_ids, left, right)
    assert (bag / "metadata.yaml").is_file()
    src = open_stereo_source(str(bag), SourceOptions(topics=("/cam/left", "/cam/right")))
    got = list(frames(src))
    src.close()
    # right ids: message k of the right topic carries 2k + 1; left 3 is dropped
    assert [read_id(f.left) // 2 for f in got] == [0, 1, 2, 4, 5]
    assert [read_id(f.right) // 2 for f in got] == [0, 1, 2, 3, 4]
    assert src.dropped == 1
    assert np.allclose(np.diff([f.t_capture for f in got]), np.diff(np.array(left)[[0, 1, 2, 4, 5]]) * 1e-9)
    with pytest.raises(FrameSourceError, match=r"no topic /stereo/left/image_raw \(image topics: /cam/left"):
        open_stereo_source(str(bag))


def test_mutual_nearest_pairs() -> None:
    assert mutual_nearest_pairs([0, 100, 200], [1, 99, 260]) == [(0, 0), (1, 1)]  # 260: beyond half a period
    assert mutual_nearest_pairs([200, 0, 100], [0, 100, 200]) == [(1, 0), (2, 1), (0, 2)]
    assert mutual_nearest_pairs([0, 100], []) == []


def test_bad_bags(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file")
    with pytest.raises(FrameSourceError, match="cannot read the bag") as e:
        open_stereo_source(str(junk))
    assert "\n" not in str(e.value)
    with pytest.raises(FrameSourceError, match="no such bag"):
        open_stereo_source(str(tmp_path / "nope.mcap"))


def test_a_format2_arm_records_its_actuators_by_name(tmp_path: Path) -> None:
    """servo --record for another arm: /wristmark/actuators carries the robot file's actuator
    names (tendon3: d, s1a, ..., s3c), and a count other than the arm's is refused."""
    from wristmark.models.arm_spec import actuator_names, load_arm
    from wristmark.models.config_files import CONFIG_DIR
    from wristmark.rig.recording.servo_recorder import ServoRecorder

    arm = load_arm(CONFIG_DIR / "robots" / "tendon3.yaml")
    rec = ServoRecorder(str(tmp_path / "t3.mcap"), arm)
    assert rec.bag.actuator_names == actuator_names(arm) and len(actuator_names(arm)) == 10
    with pytest.raises(InputError, match="expected 10 actuator positions, got 6"):
        rec.bag.write_actuators(time.monotonic(), np.zeros(6), np.zeros(6))
    rec.bag.write_actuators(time.monotonic(), np.arange(10) * 1e-4, np.arange(10) * 1e-4)
    rec.close()
    with AnyReader([tmp_path / "t3.mcap"], default_typestore=typestore()) as reader:
        joints = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                  if c.topic == "/wristmark/actuators"]
    assert len(joints) == 2 and list(joints[0].name) == list(actuator_names(arm))
    np.testing.assert_allclose(joints[1].position, np.arange(10) * 1e-4)
