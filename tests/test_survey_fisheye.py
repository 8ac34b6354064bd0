"""fidlearn.survey with a fisheye camera: the room's known answers through the Kannala-Brandt model.

The photos are the true corners of the synthetic room (``fidlearn.synthetic.survey_room``) projected
through a 147-degree fisheye (``Camera.project``, i.e. ``cv2.fisheye.projectPoints``) from known poses,
or pictures of it rendered through that lens and detected; markers up to 70 degrees off the axis, near
the picture's edge, are among them. The print scale from one fisheye photo of a wall printed at 98 %.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from helpers import (
    corner_error_mm,
    jacobian_error,
    noise_free_survey,
    projected_photos,
    small_survey_problem,
    survey_walk_room,
    survey_with_marker_7_moved,
    with_placements,
)

import fidlearn
from fidlearn.cli import main
from fidlearn.detection import Detection
from fidlearn.markermap import MarkerMap
from fidlearn.survey import check_print
from fidlearn.survey._geometry import placement_from_photo
from fidlearn.synthetic import render_scene, survey_room, survey_walk, tape_measured, visible_markers

#: 1280 x 720 at 500 px per radian: 147 degrees across, 84 degrees up and down.
FE = fidlearn.Camera(
    np.array([[500.0, 0.0, 640.0], [0.0, 500.0, 360.0], [0.0, 0.0, 1.0]]),
    [-0.03, -0.02, 0.002, 0.001],
    (1280, 720),
    model="fisheye",
)


@pytest.fixture(scope="module")
def room():
    return survey_walk_room(FE)


def photos(truth, poses, noise_px=0.0, seed=0):
    return projected_photos(truth, FE, poses, noise_px, seed)


def off_axis_deg(truth: MarkerMap, T_world_camera: np.ndarray, marker_id: int) -> float:
    """The largest angle (deg) of the marker's corners from the camera's optical axis."""
    T_cw = np.linalg.inv(T_world_camera)
    p = truth.marker_corners(marker_id) @ T_cw[:3, :3].T + T_cw[:3, 3]
    return float(np.degrees(np.arccos(p[:, 2] / np.linalg.norm(p, axis=1))).max())


def test_the_pictures_hold_markers_near_the_edge(room):
    truth, poses = room
    angles = [off_axis_deg(truth, T, i) for T in poses for i in visible_markers(truth, FE, T)]
    assert max(angles) > 65.0
    # a pinhole projection with the same K puts them elsewhere by tens of pixels: the model matters
    T, far = max(((T, i) for T in poses for i in visible_markers(truth, FE, T)), key=lambda a: off_axis_deg(truth, *a))
    pinhole = fidlearn.Camera(FE.K, np.zeros(5), FE.image_size)
    assert np.abs(pinhole.project(truth.marker_corners(far), T) - FE.project(truth.marker_corners(far), T)).max() > 50


def test_noise_free_fisheye_room_is_surveyed_exactly(room):
    truth, poses = room
    s = noise_free_survey(truth, poses, FE)
    assert corner_error_mm(s.marker_map, truth) < 1e-6
    used = {int(label.split()[1]) for label in s.camera_poses}
    # whole-room views, whose markers are small, fit the rough tape too badly to start from it
    assert len(used) >= 18
    assert all("do not fit the map" in reason for _, reason in s.unused)
    for k in used:
        assert np.abs(s.camera_poses[f"photo {k}"][:3, 3] - poses[k][:3, 3]).max() < 1e-6
    assert max(off_axis_deg(truth, poses[k], i) for k in used for i in visible_markers(truth, FE, poses[k])) > 65.0
    assert s.suspects == []
    assert max(s.photo_rms_px.values()) < 1e-6


def test_jacobian_through_the_fisheye_matches_finite_differences(room):
    prob = small_survey_problem(*room, FE)
    assert prob.model == "fisheye"
    # the residuals are the fisheye's own pixels: at x = 0 they are the projection through cv2.fisheye
    _, _, _, P = prob._points(np.zeros(prob.n_params))
    fe, _ = cv2.fisheye.projectPoints(P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), FE.K, FE.dist)
    assert np.abs(prob.reprojection_px(np.zeros(prob.n_params)) - (fe.reshape(-1, 2) - prob.obs_px)).max() < 1e-6
    assert jacobian_error(prob) < 1e-4


def test_placement_from_a_fisheye_photo_near_the_edge(room):
    truth, poses = room
    T, far = max(((T, i) for T in poses for i in visible_markers(truth, FE, T)), key=lambda a: off_axis_deg(truth, *a))
    corners = visible_markers(truth, FE, T)[far]
    R, top_left = placement_from_photo(corners, FE, T, truth.marker_size_mm)
    assert np.linalg.norm(top_left - truth.marker_corners(far)[0]) < 1e-6
    assert np.abs(R - truth.placements[far].R_world_marker).max() < 1e-9


def test_moved_marker_is_named_and_surveyed_back(room):
    _, s = survey_with_marker_7_moved(*room, FE)
    # the corner noise is estimated in the picture's own pixels: 0.1 px put in
    assert 0.07 < s.corner_sigma_px < 0.13


def test_shape_is_the_photos_and_the_gauge_the_tapes(room):
    truth, poses = room
    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=0.0, seed=6)
    s = fidlearn.survey(photos(truth, poses), tape, FE, map_sigma_mm=20)
    got = np.array([s.marker_map.placements[i].translation_mm for i in truth.ids])
    taped = np.array([tape.placements[i].translation_mm for i in truth.ids])
    true = np.array([truth.placements[i].translation_mm for i in truth.ids])
    assert np.linalg.norm((got - taped).mean(axis=0)) < 2.0
    d_got, d_true = (np.linalg.norm(a[:, None] - a[None], axis=2) for a in (got, true))
    # the pinhole survey's tolerance: the shape is the photos' to 0.2 mm
    assert np.abs(d_got - d_true).max() < 0.2


def test_marker_missing_from_the_map_is_added_at_its_true_place(room):
    truth, poses = room
    tape = with_placements(truth, {i: p for i, p in truth.placements.items() if i != 5})
    s = fidlearn.survey(photos(truth, poses, 0.1, seed=2), tape, FE, map_sigma_mm=1.0)
    assert s.added_ids == (5,)
    assert corner_error_mm(s.marker_map, truth, [5]) < 3.0
    assert np.all(s.marker_position_std_mm[5] < 3.0)


def test_cli_surveys_rendered_fisheye_pictures(tmp_path, capsys):
    truth = survey_room()
    poses = survey_walk(truth, FE, n_photos=12, seed=2)
    for k, T in enumerate(poses):
        scene = render_scene(truth, FE, T, seed=k, supersample=2, noise_std_gray=1.0)
        assert cv2.imwrite(str(tmp_path / f"photo_{k:02d}.png"), scene.image)
    camera = FE.save(tmp_path / "fisheye.json")
    tape = tape_measured(truth, sigma_mm=10.0, sigma_deg=1.0, moved={7: (0.0, 100.0, 0.0)}, seed=5)
    tape.save(tmp_path / "tape.json")
    out = tmp_path / "surveyed.json"
    argv = ["survey", tmp_path, "--camera", camera, "--map", tmp_path / "tape.json", "--map-sigma-mm", 10]
    code = main([str(a) for a in [*argv, "-o", out, "--plot", tmp_path / "survey.png"]])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "marker 7 is" in stdout
    assert "measure it again" in stdout
    assert cv2.imread(str(tmp_path / "survey.png")).shape[2] == 3
    got = MarkerMap.load(out)
    moved = np.subtract(got.placements[7].translation_mm, truth.placements[7].translation_mm)
    assert np.linalg.norm(moved) < 40
    # the surveyed shape: distances between the top-left corners as the truth's
    g = np.array([got.placements[i].translation_mm for i in truth.ids])
    t = np.array([truth.placements[i].translation_mm for i in truth.ids])
    dg, dt = (np.linalg.norm(a[:, None] - a[None], axis=2) for a in (g, t))
    assert np.abs(dg - dt).max() < 6.0  # 2.7 mm measured, from detected corners


def test_print_scale_from_a_fisheye_photo():
    from test_print_check import views, wall

    for k, T in enumerate(views(4)):
        image = render_scene(wall(0.98), FE, T, seed=k, noise_std_gray=2, blur_px=0.6).image
        r = check_print(image, wall(), FE)
        assert len(r.marker_ids) == 8
        assert abs(r.scale - 0.98) <= 0.002, (k, r)
        assert abs(r.scale - 0.98) <= 4 * r.scale_std + 3e-4


def test_a_marker_beyond_90_degrees_off_the_axis_is_left_out(room):
    from fidlearn.survey._survey import _read_photos

    truth, poses = room
    # 350 px per radian: the picture's corners are 120 degrees off the axis, where no normalized point is
    wide = fidlearn.Camera(
        np.array([[350.0, 0, 640], [0, 350.0, 360], [0, 0, 1]]), np.zeros(4), (1280, 720), "", model="fisheye"
    )
    seen = [[Detection(i, c) for i, c in visible_markers(truth, wide, T).items()] for T in poses[:2]]
    far = Detection(11, np.array([[1200.0, 20.0], [1270.0, 20.0], [1270.0, 80.0], [1200.0, 80.0]]))
    assert np.all(np.isnan(wide.undistort_points(far.corners_px)))
    kept = [d for d in seen[0] if d.id != 11]
    ph = _read_photos([[*kept, far], seen[1]], truth, wide, None)
    assert sorted(ph[0].corners) == sorted(d.id for d in kept)
    assert sorted(ph[1].corners) == sorted(d.id for d in seen[1])
