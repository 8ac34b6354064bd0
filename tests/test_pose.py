"""Pose estimation against known poses: synthetic corners from Camera.project plus Gaussian noise."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import frames
from fidlearn.camera import Camera
from fidlearn.data import data_path
from fidlearn.detection import Detection, load_image
from fidlearn.errors import CameraError, FidlearnWarning, ImageError, NoMarkersError, PoseError
from fidlearn.frames._rotations import _rotvec
from fidlearn.markermap import MarkerMap, MarkerPlacement
from fidlearn.pose import Pose, _refine, estimate_pose, locate, pose_jacobian
from fidlearn.pose._checks import _check_quads, _cheirality
from fidlearn.pose._observations import _Candidate, _make_obs
from fidlearn.pose._solvers import _front_first
from fidlearn.pose._stats import _mahalanobis2

CAM = Camera([[800.0, 0, 319.5], [0, 800.0, 239.5], [0, 0, 1]], [-0.12, 0.08, 0.001, -0.0005, 0.0], (640, 480))


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """T_world_camera of a camera at ``eye`` looking at ``target`` (OpenCV camera axes)."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return frames.make_transform(np.column_stack([x, y, z]), eye)


def wall_map(n_cols=3, n_rows=2, size=120.0, spacing=450.0) -> MarkerMap:
    """Markers on the north wall (x = 0 plane), facing +X."""
    placements = {}
    k = 0
    for r in range(n_rows):
        for c in range(n_cols):
            placements[k] = MarkerPlacement(k, (0.0, c * spacing, 1500.0 - r * spacing), (0.0, 0.0, 0.0))
            k += 1
    return MarkerMap(placements, size, dictionary="ARUCO_ORIGINAL", units="mm")


def two_wall_map() -> MarkerMap:
    """Three markers on the north wall (x = 0) and three on the west wall (y = 0, facing +Y)."""
    p = {
        0: MarkerPlacement(0, (0.0, 300.0, 1400.0), (0.0, 0.0, 0.0)),
        1: MarkerPlacement(1, (0.0, 900.0, 1300.0), (0.0, 0.0, 0.0)),
        2: MarkerPlacement(2, (0.0, 600.0, 900.0), (0.0, 0.0, 0.0)),
        3: MarkerPlacement(3, (900.0, 0.0, 1400.0), (0.0, 0.0, 90.0)),
        4: MarkerPlacement(4, (400.0, 0.0, 1200.0), (0.0, 0.0, 90.0)),
        5: MarkerPlacement(5, (700.0, 0.0, 800.0), (0.0, 0.0, 90.0)),
    }
    return MarkerMap(p, 150.0, dictionary="ARUCO_ORIGINAL", units="mm")


def observe(marker_map, T_world_camera, sigma=0.0, rng=None, camera=CAM, ids=None, extra=()):
    """Detections of the map's markers (true corners + Gaussian noise), plus extra (id, corners) pairs."""
    rng = rng if rng is not None else np.random.default_rng(0)
    dets = []
    for i, corners in marker_map.corners().items():
        if ids is not None and i not in ids:
            continue
        px = camera.project(corners, T_world_camera)
        assert camera.points_in_front(corners, T_world_camera).all()
        assert np.all((px > 15) & (px < np.array(camera.image_size) - 16)), f"marker {i} is not well inside the image"
        dets.append(Detection(i, px + rng.normal(0.0, sigma, px.shape)))
    dets.extend(Detection(i, c) for i, c in extra)
    return dets


def pose_errors(pose: Pose, T_true: np.ndarray) -> tuple[float, float]:
    return (
        float(np.linalg.norm(pose.position_mm - T_true[:3, 3])),
        frames.rotation_angle_deg(pose.T_world_camera, T_true),
    )


T_WALL = look_at([1800.0, 800.0, 1100.0], [0.0, 530.0, 1230.0])


# ---------------------------------------------------------------------------------------
# Accuracy on known poses
# ---------------------------------------------------------------------------------------
def test_several_coplanar_markers_give_the_pose_within_mm():
    m = wall_map()
    rng = np.random.default_rng(1)
    for trial in range(5):
        pose = estimate_pose(observe(m, T_WALL, 0.3, rng), m, CAM)
        pos_err, ang_err = pose_errors(pose, T_WALL)
        assert pos_err < 5.0, (trial, pos_err, ang_err)
        assert ang_err < 0.2, (trial, pos_err, ang_err)
        assert pose.method == "ippe+lm"
        assert pose.marker_ids == tuple(range(6))
        assert not pose.ambiguous
        assert not pose.rejected_ids
        assert not pose.ignored_ids
        assert 0.15 < pose.reprojection_rms_px < 0.6


def test_noise_free_corners_give_the_exact_pose():
    m = wall_map()
    pose = estimate_pose(observe(m, T_WALL), m, CAM)
    np.testing.assert_allclose(pose.T_world_camera, T_WALL, atol=1e-6)
    assert pose.reprojection_rms_px < 1e-6


def test_markers_on_two_walls_use_a_general_solver():
    m = two_wall_map()
    assert not m.is_coplanar()
    T = look_at([2300.0, 2100.0, 1300.0], [300.0, 300.0, 1100.0])
    rng = np.random.default_rng(2)
    for _ in range(5):
        dets = observe(m, T, 0.3, rng)
        pose = estimate_pose(dets, m, CAM)
        pos_err, ang_err = pose_errors(pose, T)
        assert pos_err < 15.0  # about 3.5 mm std per axis at 3 m
        assert ang_err < 0.3
        assert pose.position_ellipsoid_contains(T[:3, 3], 0.999)
        assert pose.method == "sqpnp+lm"
    with pytest.raises(PoseError, match=r"method='ippe' needs coplanar points.*sqpnp"):
        estimate_pose(dets, m, CAM, method="ippe")
    # the markers seen on one wall only are coplanar again: IPPE is used
    pose = estimate_pose(observe(m, T, 0.3, rng, ids={0, 1, 2}), m, CAM)
    assert pose.method == "ippe+lm"
    assert pose_errors(pose, T)[0] < 30.0


T_TWO_WALLS = look_at([2300.0, 2100.0, 1300.0], [300.0, 300.0, 1100.0])


