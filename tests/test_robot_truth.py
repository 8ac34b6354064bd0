"""The robot's truth for board poses: the hand-eye fit on hand-made transforms, and on the real robot photos
the agreement that the data's provenance states (data/README.md, real/robot_charuco)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import fidlearn
from benchmarks import handeye as he
from benchmarks import robot_charuco as rc


def _pose(rotvec_deg, t_mm) -> np.ndarray:
    return he.transform(Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix(), t_mm)


#: Hand-made truth: the camera 1.3 m from the robot's base, looking back at it; the board 200 mm off the flange.
T_BASE_CAMERA = _pose([-120.0, 30.0, 80.0], [-20.0, 1278.0, 284.0])
T_TOOL_BOARD = _pose([70.0, -40.0, 25.0], [63.0, 120.0, 211.0])


def _robot_poses(n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [_pose(rng.normal(0, 40, 3), rng.normal([100, 600, 600], 150)) for _ in range(n)]


def _seen(robots: list[np.ndarray]) -> list[np.ndarray]:
    return [he.invert(T_BASE_CAMERA) @ B @ T_TOOL_BOARD for B in robots]


def test_the_fit_recovers_hand_made_transforms_exactly():
    robots = _robot_poses(8, seed=3)
    for T_base_camera, T_tool_board in (
        he.initial_guess(robots, _seen(robots)),
        (lambda f: (f.T_base_camera, f.T_tool_board))(he.fit(robots, _seen(robots), rc.chess_corners_mm())),
    ):
        np.testing.assert_allclose(T_base_camera, T_BASE_CAMERA, atol=1e-6)
        np.testing.assert_allclose(T_tool_board, T_TOOL_BOARD, atol=1e-6)


def test_a_left_out_photo_is_predicted_from_its_robot_pose_alone():
    robots = _robot_poses(6, seed=5)
    seen = _seen(robots)
    wrong = [T.copy() for T in seen]
    wrong[2][:3, 3] += [50.0, -30.0, 80.0]  # a vision pose far off: it cannot move its own truth
    predicted = he.leave_one_out(robots, wrong, rc.chess_corners_mm(), judged=[2])
    np.testing.assert_allclose(predicted[0], seen[2], atol=1e-6)
    position, rotation = he.pose_error(predicted[0], wrong[2], np.zeros(3))
    assert position == pytest.approx(np.linalg.norm([50.0, -30.0, 80.0]))
    assert rotation == pytest.approx(0.0, abs=1e-6)


def test_the_robust_fit_shrugs_off_one_bad_vision_pose_and_noise():
    robots = _robot_poses(12, seed=9)
    rng = np.random.default_rng(1)
    seen = [T @ _pose(rng.normal(0, 0.02, 3), rng.normal(0, 0.2, 3)) for T in _seen(robots)]
    seen[4] = seen[4] @ _pose([3.0, 0.0, 0.0], [0.0, 0.0, 40.0])
    fit = he.fit(robots, seen, rc.chess_corners_mm())
    for T in (fit.T_base_camera @ np.linalg.inv(T_BASE_CAMERA), fit.T_tool_board @ np.linalg.inv(T_TOOL_BOARD)):
        assert np.linalg.norm(T[:3, 3]) < 2.0
        assert np.degrees(np.linalg.norm(Rotation.from_matrix(T[:3, :3]).as_rotvec())) < 0.1


def test_pose_error_and_nees_have_known_answers():
    a = _pose([0.0, 0.0, 0.0], [0.0, 0.0, 500.0])
    b = a @ _pose([0.0, 0.0, 2.0], [3.0, 4.0, 0.0])  # 2 degrees about the board's z, 5 mm along it
    position, rotation = he.pose_error(a, b, np.zeros(3))
    assert position == pytest.approx(5.0)
    assert rotation == pytest.approx(2.0)
    # the camera 1 mm off along x under a covariance of 0.25 mm^2 there: NEES 4
    cov = np.diag([1e-6, 1e-6, 1e-6, 0.25, 1.0, 1.0])
    assert he.nees(_pose([0, 0, 0], [1.0, 0, 0]), np.eye(4), cov) == pytest.approx(4.0)


def test_the_fit_needs_three_photos():
    robots = _robot_poses(2, seed=1)
    with pytest.raises(ValueError, match="at least 3"):
        he.fit(robots, _seen(robots), rc.chess_corners_mm())


def test_the_robot_photos_and_poses_are_read_as_published():
    assert rc.robot_pose(0)[:3, 3] == pytest.approx([113.074204220918, 589.2802789268905, 652.673790716681])
    R = rc.robot_pose(0)[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    cam = rc.published_camera()
    assert cam.K[0, 0] == pytest.approx(1352.02747)
    assert cam.K[1, 2] == pytest.approx(627.2995)
    assert not np.any(cam.dist)
    assert rc.photo(2).shape == (1200, 1600)  # stored grey
    assert len(rc.charuco_corners(2)[1]) == 4  # only a corner of the board in view


def test_on_the_real_photos_the_robot_agrees_with_plain_opencv_as_published():
    """Plain OpenCV with its own calibration: about 0.75-2.9 mm and 0.1-0.45 degrees, 8 mm for the farthest photo."""
    camera, rms = rc.opencv_calibration()
    assert rms < 0.6  # the lens's barrel distortion
    assert camera.dist[0] == pytest.approx(-0.14, abs=0.02)
    robots = [rc.robot_pose(i) for i in range(rc.N_PHOTOS)]
    seen = [rc.charuco_pose(i, camera).T_camera_board for i in range(rc.N_PHOTOS)]
    judged = [0, 9, 11, 15]  # the three worst of the near photos and the farthest
    predicted = he.leave_one_out(robots, seen, rc.chess_corners_mm(), judged=judged)
    for k, truth in zip(judged, predicted):
        position, rotation = he.pose_error(truth, seen[k], rc.CENTRE_MM)
        distance_m = np.linalg.norm(truth[:3, 3]) / 1000
        if k == 15:
            assert distance_m > 1.3
            assert 3.0 < position < 8.0
            assert rotation < 1.5
        else:
            assert distance_m < 0.8
            assert 0.3 < position < 2.9
            assert rotation < 0.45


@pytest.fixture(scope="module")
def opencv_camera():
    return rc.opencv_calibration()[0]


def test_the_bent_board_keeps_its_markers_and_the_pose_is_plain_opencvs(opencv_camera):
    """The board's outer column is a fraction of a millimetre off flat: its markers were rejected as moved."""
    for i in (0, 1, 5, 8, 11):  # marker 2 (and 4 or 7) rejected in these before
        pose = rc.fidlearn_pose(i, opencv_camera).pose
        assert pose.rejected_ids == (), i
        plain = rc.opencv_marker_pose(i, opencv_camera).T_camera_board
        np.testing.assert_allclose(he.invert(pose.T_world_camera)[:3, 3], plain[:3, 3], atol=0.02)


