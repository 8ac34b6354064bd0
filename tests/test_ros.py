"""ROS and TUM output against hand-computed cases (units, axes, quaternion order), camera_info YAML both ways,
the odometry CSV and the mount JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fidlearn
from fidlearn import frames
from fidlearn.errors import CameraError, OdometryRangeError, RosFormatError
from fidlearn.filtering import TrackedPose
from fidlearn.ros import (
    camera_from_camera_info,
    camera_info_yaml,
    load_camera_info,
    read_mount_json,
    read_odometry_csv,
    ros_covariance,
    ros_pose,
    save_camera_info,
    tum_line,
    write_tum,
)

# The camera 1 m in front of the seed's wall, facing it: optical z along world -X, x along +Y, y along -Z.
T_FACING = frames.make_transform(frames.rotation_from_rpy_deg(-90, 0, 90), [1000.0, 150.0, 250.0])
COV = np.diag([1e-4, 4e-4, 9e-4, 4.0, 9.0, 16.0])  # rad^2 then mm^2
COV[0, 3] = COV[3, 0] = 0.01  # rotX-x: rad mm


def test_ros_pose_of_the_optical_frame_by_hand():
    msg = ros_pose(TrackedPose(12.5, T_FACING, COV, "measured"))
    assert msg["header"] == {"stamp": {"sec": 12, "nanosec": 500_000_000}, "frame_id": "map"}
    assert msg["child_frame_id"] == "camera_optical_frame"
    p, q = msg["pose"]["pose"]["position"], msg["pose"]["pose"]["orientation"]
    assert list(p) == ["x", "y", "z"]
    assert list(q) == ["x", "y", "z", "w"]
    np.testing.assert_allclose([p["x"], p["y"], p["z"]], [1.0, 0.15, 0.25], atol=1e-12)
    # R = [[0,0,-1],[1,0,0],[0,-1,0]]: trace 0, w = 1/2, x = (R21-R12)/4w = -1/2, y = (R02-R20)/4w = -1/2, z = 1/2
    np.testing.assert_allclose([q["x"], q["y"], q["z"], q["w"]], [-0.5, -0.5, 0.5, 0.5], atol=1e-12)
    cov = np.array(msg["pose"]["covariance"]).reshape(6, 6)
    np.testing.assert_allclose(np.diag(cov), [4e-6, 9e-6, 16e-6, 1e-4, 4e-4, 9e-4], rtol=1e-12, atol=0)
    assert cov[0, 3] == pytest.approx(1e-5, abs=1e-18)  # x-rotX: 0.01 rad mm = 1e-5 rad m
    assert cov[3, 0] == cov[0, 3]
    assert np.count_nonzero(cov) == 8


def test_ros_pose_of_the_camera_link_and_of_the_base_by_hand():
    # camera_link (x forward, y left, z up) of a camera facing -X: turned 180 degrees about z
    q = ros_pose(TrackedPose(0.0, T_FACING, COV, "measured"), body="camera_link")["pose"]["pose"]["orientation"]
    np.testing.assert_allclose([q["x"], q["y"], q["z"], q["w"]], [0, 0, 1, 0], atol=1e-12)
    # a robot at (1.5 m, 0.15 m, 0) facing -X, its camera 200 mm forward and 300 mm up, looking ahead
    T_world_base = frames.make_transform(frames.rot_z(np.pi), [1500.0, 150.0, 0.0])
    T_base_optical = frames.make_transform(fidlearn.ros.R_OPTICAL_LINK.T, [200.0, 0.0, 300.0])
    T_camera_base = frames.invert_transform(T_base_optical)
    T_world_camera = T_world_base @ T_base_optical
    np.testing.assert_allclose(T_world_camera, frames.make_transform(T_FACING[:3, :3], [1300, 150, 300]), atol=1e-12)
    tracker = fidlearn.PoseTracker(
        fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json")),
        fidlearn.Camera.from_fov(60, (640, 480)),
        T_camera_base=T_camera_base,
    )
    pose = fidlearn.estimate_pose(
        [
            fidlearn.Detection(i, tracker.camera.project(c, T_world_camera))
            for i, c in tracker.marker_map.corners().items()
        ],
        tracker.marker_map,
        tracker.camera,
        corner_sigma_px=0.3,
    )
    msg = ros_pose(tracker.update(pose, 3.25))
    assert msg["child_frame_id"] == "base_link"
    assert msg["header"]["stamp"] == {"sec": 3, "nanosec": 250_000_000}
    p, q = msg["pose"]["pose"]["position"], msg["pose"]["pose"]["orientation"]
    np.testing.assert_allclose([p["x"], p["y"], p["z"]], [1.5, 0.15, 0.0], atol=1e-9)
    np.testing.assert_allclose([q["x"], q["y"], q["z"], q["w"]], [0, 0, 1, 0], atol=1e-9)


def test_ros_covariance_order_and_units():
    C = np.arange(36, dtype=float).reshape(6, 6)
    C = C + C.T
    out = np.array(ros_covariance(C)).reshape(6, 6)
    assert out[0, 0] == C[3, 3] / 1e6
    assert out[2, 5] == C[5, 2] / 1e3
    assert out[5, 3] == C[2, 0]
    assert out[3, 4] == C[0, 1]
    assert out[1, 3] == C[4, 0] / 1e3


def test_stamp_carries_and_bad_inputs():
    msg = ros_pose(TrackedPose(1.9999999999, T_FACING, COV, "measured"))
    assert msg["header"]["stamp"] == {"sec": 2, "nanosec": 0}
    with pytest.raises(RosFormatError, match="mount"):
        ros_pose(TrackedPose(0.0, T_FACING, COV, "measured"), body="base_link")
    with pytest.raises(RosFormatError, match="body"):
        ros_pose(TrackedPose(0.0, T_FACING, COV, "measured"), body="odom")
    with pytest.raises(RosFormatError, match="time"):
        ros_pose(TrackedPose(-1.0, T_FACING, COV, "measured"))


def test_tum_by_hand(tmp_path):
    line = tum_line(12.5, T_FACING)
    assert (
        line == "12.500000000 1.000000000 0.150000000 0.250000000 "
        "-0.500000000000 -0.500000000000 0.500000000000 0.500000000000"
    )
    poses = [
        TrackedPose(0.1 * k, frames.make_transform(frames.rot_z(0.3 * k), [10.0 * k, -5.0, 1.0]), COV, "measured")
        for k in range(4)
    ]
    path = write_tum(tmp_path / "track.txt", poses)
    rows = [r.split() for r in path.read_text().splitlines()]
    assert rows[0][0] == "#"
    assert len(rows) == 5
    for k, r in enumerate(rows[1:]):
        v = np.array(r, dtype=float)
        np.testing.assert_allclose(v[:4], [0.1 * k, 0.01 * k, -0.005, 0.001], atol=1e-9)
        np.testing.assert_allclose(v[4:], [0, 0, np.sin(0.15 * k), np.cos(0.15 * k)], atol=1e-11)  # about z: w >= 0


@pytest.mark.parametrize(
    "dist",
    [
        None,
        [0.1, -0.2, 0.001, 0.002],
        [0.1, -0.2, 0.001, 0.002, 0.05],
        [0.1, -0.2, 0.001, 0.002, 0.05, 0.01, 0.02, 0.03],
    ],
)
def test_camera_info_round_trips(tmp_path, dist):
    cam = fidlearn.Camera([[612.345678901, 0, 320.1], [0, 611.9, 241.7], [0, 0, 1]], dist, (640, 480))
    back = load_camera_info(save_camera_info(cam, tmp_path / "camera_info.yaml", "front_cam"))
    assert (back.K == cam.K).all()
    assert back.image_size == (640, 480)
    d = np.r_[cam.dist, 0.0] if cam.dist.size == 4 else cam.dist
    assert (back.dist == d).all()
    text = camera_info_yaml(cam, "front_cam")
    assert "camera_name: front_cam\n" in text
    assert f"distortion_model: {'rational_polynomial' if d.size == 8 else 'plumb_bob'}\n" in text


CALIBRATION_OUTPUT = """\
# written by camera_calibration (ROS)
image_width: 1280
image_height: 720
camera_name: 'narrow_stereo'
camera_matrix:
  rows: 3
  cols: 3
  data: [ 900.5,   0.  , 640.25,
           0.  , 901. , 360.75,
           0.  ,   0.  ,   1.  ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data:
  - -0.05
  - 0.1
  - 0.0
  - 0.0
  - 0.0
rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
projection_matrix:
  rows: 3
  cols: 4
  data: [900.5, 0, 640.25, 0, 0, 901, 360.75, 0, 0, 0, 1, 0]
"""


def test_camera_info_as_ros_writes_it():
    cam = camera_from_camera_info(CALIBRATION_OUTPUT)
    np.testing.assert_array_equal(cam.K, [[900.5, 0, 640.25], [0, 901, 360.75], [0, 0, 1]])
    np.testing.assert_array_equal(cam.dist, [-0.05, 0.1, 0, 0, 0])
    assert cam.image_size == (1280, 720)


@pytest.mark.parametrize(
    ("edit", "fragment"),
    [
        (lambda t: t.replace("distortion_model: plumb_bob", "distortion_model: equidistant"), "equidistant"),
        (lambda t: t.replace("cols: 5", "cols: 4"), "holds 5 numbers"),
        (lambda t: t.replace("image_width: 1280", "image_width: wide"), "image_width"),
        (lambda t: t.split("camera_matrix:")[0] + "distortion_model: plumb_bob\n", "camera_matrix"),
        (lambda t: t + "   - stray\n", "cannot read the line"),
    ],
)
def test_bad_camera_info_says_what_is_wrong(edit, fragment):
    with pytest.raises(RosFormatError, match=fragment):
        camera_from_camera_info(edit(CALIBRATION_OUTPUT))


def test_camera_info_refuses_what_ros_cannot_hold():
    with pytest.raises(RosFormatError, match="no ROS"):
        camera_info_yaml(fidlearn.Camera.from_fov(60, (640, 480), dist=[0.0] * 14))
    with pytest.raises(RosFormatError, match="camera_name"):
        camera_info_yaml(fidlearn.Camera.from_fov(60, (640, 480)), "my camera")
    with pytest.raises(CameraError):
        camera_from_camera_info(CALIBRATION_OUTPUT.replace("900.5,", "-900.5,"))


def test_odometry_csv(tmp_path):
    rows = ["t_s,x_m,y_m,z_m,qx,qy,qz,qw"]
    for k in range(5):  # driving along x at 1 m/s while turning 0.2 rad/s about z
        a = 0.2 * 0.1 * k
        rows.append(f"{0.1 * k},{0.1 * k},0,0,0,0,{np.sin(a / 2)},{np.cos(a / 2)}")
    path = tmp_path / "odom.csv"
    path.write_text("\n".join(rows) + "\n")
    odo = read_odometry_csv(path, drift=0.02)
    rel, cov = odo.between(0.1, 0.3)
    expected = frames.invert_transform(frames.make_transform(frames.rot_z(0.02), [100, 0, 0])) @ frames.make_transform(
        frames.rot_z(0.06), [300, 0, 0]
    )
    np.testing.assert_allclose(rel, expected, atol=1e-9)
    np.testing.assert_allclose(
        np.sqrt(np.diag(cov)), [0.02 * 0.04 + 1e-4] * 3 + [0.02 * np.linalg.norm(expected[:3, 3]) + 0.1] * 3
    )
    with pytest.raises(OdometryRangeError, match=r"no odometry at 0.5 s: its samples run from 0 to 0.4 s"):
        odo.between(0.1, 0.5)  # past the last sample
    with pytest.raises(OdometryRangeError, match="no odometry at -0.1 s"):
        odo.pose_at(-0.1)
    np.testing.assert_allclose(odo.pose_at(0.15)[:3, 3], [150, 0, 0], atol=1e-9)
    path.write_text("t,x,y\n0,0,0\n")
    with pytest.raises(RosFormatError, match="header"):
        read_odometry_csv(path)
    path.write_text(rows[0] + "\n0,0,0,0,0,0,0,1\n0,0,0,0,0,0,0,1\n")
    with pytest.raises(RosFormatError, match="increasing"):
        read_odometry_csv(path)
    path.write_text(rows[0] + "\n0,0,0,0,0,0,0,1\n")  # one sample holds no motion
    with pytest.raises(RosFormatError, match="two or more"):
        read_odometry_csv(path)
    path.write_text(rows[0] + "\n0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,2\n")
    with pytest.raises(RosFormatError, match=r"odom.csv: row 3: .*norm 2"):
        read_odometry_csv(path)
    path.write_bytes("\ufeff".encode() + "\n".join(rows).encode() + b"\n")  # a spreadsheet's byte-order mark
    np.testing.assert_allclose(read_odometry_csv(path).between(0.1, 0.3)[0], expected, atol=1e-9)


def test_mount_json(tmp_path):
    path = tmp_path / "mount.json"
    path.write_text(json.dumps({"units": "m", "camera_in_base": {"translation": [0.2, 0, 0.3], "rpy_deg": [0, 0, 0]}}))
    T_camera_base = read_mount_json(path)
    T_base_camera = frames.invert_transform(T_camera_base)
    np.testing.assert_allclose(T_base_camera[:3, 3], [200, 0, 300], atol=1e-12)
    np.testing.assert_allclose(T_base_camera[:3, :3] @ [0, 0, 1], [1, 0, 0], atol=1e-12)  # optical z: forward
    np.testing.assert_allclose(T_base_camera[:3, :3] @ [1, 0, 0], [0, -1, 0], atol=1e-12)  # optical x: right
    path.write_text(json.dumps({"units": "mm", "T_camera_base": T_camera_base.tolist()}))
    np.testing.assert_allclose(read_mount_json(path), T_camera_base, atol=1e-12)
    for bad, fragment in [
        ({"camera_in_base": {}}, "units"),
        ({"units": "mm", "camera_in_base": {"translation": [0, 0, 0]}}, "rpy_deg"),
        ({"units": "mm", "T_camera_base": np.ones((4, 4)).tolist()}, "T_camera_base"),
        (
            {"units": "mm", "camera_in_base": {"translation": [0, 0, 0], "rpy_deg": [0, 0, 0]}, "camera_axes": "up"},
            "camera_axes",
        ),
        ({"units": "mm", "camera_in_base": {"translation": [True, 0, 0], "rpy_deg": [0, 0, 0]}}, "not true or false"),
    ]:
        path.write_text(json.dumps(bad))
        with pytest.raises(RosFormatError, match=fragment):
            read_mount_json(path)


def test_camera_info_reads_as_yaml_elsewhere():
    """An independent YAML reader (PyYAML, when installed: jupyter-events brings it) reads what we write."""
    yaml = pytest.importorskip("yaml")
    cam = fidlearn.Camera(
        [[612.3456789, 0, 320.1], [0, 611.9, 241.7], [0, 0, 1]], [0.1, -0.2, 1e-05, -2e-4, 5e-17], (640, 480)
    )
    d = yaml.safe_load(camera_info_yaml(cam, "front_cam"))  # YAML 1.1 reads 1e-05 as text, 1.0e-05 as a number
    assert d["image_width"] == 640
    assert d["image_height"] == 480
    assert d["camera_name"] == "front_cam"
    assert d["camera_matrix"]["data"] == cam.K.reshape(-1).tolist()
    assert d["camera_matrix"]["rows"] == 3
    assert d["distortion_coefficients"]["data"] == cam.dist.tolist()
    assert d["distortion_model"] == "plumb_bob"
    assert d["projection_matrix"]["cols"] == 4
    assert d["rectification_matrix"]["data"] == np.eye(3).reshape(-1).tolist()
    # and what PyYAML writes in that layout, fidlearn reads
    back = camera_from_camera_info(yaml.safe_dump(d))
    assert (back.K == cam.K).all()
    assert (back.dist == cam.dist).all()