@pytest.mark.parametrize("method", ["ippe", "sqpnp", "iterative", "epnp"])
def test_every_named_solver_finds_the_exact_pose(method):
    # EPnP is poor on a plane (one of the lessons of comparing solvers): test the general
    # solvers on the two-wall map, IPPE on one wall
    m, T = (wall_map(), T_WALL) if method == "ippe" else (two_wall_map(), T_TWO_WALLS)
    pose = estimate_pose(observe(m, T), m, CAM, method=method)
    pos_err, ang_err = pose_errors(pose, T)
    assert pos_err < 0.5
    assert ang_err < 0.01
    assert pose.method == method  # a named solver runs alone
    dets = observe(m, T, 0.3)
    refined = estimate_pose(dets, m, CAM, method=method, refine_lm=True)
    auto = estimate_pose(dets, m, CAM)
    assert refined.method == method + "+lm"
    # the same optimum (LM stops once a step would move the pose by a few hundredths of its std)
    assert np.all(np.abs(refined.position_mm - auto.position_mm) < 0.05 * auto.position_std_mm)
    assert refined.reprojection_rms_px <= estimate_pose(dets, m, CAM, method=method).reprojection_rms_px + 1e-9


def test_one_marker_uses_ippe_square():
    m = wall_map()
    T = look_at([500.0, 200.0, 1300.0], [0.0, 60.0, 1440.0])
    pose = estimate_pose(observe(m, T, ids={0}), m, CAM)
    assert pose.method == "ippe_square+lm"
    np.testing.assert_allclose(pose.T_world_camera, T, atol=1e-6)
    same = estimate_pose(observe(m, T, ids={0}), m, CAM, method="ippe_square")
    np.testing.assert_allclose(same.T_world_camera, T, atol=1e-6)
    with pytest.raises(PoseError, match="ippe_square' solves one marker, but 6 markers"):
        estimate_pose(observe(m, T_WALL), m, CAM, method="ippe_square")


# ---------------------------------------------------------------------------------------
# Planar ambiguity
# ---------------------------------------------------------------------------------------
def test_one_marker_far_and_face_on_is_ambiguous_close_and_oblique_is_not():
    m = MarkerMap(
        {7: MarkerPlacement(7, (0.0, 0.0, 1000.0), (0.0, 0.0, 0.0))}, 80.0, dictionary="ARUCO_ORIGINAL", units="mm"
    )
    centre = m.T_world_marker(7)[:3, 3]
    rng = np.random.default_rng(3)
    far = look_at(centre + [2500.0, 60.0, 40.0], centre)
    near = look_at(centre + [300.0, 250.0, 60.0], centre)
    n_far = n_near = 0
    for _ in range(10):
        p_far = estimate_pose(observe(m, far, 0.3, rng), m, CAM)
        n_far += p_far.ambiguous
        if p_far.ambiguous:
            alt = p_far.alternative
            assert isinstance(alt, Pose)
            assert alt.alternative is None
            # the two poses are really different: the flip tilts the camera by degrees
            assert frames.rotation_angle_deg(alt.T_world_camera, p_far.T_world_camera) > 2.0
            # and the reported uncertainty reaches the other one
            assert p_far.position_ellipsoid_contains(alt.position_mm, 0.95)
            ax, ay, az = alt.position_mm
            assert f"ambiguous=True, alternative at [{ax:.1f}, {ay:.1f}, {az:.1f}]" in repr(p_far)
        p_near = estimate_pose(observe(m, near, 0.3, rng), m, CAM)
        n_near += p_near.ambiguous
        assert pose_errors(p_near, near)[0] < 10.0
    assert n_far >= 9
    assert n_near == 0


# ---------------------------------------------------------------------------------------
# Misplaced markers, unknown ids, no markers
# ---------------------------------------------------------------------------------------
def _misplaced(m: MarkerMap, marker_id: int, shift_mm) -> MarkerMap:
    placements = dict(m.placements)
    p = placements[marker_id]
    placements[marker_id] = MarkerPlacement(marker_id, tuple(np.add(p.translation_mm, shift_mm)), p.rotation_deg)
    return MarkerMap(placements, m.marker_size_mm, dictionary=m.dictionary, units="mm")


def test_a_misplaced_marker_is_rejected_and_reported():
    true_map = wall_map()
    dets = observe(true_map, T_WALL, 0.3, np.random.default_rng(4))
    wrong_map = _misplaced(true_map, 4, (0.0, 40.0, -25.0))  # measured wrongly on the wall
    dragged = estimate_pose(dets, wrong_map, CAM, reject_outliers=False)
    pose = estimate_pose(dets, wrong_map, CAM)
    assert pose.rejected_ids == (4,)
    assert 4 not in pose.marker_ids
    assert 4 in pose.residuals_px
    assert pose_errors(pose, T_WALL)[0] < 5.0
    assert pose_errors(dragged, T_WALL)[0] > 2 * pose_errors(pose, T_WALL)[0]
    assert max(pose.marker_rms_px, key=pose.marker_rms_px.get) == 4
    assert pose.marker_rms_px[4] > 10
    assert "rejected=[4]" in repr(pose)
    # the same data with the right map rejects nothing
    assert estimate_pose(dets, true_map, CAM).rejected_ids == ()


def test_a_misplaced_marker_of_three_is_rejected_and_heavy_noise_rejects_nothing():
    true_map = MarkerMap.load(data_path("world_map.json"))
    T = look_at([900.0, 250.0, 350.0], [0.0, 140.0, 230.0])
    wrong_map = _misplaced(true_map, 2, (0.0, 0.0, 30.0))  # 30 mm too high
    rng = np.random.default_rng(11)
    for _ in range(5):
        pose = estimate_pose(observe(true_map, T, 0.3, rng), wrong_map, CAM)
        assert pose.rejected_ids == (2,)
        assert pose.marker_ids == (0, 1)
        assert pose_errors(pose, T)[0] < 25.0
    # pure Gaussian noise of 1.5 px on three small markers: no marker is singled out
    rejected = sum(bool(estimate_pose(observe(true_map, T, 1.5, rng), true_map, CAM).rejected_ids) for _ in range(40))
    assert rejected <= 1


def test_with_two_markers_nothing_is_rejected_but_the_residual_tells():
    true_map = wall_map()
    wrong_map = _misplaced(true_map, 1, (0.0, 40.0, 0.0))
    pose = estimate_pose(observe(true_map, T_WALL, 0.3, ids={0, 1}), wrong_map, CAM)
    assert pose.rejected_ids == ()
    assert pose.marker_ids == (0, 1)
    assert pose.reprojection_rms_px > 5 * 0.3  # five times the corner noise
    assert min(pose.marker_rms_px.values()) > 1.0  # the error is shared: which marker is wrong cannot be told


