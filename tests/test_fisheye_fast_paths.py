"""The shortcuts of the fisheye path give what the longer computations they replace give: the profiles' levels by
one reduction over their samples, the weighted fit's last residuals and Jacobian, the ideal corners' detections."""

from __future__ import annotations

import cv2
import numpy as np

from fidlearn import Camera, frames
from fidlearn.detection import Detection
from fidlearn.pose._inputs import _as_pinhole, _lens_jacobians, _lens_refine
from fidlearn.pose._refine import _residuals
from fidlearn.pose._second_look import read_again
from fidlearn.refinement import _least, _most

K_FE = np.array([[290.050152, 0.0, 399.938345], [0.0, 289.392837, 273.885669], [0.0, 0.0, 1.0]])
D_FE = np.array([-0.030464, -0.019695, 0.002098, 0.001030])


def test_the_levels_reduction_gives_numpys_min_and_max():
    rng = np.random.default_rng(3)
    prof = (rng.uniform(0, 255, size=(5, 4, 16, 13))).astype(np.float32)
    prof[2, 1, 7, 4] = np.nan  # numpy's min and max carry a NaN through; so must these
    for part in (prof[..., :7], prof[..., 6:], prof[:0, ..., :7]):
        assert np.array_equal(_least(part), part.min(-1), equal_nan=True)
        assert np.array_equal(_most(part), part.max(-1), equal_nan=True)
    assert np.isnan(_least(prof[..., :7])[2, 1, 7])


def test_the_weighted_fit_returns_the_residuals_and_jacobian_of_its_pose():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    pinhole = Camera(K_FE, None, (800, 503))
    s = 60.0
    square = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    obj = np.concatenate([square + [x, y, 0] for x, y in ((-150, 0), (150, 40), (0, -160))])
    T = frames.look_at([100.0, -80.0, -600.0], [0.0, 0.0, 0.0])
    rng = np.random.default_rng(7)
    ideal = pinhole.project(obj, T) + rng.normal(0, 0.2, (len(obj), 2))
    D = _lens_jacobians(fisheye, ideal)
    start_R = cv2.Rodrigues(np.array([0.01, -0.02, 0.015]))[0] @ T[:3, :3]
    R, C, weighted_J, r, J = _lens_refine(obj, ideal, pinhole, D, start_R, T[:3, 3] + [3.0, -2.0, 4.0])
    r_again, J_again = _residuals(obj, ideal, pinhole.K, pinhole.dist, R, C, True)
    assert np.array_equal(r, r_again)
    assert np.array_equal(J, J_again)
    assert np.allclose(weighted_J, (D @ J.reshape(-1, 2, 6)).reshape(-1, 6))
    r_start, _ = _residuals(obj, ideal, pinhole.K, pinhole.dist, start_R, T[:3, 3] + [3.0, -2.0, 4.0], False)

    def picture_sse(res):
        w = (D @ res.reshape(-1, 2, 1)).ravel()
        return float(w @ w)

    assert picture_sse(r) < 0.01 * picture_sse(r_start)  # it moved from the start (5.4 mm off) to the fit
    assert np.linalg.norm(C - T[:3, 3]) < 3.0  # within the noise of 0.2 px on 12 corners at 0.6 m


def test_the_ideal_corners_keep_id_and_dictionary_and_drop_markers_past_90_degrees():
    fisheye = Camera(K_FE, D_FE, (800, 503), model="fisheye")
    near = Detection(4, [[390, 260], [420, 262], [418, 290], [388, 288]], "ARUCO_ORIGINAL")
    # a corner beyond 90 degrees off the axis: no pinhole picture of it
    far = Detection(9, [[0, 10], [30, 10], [30, 40], [-400, 40]], "ARUCO_ORIGINAL")
    out, pinhole = _as_pinhole([near, far], fisheye)
    assert [d.id for d in out] == [4]
    assert out[0].dictionary == "ARUCO_ORIGINAL"
    assert np.array_equal(out[0].corners_px, fisheye.undistort_points(near.corners_px))
    assert out[0].corners_px.shape == (4, 2)
    assert out[0].corners_px.dtype == np.float64
    assert pinhole.model == "pinhole"
    assert np.array_equal(pinhole.K, fisheye.K)


def test_no_missed_marker_means_no_second_look():
    assert read_again(np.full((60, 80), 255, np.uint8), [], None, None) == []
