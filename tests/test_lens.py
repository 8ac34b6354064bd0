"""One lens model: ``Camera.project`` is ``cv2.projectPoints`` for every coefficient count OpenCV has, and
``Camera.undistort_points`` is its exact inverse over the whole picture, a wide lens's corners included."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import Camera, frames

_RATIONAL = [-0.2, 0.05, 0.001, -0.001, -0.003, 0.05, -0.01, 0.002]
_PRISM = [0.001, -0.0005, 0.0008, 0.0003]
#: OpenCV's 4, 5, 8, 12 and 14 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tau_x tau_y]]]]).
LENSES = {
    4: [-0.28, 0.09, 0.001, -0.002],
    5: [-0.4, 0.16, 0.001, -0.001, -0.02],  # a wide lens: 1.2 px between OpenCV's undistortion and the exact one
    8: _RATIONAL,
    12: _RATIONAL + _PRISM,
    14: _RATIONAL + _PRISM + [0.01, -0.008],
}


def _camera(n):
    return Camera.from_fov(90, (1280, 720), dist=LENSES[n])


def _picture(camera, steps=(160, 90)):
    w, h = camera.image_size
    u, v = np.meshgrid(np.linspace(-0.5, w - 0.5, steps[0]), np.linspace(-0.5, h - 0.5, steps[1]))
    return np.stack([u.ravel(), v.ravel()], axis=1)  # the whole picture, its edges and corners too


@pytest.mark.parametrize("n", sorted(LENSES))
def test_project_is_opencvs_projectPoints_to_1e_9_px(n):
    cam = _camera(n)
    assert cam.dist.size == n
    rng = np.random.default_rng(n)
    T = frames.transform_from_rvec_tvec(rng.normal(0, 0.3, 3), rng.normal(0, 100, 3))
    pts = np.column_stack([rng.uniform(-900, 900, (400, 2)), rng.uniform(700, 3000, 400)])
    world = frames.transform_points(T, pts)  # in front of the camera at T, seen at up to 52 degrees off axis
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(T))
    by_opencv = cv2.projectPoints(world.reshape(-1, 1, 3), rvec, tvec, cam.K, cam.dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(world, T), by_opencv, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cam.project(world[0], T), by_opencv[0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("n", sorted(LENSES))
def test_undistortion_is_the_exact_inverse_of_projection_across_the_picture(n):
    cam = _camera(n)
    px = _picture(cam)
    ideal = cam.undistort_points(px)
    rays = np.column_stack([(ideal - cam.K[:2, 2]) / [cam.fx, cam.fy], np.ones(len(px))]) * 1500.0
    back = cam.project(rays, np.eye(4))
    assert np.abs(back - px).max() < 1e-6
    # OpenCV's own few fixed-point steps are a tenth of a pixel off and more at these corners
    assert np.abs(cam.undistort_points(px, exact=False) - ideal).max() > 0.1


def test_a_depth_of_zero_projects_as_opencv_does():
    cam = _camera(5)
    pts = np.array([[10.0, -20.0, 0.0], [5.0, 5.0, -100.0]])
    by_opencv = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist)[0].reshape(-1, 2)
    np.testing.assert_allclose(cam.project(pts, np.eye(4)), by_opencv, rtol=1e-12, atol=1e-9)
