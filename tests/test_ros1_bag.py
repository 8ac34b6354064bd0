"""ROS 1 bags (``.bag``) read as ROS 2 bags are: images at their header stamps, the camera of their CameraInfo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import assert_user_error
from helpers import run_cli as run

import fidlearn
from fidlearn import data_path
from fidlearn.errors import RosFormatError
from fidlearn.ros import is_bag, read_bag

MAP = data_path("world_map.json")
CAM = fidlearn.Camera(fidlearn.Camera.from_fov(60, (640, 480)).K, [0.05, -0.02, 0.0, 0.0, 0.0], (640, 480))
T0 = 1_600_000_000


@pytest.fixture(scope="module")
def drive():
    return fidlearn.render_trajectory(fidlearn.MarkerMap.load(MAP), CAM, n_frames=8, frames_to_render=[0, 4, 7])


def _ros1_bag(path, images, camera):
    """A ROS 1 bag as ``rosbag record`` writes it: bgr8 images and a CameraInfo (ROS 1's ``K``, ``D``) each."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types
    with Writer(path) as w:
        image_conn = w.add_connection("/cam/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        info_conn = w.add_connection("/cam/camera_info", "sensor_msgs/msg/CameraInfo", typestore=ts)
        for k, im in enumerate(images):
            stamp = T["builtin_interfaces/msg/Time"](sec=T0 + k, nanosec=250_000_000 + k)
            header = T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="cam_optical")
            h, wd = im.shape[:2]
            msg = T["sensor_msgs/msg/Image"](header=header, height=h, width=wd, encoding="bgr8", is_bigendian=0,
                                             step=wd * 3, data=np.ascontiguousarray(im).reshape(-1))  # fmt: skip
            roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
            info = T["sensor_msgs/msg/CameraInfo"](
                header=header, height=h, width=wd, distortion_model="plumb_bob",
                D=np.ravel(camera.dist).astype(float), K=camera.K.reshape(-1).astype(float),
                R=np.eye(3).reshape(-1), P=np.zeros(12), binning_x=0, binning_y=0, roi=roi,
            )  # fmt: skip
            t = (T0 + k) * 1_000_000_000 + 250_000_000 + k
            w.write(image_conn, t, ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
            w.write(info_conn, t, ts.serialize_ros1(info, "sensor_msgs/msg/CameraInfo"))
    return path


def test_a_ros1_bag_gives_its_frames_stamps_and_camera(tmp_path, drive):
    images = [np.dstack([im] * 3) if im.ndim == 2 else im for im in drive.images]
    bag = _ros1_bag(tmp_path / "drive.bag", images, CAM)
    assert is_bag(bag)
    frames = read_bag(bag)
    assert frames.camera_info_topic == "/cam/camera_info"
    got = list(frames)
    assert [f.stamp for f in got] == [(T0 + k) * 1_000_000_000 + 250_000_000 + k for k in range(3)]
    np.testing.assert_array_equal(got[2].image, images[2])
    np.testing.assert_allclose(got[0].camera.K, CAM.K)
    np.testing.assert_allclose(np.ravel(got[0].camera.dist), [0.05, -0.02, 0.0, 0.0, 0.0])
    assert frames.frame_id == "cam_optical"


def test_locate_reads_a_ros1_bag(tmp_path, capsys, drive):
    images = [np.dstack([im] * 3) if im.ndim == 2 else im for im in drive.images]
    bag = _ros1_bag(tmp_path / "drive.bag", images, CAM)
    code, out, err = run(capsys, "locate", bag, "--map", MAP, "--json", tmp_path / "poses.jsonl")
    assert code == 0, err
    assert "3 frames, 3 located (100 %)" in out

    rows = [json.loads(line) for line in (tmp_path / "poses.jsonl").read_text().splitlines()]
    direct = fidlearn.locate(images[0], MAP, CAM)  # the first frame given as a picture (later ones are tracked)
    np.testing.assert_allclose(rows[0]["position_mm"], direct.position_mm, atol=1e-6)
    for row, T in zip(rows, drive.T_world_camera):
        assert np.linalg.norm(np.array(row["position_mm"]) - T[:3, 3]) < 30.0  # 1-2 m from 80 mm markers, 640x480


def test_a_file_named_bag_that_is_not_one_is_a_clear_error(tmp_path, capsys):
    fake = tmp_path / "notes.bag"
    fake.write_bytes(b"#ROSBAG V1.3\nnot really")
    with pytest.raises(RosFormatError, match=r"notes.bag: cannot read this ROS 1 bag"):
        read_bag(fake)
    assert_user_error(*run(capsys, "locate", fake, "--map", MAP)[::2], "notes.bag: cannot read this")
    with pytest.raises(RosFormatError, match=r"a \.mcap or a ROS 1 \.bag file"):
        read_bag(tmp_path / "missing.bag")
