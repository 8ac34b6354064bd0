"""The synthetic world against known answers: plain OpenCV must find what the renderer says it drew.

Pixel convention everywhere: OpenCV's, pixel centres at integer coordinates.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import Board, Camera, FidlearnError, MarkerMap, data_path, frames
from fidlearn._lens import distort_normalized, undistort_exact
from fidlearn.errors import CameraError
from fidlearn.frames import look_at
from fidlearn.synthetic import (
    render_calibration_views,
    render_scene,
    render_trajectory,
    trajectory_poses,
    visible_markers,
)

WIDE_LENS = [-0.25, 0.08, 0.001, -0.0005, -0.01]


@pytest.fixture(scope="module")
def wall() -> MarkerMap:
    return MarkerMap.load(data_path("world_map.json"))


def aruco_detect(image, dictionary=cv2.aruco.DICT_ARUCO_ORIGINAL):
    """Plain OpenCV detection with sub-pixel corners: {id: (4, 2)}."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(dictionary), params)
    corners, ids, _ = detector.detectMarkers(image)
    if ids is None:
        return {}
    return {int(i): np.asarray(c, dtype=float).reshape(4, 2) for c, i in zip(corners, np.ravel(ids))}


# -- geometry of the picture ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("size", "dist", "eye", "target", "roll"),
    [
        ((640, 480), None, [1000, 190, 240], [0, 190, 240], 0.0),
        ((640, 480), WIDE_LENS, [700, -300, 400], [0, 150, 230], 10.0),
        ((1280, 720), WIDE_LENS, [500, 400, 200], [0, 200, 260], -20.0),
        ((1280, 720), [-0.05, 0.01, 0, 0, 0], [1400, 600, 500], [0, 100, 200], 35.0),
    ],
)
def test_opencv_finds_every_visible_marker_at_its_true_corners(wall, size, dist, eye, target, roll):
    camera = Camera.from_fov(60, size, dist=dist)
    T = look_at(eye, target, roll_deg=roll)
    rendered = render_scene(wall, camera, T, seed=3, noise_std_gray=1.5, blur_px=0.4, gradient=0.2)
    image, truth = rendered.image, rendered.truth
    assert sorted(truth) == [0, 1, 2]
    found = aruco_detect(image)
    assert sorted(found) == sorted(truth)
    err = np.concatenate([found[i] - truth[i] for i in truth])
    rms = np.sqrt((err**2).sum(axis=1).mean())
    assert rms < 0.5, f"corner RMS {rms:.3f} px"
    assert np.all(np.abs(err.mean(axis=0)) < 0.15), f"systematic offset {err.mean(axis=0)} px"


def test_truth_is_exactly_the_projection_of_the_3d_corners(wall):
    camera = Camera.from_fov(55, (640, 480), dist=WIDE_LENS)
    T = look_at([900, -200, 350], [0, 190, 240], roll_deg=7)
    truth = render_scene(wall, camera, T).truth
    assert sorted(truth) == [0, 1, 2]
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(T))
    for mid, px in truth.items():
        assert px.shape == (4, 2)
        assert px.dtype == np.float64
        np.testing.assert_array_equal(px, camera.project(wall.marker_corners(mid), T))
        ref, _ = cv2.projectPoints(wall.marker_corners(mid).reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist)
        np.testing.assert_allclose(px, ref.reshape(4, 2), atol=1e-9)


def test_ink_lands_where_the_geometry_says_with_no_half_pixel_offset(wall):
    """Fronto-parallel, no distortion: the dark mass of a marker has the true area and centroid.

    Area integration makes both exact up to the supersampling; a half-pixel
    slip in the pixel-centre convention would move the centroid by 0.5 px.
    """
    camera = Camera([[800, 0, 300.3], [0, 800, 251.7], [0, 0, 1]], None, (640, 480))
    T = look_at([1000, 37.3, 270.1], [0, 37.3, 270.1])
    rendered = render_scene(wall, camera, T, wall_texture_std_gray=0.0, paper_gray=230, ink_gray=25)
    image, truth = rendered.image, rendered.truth
    tl, br = truth[0][0], truth[0][2]
    side = br[0] - tl[0]
    cells = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL).markerSize + 2
    black = (
        cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL), 0, cells) < 128
    )
    cell = side / cells
    u0, v0, u1, v1 = int(tl[0]) - 3, int(tl[1]) - 3, int(br[0]) + 4, int(br[1]) + 4
    ink = (230.0 - image[v0:v1, u0:u1]) / (230.0 - 25.0)
    vv, uu = np.mgrid[v0:v1, u0:u1]
    rows, cols = np.nonzero(black)
    area = ink.sum()
    assert area == pytest.approx(black.sum() * cell**2, rel=2e-3)
    assert (ink * uu).sum() / area == pytest.approx(tl[0] + (cols.mean() + 0.5) * cell, abs=0.02)
    assert (ink * vv).sum() / area == pytest.approx(tl[1] + (rows.mean() + 0.5) * cell, abs=0.02)


