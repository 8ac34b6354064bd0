"""The markers' size error in predict_accuracy: against Monte-Carlo trials of estimate_pose on markers
printed at a randomly scaled size (each growing from its top-left corner), and the checks on its value."""

from __future__ import annotations

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, Detection, FidlearnError, MarkerMap, estimate_pose, look_at, predict_accuracy
from fidlearn.planning import noise


@pytest.fixture(scope="module")
def world():
    return MarkerMap.load(fidlearn.data_path("world_map.json"))


@pytest.fixture(scope="module")
def camera():
    return Camera.load(fidlearn.data_path("scenes/camera.json"))


def _trials(world, camera, T, sigma, common, each, n, seed):
    """Camera positions from ``n`` sets of corners of markers printed at a random size, plus corner noise."""
    rng = np.random.default_rng(seed)
    p = predict_accuracy(world, camera, T, corner_sigma_px=sigma, marker_size_rel_std=common,
                         marker_size_rel_std_each=each)  # fmt: skip
    nominal = {i: world.marker_corners(i) for i in p.marker_ids}
    root = {i: np.linalg.cholesky(noise.corner_covariance(camera.project(nominal[i], T), sigma)) for i in p.marker_ids}
    out = []
    for _ in range(n):
        scale = 1.0 + common * rng.normal()
        dets = []
        for i in p.marker_ids:
            printed = nominal[i][0] + (scale + each * rng.normal()) * (nominal[i] - nominal[i][0])
            exact = camera.project(printed, T)
            dets.append(Detection(i, exact + (root[i] @ rng.normal(size=8)).reshape(4, 2)))
        out.append(estimate_pose(dets, world, camera, corner_sigma_px=sigma, reject_outliers=False).position_mm)
    return p, np.array(out) - T[:3, 3]


@pytest.mark.parametrize(
    ("eye", "target", "sigma", "common", "each"),
    [
        ([1000, 190, 230], [0, 190, 230], 0.1, 0.005, 0.0),  # face-on, 1 m: the scale tilts the pose
        ([1500, -600, 420], [0, 190, 230], 0.2, 0.02, 0.0),  # oblique, 1.7 m
        ([700, 900, 150], [0, 190, 300], 0.2, 0.0, 0.02),  # close, from the side: each marker its own size
        ([1200, 300, 400], [0, 190, 230], 0.1, 0.01, 0.01),  # both
    ],
)
def test_size_error_covariance_equals_the_sample_covariance(world, camera, eye, target, sigma, common, each):
    T = look_at(eye, target)
    p, e = _trials(world, camera, T, sigma, common, each, 400, seed=3)
    base = predict_accuracy(world, camera, T, corner_sigma_px=sigma)
    assert np.sum(p.position_std_mm**2) > 1.5 * np.sum(base.position_std_mm**2)  # the size error matters here
    # per world axis and along the prediction's worst axis within 15 % in standard deviation (400 trials:
    # the sample's own scatter is about 3.5 %), and the median error
    sample = np.cov(e.T)
    np.testing.assert_allclose(np.sqrt(np.diag(sample)), p.position_std_mm, rtol=0.15)
    w, V = np.linalg.eigh(p.covariance[3:, 3:])
    assert np.sqrt(V[:, -1] @ sample @ V[:, -1]) == pytest.approx(np.sqrt(w[-1]), rel=0.15)
    assert np.median(np.linalg.norm(e, axis=1)) == pytest.approx(p.position_error_mm, rel=0.15)