def test_good_markers_are_not_rejected():
    m = wall_map()
    rng = np.random.default_rng(5)
    for sigma in (0.1, 0.5, 1.0):
        for _ in range(10):
            assert estimate_pose(observe(m, T_WALL, sigma, rng), m, CAM).rejected_ids == ()


def test_unknown_ids_are_ignored_and_listed():
    m = wall_map()
    junk = np.array([[10.0, 10.0], [40.0, 10.0], [40.0, 40.0], [10.0, 40.0]])
    pose = estimate_pose(observe(m, T_WALL, extra=[(42, junk), (17, junk + 100)]), m, CAM)
    assert pose.ignored_ids == (42, 17)
    assert pose.marker_ids == tuple(range(6))
    assert pose_errors(pose, T_WALL)[0] < 1e-3
    assert "ignored=[42, 17]" in repr(pose)


def test_no_known_marker_raises_a_helpful_error():
    m = wall_map()
    junk = np.array([[10.0, 10.0], [40.0, 10.0], [40.0, 40.0], [10.0, 40.0]])
    with pytest.raises(
        NoMarkersError,
        match=r"markers \[17, 42\], none of which is in the map.*ids \[0, 1, 2, 3, 4, 5\].*ARUCO_ORIGINAL",
    ):
        estimate_pose([Detection(42, junk), Detection(17, junk)], m, CAM)
    with pytest.raises(NoMarkersError, match=r"no marker was detected.*dictionary ARUCO_ORIGINAL"):
        estimate_pose([], m, CAM)


def test_inputs_are_checked():
    m = wall_map()
    dets = observe(m, T_WALL)
    with pytest.raises(PoseError, match="marker_map must be a fidlearn.MarkerMap"):
        estimate_pose(dets, {"0": 1}, CAM)
    with pytest.raises(PoseError, match="camera must be a fidlearn.Camera"):
        estimate_pose(dets, m, CAM.K)
    with pytest.raises(PoseError, match=r"detections\[1\] is a tuple"):
        estimate_pose([dets[0], (1, dets[1].corners_px)], m, CAM)
    with pytest.raises(PoseError, match="detections must be a list"):
        estimate_pose(np.zeros((4, 2)), m, CAM)
    bad = dets[2].corners_px.copy()
    bad[1, 0] = np.nan
    with pytest.raises(PoseError, match=r"detections\[2\] \(marker 2\) has NaN"):
        estimate_pose(dets[:2] + [Detection(2, bad)], m, CAM)
    with pytest.raises(PoseError, match="unknown method 'dls'"):
        estimate_pose(dets, m, CAM, method="dls")
    with pytest.raises(PoseError, match="corner_sigma_px must be a positive"):
        estimate_pose(dets, m, CAM, corner_sigma_px=-1)


# ---------------------------------------------------------------------------------------
# Conventions
# ---------------------------------------------------------------------------------------
def test_pose_conventions_match_opencv():
    m = wall_map()
    dets = observe(m, T_WALL, 0.3)
    pose = estimate_pose(dets, m, CAM)
    # T_world_camera is the closed-form inverse of T_camera_world
    R, t = pose.T_camera_world[:3, :3], pose.T_camera_world[:3, 3]
    np.testing.assert_allclose(pose.T_world_camera[:3, :3], R.T, atol=1e-12)
    np.testing.assert_allclose(pose.position_mm, -R.T @ t, atol=1e-9)
    np.testing.assert_allclose(pose.T_world_camera @ pose.T_camera_world, np.eye(4), atol=1e-9)
    # rvec, tvec are solvePnP's: projectPoints with them reproduces the corners up to the residuals
    for d in dets:
        px, _ = cv2.projectPoints(m.marker_corners(d.id), pose.rvec, pose.tvec, CAM.K, CAM.dist)
        np.testing.assert_allclose(px.reshape(4, 2) + pose.residuals_px[d.id], d.corners_px, atol=1e-9)
        assert np.abs(pose.residuals_px[d.id]).max() < 1.5
    ok, rvec, tvec = cv2.solvePnP(
        np.concatenate([m.marker_corners(d.id) for d in dets]),
        np.concatenate([d.corners_px for d in dets]),
        CAM.K,
        CAM.dist,
    )
    assert ok
    assert np.allclose(rvec.ravel(), pose.rvec, atol=1e-3)
    assert np.allclose(tvec.ravel(), pose.tvec, atol=0.5)
    np.testing.assert_allclose(pose.rpy_deg, frames.rpy_deg_from_rotation(pose.T_world_camera[:3, :3]))
    text = repr(pose)
    x, y, z = pose.position_mm
    assert f"position_mm=[{x:.1f}, {y:.1f}, {z:.1f}]" in text
    assert "ambiguous=False" in text
    assert "std_mm=" in text


def test_pose_jacobian_matches_finite_differences():
    m = two_wall_map()
    T = look_at([2300.0, 2100.0, 1300.0], [300.0, 300.0, 1100.0])
    P = np.concatenate(list(m.corners().values()))
    J = pose_jacobian(P, T, CAM)

    def pixels(delta):
        R = cv2.Rodrigues(delta[:3])[0] @ T[:3, :3]  # small rotation in world axes, on the left
        return CAM.project(P, frames.make_transform(R, T[:3, 3] + delta[3:])).ravel()

    h = np.r_[1e-6, 1e-6, 1e-6, 1e-4, 1e-4, 1e-4]
    numeric = np.column_stack(
        [(pixels(np.eye(6)[k] * h[k]) - pixels(-np.eye(6)[k] * h[k])) / (2 * h[k]) for k in range(6)]
    )
    np.testing.assert_allclose(J, numeric, rtol=1e-5, atol=1e-5 * np.abs(J).max())


# ---------------------------------------------------------------------------------------
# Covariance
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("given_sigma", [True, False])
def test_position_covariance_covers_the_truth_95_percent(given_sigma):
    m = wall_map(n_cols=2, n_rows=2, size=100.0)
    T = look_at([1800.0, 900.0, 1000.0], [0.0, 250.0, 1300.0])
    rng = np.random.default_rng(6)
    sigma = 0.5
    inside, n = 0, 300
    stds = []
    for _ in range(n):
        pose = estimate_pose(
            observe(m, T, sigma, rng), m, CAM, corner_sigma_px=sigma if given_sigma else None, reject_outliers=False
        )
        inside += pose.position_ellipsoid_contains(T[:3, 3], 0.95)
        stds.append(pose.position_std_mm)
    assert 0.90 <= inside / n <= 0.98, inside / n
    # the standard deviations say what the errors are: larger along the viewing direction
    assert np.all(np.mean(stds, axis=0) > 0.5)


