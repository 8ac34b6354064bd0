"""Predicted against measured pose error on real photos with a known pose (OpenCV's ChArUco photos),
and the marker-shift part of the noise model against Monte-Carlo trials of estimate_pose."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import corner_noise_roots, eight_marker_wall

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
    bundled = MarkerMap.load(fidlearn.data_path(f"{real.FOLDER}/board_map.json"))  # the course's copy
    assert bundled.ids == world.ids
    assert bundled.dictionary == world.dictionary
    for i in world.ids:
        np.testing.assert_allclose(bundled.marker_corners(i), world.marker_corners(i), atol=1e-9)


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
        assert np.sqrt(np.mean(res**2)) < 0.5
        assert np.abs(res).max() < 2.0
    scale, spread = measured["scale"]
    assert 0.98 < scale < 1.0  # the markers look 1 % smaller than printed
    assert spread < 0.02


def test_subset_errors_lie_where_the_prediction_says(measured):
    for (lo, hi), d in measured["groups"].items():
        q = real.ratio(d["measured"], d["difference"])
        assert 0.5 < q < 2.0, (lo, hi, q)
        # seven or more markers are off the chessboard's pose by a common 0.2 to 0.8 mm in y in every photo,
        # 1 to 3 predicted standard deviations; nothing in a marker-only pose's residuals shows that offset
        assert d["inside"].mean() > (0.5 if hi <= 6 else 0.1), (lo, hi)
        if lo >= 2:
            assert not d["flagged"].any()
            assert not d["flipped"].any()
        assert real.ratio(d["measured"], d["model"]) < 0.5  # the renders' noise is far too small here


def _shifted_trials(sigma, shift, n, seed, size_each=0.0, size_error=0.0):
    """``n`` poses from eight markers whose corners carry the noise model's parts: corner noise ``sigma``,
    a shift per marker, a size error of each marker and one common to all (about each marker's centre)."""
    rng = np.random.default_rng(seed)
    world = eight_marker_wall()  # seen from 1.2 m
    camera = Camera.load(fidlearn.data_path("scenes/camera.json"))
    T = look_at([1200, 100, 600], [0, 0, 550])
    p = predict_accuracy(world, camera, T, corner_sigma_px=sigma, marker_shift_px=shift)
    truth = {i: camera.project(world.marker_corners(i), T) for i in p.marker_ids}
    root = corner_noise_roots(truth, sigma, shift)
    grow = {i: truth[i] - truth[i].mean(axis=0) for i in p.marker_ids}
    poses = []
    for _ in range(n):
        dets = [
            Detection(
                i,
                truth[i]
                + (root[i] @ rng.normal(size=8)).reshape(4, 2)
                + (size_error + size_each * rng.normal()) * grow[i],
            )
            for i in p.marker_ids
        ]
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


@pytest.mark.parametrize(
    ("sigma", "shift", "each", "error"),
    [(0.2, 0.15, 0.0, 0.0), (0.3, 0.0, 0.0, 0.0), (0.05, 0.3, 0.0, 0.0), (0.1, 0.15, 0.005, -0.0125)],
)
def test_noise_from_a_pose_recovers_the_corner_noise_the_shift_and_the_size_errors(sigma, shift, each, error):
    world, camera, T, p, truth, poses = _shifted_trials(sigma, shift, 60, seed=4, size_each=each, size_error=error)
    found = [noise.noise_from_pose(pose, world, camera) for pose in poses]
    a, b, c = np.array([f[:3] for f in found]).T ** 2
    assert np.sqrt(np.mean(a)) == pytest.approx(sigma, rel=0.1)
    assert np.sqrt(np.mean(b)) == pytest.approx(shift, rel=0.2, abs=0.06)  # a shift of 0 is clipped at 0: biased up
    # each marker's size error: 0.5 % of a 60 px marker moves its corners 0.2 px from its centre
    assert np.sqrt(np.mean(c)) == pytest.approx(each, rel=0.3, abs=0.002)
    # the common size error is fitted, not averaged as a spread: each pose knows it to 0.15 % here (the
    # eight markers' own size errors average down), the mean of 60 to 0.02 %
    assert np.mean([f.marker_size_rel_error for f in found]) == pytest.approx(error, abs=8e-4)
    assert found[0].kwargs() == dict(zip(noise.PhotoNoise._fields, found[0]))
    # the same from the bare residuals, the Jacobian and the corners the pose saw
    pose, ids = poses[0], list(poses[0].marker_ids)
    J = pose_jacobian(np.concatenate([world.marker_corners(i) for i in ids]), pose.T_world_camera, camera)
    seen = np.array([camera.project(world.marker_corners(i), pose.T_world_camera) + pose.residuals_px[i] for i in ids])
    bare = noise.noise_from_residuals(np.array([pose.residuals_px[i] for i in ids]), J, seen)
    assert bare == pytest.approx(noise.noise_from_pose(pose, world, camera))


def test_a_known_size_error_moves_the_camera_along_its_axis_by_as_much():
    """One marker seen face-on from 1 m on its axis, looking 1 % larger than the map says: the camera is
    found 1 % nearer, about 10 mm toward the marker, on every try; the median error is that bias."""
    world = MarkerMap.from_dict(
        {"units": "mm", "marker_size_mm": 80.0, "markers": {"0": {"translation": [0, -40, 540], "rotation": [0, 0, 0]}}}
    )
    camera = Camera.load(fidlearn.data_path("scenes/camera.json"))
    T = look_at([1000, 0, 500], [0, 0, 500])
    p = predict_accuracy(world, camera, T, corner_sigma_px=0.001, marker_size_rel_error=0.01)
    # the marker's size says the camera is 1000 / 1.01 mm away: 9.9 mm nearer, along -X
    np.testing.assert_allclose(p.position_bias_mm, [-1000 * (1 - 1 / 1.01), 0, 0], atol=0.15)
    assert p.position_error_mm == pytest.approx(np.linalg.norm(p.position_bias_mm), rel=0.05)
    c = camera.project(world.marker_corners(0), T)
    found = estimate_pose([Detection(0, c.mean(axis=0) + 1.01 * (c - c.mean(axis=0)))], world, camera)
    np.testing.assert_allclose(found.position_mm - T[:3, 3], p.position_bias_mm, atol=0.15)
    assert "bias [-10.0, 0.0, 0.0] mm" in repr(p)  # first order: 1 % of the distance
    plain = predict_accuracy(world, camera, T, corner_sigma_px=0.001)
    np.testing.assert_array_equal(plain.position_bias_mm, np.zeros(3))
    assert "bias" not in repr(plain)
    np.testing.assert_allclose(p.covariance, plain.covariance)  # the spread about the bias is the same


def test_a_known_size_error_is_predicted_as_estimate_pose_meets_it():
    """Eight markers seen from 1.2 m, corner noise, a shift and markers that look 3 % smaller than the map
    says: the median of the measured errors is the predicted one, and each pose moves by the predicted bias
    against the same noise without the size error."""
    kw = {"corner_sigma_px": 0.1, "marker_shift_px": 0.15, "marker_size_rel_error": -0.03}
    world, camera, T, p, truth, poses = _shifted_trials(0.1, 0.15, 300, seed=6, size_error=-0.03)
    *_, same_noise = _shifted_trials(0.1, 0.15, 300, seed=6)
    p = predict_accuracy(world, camera, T, **kw)
    e = np.array([q.position_mm for q in poses]) - T[:3, 3]
    moved = e - (np.array([q.position_mm for q in same_noise]) - T[:3, 3])
    np.testing.assert_allclose(
        np.median(moved, axis=0), p.position_bias_mm, atol=0.05 * np.linalg.norm(p.position_bias_mm)
    )
    assert np.median(np.linalg.norm(e, axis=1)) == pytest.approx(p.position_error_mm, rel=0.1)
    without = predict_accuracy(world, camera, T, corner_sigma_px=0.1, marker_shift_px=0.15)
    assert p.position_error_mm > 1.1 * without.position_error_mm  # eight markers far apart: the bias is small


@pytest.mark.parametrize("error", [-0.5, 0.5, float("nan"), "0.01", True])
def test_a_bad_known_size_error_is_refused(error):
    world = MarkerMap.load(fidlearn.data_path("world_map.json"))
    camera = Camera.load(fidlearn.data_path("scenes/camera.json"))
    with pytest.raises(FidlearnError, match="marker_size_rel_error must be a fraction"):
        predict_accuracy(world, camera, look_at([1000, 190, 230], [0, 190, 230]), marker_size_rel_error=error)


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


def test_each_photos_prediction_uses_the_other_photos_noise_only(measured):
    noises = measured["noises"]
    for n in noises:  # each photo's all-marker pose: the markers look 1.2 to 1.4 % smaller than printed
        assert 0.05 < n.corner_sigma_px < 0.5
        assert 0.1 < n.marker_shift_px < 0.3
        assert 0.0 <= n.marker_size_rel_std_each < 0.01
        assert -0.015 < n.marker_size_rel_error < -0.01
    first = real.others_noise(noises, 0)
    rest = np.array(noises[1:])
    assert first.corner_sigma_px == pytest.approx(np.sqrt(np.mean(rest[:, 0] ** 2)))
    assert first.marker_size_rel_error == pytest.approx(np.mean(rest[:, 3]))
    # the first photo's own noise does not change its prediction; every other photo's does
    louder = [noise.PhotoNoise(1.0, 1.0, 0.1, 0.1), *noises[1:]]
    assert real.others_noise(louder, 0) == first
    assert all(real.others_noise(louder, k) != real.others_noise(noises, k) for k in range(1, len(noises)))
    # the apparent size against the reference is the least-squares scale of the detected corners about their centre
    photo = measured["photos"][0]
    grown = {
        i: fidlearn.Detection(i, d.corners_px.mean(axis=0) + 1.05 * (d.corners_px - d.corners_px.mean(axis=0)))
        for i, d in photo.detections.items()
    }
    world, camera = measured["world"], measured["camera"]
    r, v = real.size_ratios(real.Photo(photo.name, photo.reference, grown), world, camera, 0.2)
    r0, v0 = real.size_ratios(photo, world, camera, 0.2)
    np.testing.assert_allclose(r, 1.05 * r0)
    np.testing.assert_allclose(v, v0)
