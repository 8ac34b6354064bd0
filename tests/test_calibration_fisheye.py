"""Calibration with the fisheye model and the held-out choice of model (``model="auto"``), on the real fisheye
photos of data/real/fisheye_checkerboard (one lens of about 180 degrees, three independent sets, ROS's reference
calibrations) and on the bundled pinhole views."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import Board, Camera
from fidlearn.calibration import calibrate_checkerboard
from fidlearn.calibration.run import _calibrate_points
from fidlearn.errors import CalibrationError
from fidlearn.ros import load_camera_info

REAL = fidlearn.data_path("real", "fisheye_checkerboard")
BOARD = Board.checkerboard((6, 8), 25.0)  # the square size was never published: it scales poses only, never K
REFERENCE = {"mono": "ost.yaml", "left": "left.yaml", "right": "right.yaml"}


def _reference(name: str) -> Camera:
    # ROS's fisheye calibrator labelled its 4 fisheye coefficients plumb_bob: read K and D, the model is fisheye
    ros = load_camera_info(REAL / name / REFERENCE[name])
    return Camera(ros.K, ros.dist, ros.image_size, model="fisheye")


def _corners() -> dict:
    return json.loads((REAL / "corners.json").read_text())


def _board_points() -> np.ndarray:
    obj = np.zeros((48, 3))
    obj[:, :2] = np.mgrid[0:6, 0:8].T.reshape(-1, 2) * 25.0  # OpenCV's order: along the 6, then down the 8
    return obj


def test_the_stored_corners_are_what_the_finder_finds_in_the_stored_photos():
    corners = _corners()["sets"]
    for name in REFERENCE:
        photos = sorted((REAL / name).glob("*.png"))
        assert len(photos) == 6
        cal = calibrate_checkerboard(photos, board=BOARD, model="fisheye", reject_outliers=False)
        for photo in photos:
            np.testing.assert_allclose(cal.image_points_px[str(photo)], corners[name][photo.name], atol=1e-4)


def test_each_whole_set_agrees_with_ross_reference_and_with_the_other_sets():
    corners = _corners()["sets"]
    fx = {}
    for name, views in corners.items():
        img = [np.array(v) for v in views.values()]
        rms, K, dist, *_ = _calibrate_points([_board_points()] * len(img), img, (800, 503), 0, None, "fisheye")
        ref = _reference(name)
        assert len(img) in (24, 46)
        assert rms < 0.5
        assert abs(K[0, 0] / ref.fx - 1) < 0.0035  # 0.09 %, 0.33 %, 0.11 %
        assert abs(K[1, 1] / ref.fy - 1) < 0.0035
        assert np.hypot(K[0, 2] - ref.cx, K[1, 2] - ref.cy) < 2.0  # 0.1, 1.4, 1.7 px
        fx[name] = K[0, 0]
    assert max(fx.values()) / min(fx.values()) - 1 < 0.003  # independent sets of one lens: 289.79 to 290.20


def test_auto_chooses_the_fisheye_for_the_fisheye_photos_and_reports_per_view():
    cal = calibrate_checkerboard(sorted((REAL / "mono").glob("*.png")), board=BOARD, model="auto")
    assert cal.camera.model == "fisheye"
    assert cal.held_out_rms_px["fisheye"] < 0.9 * cal.held_out_rms_px["pinhole"]
    assert abs(cal.camera.fx / _reference("mono").fx - 1) < 0.01  # six photos: within 1 %
    assert set(cal.std_intrinsics) == {"fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"}
    assert 0 < cal.std_intrinsics["fx"] < 3
    lines = cal.table().splitlines()
    assert len(lines) == 2 + 6
    assert all(" used" in line for line in lines[2:])
    assert "lens model fisheye" in cal.summary()
    # the per-view RMS comes from the fisheye model: it averages to the overall RMS
    per_view = np.array(list(cal.per_view_rms_px.values()))
    assert np.sqrt(np.mean(per_view**2)) == pytest.approx(cal.rms_px, rel=1e-9)


def test_auto_keeps_the_pinhole_for_the_bundled_views():
    photos = sorted(fidlearn.data_path("calibration").glob("view_*.png"))[:8]
    cal = calibrate_checkerboard(photos, board=Board.checkerboard((9, 6), 25.0), model="auto")
    assert cal.camera.model == "pinhole"
    assert cal.camera.dist.size == 5
    truth = Camera.load(fidlearn.data_path("calibration", "camera_true.json"))
    assert abs(cal.camera.fx / truth.fx - 1) < 0.005
    assert set(cal.held_out_rms_px) == {"pinhole", "fisheye"}


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"model": "kannala"}, "model must be 'pinhole'"),
        ({"model": "auto", "flags": 1}, "not both"),
    ],
)
def test_bad_model_says_what_to_do(kwargs, message):
    with pytest.raises(CalibrationError, match=message):
        calibrate_checkerboard(sorted((REAL / "mono").glob("*.png"))[:3], board=BOARD, **kwargs)


def test_auto_needs_four_views():
    with pytest.raises(CalibrationError, match="at least 4 usable views"):
        calibrate_checkerboard(sorted((REAL / "mono").glob("*.png"))[:3], board=BOARD, model="auto")


def test_the_command_line_calibrates_a_fisheye(tmp_path):
    out = tmp_path / "camera.yml"
    cmd = [sys.executable, "-m", "fidlearn", "calibrate", str(REAL / "mono"), "--pattern", "6x8", "--square-mm", "25"]
    done = subprocess.run([*cmd, "--model", "fisheye", "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "k4" in done.stdout
    cam = Camera.load(out)
    assert cam.model == "fisheye"
    assert abs(cam.fx / _reference("mono").fx - 1) < 0.01
    assert "calibration coach:" in done.stdout  # the coach speaks for a fisheye too
    report, again = tmp_path / "r.png", tmp_path / "c.json"
    drawn = subprocess.run(
        [*cmd, "--model", "fisheye", "--report", str(report), "-o", str(again)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert drawn.returncode == 0, drawn.stderr
    assert f"the coach's picture in {report}" in drawn.stdout
    picture = cv2.imread(str(report))
    assert picture is not None
    assert picture.shape[0] > 100
    assert picture.std() > 1  # a drawn figure, not a blank
    assert Camera.load(again).model == "fisheye"


def test_charuco_takes_the_model_too():
    from fidlearn.calibration import calibrate_charuco

    photos = sorted(fidlearn.data_path("real", "opencv_charuco").glob("img_*.jpg"))
    board = Board.charuco((5, 7), 40, 20, "DICT_6X6_250")
    fish = calibrate_charuco(photos, board, model="fisheye")
    assert fish.camera.model == "fisheye"
    assert fish.rms_px < 0.25
    # OpenCV's tutorial lens is a plain one: the held-out errors are within 10 %, so auto keeps the pinhole
    auto = calibrate_charuco(photos, board, model="auto")
    assert auto.camera.model == "pinhole"
    if fidlearn._cv.OPENCV_VERSION >= (5, 0, 0):
        assert auto.camera.fx == pytest.approx(457.3, abs=0.1)  # plain cv2.calibrateCamera's (data/README.md)
        assert abs(fish.camera.fx / auto.camera.fx - 1) < 0.01
    else:  # OpenCV 4's pinhole fit settles elsewhere on these 4 photos (test_calibration): within its own noise
        assert abs(fish.camera.fx - auto.camera.fx) < 3 * auto.std_intrinsics["fx"]


def test_the_fisheyes_standard_deviations_match_the_spread_of_repeated_calibrations():
    from fidlearn import frames

    truth = Camera([[290.0, 0, 399.5], [0, 289.5, 273.5], [0, 0, 1]], [-0.03, -0.02, 0.002, 0.001], (800, 503))
    truth = Camera(truth.K, truth.dist, truth.image_size, model="fisheye")
    obj = _board_points()
    rng = np.random.default_rng(0)
    views = []
    while len(views) < 10:  # the board seen whole from random places 15 to 30 cm away
        eye = np.r_[rng.uniform(-250, 250, 2) + [62.5, 87.5], -rng.uniform(150, 300)]
        T = frames.look_at(eye, np.r_[rng.uniform(-50, 175), rng.uniform(-50, 225), 0.0], up=(0, -1, 0))
        px = truth.project(obj, T)
        if np.all((px > 5) & (px < [795, 498])):
            views.append(px)
    fx, cx, predicted = [], [], []
    for _ in range(40):
        img = [p + rng.normal(0, 0.3, p.shape) for p in views]
        fit = _calibrate_points([obj] * len(img), img, (800, 503), 0, None, "fisheye")
        fx.append(fit[1][0, 0])
        cx.append(fit[1][0, 2])
        std = fit[5]()
        predicted.append([std["fx"], std["cx"]])
    ratio = np.array([np.std(fx, ddof=1), np.std(cx, ddof=1)]) / np.mean(predicted, axis=0)
    assert np.all((ratio > 0.7) & (ratio < 1.45))  # 40 repeats: the spread itself is known to about 11 %
    assert abs(np.mean(fx) - 290.0) < 3 * np.std(fx, ddof=1) / np.sqrt(40)  # and unbiased


@pytest.mark.parametrize("model", ["fisheye", "auto"])
def test_the_command_line_prints_the_coach_for_a_fisheye(tmp_path, model):
    from fidlearn.planning.coach import coach_calibration

    out = tmp_path / "camera.yml"
    cmd = [sys.executable, "-m", "fidlearn", "calibrate", str(REAL / "mono"), "--pattern", "6x8", "--square-mm", "25"]
    done = subprocess.run([*cmd, "--model", model, "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert Camera.load(out).model == "fisheye"  # auto picks the fisheye for these photos (held-out error)
    cal = calibrate_checkerboard(sorted((REAL / "mono").glob("*.png")), board=BOARD, model=model)
    advice = coach_calibration(cal).report(omit=cal.warnings).splitlines()
    said = done.stdout.split("calibration coach: ", 1)[1].splitlines()
    assert said[0] == advice[0]
    assert said[0].startswith("reprojection uncertainty: median")
    assert [line.strip() for line in said[1 : len(advice)]] == [line.strip() for line in advice[1:]]
    assert any(line.strip().startswith("next photo:") for line in said)


def test_flags_of_ones_own_keep_the_camera_skewless_and_held_parameters_certain():
    """Flags given replace the defaults but never free the skew (a Camera has none: the fit used to end in a
    refusal of its skew); a coefficient the flags hold is 0 and has no uncertainty, in the standard deviations
    and in the camera's covariance."""
    from fidlearn.calibration import camera_with_uncertainty  # noqa: PLC0415
    from fidlearn.calibration._models import fisheye_flag  # noqa: PLC0415

    photos = sorted((REAL / "mono").glob("*.png"))
    held = ("CALIB_FIX_K3", "CALIB_FIX_K4", "CALIB_FIX_PRINCIPAL_POINT")
    flags = fisheye_flag("CALIB_RECOMPUTE_EXTRINSIC")
    for name in held:
        flags |= fisheye_flag(name)
    cal = calibrate_checkerboard(photos, board=BOARD, model="fisheye", flags=flags)
    assert cal.camera.K[0, 1] == 0
    assert cal.camera.dist[2:].tolist() == [0.0, 0.0]
    std = cal.std_intrinsics
    assert [std[k] for k in ("cx", "cy", "k3", "k4")] == [0.0] * 4
    assert min(std[k] for k in ("fx", "fy", "k1", "k2")) > 0
    cov = camera_with_uncertainty(cal).intrinsics_covariance
    assert np.diag(cov)[[2, 3, 6, 7]].tolist() == [0.0] * 4
    # without CALIB_RECOMPUTE_EXTRINSIC the fit is OpenCV's to make, but the camera still has no skew
    own = calibrate_checkerboard(photos, board=BOARD, model="fisheye", flags=fisheye_flag("CALIB_FIX_K4"))
    assert own.camera.K[0, 1] == 0