def test_covariance_is_the_cramer_rao_bound_at_the_truth():
    m = wall_map()
    pose = estimate_pose(observe(m, T_WALL), m, CAM, corner_sigma_px=0.4)
    J = pose_jacobian(np.concatenate(list(m.corners().values())), T_WALL, CAM)
    np.testing.assert_allclose(pose.covariance, 0.4**2 * np.linalg.inv(J.T @ J), rtol=1e-5, atol=1e-12)
    assert pose.corner_sigma_px == 0.4
    np.testing.assert_allclose(pose.position_std_mm, np.sqrt(np.diag(pose.covariance)[3:]))


# ---------------------------------------------------------------------------------------
# locate: detection + pose, end to end on rendered images
# ---------------------------------------------------------------------------------------
def test_locate_finds_the_camera_in_a_rendered_scene():
    from fidlearn.synthetic import render_scene

    m = wall_map()
    scene = render_scene(m, CAM, T_WALL, seed=7, blur_px=0.6, noise_std_gray=2.0, gradient=0.2)
    image, truth = scene.image, scene.truth
    assert sorted(truth) == m.ids
    pose = locate(image, m, CAM)
    pos_err, ang_err = pose_errors(pose, T_WALL)
    assert pos_err < 5.0, (pos_err, ang_err)
    assert ang_err < 0.2, (pos_err, ang_err)
    assert pose.marker_ids == tuple(m.ids)
    assert pose.rejected_ids == ()
    assert pose.reprojection_rms_px < 0.5
    assert pose.position_ellipsoid_contains(T_WALL[:3, 3], 0.999)


def test_locate_on_the_seed_map():
    from fidlearn.synthetic import render_scene

    m = MarkerMap.load(data_path("world_map.json"))
    T = frames.look_at([900.0, 250.0, 350.0], [0.0, 140.0, 230.0], roll_deg=8.0)
    scene = render_scene(m, CAM, T, seed=3, blur_px=0.5, noise_std_gray=1.5)
    image, truth = scene.image, scene.truth
    assert sorted(truth) == [0, 1, 2]
    pose = locate(image, m, CAM)
    assert pose.marker_ids == (0, 1, 2)
    assert pose_errors(pose, T)[0] < 8.0
    assert pose_errors(pose, T)[1] < 0.5


def test_locate_rescales_a_camera_of_another_resolution_and_refuses_another_aspect():
    from fidlearn.synthetic import render_scene

    m = wall_map()
    image = render_scene(m, CAM, T_WALL, seed=8, blur_px=0.6, noise_std_gray=2.0).image
    big = CAM.scaled((1280, 960))  # calibrated at twice the resolution of the image
    with pytest.warns(FidlearnWarning, match="rescaled to 640x480"):
        pose = locate(image, m, big)
    assert pose_errors(pose, T_WALL)[0] < 5.0
    with pytest.raises(CameraError, match="aspect"):
        locate(image[:360], m, CAM)


def test_locate_without_markers_says_what_to_check():
    m = wall_map()
    blank = np.full((480, 640), 200, np.uint8)
    with pytest.raises(NoMarkersError, match="no marker was detected.*ARUCO_ORIGINAL"):
        locate(blank, m, CAM)
    with pytest.raises(ImageError):
        locate("photo.jpg", m, CAM)


def test_levenberg_marquardt_reaches_the_least_squares_optimum():
    from fidlearn.pose import refine_pose_lm

    m = wall_map()
    rng = np.random.default_rng(9)
    obj = np.concatenate(list(m.corners().values()))
    img = CAM.project(obj, T_WALL) + rng.normal(0, 0.5, (len(obj), 2))
    start = T_WALL.copy()
    start[:3, :3] = cv2.Rodrigues(np.array([0.02, -0.03, 0.01]))[0] @ start[:3, :3]
    start[:3, 3] += [40.0, -30.0, 25.0]
    rvec0, tvec0 = frames.rvec_tvec_from_transform(frames.invert_transform(start))
    refined = refine_pose_lm(obj, img, CAM, rvec0, tvec0)
    T = frames.invert_transform(refined.T_camera_world)
    np.testing.assert_allclose(refined.T_camera_world, frames.transform_from_rvec_tvec(refined.rvec, refined.tvec))
    r = (img - CAM.project(obj, T)).ravel()
    assert refined.reprojection_rms_px == pytest.approx(np.sqrt(r @ r / len(obj)), rel=1e-9)
    J = pose_jacobian(obj, T, CAM)
    # a stationary point: the gradient J^T r vanishes (relative to its scale)
    assert np.all(np.abs(J.T @ r) <= 1e-4 * np.sqrt(np.sum(J**2, axis=0)) * np.linalg.norm(r))
    r_cv, t_cv = cv2.solvePnPRefineLM(obj, img, CAM.K, CAM.dist, rvec0.reshape(3, 1).copy(), tvec0.reshape(3, 1).copy())
    px_cv, _ = cv2.projectPoints(obj, r_cv, t_cv, CAM.K, CAM.dist)
    assert r @ r <= np.sum((img - px_cv.reshape(-1, 2)) ** 2) + 1e-9


def test_ippe_on_one_marker_keeps_both_solutions():
    m = wall_map()
    T = look_at([500.0, 200.0, 1300.0], [0.0, 60.0, 1440.0])
    pose = estimate_pose(observe(m, T, 0.2, ids={0}), m, CAM, method="ippe")
    assert pose.method == "ippe"
    assert pose.alternative is not None
    assert not pose.ambiguous
    assert pose_errors(pose, T)[0] < 10.0
    assert pose.alternative.reprojection_rms_px > 5 * pose.reprojection_rms_px


