"""A bag's topics as ROS tools name them: rectified images, several image topics chosen on the command line."""

from __future__ import annotations

import json
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from helpers import assert_user_error
from helpers import run_cli as run
from rosbags.rosbag2 import StoragePlugin, Writer
from test_ros_bag import messages

import fidlearn
from fidlearn import data_path
from fidlearn.errors import RosFormatError
from fidlearn.ros import decode_image, read_bag
from fidlearn.ros._messages import build, typestore

MAP = data_path("world_map.json")
#: A wide lens with a strong barrel distortion, and the projection image_proc rectifies its images to.
RAW = fidlearn.Camera(fidlearn.Camera.from_fov(70, (640, 480)).K, [-0.3, 0.1, 0.0, 0.0, 0.0], (640, 480))
P = cv2.getOptimalNewCameraMatrix(RAW.K, RAW.dist, (640, 480), 0.0)[0]


@pytest.fixture(scope="module")
def drive():
    return fidlearn.render_trajectory(fidlearn.MarkerMap.load(MAP), RAW, n_frames=6, frames_to_render=[0, 5])


def _bag(path, topics: dict[str, list[np.ndarray]]):
    """A camera driver's bag (with image_proc's topics): each topic's gray images, one CameraInfo (K, D and P)."""
    store = typestore()
    info = {"width": 640, "height": 480, "distortion_model": "plumb_bob", "d": list(RAW.dist.reshape(-1)),
            "k": list(RAW.K.reshape(-1)), "p": list(np.hstack([P, np.zeros((3, 1))]).reshape(-1))}  # fmt: skip
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        ci = w.add_connection("/cam/camera_info", "sensor_msgs/msg/CameraInfo", typestore=store)
        conns = {t: w.add_connection(t, "sensor_msgs/msg/Image", typestore=store) for t in topics}
        for k in range(len(next(iter(topics.values())))):
            stamp = 1_700_000_000_000_000_000 + k * 50_000_000
            header = {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}, "frame_id": "cam_optical"}
            w.write(ci, stamp, store.serialize_cdr(build("sensor_msgs/msg/CameraInfo", {"header": header, **info}),
                                                   "sensor_msgs/msg/CameraInfo"))  # fmt: skip
            for topic, images in topics.items():
                fields = {"header": header, "height": 480, "width": 640, "encoding": "mono8", "step": 640}
                msg = build("sensor_msgs/msg/Image", {**fields, "data": images[k].reshape(-1)})
                w.write(conns[topic], stamp, store.serialize_cdr(msg, "sensor_msgs/msg/Image"))
    return path


def test_rectified_images_have_the_projection_as_their_camera(tmp_path, drive):
    """image_proc's image_rect beside the raw images' CameraInfo: K and D there are the raw images' camera; the
    rectified ones were located with them (a distortion undone twice) and landed 10 cm and more off."""
    rect = [cv2.undistort(im, RAW.K, RAW.dist, None, P) for im in drive.images]
    bag = _bag(tmp_path / "cam", {"/cam/image_raw": list(drive.images), "/cam/image_rect": rect})
    (_, raw_cam), *_ = read_bag(bag, "/cam/image_raw").cameras()
    np.testing.assert_allclose(raw_cam.K, RAW.K)
    np.testing.assert_allclose(np.ravel(raw_cam.dist), np.ravel(RAW.dist))
    frames = list(read_bag(bag, "/cam/image_rect"))
    np.testing.assert_allclose(frames[0].camera.K, P)
    assert not np.any(frames[0].camera.dist)
    for frame, T_true in zip(frames, drive.T_world_camera):
        pose = fidlearn.locate(frame.image, MAP, frame.camera)
        assert np.linalg.norm(pose.position_mm - T_true[:3, 3]) < 40.0  # K and D: 490 and 120 mm


def test_several_image_topics_name_the_command_line_option(tmp_path, capsys, drive):
    bag = _bag(tmp_path / "cam", {"/cam/image_raw": list(drive.images), "/cam/image_mono": list(drive.images)})
    code, _, err = run(capsys, "locate", bag, "--map", MAP)
    assert_user_error(code, err, "2 image topics (/cam/image_mono, /cam/image_raw); choose one with --image-topic")
    code, out, err = run(capsys, "locate", bag, "--map", MAP, "--image-topic", "/cam/image_raw")
    assert code == 0, err
    assert "2 frames, 2 located (100 %)" in out


@pytest.mark.parametrize("fmt", ["tum", "ros"])
def test_tracked_tum_and_ros_lines_carry_the_images_stamps(tmp_path, capsys, drive, fmt):
    """A PoseWithCovarianceStamped (or a TUM line) of a bag's frame at its image's stamp, as -o OUT.mcap writes
    it: it said 0 s and 0.05 s for images stamped 1700000000.0 and 1700000000.05 s."""
    bag = _bag(tmp_path / "cam", {"/cam/image_raw": list(drive.images)})
    out = tmp_path / ("track.txt" if fmt == "tum" else "track.jsonl")
    code, _, err = run(capsys, "locate", bag, "--map", MAP, "--track", "--format", fmt, "-o", out)
    assert code == 0, err
    lines = out.read_text().splitlines()
    if fmt == "tum":
        assert [line.split()[0] for line in lines[1:]] == ["1700000000.000000000", "1700000000.050000000"]
    else:
        stamps = [json.loads(line)["header"]["stamp"] for line in lines]
        assert stamps == [{"sec": 1_700_000_000, "nanosec": 0}, {"sec": 1_700_000_000, "nanosec": 50_000_000}]


