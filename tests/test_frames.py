"""Transforms: known rotations, closed-form inverse, rvec/tvec and roll-pitch-yaw round trips."""

import math

import cv2
import numpy as np
import pytest

from fidlearn import frames
from fidlearn.errors import TransformError


def test_rpy_is_fixed_axis_zyx():
    # yaw 90 turns +X into +Y; pitch 90 turns +X into -Z; roll 90 turns +Y into +Z (right hand rule)
    assert np.allclose(frames.rotation_from_rpy_deg(0, 0, 90) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(frames.rotation_from_rpy_deg(0, 90, 0) @ [1, 0, 0], [0, 0, -1])
    assert np.allclose(frames.rotation_from_rpy_deg(90, 0, 0) @ [0, 1, 0], [0, 0, 1])
    r, p, y = np.radians([10, 20, 30])
    expected = frames.rot_z(y) @ frames.rot_y(p) @ frames.rot_x(r)
    assert np.allclose(frames.rotation_from_rpy_deg(10, 20, 30), expected)


def test_right_angles_are_exact():
    R = frames.rotation_from_rpy_deg(0, 0, 180)
    assert R.tolist() == [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]


@pytest.mark.parametrize("rpy", [(0, 0, 0), (10, -20, 30), (-170, 45, 179), (5, 89, -60), (0, -89.5, 12)])
def test_rpy_round_trip(rpy):
    R = frames.rotation_from_rpy_deg(*rpy)
    assert np.allclose(frames.rpy_deg_from_rotation(R), rpy, atol=1e-9)


def test_rpy_at_gimbal_lock_keeps_the_rotation():
    R = frames.rotation_from_rpy_deg(30, 90, 10)
    rpy = frames.rpy_deg_from_rotation(R)
    assert rpy[0] == 0.0
    assert rpy[1] == pytest.approx(90)
    assert np.allclose(frames.rotation_from_rpy_deg(*rpy), R)


def test_inverse_closed_form_matches_general_inverse():
    T = frames.make_transform(frames.rotation_from_rpy_deg(12, -34, 56), [100.0, -2000.0, 350.0])
    T_inv = frames.invert_transform(T)
    assert np.allclose(T_inv, np.linalg.inv(T))
    assert np.allclose(T @ T_inv, np.eye(4))
    # hand check: camera 1 m along world X looking back gives a point at the world origin 1 m ahead
    T_world_camera = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, 180), [1000, 0, 0])
    p_camera = frames.transform_points(frames.invert_transform(T_world_camera), [0, 0, 0])
    assert np.allclose(p_camera, [1000, 0, 0])


def test_compose_chains_frames():
    T_world_camera = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, 90), [0, 0, 1000])
    T_camera_marker = frames.make_transform(np.eye(3), [0, 0, 500])
    T_world_marker = frames.compose(T_world_camera, T_camera_marker)
    assert np.allclose(T_world_marker[:3, 3], [0, 0, 1500])
    assert np.allclose(frames.compose(), np.eye(4))


def test_rvec_tvec_round_trip_and_opencv_agreement():
    rvec = np.array([0.1, -0.4, 0.25])
    tvec = np.array([12.0, -30.0, 900.0])
    T = frames.transform_from_rvec_tvec(rvec, tvec)
    R_cv, _ = cv2.Rodrigues(rvec)
    assert np.allclose(T[:3, :3], R_cv)
    r2, t2 = frames.rvec_tvec_from_transform(T)
    assert np.allclose(r2, rvec)
    assert np.allclose(t2, tvec)


def test_transform_points_shapes():
    T = frames.make_transform(frames.rotation_from_rpy_deg(0, 0, 90), [1, 2, 3])
    pts = frames.transform_points(T, np.array([[1.0, 0, 0], [0, 1, 0]]))
    assert pts.shape == (2, 3)
    assert np.allclose(pts, [[1, 3, 3], [0, 2, 3]])
    with pytest.raises(TransformError, match=r"expected \(N, 3\)"):
        frames.transform_points(T, np.zeros((2, 2)))


@pytest.mark.parametrize(
    ("matrix", "message"),
    [
        (np.eye(3), r"shape \(3, 3\), expected a \(4, 4\)"),
        (np.diag([1.0, 1.0, 1.0, 2.0]), r"bottom row \[0.0, 0.0, 0.0, 2.0\]"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "not orthonormal"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "reflection, not a rotation"),
        (np.full((4, 4), np.nan), "NaN or infinity"),
    ],
)
def test_check_transform_says_what_is_wrong(matrix, message):
    with pytest.raises(TransformError, match=message):
        frames.check_transform(matrix)


def test_rotation_angle():
    assert frames.rotation_angle_deg(frames.rot_z(np.radians(30))) == pytest.approx(30)
    R = frames.rotation_from_rpy_deg(0, 0, 10)
    assert frames.rotation_angle_deg(R, frames.rotation_from_rpy_deg(0, 0, 25)) == pytest.approx(15)


@pytest.mark.parametrize("angle_rad", [3e-6, 9e-6, 2e-5])
def test_rvec_of_a_tiny_rotation_is_not_zero(angle_rad):
    # cv2.Rodrigues gives a zero vector below about 1e-5 rad: a camera turned 9e-6 rad
    # projected 0.02 px off on an HD camera (Camera.project goes through the rvec).
    axis = np.array([0.6, -0.8, 0.0])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + math.sin(angle_rad) * K + (1 - math.cos(angle_rad)) * K @ K
    rvec, tvec = frames.rvec_tvec_from_transform(frames.make_transform(R, [1, 2, 3]))
    np.testing.assert_allclose(rvec, angle_rad * axis, rtol=0, atol=1e-12)  # rad
    np.testing.assert_allclose(cv2.Rodrigues(rvec)[0], R, atol=1e-15)
    assert tvec.tolist() == [1, 2, 3]
    from fidlearn import Camera

    cam = Camera.from_fov(60, (1920, 1080))
    T = frames.make_transform(R, [0, 0, 0])
    P = np.array([[900.0, 500.0, 1000.0]])
    exact = cam.K @ (R.T @ P[0])  # the camera at the origin: p_camera = R^T p_world
    np.testing.assert_allclose(cam.project(P, T)[0], exact[:2] / exact[2], atol=1e-9)


def test_look_at_is_public_in_frames_and_at_the_top_level_only():
    from fidlearn import look_at as top_level
    from fidlearn import synthetic

    assert frames.look_at is top_level
    assert not hasattr(synthetic, "look_at")
    assert frames.look_at.__module__ == "fidlearn.frames"
    T = frames.look_at([0.0, -2000.0, 500.0], [0.0, 0.0, 500.0])  # looking north (+Y), Z up
    np.testing.assert_allclose(T[:3, :3], [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-15)  # x east, y down, z north
    np.testing.assert_array_equal(T[:3, 3], [0.0, -2000.0, 500.0])
