"""refine_pose_lm and noise_from_pose with a fisheye camera, through ``cv2.fisheye``'s projection: the LM's Jacobian
against finite differences of ``Camera.project``, refined poses on rendered fisheye scenes against their known
truth, and the corner noise and marker shift measured from poses whose picture corners carry a known noise."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from helpers import corner_noise_roots, eight_marker_wall

import fidlearn
from fidlearn import Camera, Detection, MarkerMap, estimate_pose, frames
from fidlearn.planning import noise
from fidlearn.pose import refine_pose_lm
from fidlearn.pose._refine import _residuals
from fidlearn.synthetic import render_scene

#: ROS's calibration of the real fisheye lens of data/real/fisheye_checkerboard (mono set).
K_FE = np.array([[290.050152, 0.0, 399.938345], [0.0, 289.392837, 273.885669], [0.0, 0.0, 1.0]])
D_FE = np.array([-0.030464, -0.019695, 0.002098, 0.001030])
FE = Camera(K_FE, D_FE, (800, 503), model="fisheye")
EYES = [[500.0, 150.0, 300.0], [600.0, -100.0, 250.0], [450.0, 400.0, 400.0]]


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))


def test_the_fisheye_lm_jacobian_is_the_projections_derivative():
    lens = Camera(K_FE, [0.02, -0.01, 0.004, -0.001], FE.image_size, model="fisheye")
    T = frames.look_at([800.0, 100.0, 400.0], [0.0, 0.0, 500.0], roll_deg=10.0)
    P = np.array([[0.0, 0.0, 500.0], [0.0, 600.0, 200.0], [0.0, -900.0, 900.0], [300.0, 2500.0, 400.0]])
    R_wc, C = T[:3, :3], T[:3, 3]
    r, J = _residuals(P, np.zeros((4, 2)), lens.K, lens.dist, R_wc, C, True, "fisheye")
    np.testing.assert_allclose(-r.reshape(-1, 2), lens.project(P, T), atol=1e-9)  # the library's projection
    h = np.array([1e-6] * 3 + [1e-3] * 3)
    for k in range(6):
        step = np.zeros(6)
        step[k] = h[k]
        moved = []
        for sign in (1, -1):
            Tk = T.copy()
            Tk[:3, :3] = cv2.Rodrigues(sign * step[:3])[0] @ R_wc
            Tk[:3, 3] = C + sign * step[3:]
            moved.append(lens.project(P, Tk).reshape(-1))
        fd = (moved[0] - moved[1]) / (2 * h[k])
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())


def test_refine_pose_lm_returns_the_exact_pose_from_exact_fisheye_corners():
    walls = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    T = frames.look_at(EYES[0], [0.0, 150.0, 260.0])
    ids = [i for i in walls.ids if FE.points_in_front(walls.marker_corners(i), T).all()]
    P = np.concatenate([walls.marker_corners(i) for i in ids])
    T_cw = np.linalg.inv(T)
    rvec = cv2.Rodrigues(T_cw[:3, :3])[0].ravel() + np.radians([1.0, -1.0, 0.5])
    refined = refine_pose_lm(P, FE.project(P, T), FE, rvec, T_cw[:3, 3] + [20.0, -10.0, 15.0])
    np.testing.assert_allclose(refined.T_camera_world, T_cw, atol=1e-6)
    assert refined.reprojection_rms_px < 1e-6


def test_refine_pose_lm_on_rendered_fisheye_scenes_is_at_least_as_close_to_the_truth():
    walls = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    for seed, eye in enumerate(EYES):
        T = frames.look_at(eye, [0.0, 150.0, 260.0], roll_deg=5 * seed)
        scene = render_scene(walls, FE, T, seed=seed, blur_px=0.5, noise_std_gray=1.0)
        dets = [d for d in fidlearn.detect_markers(scene.image, walls.dictionary) if d.id in scene.truth]
        P = np.concatenate([walls.marker_corners(d.id) for d in dets])
        px = np.concatenate([d.corners_px for d in dets])
        # the unrefined pose: OpenCV's PnP on the exactly undistorted corners (every corner weighed alike there)
        ok, rvec, tvec = cv2.solvePnP(P, FE.undistort_points(px), FE.K, None, flags=cv2.SOLVEPNP_SQPNP)
        assert ok
        start = frames.transform_from_rvec_tvec(rvec.ravel(), tvec.ravel())
        refined = refine_pose_lm(P, px, FE, rvec.ravel(), tvec.ravel())
        truth = np.linalg.inv(T)
        before = np.linalg.norm(np.linalg.inv(start)[:3, 3] - T[:3, 3])
        after = np.linalg.norm(np.linalg.inv(refined.T_camera_world)[:3, 3] - T[:3, 3])
        assert after <= before  # 1.09, 1.49, 1.14 mm before; 1.04, 0.72, 0.89 mm after
        turned = _angle_deg(refined.T_camera_world[:3, :3] @ truth[:3, :3].T)
        assert turned <= _angle_deg(start[:3, :3] @ truth[:3, :3].T)  # 0.07 degrees before; 0.02 to 0.06 after
        assert refined.reprojection_rms_px < 0.3


def _noisy_fisheye_poses(sigma: float, shift: float, n: int, seed: int):
    """``n`` fisheye poses from eight markers whose picture corners carry corner noise ``sigma`` and a shift per
    marker ``shift`` (px per axis; :func:`noise.corner_covariance`, :func:`noise.marker_shift_covariance`)."""
    rng = np.random.default_rng(seed)
    world = eight_marker_wall()
    T = frames.look_at([600, 100, 600], [0, 0, 550])
    truth = {i: FE.project(world.marker_corners(i), T) for i in world.ids}
    root = corner_noise_roots(truth, sigma, shift)  # the noise model's, as the fisheye picture draws the corners
    poses = []
    for _ in range(n):
        dets = [Detection(i, truth[i] + (root[i] @ rng.normal(size=8)).reshape(4, 2)) for i in world.ids]
        poses.append(estimate_pose(dets, world, FE, corner_sigma_px=sigma, reject_outliers=False))
    return world, poses


@pytest.mark.parametrize(("sigma", "shift"), [(0.3, 0.0), (0.1, 0.2)])
def test_noise_from_a_fisheye_pose_recovers_the_known_corner_noise_and_shift(sigma, shift):
    world, poses = _noisy_fisheye_poses(sigma, shift, 60, seed=5)
    found = [noise.noise_from_pose(pose, world, FE) for pose in poses]
    a, b = np.array([f[:2] for f in found]).T ** 2
    # measured: 0.302 and 0.051 px; 0.101 and 0.201 px (the pose's undistorted-pixel residuals read as the
    # picture's would give 0.41 px for 0.3)
    assert np.sqrt(np.mean(a)) == pytest.approx(sigma, rel=0.1)
    assert np.sqrt(np.mean(b)) == pytest.approx(shift, rel=0.2, abs=0.06)
