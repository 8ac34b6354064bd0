"""The bent-board test: a bow large and significant is called bent, with its size; a flat board is not.

Known answers: boards bowed by a known sag (a quadratic lift of their points) come back with that
sag within its stated standard deviation; a bow far smaller than a board can have
(``BENT_MIN_SAG_MM``) is not called bent however significant its fit, as a flat screen's or a
lens model's small smooth residuals are not; OpenCV's right02.jpg (its board bent, as left02.jpg
shows) is called bent by about 1.5 mm, the rigid robot-held ChArUco board and the tutorial's
ChArUco photos are not.
"""

from __future__ import annotations

import glob
import math

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import Board, Camera, frames
from fidlearn.planning.bent_board import BENT_MIN_SAG_MM, bend_flag, bent_views, board_bends

CAMERA = Camera.load(fidlearn.data_path("calibration/camera_true.json"))
BOARD = np.array([[i * 25.0, j * 25.0, 0.0] for j in range(6) for i in range(9)])


def _poses(rng, n=16):
    poses = []
    for k in range(n):
        ang = rng.uniform(-35, 35, size=3) * [1, 1, 0.5]
        R = frames.rotation_from_rpy_deg(*ang)
        u, v = ((k % 4) + 0.5) / 4 - 0.5, ((k // 4 % 4) + 0.5) / 4 - 0.5
        centre = np.array([u * 500, v * 380, 650.0]) * [1, 1, rng.uniform(0.9, 1.1)]
        poses.append(frames.make_transform(R, centre - R @ BOARD.mean(axis=0)))
    return poses


def _calibrate(rng, sags: dict, sigma=0.1, n=16):
    """Views of the board, view k bowed along its long side by ``sags[k]`` mm (highest minus lowest)."""
    observed = []
    for k, T in enumerate(_poses(rng, n)):
        pts = BOARD.copy()
        x = (pts[:, 0] - pts[:, 0].mean()) / np.ptp(pts[:, 0])  # -0.5 .. 0.5: x^2 spans 0.25
        pts[:, 2] = sags.get(k, 0.0) / 0.25 * x**2
        px = CAMERA.project(frames.transform_points(T, pts), np.eye(4))
        observed.append(px + rng.normal(0, sigma, px.shape))
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [BOARD.astype(np.float32)] * n, [o.astype(np.float32) for o in observed], CAMERA.image_size, None, None
    )
    names = [f"view {i}" for i in range(n)]
    T = {m: frames.transform_from_rvec_tvec(r, t) for m, r, t in zip(names, rvecs, tvecs)}
    return Camera(K, dist.ravel(), CAMERA.image_size), dict.fromkeys(names, BOARD), dict(zip(names, observed)), T


@pytest.mark.parametrize("sag", [2.0, 4.0])
def test_a_known_bow_is_called_bent_with_its_size(sag):
    bends = board_bends(*_calibrate(np.random.default_rng(int(sag)), {5: sag}))
    assert [b.name for b in bends] == ["view 5"]
    b = bends[0]
    assert abs(b.sag_mm - sag) < max(3 * b.sag_std_mm, 0.1 * sag), b
    assert b.limit < b.F
    assert "does not look flat in view 5" in bend_flag(bends, 16)


@pytest.mark.slow
def test_a_bow_too_small_for_a_board_is_not_called_bent_however_significant():
    # corners to 0.01 px: a 0.4 mm bow is highly significant, as a flat screen's or a lens model's
    # small smooth residuals are; it is not a bent board
    data = _calibrate(np.random.default_rng(2), {5: 0.4}, sigma=0.01)
    assert bent_views(*data) == []
    import fidlearn.planning.bent_board as bb

    with pytest.MonkeyPatch.context() as mp:  # the size threshold is what keeps it out
        mp.setattr(bb, "BENT_MIN_SAG_MM", 0.0)
        (b,) = board_bends(*data)
    assert b.name == "view 5"
    assert 10 * b.limit < b.F
    assert b.sag_mm == pytest.approx(0.4, abs=3 * b.sag_std_mm + 0.02)
    assert b.sag_mm < BENT_MIN_SAG_MM


@pytest.mark.slow
def test_flat_boards_are_not_called_bent():
    for seed in range(3):
        assert bent_views(*_calibrate(np.random.default_rng(10 + seed), {})) == []


@pytest.mark.slow
def test_many_bent_views_point_at_the_lens_model():
    bends = board_bends(*_calibrate(np.random.default_rng(4), {1: 3.0, 6: 3.0, 11: 3.0, 14: 3.0}, n=12 + 4))
    assert len(bends) == 4
    assert "the lens model more likely cannot describe this lens" in bend_flag(bends, 10)
    assert "does not look flat in" in bend_flag(bends[:1], 10)


@pytest.mark.slow
def test_opencvs_right02_is_bent_by_about_a_millimetre_and_a_half():
    views = sorted(glob.glob(str(fidlearn.data_path("real", "opencv_checkerboard_right")) + "/right*.jpg"))
    kept = fidlearn.calibrate_checkerboard(views, (9, 6), 25.0, reject_outliers=False)
    bends = {b.name.rsplit("/", 1)[-1]: b for b in board_bends(kept.camera, *_views(kept))}
    b = bends["right02.jpg"]
    assert 1.0 < b.sag_mm < 2.2  # measured 1.53 +- 0.27 mm (25 mm squares, a stand-in)
    assert math.isfinite(b.sag_std_mm)
    assert 0.1 < b.sag_std_mm < 0.6


@pytest.mark.slow
@pytest.mark.parametrize(
    ("folder", "board"),
    [
        ("robot_charuco", Board.charuco((5, 7), 36.195, 18.256, "DICT_6X6_250")),
        ("opencv_charuco", Board.charuco((5, 7), 40, 20, "DICT_6X6_250")),
    ],
)
def test_rigid_real_boards_are_not_called_bent(folder, board):
    # the robot's board and the tutorial's: fitted sags 0.2-1.1 mm, none significant
    photos = sorted(glob.glob(str(fidlearn.data_path("real", folder)) + "/*.[pj][np]g"))
    cal = fidlearn.calibrate_charuco(photos, board)
    assert bent_views(cal.camera, *_views(cal)) == []


def _views(cal):
    return cal.board_points_mm, cal.image_points_px, cal.T_camera_board