def test_distorted_checkerboard_corners_sit_on_their_projections():
    """cornerSubPix on an X-corner is unbiased: it checks the distortion mapping to a few hundredths of a pixel."""
    camera = Camera([[560, 0, 330.2], [0, 558, 236.4], [0, 0, 1]], [-0.3, 0.12, 0.001, -0.001, -0.02], (640, 480))
    views = render_calibration_views(camera, n_views=9, seed=5, views=[0, 4, 8], noise_std_gray=0.0, blur_px=0.0)
    for image, truth in zip(views.images, views.image_points):
        ok, found = cv2.findChessboardCorners(image, (9, 6))
        assert ok
        found = cv2.cornerSubPix(
            image, found, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
        ).reshape(-1, 2)
        if np.linalg.norm(found[0] - truth[0]) > np.linalg.norm(found[0] - truth[-1]):
            found = found[::-1]
        err = found - truth
        assert np.sqrt((err**2).sum(axis=1).mean()) < 0.1
        assert np.all(np.abs(err.mean(axis=0)) < 0.03)


def test_exact_undistortion_inverts_opencvs_projection():
    K = np.array([[700.0, 0, 330], [0, 690, 250], [0, 0, 1]])
    dist = np.array([-0.3, 0.1, 0.002, -0.001, -0.02, 0.01, 0.002, 0.001, 0.001, -0.0005, 0.0007, 0.0002])
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.45, 0.45, size=(200, 2))
    ref, _ = cv2.projectPoints(
        np.column_stack([xy, np.ones(len(xy))]).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist
    )
    ref = ref.reshape(-1, 2)
    mine = distort_normalized(xy, dist) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    np.testing.assert_allclose(mine, ref, atol=1e-9)
    np.testing.assert_allclose(undistort_exact(ref, K, dist), xy, atol=1e-10)


# -- what is and is not in the truth ---------------------------------------------------------------


