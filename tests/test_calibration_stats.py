"""The calibration's statistics against OpenCV's: the camera of ``cv2.calibrateCamera`` to the bit,
the standard deviations (computed on first read) against ``cv2.calibrateCameraExtended``'s, the
per-view errors against a reprojection with the returned camera, and the view diversity against
its pairwise definition."""

from __future__ import annotations

import pickle

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import data_path, frames
from fidlearn.calibration import Calibration, ViewDiversity, _stats, calibrate_checkerboard, view_diversity
from fidlearn.errors import TransformError

PATTERN, SQUARE_MM = (9, 6), 25.0


@pytest.fixture
def one_thread():
    """OpenCV's calibration sums in parallel, in an order that varies (K then differs by about 1e-10 between
    runs of the same call); with one thread it is reproducible to the bit."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    yield
    cv2.setNumThreads(before)


@pytest.fixture(scope="module")
def right_points():
    """The bundled photos' corners as fidlearn finds them: (board points, pixels) per view, float32."""
    files = sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))
    cal = calibrate_checkerboard(files, PATTERN, SQUARE_MM, reject_outliers=False)
    obj = [cal.board_points_mm[n].astype(np.float32).reshape(-1, 1, 3) for n in cal.used]
    img = [cal.image_points_px[n].astype(np.float32).reshape(-1, 1, 2) for n in cal.used]
    return files, obj, img


@pytest.mark.usefixtures("one_thread")
def test_camera_rms_and_std_devs_are_opencvs(right_points):
    files, obj, img = right_points
    cal = calibrate_checkerboard(files, PATTERN, SQUARE_MM, reject_outliers=False)
    rms, K, dist, _r, _t, std_int, _std_ext, per_view = cv2.calibrateCameraExtended(obj, img, (640, 480), None, None)
    # the same camera and RMS, to the bit
    assert np.array_equal(cal.camera.K, K)
    assert np.array_equal(cal.camera.dist, dist.ravel())
    assert cal.rms_px == rms
    # the standard deviations, computed on first read, are calibrateCameraExtended's
    std = cal.std_intrinsics
    assert list(std) == ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"]
    np.testing.assert_allclose(list(std.values()), std_int.ravel()[:9], rtol=1e-6)
    assert cal.std_intrinsics is std  # computed once, then kept
    np.testing.assert_allclose([cal.per_view_rms_px[str(f)] for f in files], per_view.ravel(), rtol=1e-10)


def test_per_view_errors_are_those_of_the_returned_camera_and_poses(right_points):
    files, obj, img = right_points
    cal = calibrate_checkerboard(files, PATTERN, SQUARE_MM, reject_outliers=False)
    for name in cal.used:
        T = cal.T_camera_board[name]
        rvec, tvec = cv2.Rodrigues(T[:3, :3])[0], T[:3, 3]
        px, _ = cv2.projectPoints(cal.board_points_mm[name], rvec, tvec, cal.camera.K, cal.camera.dist)
        e = px.reshape(-1, 2) - cal.image_points_px[name]
        assert cal.per_view_rms_px[name] == pytest.approx(np.sqrt(np.mean(np.sum(e**2, axis=1))), rel=1e-9)


@pytest.mark.usefixtures("one_thread")
@pytest.mark.parametrize(
    "flags",
    [
        cv2.CALIB_RATIONAL_MODEL,
        cv2.CALIB_FIX_ASPECT_RATIO,
        cv2.CALIB_FIX_PRINCIPAL_POINT,
        cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3,
        cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_TANGENT_DIST,
        cv2.CALIB_THIN_PRISM_MODEL,
    ],
)
def test_std_devs_follow_the_flags_like_opencv(right_points, flags):
    _files, obj, img = right_points
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, (640, 480), None, None, flags=flags)
    ref = cv2.calibrateCameraExtended(obj, img, (640, 480), None, None, flags=flags)
    assert np.array_equal(ref[1], K)
    assert ref[0] == rms
    ours = _stats.std_intrinsics(obj, K, dist, rvecs, tvecs, rms, flags)
    theirs = ref[5].ravel()[: len(ours)]
    assert np.array_equal(ours == 0, theirs == 0)  # the parameters held fixed
    np.testing.assert_allclose(ours, theirs, rtol=1e-4)


def test_std_devs_given_are_kept_and_a_calibration_pickles(right_points):
    files, _obj, _img = right_points
    cal = calibrate_checkerboard(files[:5], PATTERN, SQUARE_MM)
    again = pickle.loads(pickle.dumps(cal))  # before the first read: the inputs travel along
    assert again.std_intrinsics == cal.std_intrinsics
    assert again.camera.fx == cal.camera.fx
    given = Calibration(cal.camera, cal.rms_px, cal.per_view_rms_px, cal.used, {"fx": 1.5}, [])
    assert given.std_intrinsics == {"fx": 1.5}
    assert "fx=" in repr(given)
    assert "±1.50" in repr(given)
    assert Calibration(cal.camera, 0.1, {}, [], None, []).std_intrinsics == {}


def _diversity_pairwise(T_camera_board):
    """view_diversity as defined: every pair of views, one at a time."""
    names = list(T_camera_board)
    spread, duplicates = 0.0, []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            Ti, Tj = T_camera_board[names[i]], T_camera_board[names[j]]
            cos = float(np.clip(abs(Ti[:3, 2] @ Tj[:3, 2]), -1, 1))
            spread = max(spread, np.degrees(np.arccos(cos)))
            angle = frames.rotation_angle_deg(Ti[:3, :3], Tj[:3, :3])
            moved = np.linalg.norm(Ti[:3, 3] - Tj[:3, 3]) / np.linalg.norm(Ti[:3, 3])
            if angle < 2.0 and moved < 0.02:
                duplicates.append((names[i], names[j], angle, moved))
    return spread, duplicates


def test_view_diversity_is_its_pairwise_definition():
    rng = np.random.default_rng(7)
    T = {}
    for k in range(25):
        R = fidlearn.rotation_from_rpy_deg(*rng.uniform(-40, 40, 3))
        T[f"v{k}"] = fidlearn.make_transform(R, rng.uniform(-100, 100, 3) + [0, 0, 600])
    for k in (3, 11, 11, 20):  # near duplicates: turned under 2 deg and moved under 2 %
        R = fidlearn.rotation_from_rpy_deg(*rng.uniform(-1, 1, 3)) @ T[f"v{k}"][:3, :3]
        T[f"v{k}_again{len(T)}"] = fidlearn.make_transform(R, T[f"v{k}"][:3, 3] * 1.005)
    diversity = view_diversity(T)
    duplicates = [(d.a, d.b, d.angle_deg, d.moved_fraction) for d in diversity.duplicates]
    ref_spread, ref_duplicates = _diversity_pairwise(T)
    assert diversity.spread_deg == pytest.approx(ref_spread, abs=1e-9)
    assert [d[:2] for d in duplicates] == [d[:2] for d in ref_duplicates]
    assert len(duplicates) >= 4
    np.testing.assert_allclose([d[2:] for d in duplicates], [d[2:] for d in ref_duplicates], atol=1e-6)
    assert view_diversity({"a": T["v0"]}) == ViewDiversity(0.0, []) == view_diversity({})
    with pytest.raises(TransformError):
        view_diversity({"a": T["v0"], "b": np.diag([1.0, 1.0, -1.0, 1.0])})
