"""The real benchmark's judging of the calibration's error (``benchmarks/real_calibration.py``) and its coached
subset of the robot's photos (``robot_charuco.coached_photos``)."""

from __future__ import annotations

import numpy as np
from test_pose import CAM, look_at, observe, wall_map

from benchmarks import real_calibration as rcal
from benchmarks import robot_charuco as rc
from fidlearn import Camera, estimate_pose


def test_the_judge_s_response_is_the_term_estimate_pose_adds():
    """``response`` (the benchmark's own code, ``pose_jacobian`` and ``cv2.projectPoints``) gives the covariance
    ``estimate_pose`` adds for a camera carrying its calibration's covariance."""
    m = wall_map(n_cols=4, n_rows=3, size=120.0, spacing=300.0)
    T = look_at([1700.0, 500.0, 1100.0], [0.0, 450.0, 1150.0])
    dets = observe(m, T, sigma=0.2)
    rng = np.random.default_rng(3)
    B = rng.standard_normal((9, 9)) * np.r_[2.0, 2.0, 2.0, 2.0, 0.01, 0.01, 0.001, 0.001, 0.01][:, None]
    cov_k = B @ B.T
    cam = Camera(CAM.K, CAM.dist, CAM.image_size, intrinsics_covariance=cov_k)
    with_k = estimate_pose(dets, m, cam, corner_sigma_px=0.2)
    without = estimate_pose(dets, m, rcal.plain(cam), corner_sigma_px=0.2)
    P = np.concatenate([m.marker_corners(i) for i in with_k.marker_ids])
    A = rcal.response(P, with_k.T_world_camera, cam)
    want = A @ cov_k @ A.T
    np.testing.assert_allclose(with_k.covariance - without.covariance, want, rtol=1e-6, atol=1e-9 * np.abs(want).max())
    moved = rcal.moved(cam, np.r_[1.0, 0, 0, 0, 0, 0, 0, 0, 0])
    assert moved.fx == cam.fx + 1.0
    assert moved.intrinsics_covariance is None
    L = rcal.axes(cam)
    np.testing.assert_allclose(L @ L.T, cov_k, atol=1e-9 * np.abs(cov_k).max())


def test_the_coached_subset_lowers_the_predicted_uncertainty_more_than_the_first_photos():
    """Ten distinct photos, each with a calibration view (photo 2 has too few chess corners), whose predicted
    uncertainty map is lower than that of photos 0-9 by the same measure."""
    chosen = rc.coached_photos()
    assert len(chosen) == 10
    assert len(set(chosen)) == 10
    assert 2 not in chosen
    assert all(0 <= i < rc.N_PHOTOS for i in chosen)
    first = [i for i in range(rc.N_PHOTOS) if i != 2][:10]
    assert rc.predicted_uncertainty_px(chosen) < rc.predicted_uncertainty_px(first)
    # one photo more never raises the prediction (its information only adds)
    assert rc.predicted_uncertainty_px(range(rc.N_PHOTOS)) <= rc.predicted_uncertainty_px(chosen)