def test_a_pose_is_slotted_pickles_with_its_alternative_and_builds_it_once():
    import pickle

    m = wall_map()
    T = look_at([500.0, 200.0, 1300.0], [0.0, 60.0, 1440.0])
    pose = estimate_pose(observe(m, T, 0.2, ids={0}), m, CAM, method="ippe")
    assert not hasattr(pose, "__dict__")  # a plain slotted dataclass: attribute reads are slot reads
    again = pickle.loads(pickle.dumps(pose))  # its alternative not yet built: pickled built
    assert pose.alternative is pose.alternative  # built on the first read, then kept
    assert repr(again) == repr(pose)
    assert "alternative at" in repr(pose)
    np.testing.assert_array_equal(again.alternative.T_world_camera, pose.alternative.T_world_camera)
    assert again.alternative.method == pose.alternative.method == "ippe (not refined)"
    with pytest.raises(TypeError):
        Pose(np.eye(4), (0,), {}, 0.1, None, 0.1, True)  # the options are keyword-only


# ---------------------------------------------------------------------------------------
# The bundled data: rendered scenes with known poses, a real photo with known distances
# ---------------------------------------------------------------------------------------
def _seed_pipeline_position(image, marker_map, camera):
    """The seed's pipeline: default detector (no corner refinement), IPPE over all corners, no LM."""
    from fidlearn import _cv

    corners, ids, _ = _cv.detect(_cv.make_detector(marker_map.dictionary), image)
    known = [(marker_map.marker_corners(int(i)), c) for c, i in zip(corners, ids) if int(i) in marker_map]
    ok, rvec, tvec = cv2.solvePnP(
        np.concatenate([k[0] for k in known]),
        np.concatenate([k[1] for k in known]),
        camera.K,
        camera.dist,
        flags=_cv.solvepnp_flag("IPPE"),
    )
    return frames.invert_transform(frames.transform_from_rvec_tvec(rvec, tvec))[:3, 3] if ok else None


def test_locate_on_the_bundled_scenes_beats_the_seed_pipeline():
    import json

    from fidlearn.detection import load_image

    record = json.loads(data_path("scenes", "poses.json").read_text())
    camera = Camera.load(data_path("scenes", "camera.json"))
    ours, seed = [], []
    for entry in record["images"]:
        m = MarkerMap.load(data_path(entry["map"]))
        image = load_image(data_path("scenes", entry["image"]))
        T = np.array(entry["T_world_camera"])
        pose = locate(image, m, camera)
        assert set(pose.marker_ids) == set(entry["visible_ids"]), entry["image"]
        err, ang = pose_errors(pose, T)
        assert err < 15.0, (entry["image"], err, ang)
        assert ang < 0.5, (entry["image"], err, ang)
        assert pose.position_ellipsoid_contains(T[:3, 3], 0.999), entry["image"]
        ours.append(err)
        if m.is_coplanar():
            seed.append(np.linalg.norm(_seed_pipeline_position(image, m, camera) - T[:3, 3]))
        else:
            assert pose.method == "sqpnp+lm"
    assert np.median(ours) <= 0.5 * np.median(seed), (np.median(ours), np.median(seed))


def test_markers_of_the_real_photo_are_70_to_90_cm_away():
    from fidlearn.detection import detect_markers, load_image

    folder = data_path("real", "opencv_aruco_photo")
    image = load_image(folder / "singlemarkersoriginal.jpg")
    camera = Camera.load(folder / "tutorial_camera_params.yml", image_size=(image.shape[1], image.shape[0]))
    detections = detect_markers(image, "6X6_250")
    assert sorted(d.id for d in detections) == [23, 40, 62, 98, 124, 203]
    for d in detections:  # each marker alone, as its own 50 mm map
        m = MarkerMap(
            {d.id: MarkerPlacement(d.id, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))}, 50.0, dictionary="6X6_250", units="mm"
        )
        pose = estimate_pose([d], m, camera)
        distance = np.linalg.norm(pose.position_mm - m.T_world_marker(d.id)[:3, 3])
        assert 650.0 < distance < 950.0, (d.id, distance)
        assert pose.reprojection_rms_px < 0.5
        assert not pose.ambiguous


def test_the_solver_is_as_good_as_lm_started_at_the_truth():
    """Median NEES of the camera centre (w.r.t. the Cramer-Rao bound at the true pose) within 10 %."""
    from fidlearn.pose import refine_pose_lm

    m = MarkerMap.load(data_path("world_map.json"))
    T = look_at([1300.0, 500.0, 600.0], [0.0, 140.0, 230.0])
    obj = np.concatenate(list(m.corners().values()))
    sigma = 0.5
    J = pose_jacobian(obj, T, CAM)
    P = sigma**2 * np.linalg.inv(J.T @ J)[3:, 3:]
    rvec0, tvec0 = frames.rvec_tvec_from_transform(frames.invert_transform(T))
    rng = np.random.default_rng(12)
    ours, truth = [], []
    for _ in range(100):
        dets = observe(m, T, sigma, rng)
        pose = estimate_pose(dets, m, CAM)
        refined = refine_pose_lm(obj, np.concatenate([d.corners_px for d in dets]), CAM, rvec0, tvec0)
        C = frames.invert_transform(refined.T_camera_world)[:3, 3]
        for est, out in ((pose.position_mm, ours), (C, truth)):
            e = est - T[:3, 3]
            out.append(e @ np.linalg.solve(P, e))
    assert np.median(ours) <= 1.1 * np.median(truth)
    assert np.mean(np.array(ours) > 25) <= np.mean(np.array(truth) > 25) + 0.02
    assert 1.5 < np.median(truth) < 3.5  # chi-square(3) median 2.37: the bound is reached


