"""The bag pipeline's faster paths give what the plain ones give: pose, TF and odometry messages made directly
are the generic builder's byte for byte."""

from __future__ import annotations

import numpy as np

import fidlearn
from fidlearn import data_path
from fidlearn.filtering import TrackedPose
from fidlearn.filtering._so3 import quaternion_xyzw
from fidlearn.ros import ros_pose
from fidlearn.ros._bag_out import TOPICS, _twist, pose_messages
from fidlearn.ros._messages import build, stamp_dict, typestore

MAP = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAM = fidlearn.Camera.from_fov(60, (640, 480))
T0 = 1_700_000_000_000_000_000


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
