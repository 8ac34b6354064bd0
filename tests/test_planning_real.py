"""Predicted against measured pose error on real photos with a known pose (OpenCV's ChArUco photos),
and the marker-shift part of the noise model against Monte-Carlo trials of estimate_pose."""

from __future__ import annotations

import numpy as np
import pytest

import fidlearn
from benchmarks import planning_real as real
from fidlearn import Camera, Detection, FidlearnError, MarkerMap, estimate_pose, look_at, predict_accuracy
from fidlearn.errors import PoseError
from fidlearn.planning import noise
from fidlearn.pose import pose_jacobian


@pytest.fixture(scope="module")
def measured():
    return real.measure(most=8)


def test_the_board_map_is_the_boards_nominal_geometry():
    world = real.board_map()
    obj = np.asarray(real.board().getObjPoints(), dtype=float).reshape(-1, 4, 3)
    assert world.ids == list(range(17))
    for i in world.ids:
        np.testing.assert_allclose(world.marker_corners(i), obj[i], atol=1e-9)
    c = world.marker_corners(0)  # TL, TR, BR, BL: right along the board's x, down along its y, 20 mm sides
    np.testing.assert_allclose(c[1] - c[0], [20, 0, 0], atol=1e-9)
    np.testing.assert_allclose(c[3] - c[0], [0, 20, 0], atol=1e-9)
    np.testing.assert_allclose(world.normal(0), [0, 0, -1], atol=1e-9)  # facing the camera, at negative z


def test_the_reference_pose_reprojects_the_chessboard_corners_and_the_markers(measured):
    world, camera = measured["world"], measured["camera"]
    for ph in measured["photos"]:
        ref = ph.reference
        assert len(ref.points_px) >= 16
        assert ref.rms_px < 0.2  # px per axis: the published calibration fits these corners at 0.18 px
        assert ref.T_world_camera[2, 3] < -200  # in front of the board (negative z)
        assert 300 < np.linalg.norm(ref.T_world_camera[:3, 3] - [100, 140, 0]) < 500  # from the centre, mm
        assert ref.position_error_mm < 1.0
        assert len(ph.detections) >= 13
        res = real.marker_residuals(ph, world, camera)
        assert np.sqrt(np.mean(res**2)) < 0.5 and np.abs(res).max() < 2.0
    scale, spread = measured["scale"]
    assert 0.98 < scale < 1.0 and spread < 0.02  # the markers look 1 % smaller than printed


def test_subset_errors_lie_where_the_prediction_says(measured):
    for (lo, hi), d in measured["groups"].items():
        q = real.ratio(d["measured"], d["difference"])
        assert 0.5 < q < 2.0, (lo, hi, q)
        assert d["inside"].mean() > 0.15, (lo, hi)
        if lo >= 2:
            assert not d["flagged"].any() and not d["flipped"].any()
        assert real.ratio(d["measured"], d["model"]) < 0.5  # the renders' noise is far too small here


def _shifted_trials(sigma, shift, n, seed):
    rng = np.random.default_rng(seed)
    # eight 80 mm markers on the wall X = 0, seen from 1.2 m
    places = [(y, z) for y in (-450, -150, 150, 450) for z in (300, 800)]
    world = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80.0,
            "markers": {str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]} for k, (y, z) in enumerate(places)},
        }
    )
    camera = Camera.load(fidlearn.data_path("scenes/camera.json"))
    T = look_at([1200, 100, 600], [0, 0, 550])
    p = predict_accuracy(world, camera, T, corner_sigma_px=sigma, marker_shift_px=shift)
    truth = {i: camera.project(world.marker_corners(i), T) for i in p.marker_ids}
    root = {
        i: np.linalg.cholesky(noise.corner_covariance(truth[i], sigma) + noise.marker_shift_covariance(shift))
        for i in p.marker_ids
    }
    poses = []
    for _ in range(n):
        dets = [Detection(i, truth[i] + (root[i] @ rng.normal(size=8)).reshape(4, 2)) for i in p.marker_ids]
        poses.append(estimate_pose(dets, world, camera, corner_sigma_px=sigma, reject_outliers=False))
    return world, camera, T, p, truth, poses


