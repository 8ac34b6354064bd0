"""The pose covariance on a fisheye camera: each corner's picture noise carried through the undistortion, so that
corners near the edge of a 160-degree lens (stretched by the undistortion) count for what they are worth."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, MarkerMap, frames
from fidlearn._fisheye_edges import refine_edges_fisheye, straighten_edges_fisheye
from fidlearn.detection import Detection
from fidlearn.pose._inputs import _lens_jacobians
from fidlearn.synthetic import render_scene

W, H = 800, 600
F = (W / 2) / math.radians(80)  # equidistant: 160 degrees across the picture's width
CAM = Camera([[F, 0, W / 2 - 0.5], [0, F, H / 2 - 0.5], [0, 0, 1]], [0.0] * 4, (W, H), model="fisheye")
#: 120 mm markers on a wall 3 m wide, the camera 40 cm in front of it: seen from the centre to 77 degrees off axis
WALL = MarkerMap.from_dict(
    {
        str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]}
        for k, (y, z) in enumerate((y, z) for y in range(-1500, 1501, 300) for z in range(-900, 901, 300))
    },
    marker_size_mm=120,
    units="mm",
)
T = frames.look_at([400.0, 0.0, 0.0], [0.0, 0.0, 0.0])


def _off_axis_deg(T_world_camera: np.ndarray) -> dict[int, float]:
    T_cw = np.linalg.inv(T_world_camera)
    out = {}
    for i, c in WALL.corners().items():
        x = T_cw[:3, :3] @ c.mean(axis=0) + T_cw[:3, 3]
        out[i] = math.degrees(math.atan2(math.hypot(x[0], x[1]), x[2]))
    return out


def test_lens_jacobians_are_the_inverse_of_the_undistortions():
    px = np.array([[400.0, 300.0], [700.0, 120.0], [60.0, 540.0]])
    ideal = CAM.undistort_points(px)
    D = _lens_jacobians(CAM, ideal)
    h = 1e-3
    for k in range(2):  # d(ideal) / d(picture px) by differences of the exact undistortion
        step = np.zeros(2)
        step[k] = h
        G_k = (CAM.undistort_points(px + step) - CAM.undistort_points(px - step)) / (2 * h)
        np.testing.assert_allclose(np.einsum("nij,nj->ni", D, G_k), np.tile(np.eye(2)[k], (3, 1)), atol=1e-4)
    np.testing.assert_allclose(D[0], np.eye(2), atol=1e-3)  # at the centre the lens is a pinhole
    assert np.linalg.det(D[1]) < 0.2  # near the edge the undistortion stretches a pixel more than five times


@pytest.mark.parametrize("where", ["centre", "edge"])
def test_the_95_percent_ellipsoid_holds_the_truth_at_the_centre_and_at_the_edge(where):
    ang = _off_axis_deg(T)
    ids = sorted(ang, key=ang.get)[:3] if where == "centre" else [i for i in ang if 72 < ang[i] < 76][:3]
    rng = np.random.default_rng(7)
    inside, stds = 0, []
    n = 150
    for _ in range(n):
        dets = [Detection(i, CAM.project(WALL.marker_corners(i), T) + rng.normal(0, 0.5, (4, 2))) for i in ids]
        pose = fidlearn.estimate_pose(dets, WALL, CAM, corner_sigma_px=0.5)
        inside += pose.position_ellipsoid_contains(T[:3, 3])
        stds.append(np.linalg.norm(pose.position_std_mm))
    # binomial(150, 0.95): 3 standard deviations are 5 %; the ideal pixels' equal noise held 1.5 % at the edge
    assert 0.89 <= inside / n <= 1.0
    if where == "edge":
        assert np.median(stds) > 15.0  # 25 mm: three markers 75 degrees off axis
    else:
        assert np.median(stds) < 5.0  # 2.8 mm


def test_a_rendered_pose_from_the_edge_states_more_uncertainty_than_one_from_the_centre():
    T_r = frames.look_at([420.0, 30.0, -20.0], [0.0, 10.0, 5.0], roll_deg=4)
    scene = render_scene(WALL, CAM, T_r, seed=3, blur_px=0.5, noise_std_gray=2.0)
    ang = _off_axis_deg(T_r)
    dets = [d for d in fidlearn.detect_markers(scene.image, WALL.dictionary) if d.id in WALL]
    centre = [d for d in dets if ang[d.id] < 50]
    edge = [d for d in dets if ang[d.id] > 66]
    assert len(centre) >= 4
    assert len(edge) >= 4
    poses = {name: fidlearn.estimate_pose(ds, WALL, CAM) for name, ds in (("centre", centre), ("edge", edge))}
    for pose in poses.values():
        assert np.linalg.norm(pose.position_mm - T_r[:3, 3]) < 8.0
    # each pose's picture-pixel noise: the detector's, not the ideal pixels' (several times wider at the edge)
    assert poses["edge"].corner_sigma_px < 1.0
    size = {k: float(np.linalg.norm(p.position_std_mm)) for k, p in poses.items()}
    assert size["edge"] > 2 * size["centre"]
    every = fidlearn.estimate_pose(dets, WALL, CAM)
    assert np.linalg.norm(every.position_mm - T_r[:3, 3]) < 3.0
    assert np.linalg.norm(every.position_std_mm) < size["edge"]


@pytest.fixture(scope="module")
def squeezed():
    """A wall seen across the fisheye, its markers squeezed along the radius: the pose, the scene, the detected
    ("edges") corners and their truth."""
    T_r = frames.look_at([450.0, -100.0, 60.0], [0.0, 200.0, -100.0], roll_deg=-8)
    scene = render_scene(WALL, CAM, T_r, seed=4, blur_px=0.5, noise_std_gray=2.0)
    dets = [d for d in fidlearn.detect_markers(scene.image, WALL.dictionary) if d.id in scene.truth]
    return T_r, scene, np.stack([d.corners_px for d in dets]), np.stack([scene.truth[d.id] for d in dets])


def test_edges_refinement_on_a_fisheye_loses_its_straight_line_bias(squeezed):
    T_r, scene, raw, truth = squeezed
    fixed = straighten_edges_fisheye(raw, CAM, 7)
    rms_raw = np.sqrt(np.mean((raw - truth) ** 2))
    rms_fixed = np.sqrt(np.mean((fixed - truth) ** 2))
    assert rms_raw > 0.2  # 0.27 px: lines fitted to curved sides
    assert rms_fixed < 0.5 * rms_raw  # 0.07 px
    np.testing.assert_array_equal(straighten_edges_fisheye(raw, Camera(CAM.K, None, (W, H)), 7), raw)
    pose = fidlearn.locate(scene.image, WALL, CAM)  # locate takes the bias out of its "edges" corners
    assert np.linalg.norm(pose.position_mm - T_r[:3, 3]) < 0.4
    bent = fidlearn.locate(scene.image, WALL, CAM, refine="subpix")
    assert np.linalg.norm(pose.position_mm - T_r[:3, 3]) < np.linalg.norm(bent.position_mm - T_r[:3, 3])


@pytest.mark.slow
def test_rendered_fisheye_poses_are_covered_about_95_percent():
    """40 renders, the corners' noise known (their RMS error against the truth): the 95 % ellipsoid holds the truth."""
    rng = np.random.default_rng(11)
    inside, n = 0, 40
    for seed in range(n):
        eye = [rng.uniform(300, 700), rng.uniform(-400, 400), rng.uniform(-300, 300)]
        T_r = frames.look_at(eye, [0.0, rng.uniform(-300, 300), rng.uniform(-200, 200)], roll_deg=rng.uniform(-20, 20))
        scene = render_scene(WALL, CAM, T_r, seed=seed, blur_px=0.5, noise_std_gray=2.0)
        dets = [d for d in fidlearn.detect_markers(scene.image, WALL.dictionary) if d.id in scene.truth]
        straight = refine_edges_fisheye(scene.image, np.stack([d.corners_px for d in dets]), CAM, 7)  # as locate
        truth = np.stack([scene.truth[d.id] for d in dets])
        sigma = float(np.sqrt(np.mean((straight - truth) ** 2)))
        dets = [Detection(d.id, c) for d, c in zip(dets, straight)]
        pose = fidlearn.estimate_pose(dets, WALL, CAM, corner_sigma_px=sigma)
        inside += pose.position_ellipsoid_contains(T_r[:3, 3])
    assert 0.85 <= inside / n <= 1.0  # 94 % of the first 16


def test_fisheye_sides_fitted_as_the_lens_bends_them_with_the_markers_own_levels(squeezed):
    """Markers squeezed along the radius (a white margin of 2 px): their edges found at the marker's own levels."""
    _, scene, raw, truth = squeezed
    straight = straighten_edges_fisheye(raw, CAM, 7)
    fitted = refine_edges_fisheye(scene.image, raw, CAM, 7)
    err_straight = np.linalg.norm(straight - truth, axis=2)
    err_fitted = np.linalg.norm(fitted - truth, axis=2)
    assert np.sqrt(np.mean(err_straight**2)) > 0.1  # 0.12 px: edges put inside the squeezed margins
    assert np.sqrt(np.mean(err_fitted**2)) < 0.75 * np.sqrt(np.mean(err_straight**2))  # 0.08 px
    assert np.median(err_fitted) < 0.75 * np.median(err_straight)  # 0.037 px against 0.058
    pinhole = Camera(CAM.K, None, (W, H))
    np.testing.assert_array_equal(refine_edges_fisheye(scene.image, raw, pinhole, 7), raw)
