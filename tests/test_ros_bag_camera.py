"""A camera file given for a ROS 2 bag: it must be the bag's camera, and it stands in for an uncalibrated one."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from helpers import assert_user_error
from helpers import run_cli as run
from test_ros_bag import CAM, _driver_bag, _info, stamps

import fidlearn
from fidlearn import data_path
from fidlearn.errors import CameraError
from fidlearn.ros import read_bag, write_image_bag
from fidlearn.ros._camera_info import camera_disagreement

MAP = data_path("world_map.json")


@pytest.fixture(scope="module")
def drive():
    return fidlearn.render_trajectory(fidlearn.MarkerMap.load(MAP), CAM, n_frames=6, frames_to_render=[0, 5])


def _moved(camera, **change):
    K = camera.K.copy()
    K[0, 0] *= change.get("f", 1.0)
    K[1, 1] *= change.get("f", 1.0)
    K[0, 2] += change.get("cx", 0.0)
    return fidlearn.Camera(K, change.get("dist", camera.dist), (camera.width, camera.height))


def test_the_same_calibration_saved_again_agrees_and_another_does_not(tmp_path):
    cam = fidlearn.Camera(CAM.K, [0.1, -0.05, 0.001, 0.002, 0.01], (640, 480))
    cam.save(tmp_path / "c.yml")  # OpenCV YAML: the numbers written and read back
    assert camera_disagreement(cam, fidlearn.Camera.load(tmp_path / "c.yml")) is None
    assert camera_disagreement(cam, _moved(cam, f=1.0005)) is None  # 0.3 px at the corners: rounding's size
    said = camera_disagreement(cam, _moved(cam, f=1.01))  # 1 % in f: 4-5 px at the picture's corners
    assert said is not None
    assert "px apart" in said
    assert "fx 554.3" in said  # both cameras named
    apart = float(said.split("up to ")[1].split(" px")[0])
    assert 3.0 < apart < 6.0
    assert camera_disagreement(cam, _moved(cam, cx=2.0)).startswith("the two cameras put one ray up to 2.0 px")
    assert camera_disagreement(cam, _moved(cam, dist=[0.0] * 5)) is not None  # the bag's distortion left out


def test_a_camera_file_stands_in_for_an_uncalibrated_camera_info(tmp_path, capsys, drive):
    images = [cv2.cvtColor(im, cv2.COLOR_GRAY2BGR) for im in drive.images]
    bag = _driver_bag(tmp_path / "raw", images, info=_info(k=[0.0] * 9, d=()))
    with pytest.raises(CameraError, match=r"not calibrated \(K is all zeros\); give a camera file \(--camera"):
        read_bag(bag)
    CAM.save(tmp_path / "cam.json")
    frames = list(read_bag(bag, camera=CAM))
    assert [f.camera for f in frames] == [CAM, CAM]
    code, out, err = run(capsys, "locate", bag, "--map", MAP, "--camera", tmp_path / "cam.json")
    assert code == 0, err
    assert "2 frames, 2 located (100 %)" in out
    pose = fidlearn.locate(frames[1].image, MAP, CAM)
    assert np.linalg.norm(pose.position_mm - drive.T_world_camera[1][:3, 3]) < 5.0


def test_a_camera_file_that_is_not_the_bags_is_refused(tmp_path, capsys, drive):
    bag = write_image_bag(tmp_path / "in.mcap", drive.images, CAM, stamps(2))
    assert read_bag(bag, camera=CAM) is not None  # the bag's own camera: agreed
    other = _moved(CAM, f=1.05)
    with pytest.raises(CameraError, match="the camera given is not the bag's: the two cameras put one ray up to"):
        read_bag(bag, camera=other)
    other.save(tmp_path / "other.json")
    out = tmp_path / "out.mcap"
    code, _, err = run(capsys, "locate", bag, "--map", MAP, "--camera", tmp_path / "other.json", "-o", out)
    assert_user_error(
        code, err, "in.mcap /camera/camera_info: the camera given is not the bag's", "the bag's CameraInfo"
    )
    assert not out.exists()
    with pytest.raises(CameraError, match="give a fidlearn.Camera"):
        read_bag(bag, camera=str(tmp_path / "other.json"))


@pytest.mark.parametrize("track", [False, True])
def test_annotated_images_go_into_the_output_bag_at_the_stamps(tmp_path, capsys, drive, track):
    from test_ros_bag import messages

    bag = write_image_bag(tmp_path / "in.mcap", drive.images, CAM, stamps(2))
    out = tmp_path / "out.mcap"
    code, _, err = run(capsys, "locate", bag, "--map", MAP, *(["--track"] if track else []), "-o", out,
                       "--annotated-images")  # fmt: skip
    assert code == 0, err
    got = messages(out, "/fidlearn/image_annotated/compressed")
    assert [t for t, _ in got] == stamps(2)
    for (_, msg), T in zip(got, drive.T_world_camera):
        assert msg.format == "jpeg"
        assert msg.header.frame_id == "camera"
        drawn = cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_COLOR)
        assert drawn.shape == (480, 640, 3)
        # the drawing is in colour where the markers are; the rendered picture itself is gray
        colour = np.abs(drawn.astype(int) - drawn.mean(axis=2, keepdims=True)).max(axis=2) > 40
        px = CAM.project(fidlearn.MarkerMap.load(MAP).marker_corners(0), T)
        x0, y0 = np.clip(px.min(axis=0).astype(int) - 6, 0, None)
        x1, y1 = px.max(axis=0).astype(int) + 6
        assert colour[y0:y1, x0:x1].mean() > 0.02  # the marker's outline and id drawn around it
        assert colour.mean() < 0.2
    assert len(messages(out, "/fidlearn/pose")) == 2


def test_annotated_images_need_a_bag_output(tmp_path, capsys, drive):
    bag = write_image_bag(tmp_path / "in.mcap", drive.images, CAM, stamps(2))
    assert_user_error(*run(capsys, "locate", bag, "--map", MAP, "--annotated-images")[::2], "add -o OUT.mcap")
    pic = data_path("scenes", "scene_00.png")
    cam = data_path("scenes", "camera.json")
    assert_user_error(*run(capsys, "locate", pic, "--camera", cam, "--map", MAP, "--annotated-images")[::2],
                      "give a bag and -o OUT.mcap")  # fmt: skip