def test_markers_behind_the_camera_are_neither_drawn_nor_in_the_truth(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([500, 190, 240], [2000, 190, 240])  # in the room, looking away from the wall
    rendered = render_scene(wall, camera, T, wall_texture_std_gray=0.0, wall_gray=120)
    image, truth = rendered.image, rendered.truth
    assert truth == {}
    assert np.all(image == 120)


def test_markers_seen_from_behind_the_wall_are_not_drawn(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([-800, 190, 240], [0, 190, 240])  # behind the wall, facing the back of the sheets
    rendered = render_scene(wall, camera, T, wall_texture_std_gray=0.0, wall_gray=120)
    image, truth = rendered.image, rendered.truth
    assert truth == {}
    assert np.all(image == 120)


def test_a_marker_partly_outside_the_frame_is_drawn_but_left_out_of_the_truth(wall):
    camera = Camera.from_fov(50, (640, 480))
    T = look_at([400, 226, 250], [0, 226, 250])  # the left image edge runs through marker 0
    rendered = render_scene(wall, camera, T)
    image, truth = rendered.image, rendered.truth
    assert sorted(truth) == [1, 2]
    px0 = camera.project(wall.marker_corners(0), T)
    assert np.any(px0[:, 0] < 0)  # really straddles the edge
    assert np.any(px0[:, 0] > 0)
    assert image[:, :5].min() < 60  # its ink reaches the image border
    assert set(truth) <= set(aruco_detect(image))


def test_a_sheet_crossing_the_camera_plane_is_drawn_where_it_is_in_front(wall):
    """The camera stands 20 mm from the wall inside marker 0's span, looking along the wall."""
    camera = Camera.from_fov(90, (320, 240))
    T = look_at([20.0, 40.0, 260.0], [60.0, 2000.0, 250.0])
    depths = frames.transform_points(frames.invert_transform(T), wall.marker_corners(0))[:, 2]
    assert depths.min() < 0 < depths.max()  # marker 0 really crosses the camera's plane
    rendered = render_scene(wall, camera, T, wall_texture_std_gray=0.0, wall_gray=120, paper_gray=230, ink_gray=25)
    image, truth = rendered.image, rendered.truth
    assert 0 not in truth
    # a few cm in front of the camera: a point of marker 0's black right border and one of its white margin
    ink_px, paper_px = np.round(camera.project(np.array([[0.0, 74.0, 262.0], [0.0, 86.0, 262.0]]), T)).astype(int)
    assert np.all((ink_px > 0) & (ink_px < [319, 239]))
    assert np.all((paper_px > 0) & (paper_px < [319, 239]))
    assert image[ink_px[1], ink_px[0]] < 40
    assert image[paper_px[1], paper_px[0]] > 215


@pytest.mark.parametrize(("front", "back"), [(7, 3), (3, 7)])
def test_the_nearest_sheet_wins(front, back):
    """One marker hangs 100 mm in front of another and hides it, whichever id comes first."""
    scene = MarkerMap.from_dict(
        {
            str(back): {"translation": [0, 0, 300], "rotation": [0, 0, 0]},
            str(front): {"translation": [100, 10, 290], "rotation": [0, 0, 0]},
        },
        units="mm",
        marker_size_mm=100,
    )
    camera = Camera.from_fov(50, (640, 480))
    T = look_at([900, 60, 240], [0, 60, 240])
    rendered = render_scene(scene, camera, T)
    image, truth = rendered.image, rendered.truth
    assert sorted(truth) == sorted([front, back])  # the truth does not model occlusion
    found = aruco_detect(image)
    assert sorted(found) == [front]
    assert np.abs(found[front] - truth[front]).max() < 0.5


def test_visible_means_in_front_inside_and_facing(wall):
    camera = Camera.from_fov(60, (640, 480))
    T = look_at([1000, 190, 240], [0, 190, 240])
    assert sorted(visible_markers(wall, camera, T)) == [0, 1, 2]
    tight = visible_markers(wall, camera, T, margin_px=300)
    assert tight == {}


# -- options --------------------------------------------------------------------------------------


def test_same_seed_same_pixels_and_another_seed_other_noise(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([800, 190, 240], [0, 190, 240])
    a = render_scene(wall, camera, T, seed=4, noise_std_gray=2.0).image
    b = render_scene(wall, camera, T, seed=4, noise_std_gray=2.0).image
    c = render_scene(wall, camera, T, seed=5, noise_std_gray=2.0).image
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)
    assert np.abs(a.astype(int) - c.astype(int)).mean() < 4


def test_blur_gradient_and_bgr(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([800, 190, 240], [0, 190, 240])
    sharp = render_scene(wall, camera, T, wall_texture_std_gray=0.0).image
    blurred = render_scene(wall, camera, T, wall_texture_std_gray=0.0, blur_px=2.0).image
    assert np.abs(np.diff(blurred.astype(float), axis=1)).max() < np.abs(np.diff(sharp.astype(float), axis=1)).max()
    lit = render_scene(wall, camera, T, wall_texture_std_gray=0.0, gradient=0.4, gradient_angle_deg=0.0).image
    assert lit[5, -5] > lit[5, 4] + 30  # brighter to the right
    bgr = render_scene(wall, camera, T, wall_texture_std_gray=0.0, bgr=True).image
    assert bgr.shape == (240, 320, 3)
    np.testing.assert_array_equal(bgr[..., 1], sharp)


def test_bad_options_say_what_to_do(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([800, 190, 240], [0, 190, 240])
    with pytest.raises(FidlearnError, match="supersample must be a whole number from 1 to 16"):
        render_scene(wall, camera, T, supersample=0)
    with pytest.raises(FidlearnError, match="noise_std_gray must be a number from 0 to 255"):
        render_scene(wall, camera, T, noise_std_gray=-1)
    for name, value in [  # a NaN gray or gradient made an all-black picture with markers in its truth
        ("gradient", float("nan")),
        ("wall_gray", float("nan")),
        ("paper_gray", "white"),
        ("margin_cells", None),
        ("margin_cells", 1e9),
        ("margin_px", float("nan")),
    ]:
        with pytest.raises(FidlearnError, match=f"{name} must be a number from"):
            render_scene(wall, camera, T, **{name: value})
    tilted = Camera(camera.K, np.r_[np.zeros(12), 0.01, 0.0], (320, 240))
    with pytest.raises(CameraError, match="tilted sensor"):
        render_scene(wall, tilted, T)
    with pytest.raises(FidlearnError, match="eye .* and the target are the same point"):
        look_at([1, 2, 3], [1, 2, 3])


def test_the_map_comes_before_the_camera(wall):
    camera = Camera.from_fov(60, (320, 240))
    T = look_at([800, 190, 240], [0, 190, 240])
    for call in (render_scene, visible_markers):
        with pytest.raises(FidlearnError, match=r"the map comes first, then the camera; the arguments are swapped"):
            call(camera, wall, T)
    with pytest.raises(FidlearnError, match=r"render_trajectory\(marker_map, camera, ...\): the map comes first"):
        render_trajectory(camera, wall, n_frames=2)
    with pytest.raises(FidlearnError, match="marker_map must be a fidlearn.MarkerMap .*the map comes first"):
        render_scene("map.json", camera, T)


def test_look_at_gives_an_opencv_camera_frame():
    T = look_at([1500, 0, 300], [0, 0, 300])
    np.testing.assert_allclose(T[:3, 0], [0, 1, 0], atol=1e-12)  # x right: +Y when facing the north wall
    np.testing.assert_allclose(T[:3, 1], [0, 0, -1], atol=1e-12)  # y down
    np.testing.assert_allclose(T[:3, 2], [-1, 0, 0], atol=1e-12)  # z forward
    frames.check_transform(look_at([100, 200, 300], [0, -50, 20], roll_deg=33))


# -- calibration views and the drive ---------------------------------------------------------------


def test_calibration_views_tell_the_truth_and_render_one_view_alone():
    camera = Camera([[600, 0, 322], [0, 601, 238], [0, 0, 1]], [-0.1, 0.03, 0, 0, 0], (640, 480))
    full = render_calibration_views(camera, n_views=3, seed=2)
    one = render_calibration_views(camera, n_views=3, seed=2, views=[2])
    np.testing.assert_array_equal(one.images[0], full.images[2])
    np.testing.assert_array_equal(one.T_world_camera[0], full.T_world_camera[2])
    assert full.object_points.shape == (54, 3)
    for T, px in zip(full.T_world_camera, full.image_points):
        np.testing.assert_array_equal(px, camera.project(full.object_points, T))
        assert np.all((px > 0) & (px < [639, 479]))
        tilt = frames.rotation_angle_deg(frames.invert_transform(T)[:3, :3])
        assert 5 < tilt < 90
    with pytest.raises(FidlearnError, match=r"views \[3\] do not exist"):
        render_calibration_views(camera, n_views=3, views=[3])


def test_charuco_views_are_found_by_opencvs_charuco_detector():
    camera = Camera([[600, 0, 322], [0, 601, 238], [0, 0, 1]], [-0.1, 0.03, 0, 0, 0], (640, 480))
    views = render_calibration_views(camera, n_views=2, board=Board.charuco((5, 7), 40, 20), seed=3)
    assert views.board.squares == (5, 7)
    assert views.board.square_size_mm == 40
    assert views.board.marker_size_mm == 20
    detector = cv2.aruco.CharucoDetector(views.board.cv_board())
    for image, truth in zip(views.images, views.image_points):
        corners, ids, _, _ = detector.detectBoard(image)
        assert ids is not None
        assert len(ids) == 24
        err = corners.reshape(-1, 2) - truth[np.ravel(ids)]
        assert np.sqrt((err**2).sum(axis=1).mean()) < 0.2


def test_a_calibration_board_must_be_a_board():
    camera = Camera.from_fov(60, (320, 240))
    with pytest.raises(FidlearnError, match=r"board must be a fidlearn.Board \(Board.checkerboard"):
        render_calibration_views(camera, n_views=1, board=(9, 6))
    views = render_calibration_views(camera, n_views=1, board=Board.checkerboard((5, 4), 20), supersample=1)
    assert views.board.inner_corners == (5, 4)
    assert views.image_points[0].shape == (20, 2)
    assert "checkerboard 5x4 inner corners, 20 mm squares" in repr(views)


def test_the_drive_stays_at_marker_height_and_keeps_the_markers_in_view(wall):
    poses = trajectory_poses(wall, n_frames=12, seed=1)
    centre = np.mean([wall.marker_corners(i).mean(axis=0) for i in wall.ids], axis=0)
    for T in poses:
        frames.check_transform(T)
        assert abs(T[2, 3] - centre[2]) < 5  # camera at the markers' height
        to_markers = (centre - T[:3, 3]) / np.linalg.norm(centre - T[:3, 3])
        assert to_markers @ T[:3, 2] > np.cos(np.radians(10))  # looking at the markers, give or take the sway
    dist = [np.linalg.norm(T[:2, 3] - centre[:2]) for T in poses]
    assert dist[0] > 2000  # it drives toward the wall
    assert dist[-1] < 1100
    camera = Camera.from_fov(60, (320, 240))
    drive = render_trajectory(wall, camera, n_frames=12, seed=1, frames_to_render=[0, 11])
    assert len(drive) == 2
    assert all(sorted(t) == [0, 1, 2] for t in drive.truth)
    np.testing.assert_array_equal(drive.T_world_camera[1], poses[11])
    again = render_trajectory(wall, camera, n_frames=12, seed=1, frames_to_render=[11])
    np.testing.assert_array_equal(again.images[0], drive.images[1])