# ---------------------------------------------------------------------------------------
# Arguments, impossible corners, impossible poses, fits that are no pose
# ---------------------------------------------------------------------------------------
def test_locate_and_estimate_pose_take_paths_and_check_every_argument_first():
    from fidlearn.synthetic import render_scene

    map_path = data_path("world_map.json")
    camera_path = data_path("scenes", "camera.json")
    m, camera = MarkerMap.load(map_path), Camera.load(camera_path)
    T = look_at([900.0, 250.0, 350.0], [0.0, 140.0, 230.0])
    image = render_scene(m, camera, T, seed=5, blur_px=0.5, noise_std_gray=1.0).image
    pose = locate(image, m, camera)
    assert pose_errors(pose, T)[0] < 10.0
    for mp, cp in ((str(map_path), camera), (m, str(camera_path)), (map_path, camera_path)):
        np.testing.assert_allclose(locate(image, mp, cp).T_world_camera, pose.T_world_camera, atol=1e-9)
    dets = observe(m, T, camera=camera)
    np.testing.assert_allclose(estimate_pose(dets, str(map_path), str(camera_path)).T_world_camera, T, atol=1e-6)
    # the learner's mistakes, each refused before any detection with what to do
    with pytest.raises(
        PoseError,
        match=r"marker_map must be a fidlearn.MarkerMap or the path of a map file, got Camera "
        r"\(arguments swapped\? the order is marker_map, camera\); load a file with MarkerMap.load",
    ):
        locate(image, camera, m)
    with pytest.raises(PoseError, match=r"marker_map must be .*got dict; load a file with MarkerMap.load\(path\)"):
        estimate_pose(dets, {"0": [0, 0, 1]}, camera)
    with pytest.raises(
        PoseError,
        match=r"camera must be a fidlearn.Camera or the path of a camera file, got ndarray; "
        r"load a file with Camera.load\(path\)",
    ):
        locate(image, m, camera.K)
    with pytest.raises(
        PoseError,
        match=r"locate\(\) got unknown option 'sigma'; it takes refine, detector_params and "
        r"estimate_pose's corner_sigma_px, method",
    ):
        locate(image, m, camera, sigma=0.3)
    with pytest.raises(PoseError, match="unknown method 'dls'"):
        locate(image, m, camera, method="dls")
    with pytest.raises(PoseError, match="reject_outliers must be True or False, got 'no'"):
        locate(image, m, camera, reject_outliers="no")
    with pytest.raises(PoseError, match="corner_sigma_px must be a positive number of pixels, got '0.3'"):
        estimate_pose(dets, m, camera, corner_sigma_px="0.3")
    with pytest.raises(PoseError, match="refine_lm must be True, False or None"):
        estimate_pose(dets, m, camera, refine_lm="yes")
    from fidlearn.errors import MapError

    with pytest.raises(MapError):  # a path that is not there: MarkerMap.load's own message
        locate(image, "no_such_map.json", camera)


SQUARE = np.array([[100.0, 100.0], [160.0, 100.0], [160.0, 160.0], [100.0, 160.0]])  # TL, TR, BR, BL on screen


@pytest.mark.parametrize(
    ("corners", "message"),
    [
        (
            SQUARE[[0, 3, 2, 1]],
            r"marker 1: its image corners \[\[100.0, 100.0\], \[100.0, 160.0\].* run anticlockwise on the "
            r"screen.*are they listed TL, BL, BR, TR\? corners\[\[0, 3, 2, 1\]\] puts them right",
        ),
        (SQUARE[[0, 2, 1, 3]], r"marker 1: .* do not form a convex quadrilateral \(the outline crosses itself"),
        (
            [[100.0, 100.0], [150.0, 100.0], [200.0, 100.0], [250.0, 100.0]],
            r"marker 1: .* enclose no area \(they lie on a line",
        ),
        ([[100.0, 100.0]] * 4, r"marker 1: its image corners \[\[100.0, 100.0\], \[100.0, 100.0\].* enclose no area"),
        (
            [[100.0, 100.0], [160.0, 100.0], [160.0, 160.0], [150.0, 110.0]],
            r"marker 1: .* do not form a convex quadrilateral",
        ),
    ],
)
def test_corners_no_marker_can_give_are_refused_naming_the_marker(corners, message):
    m = wall_map()
    good = observe(m, T_WALL, ids={0, 2, 3})
    with pytest.raises(PoseError, match=message):
        estimate_pose(good + [Detection(1, corners)], m, CAM)
    # an id the map does not know is ignored, whatever its corners
    assert estimate_pose(good + [Detection(42, corners)], m, CAM).ignored_ids == (42,)


