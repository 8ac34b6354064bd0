"""The bundled data: it holds what data/README.md says, calibrates back to its truth and regenerates.

Regeneration compares pixels exactly when the OpenCV and NumPy that run the test
are the ones that made the files (recorded in each JSON's ``provenance``);
another release may round ``cv2.remap``/``cv2.resize``/``cv2.GaussianBlur``
or draw normal deviates differently, so then a gray level or two may move and
the test allows that, never a change of geometry (see data/README.md).
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from fidlearn import Board, Camera, MarkerMap, data_dir, data_path
from fidlearn.synthetic import (
    render_calibration_views,
    render_scene,
    render_trajectory,
    survey_room,
    survey_walk,
    tape_measured,
    trajectory_poses,
)


def read_json(*parts):
    return json.loads(data_path(*parts).read_text(encoding="utf-8"))


def read_gray(*parts):
    image = cv2.imread(str(data_path(*parts)), cv2.IMREAD_UNCHANGED)
    assert image is not None
    assert image.ndim == 2
    assert image.dtype == np.uint8
    return image


def assert_same_pixels(rendered: np.ndarray, committed: np.ndarray, provenance: dict) -> None:
    assert rendered.shape == committed.shape
    assert rendered.dtype == committed.dtype
    if provenance["opencv"] == cv2.__version__ and provenance["numpy"] == np.__version__:
        np.testing.assert_array_equal(rendered, committed)
    else:  # another OpenCV or NumPy release: rounding may differ, the picture may not
        diff = np.abs(rendered.astype(int) - committed.astype(int))
        assert diff.mean() < 1.0
        assert np.mean(diff <= 4) > 0.995


# -- what is there ----------------------------------------------------------------------------------


def test_data_stays_small_and_synthetic_frames_are_png():
    # the robot's 16 lossless 1600x1200 grey photos (16 MB), the fisheye's 18 photos as published (3.7 MB)
    # and TUM VI's six 1024x1024 grey AprilGrid frames (3.1 MB) have budgets of their own
    robot = data_path("real", "robot_charuco")
    fisheye = data_path("real", "fisheye_checkerboard")
    aprilgrid = data_path("real", "tumvi_aprilgrid")
    own = (robot, fisheye, aprilgrid)
    files = [p for p in data_dir().rglob("*") if p.is_file() and not any(f in p.parents for f in own)]
    assert sum(p.stat().st_size for p in files) < 15e6
    assert sum(p.stat().st_size for p in robot.iterdir()) < 17e6
    assert sum(p.stat().st_size for p in fisheye.rglob("*") if p.is_file()) < 4e6
    assert sum(p.stat().st_size for p in aprilgrid.iterdir()) < 3.3e6
    for folder in ("calibration", "scenes", "trajectory"):
        assert not [p for p in data_path(folder).iterdir() if p.suffix.lower() in (".jpg", ".jpeg")]


def test_real_photos_are_all_there_and_readable():
    right = sorted(p.name for p in data_path("real", "opencv_checkerboard_right").glob("*.jpg"))
    assert right == [f"right{i:02d}.jpg" for i in (1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14)]
    charuco = sorted(p.name for p in data_path("real", "opencv_charuco").glob("*.jpg"))
    assert charuco == ["chocclusion_original.jpg", "img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg"]
    for parts in [
        ("real", "opencv_checkerboard_right", "right01.jpg"),
        ("real", "opencv_charuco", "img_00.jpg"),
        ("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"),
    ]:
        image = cv2.imread(str(data_path(*parts)))
        assert image is not None
        assert image.shape[:2] == (480, 640)
    # the published numbers of the tutorial's ChArUco calibration (data/README.md)
    cam = Camera.load(data_path("real", "opencv_charuco", "tutorial_camera_charuco.yml"))
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == pytest.approx((452.511, 456.767, 317.703, 277.752), abs=1e-3)
    cam = Camera.load(data_path("real", "opencv_aruco_photo", "tutorial_camera_params.yml"), image_size=(640, 480))
    assert cam.fx == pytest.approx(628.158)


def test_two_walls_map_adds_side_walls_to_the_seed_map():
    seed = MarkerMap.load(data_path("world_map.json"))
    both = MarkerMap.load(data_path("two_walls_map.json"))
    assert both.ids == [0, 1, 2, 3, 4, 5]
    assert both.marker_size_mm == 80
    assert both.dictionary == seed.dictionary
    for mid in seed.ids:
        np.testing.assert_allclose(both.marker_corners(mid), seed.marker_corners(mid), atol=1e-9)
    np.testing.assert_allclose(both.normal(3), [0, 1, 0], atol=1e-12)  # west wall, facing east into the room
    np.testing.assert_allclose(both.normal(5), [0, -1, 0], atol=1e-12)  # east wall, facing west
    assert not both.is_coplanar()


# -- calibration -----------------------------------------------------------------------------------


def test_synthetic_checkerboard_views_calibrate_back_to_the_true_camera():
    truth = Camera.load(data_path("calibration", "camera_true.json"))
    record = read_json("calibration", "views.json")
    pattern = tuple(record["arguments"]["pattern_size"])
    assert pattern == (9, 6)
    assert len(record["views"]) == 20
    object_points = np.array(record["object_points_mm"], dtype=np.float32)
    found = []
    for view in record["views"]:
        image = read_gray("calibration", view["image"])
        assert image.shape == (480, 640)
        ok, corners = cv2.findChessboardCorners(image, pattern)
        assert ok, view["image"]
        corners = cv2.cornerSubPix(
            image, corners, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 1e-3)
        )
        found.append(corners)
        # the recorded truth is where OpenCV finds the corners (either end first)
        c, t = corners.reshape(-1, 2), np.array(view["corners_px"])
        assert min(np.abs(c - t).max(), np.abs(c[::-1] - t).max()) < 0.5
    rms, K, dist, _, _ = cv2.calibrateCamera([object_points] * len(found), found, truth.image_size, None, None)
    assert rms < 0.3
    assert K[0, 0] == pytest.approx(truth.fx, rel=0.005)
    assert K[1, 1] == pytest.approx(truth.fy, rel=0.005)
    assert K[0, 2] == pytest.approx(truth.cx, abs=2.0)
    assert K[1, 2] == pytest.approx(truth.cy, abs=2.0)


def test_a_calibration_view_regenerates_from_its_recipe():
    record = read_json("calibration", "views.json")
    args = dict(record["arguments"])
    camera = Camera.load(data_path("calibration", "camera_true.json"))
    view = 13
    again = render_calibration_views(
        camera,
        n_views=args.pop("n_views"),
        board=Board.checkerboard(args.pop("pattern_size"), args.pop("square_size_mm")),
        seed=args.pop("seed"),
        views=[view],
        **args,
    )
    np.testing.assert_allclose(again.T_world_camera[0], record["views"][view]["T_world_camera"], atol=1e-9)
    assert_same_pixels(again.images[0], read_gray("calibration", record["views"][view]["image"]), record["provenance"])


# -- scenes and the drive ----------------------------------------------------------------------------


def test_scene_records_hold_the_projection_of_the_map_and_opencv_finds_them():
    record = read_json("scenes", "poses.json")
    camera = Camera.load(data_path("scenes", record["camera"]))
    assert camera.image_size == (1280, 720)
    assert len(record["images"]) == 10
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL))
    for item in record["images"]:
        marker_map = MarkerMap.load(data_path(item["map"]))
        T = np.array(item["T_world_camera"])
        distance = np.linalg.norm(T[:3, 3] - np.mean([c.mean(axis=0) for c in marker_map.corners().values()], axis=0))
        assert 900 < distance < 3100
        assert item["visible_ids"]
        assert [int(k) for k in item["corners_px"]] == item["visible_ids"]
        for mid, px in item["corners_px"].items():
            np.testing.assert_allclose(px, camera.project(marker_map.marker_corners(int(mid)), T), atol=1e-5)
        _, ids, _ = detector.detectMarkers(read_gray("scenes", item["image"]))
        assert ids is not None, item["image"]
        assert set(item["visible_ids"]) <= set(np.ravel(ids).tolist()), item["image"]
    assert {item["map"] for item in record["images"]} == {"world_map.json", "two_walls_map.json"}


def test_a_scene_regenerates_from_its_record():
    record = read_json("scenes", "poses.json")
    camera = Camera.load(data_path("scenes", record["camera"]))
    item = record["images"][7]
    scene = render_scene(
        MarkerMap.load(data_path(item["map"])),
        camera,
        np.array(item["T_world_camera"]),
        seed=item["seed"],
        **record["render"],
    )
    image, truth = scene.image, scene.truth
    assert sorted(truth) == item["visible_ids"]
    assert_same_pixels(image, read_gray("scenes", item["image"]), record["provenance"])


def test_a_survey_photo_regenerates_from_its_record_and_the_maps_are_what_they_say():
    record = read_json("survey", "poses.json")
    camera = Camera.load(data_path("survey", record["camera"]))
    truth = MarkerMap.load(data_path("survey", record["true_map"]))
    assert truth.corners().keys() == survey_room(record["marker_size_mm"]).corners().keys()
    poses = survey_walk(truth, camera, n_photos=record["n_photos"], seed=record["seed"])
    item = record["photos"][5]
    np.testing.assert_allclose(poses[5], item["T_world_camera"], atol=1e-9)
    scene = render_scene(truth, camera, poses[5], seed=item["seed"], **record["render"])
    image, seen = scene.image, scene.truth
    assert sorted(seen) == item["visible_ids"]
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, record["jpeg_quality"]])
    assert_same_pixels(
        cv2.imdecode(buf, cv2.IMREAD_UNCHANGED), read_gray("survey", item["image"]), record["provenance"]
    )
    tape, tp = MarkerMap.load(data_path("survey", record["tape_map"])), record["tape"]
    moved = {int(k): tuple(v) for k, v in tp["moved"].items()}
    again = tape_measured(
        truth, sigma_mm=tp["sigma_mm"], sigma_deg=tp["sigma_deg"], moved=moved, seed=tp["seed"], units=tp["units"]
    )
    assert tape.units == "cm"
    assert max(np.abs(tape.corners()[i] - again.corners()[i]).max() for i in tape.ids) < 1e-6
    off = np.subtract(tape.placements[7].translation_mm, truth.placements[7].translation_mm)
    assert np.linalg.norm(off) > 60  # marker 7 was moved after it was taped


def test_trajectory_frames_regenerate_from_the_seed():
    record = read_json("trajectory", "poses.json")
    camera = Camera.load(data_path("trajectory", record["camera"]))
    marker_map = MarkerMap.load(data_path(record["map"]))
    poses = trajectory_poses(marker_map, record["n_frames"], record["seed"])
    assert len(record["frames"]) == record["n_frames"] == 40
    for pose, frame in zip(poses, record["frames"]):
        np.testing.assert_allclose(pose, frame["T_world_camera"], atol=1e-9)
    frame = 23
    drive = render_trajectory(
        marker_map, camera, seed=record["seed"], poses=poses, frames_to_render=[frame], **record["render"]
    )
    assert sorted(drive.truth[0]) == record["frames"][frame]["visible_ids"]
    assert_same_pixels(drive.images[0], read_gray("trajectory", record["frames"][frame]["image"]), record["provenance"])


def test_the_drive_is_seen_by_opencv_and_its_solvepnp_agrees_with_the_true_poses():
    """Plain OpenCV on three frames: every listed marker is found, and solvePnP lands near the true pose."""
    record = read_json("trajectory", "poses.json")
    camera = Camera.load(data_path("trajectory", record["camera"]))
    marker_map = MarkerMap.load(data_path(record["map"]))
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL), params)
    for frame in (record["frames"][0], record["frames"][20], record["frames"][39]):
        corners, ids, _ = detector.detectMarkers(read_gray("trajectory", frame["image"]))
        ids = np.ravel(ids).tolist()
        assert set(frame["visible_ids"]) <= set(ids)
        assert frame["visible_ids"] == [0, 1, 2]
        object_points = np.concatenate([marker_map.marker_corners(i) for i in ids])
        image_points = np.concatenate([np.asarray(c, dtype=float).reshape(4, 2) for c in corners])
        ok, rvec, tvec = cv2.solvePnP(object_points, image_points, camera.K, camera.dist, flags=cv2.SOLVEPNP_ITERATIVE)
        assert ok
        R, _ = cv2.Rodrigues(rvec)
        position = -R.T @ tvec.ravel()
        true_position = np.array(frame["T_world_camera"])[:3, 3]
        distance = np.linalg.norm(
            true_position - np.mean([c.mean(axis=0) for c in marker_map.corners().values()], axis=0)
        )
        assert (
            np.linalg.norm(position - true_position) < 0.05 * distance
        )  # 80 mm markers, 20-60 px: depth is the weak axis