def test_a_marker_shift_is_predicted_as_estimate_pose_meets_it():
    world, camera, T, p, truth, poses = _shifted_trials(0.1, 0.3, 300, seed=3)
    assert len(p.marker_ids) >= 4
    C = np.array([q.position_mm for q in poses]) - T[:3, 3]
    np.testing.assert_allclose(np.sqrt(np.diag(np.cov(C.T))), p.position_std_mm, rtol=0.15)
    without = predict_accuracy(world, camera, T, corner_sigma_px=0.1)
    assert p.position_error_mm > 1.5 * without.position_error_mm
    assert predict_accuracy(world, camera, T, corner_sigma_px=0.1, marker_shift_px=0.0).position_error_mm == (
        without.position_error_mm
    )


@pytest.mark.parametrize("sigma, shift", [(0.2, 0.15), (0.3, 0.0), (0.05, 0.3)])
def test_noise_from_a_pose_recovers_the_corner_noise_and_the_shift(sigma, shift):
    world, camera, T, p, truth, poses = _shifted_trials(sigma, shift, 60, seed=4)
    a, b = np.array([noise.noise_from_pose(pose, world, camera) for pose in poses]).T ** 2
    assert np.sqrt(np.mean(a)) == pytest.approx(sigma, rel=0.1)
    assert np.sqrt(np.mean(b)) == pytest.approx(shift, rel=0.2, abs=0.06)  # a shift of 0 is clipped at 0: biased up
    # the same from the bare residuals, the Jacobian and the corners the pose saw
    pose, ids = poses[0], list(poses[0].marker_ids)
    J = pose_jacobian(np.concatenate([world.marker_corners(i) for i in ids]), pose.T_world_camera, camera)
    seen = np.array([camera.project(world.marker_corners(i), pose.T_world_camera) + pose.residuals_px[i] for i in ids])
    bare = noise.noise_from_residuals(np.array([pose.residuals_px[i] for i in ids]), J, seen)
    assert bare == pytest.approx(noise.noise_from_pose(pose, world, camera))


@pytest.mark.parametrize("shift", [-0.1, float("nan"), "0.2", True])
def test_a_bad_marker_shift_is_refused(shift):
    world = MarkerMap.load(fidlearn.data_path("world_map.json"))
    camera = Camera.load(fidlearn.data_path("scenes/camera.json"))
    with pytest.raises(FidlearnError, match="marker_shift_px"):
        predict_accuracy(world, camera, look_at([1000, 190, 230], [0, 190, 230]), marker_shift_px=shift)


def test_noise_needs_four_markers():
    with pytest.raises(PoseError, match="at least 4 markers"):
        noise.noise_from_residuals(np.zeros((3, 4, 2)), np.zeros((24, 6)), np.zeros((3, 4, 2)))
    world, camera, T, p, truth, poses = _shifted_trials(0.2, 0.1, 1, seed=5)
    three = estimate_pose([Detection(i, truth[i]) for i in p.marker_ids[:3]], world, camera)
    with pytest.raises(PoseError, match="at least 4 markers"):
        noise.noise_from_pose(three, world, camera)


def test_the_size_error_of_each_photo_comes_from_the_other_photos_only(measured):
    photos, world, camera, noises = measured["photos"], measured["world"], measured["camera"], measured["noises"]
    sizes = real.size_errors(photos, world, camera, noises)
    assert sizes == measured["sizes"]
    for common, each in sizes:
        assert 0.005 < common < 0.02 and 0.0 <= each < 0.01  # the markers look 1 % smaller than printed
    # the first photo's markers detected 5 % larger about their centres: its own size error does not move,
    # every other photo's does
    first = photos[0]
    grown = {
        i: fidlearn.Detection(i, d.corners_px.mean(axis=0) + 1.05 * (d.corners_px - d.corners_px.mean(axis=0)))
        for i, d in first.detections.items()
    }
    changed = real.size_errors([real.Photo(first.name, first.reference, grown), *photos[1:]], world, camera, noises)
    assert changed[0] == sizes[0]
    assert all(c[0] != s[0] for c, s in zip(changed[1:], sizes[1:]))
    # the ratio is the least-squares scale of the detected corners about their centre
    r, v = real.size_ratios(real.Photo(first.name, first.reference, grown), world, camera, 0.2)
    r0, v0 = real.size_ratios(first, world, camera, 0.2)
    np.testing.assert_allclose(r, 1.05 * r0)
    np.testing.assert_allclose(v, v0)
