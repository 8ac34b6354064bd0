"""A fisheye camera end to end: the renderer draws through the fisheye model (the detected corners land on the
true ones), and locate / estimate_pose find the known pose from the exactly undistorted corners."""

from __future__ import annotations

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, MarkerMap, frames
from fidlearn.pose._inputs import _check_inputs
from fidlearn.synthetic import render_scene

#: ROS's calibration of the real fisheye lens of data/real/fisheye_checkerboard (mono set).
K_FE = np.array([[290.050152, 0.0, 399.938345], [0.0, 289.392837, 273.885669], [0.0, 0.0, 1.0]])
D_FE = np.array([-0.030464, -0.019695, 0.002098, 0.001030])
EYES = [[500.0, 150.0, 300.0], [600.0, -100.0, 250.0], [450.0, 400.0, 400.0]]


@pytest.fixture(scope="module")
def scenes():
    cam = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    walls = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    out = []
    for seed, eye in enumerate(EYES):
        T = frames.look_at(eye, [0.0, 150.0, 260.0], roll_deg=5 * seed)
        out.append(render_scene(walls, cam, T, seed=seed, blur_px=0.5, noise_std_gray=1.0))
    return out


def test_the_renderer_draws_through_the_fisheye(scenes):
    for scene in scenes:
        assert scene.camera.model == "fisheye"
        dets = fidlearn.detect_markers(scene.image, scene.marker_map.dictionary)
        matched = [d for d in dets if d.id in scene.truth]
        assert len(matched) >= 3
        for d in matched:  # a pinhole drawing of these corners would be tens of pixels away
            assert np.abs(d.corners_px - scene.truth[d.id]).max() < 0.3
    # markers far off the axis (80 degrees) are seen whole, as the fisheye sees them
    assert 3 in scenes[2].truth


def test_locate_finds_the_known_pose_with_a_fisheye_camera(scenes):
    for scene in scenes:
        pose = fidlearn.locate(scene.image, scene.marker_map, scene.camera)
        T = scene.T_world_camera
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 2.0  # 0.7 to 1.1 mm at half a metre
        R = pose.T_world_camera[:3, :3].T @ T[:3, :3]
        assert np.degrees(np.arccos(min(1.0, (np.trace(R) - 1) / 2))) < 0.2
        assert pose.reprojection_rms_px < 0.3
    # the same photos read as a pinhole camera with the same four numbers: the pose is far off
    scene = scenes[0]
    wrong = fidlearn.locate(scene.image, scene.marker_map, Camera(K_FE, D_FE, (800, 503)))
    assert np.linalg.norm(wrong.position_mm - scene.T_world_camera[:3, 3]) > 10.0


def test_estimate_pose_leaves_out_a_marker_beyond_90_degrees():
    wide = Camera([[200, 0, 399.5], [0, 200, 251.5], [0, 0, 1]], [0.0] * 4, (800, 503), model="fisheye")
    walls = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    T = frames.look_at([500.0, 150.0, 300.0], [0.0, 150.0, 260.0])
    dets = [fidlearn.detection.Detection(m, wide.project(walls.marker_corners(m), T)) for m in (0, 1, 2)]
    # a known marker reported in the picture's corner, which this lens sees 103 degrees off the axis
    beyond = fidlearn.detection.Detection(5, [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    kept, _, pinhole = _check_inputs([*dets, beyond], walls, wide)
    assert [d.id for d in kept] == [0, 1, 2]
    assert pinhole.model == "pinhole"
    assert not pinhole.has_distortion
    np.testing.assert_allclose(kept[0].corners_px, wide.undistort_points(dets[0].corners_px))
    pose = fidlearn.estimate_pose([*dets, beyond], walls, wide)
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 1e-3  # exact corners: the exact pose
    assert 5 not in pose.marker_ids
    assert pose.rejected_ids == (5,)  # reported as the rim test reports the markers just inside 90 degrees
    # an id the map has not, past 90 degrees: ignored, as it is anywhere in the picture
    stranger = fidlearn.detection.Detection(40, beyond.corners_px)
    assert fidlearn.estimate_pose([*dets, stranger], walls, wide).ignored_ids == (40,)
    # only markers past 90 degrees: no pose, and the error says why
    with pytest.raises(fidlearn.PoseError, match=r"markers \[5\] have a corner 90 degrees or more off"):
        fidlearn.estimate_pose([beyond], walls, wide)


def test_the_undistorted_picture_with_the_undistorted_camera_finds_the_pose(scenes):
    from fidlearn.planning import predict_accuracy

    scene = scenes[0]
    # (OpenCV's new camera for this 180-degree lens is a narrow 80 px focal length: twice the picture size)
    ideal = scene.camera.undistorted(0.0, (1600, 1006))
    picture = scene.camera.undistort_image(scene.image, 0.0, (1600, 1006))
    pose = fidlearn.locate(picture, scene.marker_map, ideal)
    err = pose.position_mm - scene.T_world_camera[:3, 3]
    assert np.all(np.abs(err) < 3 * pose.position_std_mm)
    assert np.linalg.norm(err) < 10.0
    assert predict_accuracy(scene.marker_map, ideal, scene.T_world_camera) is not None


def test_a_marker_at_the_rim_is_left_out_of_the_pose_with_its_reason():
    # a 160-degree equidistant fisheye (286 px per radian) before a wall of 120 mm markers; from this pose marker
    # 14 is seen 84.5 to 89.9 degrees off the axis: past 89.8 (tan = 286) a one-pixel error in the picture bends
    # its ideal pinhole pixel as much as it moves it (RIM_PICTURE_PX); its neighbour 24, at up to 81 degrees, is kept
    size = (800, 600)
    f = 400 / np.radians(80)
    lens = Camera([[f, 0, 399.5], [0, f, 299.5], [0, 0, 1]], [0.0] * 4, size, model="fisheye")
    wall = MarkerMap.from_dict(
        {
            str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]}
            for k, (y, z) in enumerate((y, z) for y in range(-1500, 1501, 300) for z in range(-900, 901, 300))
        },
        marker_size_mm=120,
        units="mm",
    )
    rng = np.random.default_rng(1001)
    eye = [rng.uniform(300, 700), rng.uniform(-400, 400), rng.uniform(-300, 300)]
    T = frames.look_at(eye, [0.0, rng.uniform(-600, 600), rng.uniform(-400, 400)], roll_deg=rng.uniform(-20, 20))
    scene = render_scene(wall, lens, T, seed=1, blur_px=0.5, noise_std_gray=2.0)
    dets = [d for d in fidlearn.detect_markers(scene.image, wall.dictionary) if d.id in wall]
    rim = next(d for d in dets if d.id == 14)
    off_axis = np.degrees(np.hypot(*((rim.corners_px - [399.5, 299.5]) / f).T))  # equidistant: angle = r / f
    assert off_axis.min() > 84
    assert 89 < off_axis.max() < 90
    assert np.tan(np.radians(off_axis.max())) > f
    for others in (True, False):  # left out before the outlier screen, which need not run
        pose = fidlearn.locate(scene.image, wall, lens, reject_outliers=others)
        assert pose.rejected_ids == (14,)
        assert 14 not in pose.marker_ids
        assert len(pose.marker_ids) == len(dets) - 1
        assert 24 in pose.marker_ids
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 0.3  # 0.06 mm (its sides fitted as the lens bends them)
    # alone, the rim marker is not left out: a pose from it beats none
    alone = fidlearn.estimate_pose([rim], wall, lens)
    assert alone.marker_ids == (14,)
    assert alone.rejected_ids == ()
