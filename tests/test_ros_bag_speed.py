"""The bag pipeline's faster paths give what the plain ones give: pose, TF and odometry messages made directly
are the generic builder's byte for byte; a lone MCAP file read through its index gives rosbags' messages in
rosbags' order, and its errors are the bag's clear error."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

import fidlearn
from fidlearn import data_path
from fidlearn.errors import RosFormatError
from fidlearn.filtering import TrackedPose
from fidlearn.filtering._so3 import quaternion_xyzw
from fidlearn.ros import read_bag, ros_pose, write_image_bag
from fidlearn.ros._bag_out import TOPICS, _twist, pose_messages
from fidlearn.ros._mcap_index import topic_messages
from fidlearn.ros._messages import build, stamp_dict, typestore

MAP = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAM = fidlearn.Camera.from_fov(60, (640, 480))
SMALL = fidlearn.Camera.from_fov(60, (64, 48))
T0 = 1_700_000_000_000_000_000
STEP = 100_000_000


def _generic(stamp_ns, pose, camera_frame):
    """The pose's messages built from dicts by the generic builder, the TF from the pose's matrix."""
    tracked = isinstance(pose, TrackedPose)
    body = "base_link" if tracked and pose.T_world_base is not None else "camera_optical_frame"
    msg = ros_pose(pose, stamp_ns / 1e9, body=body)
    msg["header"]["stamp"] = stamp_dict(stamp_ns)
    child = "base_link" if msg.pop("child_frame_id") == "base_link" else camera_frame
    T = np.asarray(pose.T_world_base if body == "base_link" else pose.T_world_camera, dtype=float)
    transform = {
        "translation": dict(zip("xyz", (float(v) for v in T[:3, 3] / 1000.0))),
        "rotation": dict(zip("xyzw", (float(v) for v in quaternion_xyzw(T[:3, :3])))),
    }
    tf = {"header": msg["header"], "child_frame_id": child, "transform": transform}
    out = [("/fidlearn/pose", msg), ("/tf", {"transforms": [tf]})]
    if tracked:
        lin, ang = _twist(pose, T)
        twist = {"linear": dict(zip("xyz", lin)), "angular": dict(zip("xyz", ang))}
        odo = {"header": msg["header"], "child_frame_id": child, "pose": msg["pose"],
               "twist": {"twist": twist, "covariance": [-1.0] + [0.0] * 35}}  # fmt: skip
        out.append(("/fidlearn/odometry", odo))
    return [(topic, build(TOPICS[topic], values)) for topic, values in out]


def test_pose_messages_are_the_generic_builders_byte_for_byte():
    drive = fidlearn.render_trajectory(MAP, CAM, n_frames=40, frames_to_render=[30])
    pose = fidlearn.locate(drive.images[0], MAP, CAM)
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6))
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 7, 95), [1200.0, -300.0, 250.0])
    mount = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, -90), [0.0, -300.0, -200.0])
    moving = {"velocity_mm_s": np.array([100.0, -5, 2]), "angular_velocity_rad_s": np.array([0.01, 0, 0.5])}
    poses = [
        pose,
        TrackedPose(0.25, T, A @ A.T, "measured", **moving),
        TrackedPose(0.25, T, A @ A.T, "predicted", T_world_base=T @ mount, base_covariance=A.T @ A, **moving),
    ]
    store = typestore()
    for p in poses:
        for stamp in (T0 + 987_654_321, 3):
            fast, generic = pose_messages(stamp, p, "cam"), _generic(stamp, p, "cam")
            assert [t for t, _ in fast] == [t for t, _ in generic]
            for (topic, a), (_, b) in zip(fast, generic):
                assert bytes(store.serialize_cdr(a, TOPICS[topic])) == bytes(store.serialize_cdr(b, TOPICS[topic]))


def _rosbags_messages(path, topic):
    """``(log time, CDR bytes)`` of a topic as rosbags reads them, chunk by chunk."""
    with AnyReader([path], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [(t, bytes(raw)) for _, t, raw in reader.messages(connections=conns)]


def _bag(path, n=5, step=STEP):
    """``n`` frames, frame k all gray 20 k, written ``step`` ns apart (0: all at one stamp)."""
    images = [np.full((48, 64, 3), 20 * k, np.uint8) for k in range(n)]
    return write_image_bag(path, images, SMALL, [T0 + step * k for k in range(n)])


@pytest.mark.parametrize("step", [STEP, 0])
def test_a_lone_mcap_read_by_its_index_gives_rosbags_messages_in_rosbags_order(tmp_path, step):
    bag = _bag(tmp_path / "in.mcap", 5, step)
    for topic in ("/camera/image_raw", "/camera/camera_info"):
        with open(bag, "rb") as f:
            indexed = [(t, bytes(raw)) for t, raw in topic_messages(f, topic)]
        assert indexed == _rosbags_messages(bag, topic)
        assert len(indexed) == 5


def test_a_lone_mcap_gives_the_frames_its_bag_folder_gives(tmp_path):
    lone, folder = _bag(tmp_path / "in.mcap", 4), _bag(tmp_path / "folder", 4)
    a, b = list(read_bag(lone)), list(read_bag(folder))
    assert [f.stamp for f in a] == [f.stamp for f in b] == [T0 + STEP * k for k in range(4)]
    assert all(np.array_equal(x.image, y.image) for x, y in zip(a, b))
    assert all(np.array_equal(x.camera.K, y.camera.K) for x, y in zip(a, b))
    assert [int(f.image[0, 0, 0]) for f in a] == [0, 20, 40, 60]
    assert np.allclose(a[0].camera.K, SMALL.K)
    assert (a[0].camera.width, a[0].camera.height) == (64, 48)


def test_an_unindexed_mcap_is_left_to_rosbags(tmp_path):
    bag = _bag(tmp_path / "in.mcap", 3)
    data = bag.read_bytes()
    (tmp_path / "plain.mcap").write_bytes(data[:-28] + bytes(8) + data[-20:])  # the footer's summary start: 0
    with open(tmp_path / "plain.mcap", "rb") as f:
        assert topic_messages(f, "/camera/image_raw") is None
    assert [f.stamp for f in read_bag(tmp_path / "plain.mcap")] == [T0 + STEP * k for k in range(3)]


def test_an_index_pointing_elsewhere_is_a_clear_error_after_the_frames_before_it(tmp_path):
    bag = _bag(tmp_path / "in.mcap", 4)
    data = bytearray(bag.read_bytes())
    at = data.find(struct.pack("<Q", T0 + 2 * STEP) + struct.pack("<Q", T0 + 2 * STEP))  # image 2's log and publish
    assert data[at - 15] == 0x05
    data[at - 6 : at] = bytes(6)  # its channel and sequence: the index now points at another channel's message
    data[at - 6] = 0x7F
    (tmp_path / "bad.mcap").write_bytes(bytes(data))
    frames = iter(read_bag(tmp_path / "bad.mcap"))
    assert [next(frames).stamp for _ in range(2)] == [T0, T0 + STEP]
    with pytest.raises(RosFormatError, match="bad.mcap: cannot read this ROS 2 bag"):
        next(frames)


def test_an_index_listing_another_number_of_messages_than_the_bag_has_is_not_used(tmp_path):
    bag = _bag(tmp_path / "in.mcap", 3)
    with open(bag, "rb") as f:
        assert [t for t, _ in topic_messages(f, "/camera/image_raw", 3)] == [T0 + STEP * k for k in range(3)]
        assert topic_messages(f, "/camera/image_raw", 4) is None  # messages the index does not list: rosbags reads
        assert topic_messages(f, "/no/such/topic") is None
