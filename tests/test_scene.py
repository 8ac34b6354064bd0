"""render_scene's Scene: the picture, the true corners, and the truth file ``fidlearn render --truth`` writes."""

from __future__ import annotations

import json

import numpy as np

from fidlearn import Camera, MarkerMap, data_path, look_at
from fidlearn.cli import main
from fidlearn.images import load_image
from fidlearn.synthetic import Scene, render_scene, visible_markers

WORLD = MarkerMap.load(data_path("world_map.json"))
CAMERA = Camera.from_fov(60, (320, 240))
T = look_at([1200, 200, 250], [0, 200, 250])


def test_the_scene_holds_the_picture_its_truth_and_what_it_came_from():
    scene = render_scene(WORLD, CAMERA, T, seed=7, noise_std_gray=1.5, blur_px=0.5)
    assert isinstance(scene, Scene)
    assert scene.image.shape == (240, 320)
    assert scene.image.dtype == np.uint8
    assert sorted(scene.truth) == sorted(visible_markers(WORLD, CAMERA, T)) == [0, 1, 2]
    for i, corners in scene.truth.items():
        np.testing.assert_array_equal(corners, CAMERA.project(WORLD.marker_corners(i), T))
    np.testing.assert_array_equal(scene.T_world_camera, T)
    assert scene.camera is CAMERA
    assert scene.marker_map is WORLD
    assert (scene.seed, scene.noise_std_gray, scene.blur_px) == (7, 1.5, 0.5)


def test_the_truth_record_says_the_pose_and_the_corners():
    scene = render_scene(WORLD, CAMERA, T, seed=2)
    rec = scene.truth_record("scene.png", "maps/world_map.json")
    assert rec["image"] == "scene.png"
    assert rec["map"] == "maps/world_map.json"
    assert rec["position_mm"] == [1200.0, 200.0, 250.0]
    assert np.allclose(rec["rpy_deg"], [-90.0, 0.0, 90.0])  # facing -X, level
    assert rec["markers_px"] == {str(i): scene.truth[i].tolist() for i in (0, 1, 2)}
    assert rec["camera"] == CAMERA.to_dict()
    assert rec["dictionary"] == WORLD.dictionary
    assert (rec["seed"], rec["noise_std_gray"], rec["blur_px"]) == (2, 0.0, 0.0)
    assert scene.truth_record("scene.png")["map"] == WORLD.source


def test_save_truth_writes_what_fidlearn_render_writes(tmp_path):
    camera_file = tmp_path / "camera.json"
    CAMERA.save(camera_file)
    world = data_path("world_map.json")
    argv = [
        "render",
        "--map",
        str(world),
        "--camera",
        str(camera_file),
        "--from",
        "1200,200,250",
        "--look-at",
        "0,200,250",
    ]
    assert (
        main(
            argv
            + ["--seed", "3", "--noise", "1.5", "-o", str(tmp_path / "cli.png"), "--truth", str(tmp_path / "cli.json")]
        )
        == 0
    )
    scene = render_scene(WORLD, Camera.load(camera_file), T, seed=3, noise_std_gray=1.5, blur_px=0.0)
    out = scene.save_truth(tmp_path / "lib.json", "cli.png", str(world))
    assert out.read_bytes() == (tmp_path / "cli.json").read_bytes()
    np.testing.assert_array_equal(load_image(tmp_path / "cli.png"), scene.image)
    text = out.read_text()
    assert '"position_mm": [1200.0, 200.0, 250.0]' in text  # a matrix row on one line
    assert json.loads(text)["markers_px"]["0"] == scene.truth[0].tolist()