def test_a_marker_moved_on_the_bent_board_is_still_rejected(opencv_camera):
    board = rc.board_map().to_dict()
    board["markers"]["7"]["translation"][0] += 4.0  # 4 mm along the board: a fifth of the marker's side
    moved = fidlearn.MarkerMap.from_dict(board)
    for i in (0, 8):
        pose = fidlearn.estimate_pose(list(rc.markers(i)), moved, opencv_camera)
        assert pose.rejected_ids == (7,), (i, pose.rejected_ids)


def test_the_covariance_with_the_truths_own_holds_the_robots_position(opencv_camera):
    """Judged against the robot with the leave-one-out prediction's covariance added (photos 0, 4, 8, 12).

    The position NEES is inside the 95 % ellipsoid (7.81) for each; under the covariance of corner noise
    alone, as fidlearn had it, the 6-dof NEES was 587-2968 for these photos; the truth's covariance added
    brings it to tens (the robot's own error at the judged photo is not in it)."""
    robots = [rc.robot_pose(i) for i in range(rc.N_PHOTOS)]
    measured = [rc.fidlearn_pose(i, opencv_camera) for i in range(rc.N_PHOTOS)]
    poses = [m.T_camera_board for m in measured]
    for k in (0, 4, 8, 12):
        T, cov_truth = he.predict_with_covariance(robots, poses, rc.chess_corners_mm(), k)
        assert np.all(np.linalg.eigvalsh(cov_truth) > 0)
        pose = measured[k].pose
        e = he.camera_error(he.invert(T), pose.T_world_camera)
        cov = pose.covariance + cov_truth
        assert e[3:] @ np.linalg.solve(cov[3:, 3:], e[3:]) < 7.81, k
        assert e @ np.linalg.solve(cov, e) < 100, k
