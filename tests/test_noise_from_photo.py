"""fidlearn.planning.noise_from_photo: a photo's noise, as detect + estimate_pose + noise_from_pose give it."""

from __future__ import annotations

import numpy as np
import pytest

import fidlearn
from fidlearn import CameraError, ImageError, PoseError, data_path
from fidlearn.images import load_image
from fidlearn.planning import MeasuredNoise, noise_from_photo, noise_from_pose

REAL = data_path("real", "opencv_charuco")
CAMERA = fidlearn.Camera.load(REAL / "tutorial_camera_charuco.yml", image_size=(640, 480))
BOARD = fidlearn.MarkerMap.load(REAL / "board_map.json")
PHOTO = load_image(REAL / "img_00.jpg")


def test_the_photo_gives_the_noise_of_its_pose():
    found = noise_from_photo(PHOTO, BOARD, CAMERA)
    assert isinstance(found, MeasuredNoise)
    assert len(found.pose.marker_ids) == 17
    pose = fidlearn.estimate_pose(fidlearn.detect_markers(PHOTO, BOARD.dictionary), BOARD, CAMERA)
    np.testing.assert_allclose(found.pose.T_world_camera, pose.T_world_camera, atol=1e-12)
    assert found.noise == pytest.approx(noise_from_pose(pose, BOARD, CAMERA))
    assert found.kwargs() == found.noise.kwargs()
    assert -0.02 < found.noise.marker_size_rel_error < -0.01  # these photos' markers look 1.3 % small


def test_what_cannot_give_a_noise_is_refused():
    with pytest.raises(CameraError, match=r"^the photo is 320x240 and the camera 640x480; take it at the resolution"):
        noise_from_photo(PHOTO[::2, ::2].copy(), BOARD, CAMERA)
    three = fidlearn.MarkerMap.load(data_path("world_map.json"))
    scenes = fidlearn.Camera.load(data_path("scenes", "camera.json"))
    with pytest.raises(PoseError, match="the pose used 3 markers; at least 4"):
        noise_from_photo(load_image(data_path("scenes", "scene_00.png")), three, scenes)
    with pytest.raises(ImageError, match="image must be a picture"):
        noise_from_photo("img_00.jpg", BOARD, CAMERA)
    with pytest.raises(PoseError, match="camera must be a fidlearn Camera"):
        noise_from_photo(PHOTO, BOARD, "camera.json")