def _stamped_bag(path, images, stamps_ns):
    """Gray images at the given header stamps, recorded 50 ms apart (the receive times always increase)."""
    store = typestore()
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/cam/image_raw", "sensor_msgs/msg/Image", typestore=store)
        for k, (image, stamp) in enumerate(zip(images, stamps_ns)):
            header = {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}, "frame_id": "cam_optical"}
            msg = build("sensor_msgs/msg/Image", {"header": header, "height": 480, "width": 640, "encoding": "mono8",
                                                  "step": 640, "data": image.reshape(-1)})  # fmt: skip
            w.write(conn, 1_700_000_000_000_000_000 + k * 50_000_000, store.serialize_cdr(msg, "sensor_msgs/msg/Image"))
    return path


@pytest.mark.parametrize("back_ns", [0, 20_000_000])
def test_an_image_stamped_again_or_earlier_is_left_out_of_the_track(tmp_path, capsys, drive, back_ns):
    """A driver that stamps two images alike (or a clock set back) stopped the track with an error that named
    neither the bag nor a way out: "frame 2's time 0.050000000 s is not after the previous frame's"."""
    t0 = 1_700_000_000_000_000_000
    images = [drive.images[0], drive.images[1], drive.images[1], drive.images[1]]
    stamps_ns = [t0, t0 + 50_000_000, t0 + 50_000_000 - back_ns, t0 + 100_000_000]
    bag = _stamped_bag(tmp_path / "cam.mcap", images, stamps_ns)
    RAW.save(tmp_path / "cam.json")
    out = tmp_path / "poses.mcap"
    code, stdout, err = run(
        capsys, "locate", bag, "--map", MAP, "--camera", tmp_path / "cam.json", "--track", "-o", out
    )
    assert code == 0, err
    said = "repeats" if back_ns == 0 else "is 0.020000000 s before"
    assert err.splitlines() == [
        f"warning: cam.mcap#2: its header stamp 1700000000.{50_000_000 - back_ns:09d} s {said} the last image's; "
        "left out of the track (a track needs increasing stamps)"
    ]
    assert "3 frames tracked" in stdout
    rows = [line.split()[:2] for line in stdout.splitlines() if line.startswith("cam.mcap#")]
    assert rows == [["cam.mcap#0", "0.000"], ["cam.mcap#1", "0.050"], ["cam.mcap#3", "0.100"]]
    assert [t for t, _ in messages(out, "/fidlearn/pose")] == [t0, t0 + 50_000_000, t0 + 100_000_000]


@pytest.mark.parametrize(("encoding", "order"), [("yuv422", "UYVY"), ("yuv422_yuy2", "YUYV")])
def test_yuv422_images_are_read_as_their_colours(encoding, order):
    """usb_cam and v4l2_camera publish two pixels in four bytes, their colour shared: built here by hand from a
    known picture of pairs of equal pixels (so no colour is lost), decoded to within the conversion's rounding."""
    rng = np.random.default_rng(3)
    bgr = np.repeat(rng.integers(40, 215, (6, 4, 3), dtype=np.uint8), 2, axis=1)  # 6 x 8, pixel pairs alike
    b, g, r = (bgr[..., k].astype(float) / 255 for k in range(3))  # BT.601 video range, as cameras send it
    y = np.round(16 + 65.481 * r + 128.553 * g + 24.966 * b).astype(np.uint8)
    u = np.round(128 - 37.797 * r - 74.203 * g + 112.0 * b).astype(np.uint8)[:, ::2]
    v = np.round(128 + 112.0 * r - 93.786 * g - 18.214 * b).astype(np.uint8)[:, ::2]
    packed = np.empty((6, 4, 4), np.uint8)  # per pair of pixels
    if order == "UYVY":
        packed[..., 0], packed[..., 1], packed[..., 2], packed[..., 3] = u, y[:, ::2], v, y[:, 1::2]
    else:
        packed[..., 0], packed[..., 1], packed[..., 2], packed[..., 3] = y[:, ::2], u, y[:, 1::2], v
    step = 8 * 2 + 4  # a row stride wider than the pixels
    rows = np.zeros((6, step), np.uint8)
    rows[:, :16] = packed.reshape(6, 16)
    msg = SimpleNamespace(encoding=encoding, height=6, width=8, step=step, is_bigendian=0, data=rows.reshape(-1))
    out = decode_image(msg, "cam.mcap")
    assert out.shape == (6, 8, 3)
    assert np.abs(out.astype(int) - bgr.astype(int)).max() <= 3
    odd = SimpleNamespace(encoding=encoding, height=6, width=7, step=step, is_bigendian=0, data=rows.reshape(-1))
    with pytest.raises(RosFormatError, match="in pairs; its width 7 is odd"):
        decode_image(odd, "cam.mcap")
