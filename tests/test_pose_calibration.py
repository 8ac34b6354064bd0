"""A camera's calibration error in a pose's covariance (``Camera.intrinsics_covariance``): its Jacobian against
finite differences of the solved pose, the coverage of the truth by the 95 % ellipsoid when the intrinsics are
drawn wrong from a known covariance, and the covariance's checks, file and rescaling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from test_pose import CAM, look_at, observe, wall_map

from fidlearn import Camera, estimate_pose
from fidlearn.errors import CameraError

NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
#: Standard deviations of a plausible calibration of CAM (px, px, px, px, then the coefficients).
STD = np.array([4.0, 4.0, 3.0, 3.0, 0.01, 0.02, 0.0005, 0.0005, 0.0])


def _cov_k() -> np.ndarray:
    """A full covariance of the intrinsics with STD on its diagonal (fx and fy, k1 and k2 correlated)."""
    corr = np.eye(9)
    corr[0, 1] = corr[1, 0] = 0.8
    corr[4, 5] = corr[5, 4] = -0.6
    return corr * np.outer(STD, STD)


def _camera(values, cov=None) -> Camera:
    fx, fy, cx, cy, *dist = values
    return Camera([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dist, CAM.image_size, intrinsics_covariance=cov)


TRUE = np.r_[CAM.fx, CAM.fy, CAM.cx, CAM.cy, CAM.dist]


def _scene():
    m = wall_map(n_cols=4, n_rows=3, size=120.0, spacing=300.0)
    return m, look_at([1700.0, 500.0, 1100.0], [0.0, 450.0, 1150.0])


def _least_squares_pose(camera: Camera, P: np.ndarray, px: np.ndarray, T0: np.ndarray) -> np.ndarray:
    """The pose minimising the corners' squared reprojection error, solved tightly (scipy), as ``[dtheta, dC]``
    from ``T0``."""

    def residuals(x):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix() @ T0[:3, :3]
        T[:3, 3] = T0[:3, 3] + x[3:]
        return (camera.project(P, T) - px).ravel()

    return least_squares(residuals, np.zeros(6), x_scale=np.r_[1e-3, 1e-3, 1e-3, 1, 1, 1], xtol=1e-15, ftol=1e-15).x


@pytest.mark.parametrize("k", range(9))
def test_the_added_covariance_is_the_least_squares_pose_s_finite_difference(k):
    """One intrinsic of variance s^2: the covariance grows by ``s^2 a a^T``, ``a`` the derivative of the pose that
    fits the corners best on that intrinsic, by central differences (noise-free corners, the corner noise given)."""
    m, T = _scene()
    dets = observe(m, T)
    P = np.concatenate([m.corners()[d.id] for d in dets])
    px = np.concatenate([d.corners_px for d in dets])
    h = 0.1 if k < 4 else 1e-4
    plus, minus = TRUE.copy(), TRUE.copy()
    plus[k] += h
    minus[k] -= h
    a = (_least_squares_pose(_camera(plus), P, px, T) - _least_squares_pose(_camera(minus), P, px, T)) / (2 * h)
    cov_k = np.zeros((9, 9))
    cov_k[k, k] = 2.0**2 if k < 4 else 0.01**2
    without = estimate_pose(dets, m, _camera(TRUE), corner_sigma_px=0.3).covariance
    added = estimate_pose(dets, m, _camera(TRUE, cov_k), corner_sigma_px=0.3).covariance - without
    want = cov_k[k, k] * np.outer(a, a)
    assert np.abs(added - want).max() < 1e-3 * np.abs(want).max(), (NAMES[k], np.diag(added), np.diag(want))
    assert np.sqrt(want[3:, 3:].trace()) > 0.05  # the intrinsic does move the camera (mm)


def test_a_wrong_calibration_is_covered_only_with_its_covariance():
    """The intrinsics drawn wrong from a known covariance, the corners with 0.3 px noise: the 95 % position
    ellipsoid holds the true camera in 90-99 % of 300 draws when the camera carries that covariance (98 %: the
    wrong distortion leaves a pattern in the residuals that the marker shift and size terms take for noise, the
    same error counted a little twice), and in 11 % without it (the calibration's error dominates with 12
    markers and no residual shows most of it)."""
    m, T = _scene()
    cov_k = _cov_k()
    L = np.linalg.cholesky(cov_k + 1e-30 * np.eye(9))
    rng = np.random.default_rng(5)
    inside = {"with": 0, "without": 0}
    n = 300
    for _ in range(n):
        wrong = TRUE + L @ rng.standard_normal(9)
        dets = observe(m, T, sigma=0.3, rng=rng)
        for name, cov in (("with", cov_k), ("without", None)):
            pose = estimate_pose(dets, m, _camera(wrong, cov), corner_sigma_px=0.3)
            inside[name] += pose.position_ellipsoid_contains(T[:3, 3])
    assert 0.90 * n <= inside["with"] <= 0.99 * n, inside
    assert inside["without"] < 0.6 * n, inside


def test_the_covariance_is_checked_written_and_rescaled(tmp_path):
    cov = _cov_k()
    cam = _camera(TRUE, cov)
    loaded = Camera.load(cam.save(tmp_path / "cam.json"))
    assert np.array_equal(loaded.intrinsics_covariance, cam.intrinsics_covariance)
    assert Camera.load(_camera(TRUE).save(tmp_path / "plain.json")).intrinsics_covariance is None
    half = cam.scaled((320, 240))
    s = np.r_[0.5, 0.5, 0.5, 0.5, np.ones(5)]
    np.testing.assert_allclose(half.intrinsics_covariance, cov * np.outer(s, s))
    with pytest.raises(CameraError, match=r"expected \(9, 9\)"):
        _camera(TRUE, np.eye(4))
    bad = cov.copy()
    bad[0, 0] = -1.0
    with pytest.raises(CameraError, match="not a covariance"):
        _camera(TRUE, bad)
    with pytest.raises(CameraError, match="NaN"):
        _camera(TRUE, np.full((9, 9), np.nan))