def test_mirrored_corners_and_a_camera_facing_away_no_longer_give_a_perfect_fit_behind_the_wall():
    world = MarkerMap.load(data_path("world_map.json"))
    cam = Camera.from_fov(60, (640, 480))
    T = frames.make_transform(frames.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    mirrored = Detection(0, cam.project(world.corners()[0], T)[[0, 3, 2, 1]])
    with pytest.raises(PoseError, match="marker 0: .* run anticlockwise on the screen"):
        estimate_pose([mirrored], world, cam)  # was: RMS 0.00 px with the camera at x = -1000, behind the wall
    with pytest.raises(PoseError, match="marker 0: .* run anticlockwise on the screen"):
        estimate_pose([Detection(i, cam.project(c, T)[[0, 3, 2, 1]]) for i, c in world.corners().items()], world, cam)
    # the same wall "seen" by a camera turned away from it (the points behind it projected anyway)
    T_away = frames.make_transform(frames.rotation_from_rpy_deg(-90, 0, -90), [1000, 150, 250])
    with pytest.raises(PoseError, match=r"run anticlockwise on the screen.*\(A camera behind the marker"):
        estimate_pose([Detection(i, cam.project(c, T_away)) for i, c in world.corners().items()], world, cam)


def _turned(m: MarkerMap, marker_id: int, yaw_deg: float) -> MarkerMap:
    placements = dict(m.placements)
    p = placements[marker_id]
    placements[marker_id] = MarkerPlacement(
        marker_id, p.translation_mm, tuple(np.add(p.rotation_deg, [0.0, 0.0, yaw_deg]))
    )
    return MarkerMap(placements, m.marker_size_mm, dictionary=m.dictionary, units="mm")


def test_a_marker_turned_the_wrong_way_in_the_map_is_never_seen_from_behind():
    world = MarkerMap.load(data_path("world_map.json"))
    T = look_at([900.0, 250.0, 350.0], [0.0, 140.0, 230.0])
    dets = observe(world, T)
    wrong = _turned(world, 1, 180.0)  # marker 1 faces into the wall in the map
    assert wrong.normal(1) @ world.normal(1) < -0.99
    # two markers on one wall facing opposite ways: no camera sees both printed faces, and no pose fits
    two = [d for d in dets if d.id in (0, 1)]
    side = np.median([d.side_px for d in two])
    with pytest.raises(
        PoseError,
        match=rf"the corners do not fit the map: reprojection error [\d.]+ px for markers \[0, 1\], "
        rf"which are about {side:.0f} px wide.* \(Even that best fit would see marker [01] from behind.\)$",
    ):
        estimate_pose(two, wrong, CAM)
    # with a third marker the turned one disagrees with the others and is left out
    pose = estimate_pose(dets, wrong, CAM)
    assert pose.rejected_ids == (1,)
    assert pose_errors(pose, T)[0] < 1e-3


def test_only_poses_a_camera_can_have_are_chosen():
    """A mirror-image candidate that fits better loses to one that sees the markers' faces; none left raises."""
    m = wall_map()
    dets = observe(m, T_WALL)
    obs = _make_obs(m.ids, {d.id: d.corners_px for d in dets}, m.corners())
    true = _Candidate(T_WALL[:3, :3].copy(), T_WALL[:3, 3].copy(), 1.0, None, refined=True)
    # the camera mirrored through the wall (x = 0): it would see the markers' backs
    F = np.diag([-1.0, 1.0, 1.0])
    behind_wall = _Candidate(F @ T_WALL[:3, :3] @ F, F @ T_WALL[:3, 3], 0.5, None, refined=True)
    # the camera turned round on the spot: every corner behind it
    turned = _Candidate(T_WALL[:3, :3] @ np.diag([-1.0, 1.0, -1.0]), T_WALL[:3, 3].copy(), 0.25, None, refined=True)
    ordered = _front_first(obs, CAM, [turned, behind_wall, true], refine_lm=True)
    assert ordered[0] is true
    assert behind_wall.problem.startswith(
        "markers [0, 1, 2, 3, 4, 5] would be seen from behind (from the back of their printed face) by the pose "
        "that fits the corners best (reprojection error 0.1 px): are their rotations in the map wrong (yaw 180"
    )
    assert behind_wall.problem.endswith("or the corners mirrored (TL, BL, BR, TR instead of TL, TR, BR, BL)?")
    assert turned.problem.startswith(
        "markers [0, 1, 2, 3, 4, 5] would be behind the camera in the pose that fits the corners best"
    )
    # one marker of several seen from behind: it may be another one's rotation that is wrong
    one_back = _Candidate(T_WALL[:3, :3].copy(), T_WALL[:3, 3].copy(), 1.0, None)
    obs_one = _make_obs([0, 1], {d.id: d.corners_px for d in dets}, _turned(m, 1, 180.0).corners())
    assert _cheirality(obs_one, one_back).endswith(
        "With markers [0, 1] in view, the wrong rotation may be another one's."
    )
    assert one_back.problem.startswith("marker 1 would be seen from behind (from the back of its printed face)")
    # no candidate left: the best one's problem is what estimate_pose reports
    assert _front_first(obs, CAM, [turned, behind_wall], refine_lm=True)[0] is turned
    assert true.problem is None
    # the true pose's checks agree with the map's own normals and Camera.points_in_front
    for i in m.ids:
        assert (T_WALL[:3, 3] - m.T_world_marker(i)[:3, 3]) @ m.normal(i) > 0
    assert CAM.points_in_front(obs.obj, T_WALL).all()


def test_a_fit_far_worse_than_any_detector_is_refused():
    m = wall_map()
    dets = observe(m, T_WALL, 0.3)
    # positions in cm read as mm: the markers keep their size, the layout shrinks tenfold
    cm_as_mm = MarkerMap(
        {
            i: MarkerPlacement(i, tuple(np.multiply(p.translation_mm, 0.1)), p.rotation_deg)
            for i, p in m.placements.items()
        },
        m.marker_size_mm,
        dictionary=m.dictionary,
        units="mm",
    )
    with pytest.raises(
        PoseError,
        match=r"the corners do not fit the map: reprojection error \d+\.\d px for markers "
        r"\[0, 1, 2, 3, 4, 5\], which are about 52 px wide in the image.*check the map's "
        r"positions and rotations, the marker size, the units, the corner order",
    ):
        estimate_pose(dets, cm_as_mm, CAM)
    # every marker's corners listed from the wrong starting point (clockwise still): no pose fits
    with pytest.raises(PoseError, match="the corners do not fit the map: reprojection error"):
        estimate_pose([Detection(d.id, d.corners_px[[1, 2, 3, 0]]) for d in dets], m, CAM, reject_outliers=False)
    # well below the threshold (0.4 marker sides): a marker 4 cm off still gives a (dragged) pose
    pose = estimate_pose(dets, _misplaced(m, 4, (0.0, 40.0, -25.0)), CAM, reject_outliers=False)
    side = np.median([d.side_px for d in dets])
    assert 2.0 < pose.reprojection_rms_px < 0.4 * side


def test_a_bad_fit_does_not_make_the_flip_look_as_good():
    """Residuals of a wrong map are not noise: the ambiguity test counts at most AMBIGUITY_MAX_SIGMA_PX."""
    from fidlearn import pose as pose_mod

    m = wall_map(n_cols=2, n_rows=1, size=100.0, spacing=300.0)
    T = look_at([1623.0, 744.0, 1229.0], [0.0, 150.0, 1450.0])
    wrong = _misplaced(m, 1, (0.0, 19.0, -73.0))
    dets = observe(m, T)
    pose = estimate_pose(dets, wrong, CAM)
    assert pose.reprojection_rms_px > 4.0
    assert pose.corner_sigma_px > pose_mod.AMBIGUITY_MAX_SIGMA_PX
    assert pose.alternative is not None
    assert not pose.ambiguous
    # what the residuals alone would have said
    extra = (pose.alternative.reprojection_rms_px**2 - pose.reprojection_rms_px**2) * len(pose.marker_ids) * 4
    assert (
        pose_mod.AMBIGUITY_CHI2 * pose_mod.AMBIGUITY_MAX_SIGMA_PX**2
        < extra
        < pose_mod.AMBIGUITY_CHI2 * pose.corner_sigma_px**2
    )
    # a given corner noise is taken at its word
    assert estimate_pose(dets, wrong, CAM, corner_sigma_px=pose.corner_sigma_px).ambiguous


def test_rotations_below_opencvs_rodrigues_threshold_are_kept():
    """cv2.Rodrigues returns exactly zero below about 1e-5 rad; the pose maths must not."""
    from fidlearn.pose import refine_pose_lm

    r_true = np.array([3e-7, -2e-7, 1e-7])
    assert not cv2.Rodrigues(cv2.Rodrigues(r_true)[0])[0].any()  # the OpenCV behaviour worked around
    np.testing.assert_allclose(_rotvec(cv2.Rodrigues(r_true)[0]), r_true, rtol=1e-6, atol=1e-15)
    assert _refine._rotvec is _rotvec  # one small-angle fix in frames, shared with rvec_tvec_from_transform
    # refine_pose_lm returns the tiny rotation of a camera looking straight at a wall
    P = np.array([[x, y, 2000.0 + 0.5 * x] for x in (-300.0, 0.0, 300.0) for y in (-200.0, 200.0)])
    T_cw = frames.make_transform(cv2.Rodrigues(r_true)[0], [10.0, -5.0, 30.0])
    img = CAM.project(P, frames.invert_transform(T_cw))
    np.testing.assert_allclose(refine_pose_lm(P, img, CAM, r_true, T_cw[:3, 3]).rvec, r_true, rtol=1e-3, atol=1e-12)
    # the distance between two poses 1e-7 rad apart is not zero
    a = _Candidate(np.eye(3), np.zeros(3), 0.0, None)
    b = _Candidate(cv2.Rodrigues(np.array([1e-7, 0.0, 0.0]))[0], np.zeros(3), 0.0, None)
    assert _mahalanobis2(a, b, np.diag([1e14, 1, 1, 1, 1, 1.0]), 1.0) == pytest.approx(1.0, rel=1e-6)


def test_noisy_corners_of_a_marker_seen_edge_on_are_not_called_mirrored():
    """Benchmarks feed true corners plus noise: a marker a few pixels wide may fold over; it is not a mistake."""
    folded = np.array([[345.3, 281.1], [344.0, 290.3], [339.3, 308.6], [341.3, 300.0]])  # 5 px wide, 1 px noise
    flipped = folded * [-1.0, 1.0] + [690.0, 0.0]  # its mirror image: anticlockwise, by noise
    assert np.sum(flipped[:, 0] * np.roll(flipped[:, 1], -1) - np.roll(flipped[:, 0], -1) * flipped[:, 1]) < 0
    _check_quads([7, 8], np.concatenate([folded, flipped]))  # no PoseError
    with pytest.raises(PoseError, match="marker 8: .* run anticlockwise"):
        _check_quads([7, 8], np.concatenate([folded, SQUARE[[0, 3, 2, 1]]]))
    # a camera estimated a little behind the plane of a marker seen at a grazing angle is a pose;
    # far behind it is not
    m = MarkerMap(
        {0: MarkerPlacement(0, (0.0, 0.0, 1000.0), (0.0, 0.0, 0.0))}, 100.0, dictionary="ARUCO_ORIGINAL", units="mm"
    )
    centre = m.T_world_marker(0)[:3, 3]
    obs = _make_obs([0], {0: SQUARE}, m.corners())
    for elevation_deg, ok in ((30.0, True), (-5.0, True), (-20.0, False)):
        e = np.radians(elevation_deg)
        T = look_at(centre + 2000.0 * np.array([np.sin(e), np.cos(e), 0.0]), centre)
        cand = _Candidate(T[:3, :3], T[:3, 3], 0.0, None)
        assert (_cheirality(obs, cand) is None) == ok, elevation_deg


def _seed_room_with_a_stranger():
    """The seed map, and a picture of it with marker 7 (not in the map) taped beside marker 1."""
    from fidlearn.frames import look_at
    from fidlearn.synthetic import render_scene

    m = MarkerMap.load(data_path("world_map.json"))
    placements = dict(m.placements)
    placements[7] = MarkerPlacement(7, (0.0, 450.0, 304.8), (0.0, 0.0, 0.0))
    room = MarkerMap(placements, m.marker_size_mm, dictionary=m.dictionary, units="mm")
    T_true = look_at([1400, 250, 300], [0, 250, 250])
    scene = render_scene(room, CAM, T_true, seed=5, blur_px=0.5, noise_std_gray=1.0)
    image, truth = scene.image, scene.truth
    assert 7 in truth
    return m, image, T_true


def test_locate_looks_for_the_map_markers_only_and_lists_strangers_when_asked():
    m, image, T_true = _seed_room_with_a_stranger()
    fast = locate(image, m, CAM)
    full = locate(image, m, CAM, only_map_markers=False)
    assert fast.marker_ids == full.marker_ids == (0, 1, 2)
    assert fast.ignored_ids == ()
    assert full.ignored_ids == (7,)
    # the same corners, so the same pose, and the true one (within 1 % of the 1.4 m distance)
    assert np.allclose(fast.T_world_camera, full.T_world_camera)
    assert np.linalg.norm(fast.position_mm - T_true[:3, 3]) < 14.0
    with pytest.raises(PoseError, match="only_map_markers must be True or False"):
        locate(image, m, CAM, only_map_markers="yes")


def test_locate_names_the_markers_it_saw_when_none_is_in_the_map():
    m, image, _ = _seed_room_with_a_stranger()
    only_seven = MarkerMap(
        {9: MarkerPlacement(9, (0.0, 0.0, 300.0), (0.0, 0.0, 0.0))}, 80, dictionary="ARUCO_ORIGINAL", units="mm"
    )
    with pytest.raises(NoMarkersError, match=r"0, 1, 2, 7"):
        locate(image, only_seven, CAM)


def test_locate_passes_detector_params_to_the_detector():
    """A detector told to ignore small markers finds none of the seed's, so locate says so."""
    world = MarkerMap.load(data_path("world_map.json"))
    camera = Camera.load(data_path("scenes", "camera.json"))
    image = load_image(data_path("scenes", "scene_00.png"))
    assert list(locate(image, world, camera).marker_ids) == [0, 1, 2]
    with pytest.raises(NoMarkersError):
        locate(image, world, camera, detector_params={"minMarkerPerimeterRate": 3.5})


@pytest.mark.parametrize("side_deg", [5.0, 15.0, 30.0])
@pytest.mark.parametrize("n_markers", [1, 2])
def test_level_view_with_mirror_symmetric_corners_is_solved(side_deg, n_markers):
    """A camera level with the markers' centre, turned about the vertical: the exact corners are mirror-symmetric
    in the image, where OpenCV's IPPE returns a pose 21 px off; the pose is still found, exactly."""
    markers = {"0": {"translation": [0, -40, 1040], "rotation": [0, 0, 0]}}
    if n_markers == 2:
        markers["1"] = {"translation": [0, 160, 1040], "rotation": [0, 0, 0]}
    marker_map = MarkerMap.from_dict(markers, units="mm", marker_size_mm=80)
    camera = Camera.from_fov(60, (640, 480))
    centre = np.mean([marker_map.marker_corners(i).mean(axis=0) for i in marker_map.ids], axis=0)
    a = np.radians(side_deg)
    eye = centre + [1500 * np.cos(a), 1500 * np.sin(a), 0.0]
    T = look_at(eye, centre)
    dets = [Detection(i, camera.project(marker_map.marker_corners(i), T)) for i in marker_map.ids]
    pose = estimate_pose(dets, marker_map, camera)
    np.testing.assert_allclose(pose.T_world_camera, T, atol=1e-6)