def test_one_marker_printed_larger_puts_the_camera_nearer_its_top_left_corner_by_that_fraction():
    # One marker printed (1 + d) times the map's size, its top-left corner where the map says: the picture is
    # exactly that of the map's marker seen from TL + (C - TL) / (1 + d), so the camera centre moves by
    # -d (C - TL) and the rotation not at all: the prediction adds std^2 (C - TL)(C - TL)^T, and nothing to
    # the rotation, from any viewpoint.
    camera = Camera.from_fov(60, (1280, 720))
    m = MarkerMap.from_dict(
        {"units": "mm", "marker_size_mm": 100, "markers": {"0": {"translation": [0, -50, 1050], "rotation": [0, 0, 0]}}}
    )
    tl = m.marker_corners(0)[0]
    for eye in ([800, 0, 1000], [600, -300, 1200], [700, 250, 800]):
        T = look_at(eye, [0, 0, 1000])
        p0 = predict_accuracy(m, camera, T, corner_sigma_px=0.2)
        p = predict_accuracy(m, camera, T, corner_sigma_px=0.2, marker_size_rel_std=0.01)
        c = np.asarray(eye, dtype=float) - tl
        np.testing.assert_allclose(p.covariance[3:, 3:] - p0.covariance[3:, 3:], 1e-4 * np.outer(c, c), atol=1e-6)
        np.testing.assert_allclose(p.covariance[:3] - p0.covariance[:3], 0.0, atol=1e-12)
        # the same size error of each marker on its own is the same thing for one marker
        each = predict_accuracy(m, camera, T, corner_sigma_px=0.2, marker_size_rel_std_each=0.01)
        np.testing.assert_allclose(each.covariance, p.covariance, rtol=1e-6, atol=1e-9)
        # and estimate_pose on the exact corners of the larger print finds that camera
        printed = tl + 1.01 * (m.marker_corners(0) - tl)
        pose = estimate_pose([Detection(0, camera.project(printed, T))], m, camera)
        np.testing.assert_allclose(pose.position_mm, tl + c / 1.01, atol=1e-3)


def test_zero_leaves_the_prediction_unchanged(world, camera):
    T = look_at([1500, -600, 420], [0, 190, 230])
    a = predict_accuracy(world, camera, T, marker_shift_px=0.1)
    b = predict_accuracy(world, camera, T, marker_shift_px=0.1, marker_size_rel_std=0.0, marker_size_rel_std_each=0)
    assert np.array_equal(a.covariance, b.covariance)
    assert a.position_error_mm == b.position_error_mm


@pytest.mark.parametrize("name", ["marker_size_rel_std", "marker_size_rel_std_each"])
@pytest.mark.parametrize("bad", [-0.01, 0.5, 2.0, float("nan"), float("inf"), True, "0.01"])
def test_bad_size_errors_are_refused(world, camera, name, bad):
    with pytest.raises(FidlearnError, match=f"{name} must be a fraction"):
        predict_accuracy(world, camera, look_at([1000, 190, 230], [0, 190, 230]), **{name: bad})


def test_the_room_plan_takes_the_size_error_and_refuses_a_bad_one(world, camera):
    kw = {"area": (600, -500, 2100, 900), "step_mm": 500, "headings": 2, "corner_sigma_px": 0.2}
    plain = fidlearn.plan_room(world, camera, **kw)
    sized = fidlearn.plan_room(world, camera, **kw, marker_size_rel_std=0.01, marker_size_rel_std_each=0.005)
    x, y = sized.x_mm[0], sized.y_mm[0]
    T = look_at([x, y, sized.height_mm], sized.target_mm)
    one = predict_accuracy(
        world, camera, T, corner_sigma_px=0.2, marker_size_rel_std=0.01, marker_size_rel_std_each=0.005
    )
    assert sized.toward_mm[0, 0] == one.position_error_mm
    ok = np.isfinite(plain.median_mm)
    assert ok.any()
    assert np.all(sized.median_mm[ok] > plain.median_mm[ok])
    for bad in ({"marker_size_rel_std": -0.01}, {"marker_size_rel_std_each": 0.7}, {"marker_shift_px": -1.0}):
        with pytest.raises(FidlearnError, match=next(iter(bad))):
            fidlearn.plan_room(world, camera, **kw, **bad)
        with pytest.raises(FidlearnError, match=next(iter(bad))):
            fidlearn.planning.suggest_markers(world, camera, 5.0, area=kw["area"], **bad)
