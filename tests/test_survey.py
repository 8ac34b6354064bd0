"""fidlearn.survey: the map from photos joined with the tape, checked against rooms with known answers.

The photos are the true corners of a synthetic room (``fidlearn.synthetic.survey_room``) projected
from known poses, with or without Gaussian noise; the tape maps carry known errors.
"""

from __future__ import annotations

import json
import math
import warnings

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
from fidlearn.detection import Detection
from fidlearn.errors import FidlearnWarning, ImageError, MapError, SurveyError
from fidlearn.markermap import MarkerMap
from fidlearn.survey._problem import Problem
from fidlearn.synthetic import tape_measured

CAM = fidlearn.Camera.from_fov(70, (1280, 720), dist=[-0.1, 0.02, 0.001, -0.001, 0.0])


@pytest.fixture(scope="module")
def room():
    return survey_walk_room(CAM)


def photos(truth, poses, noise_px=0.0, seed=0, drop=()):
    return projected_photos(truth, CAM, poses, noise_px, seed, drop)


def test_noise_free_room_is_surveyed_exactly(room):
    truth, poses = room
    s = noise_free_survey(truth, poses, CAM)
    assert corner_error_mm(s.marker_map, truth) < 1e-6
    assert len(s.camera_poses) == len(poses)
    for T_true, T in zip(poses, s.camera_poses.values()):
        assert np.abs(T[:3, 3] - T_true[:3, 3]).max() < 1e-6
    assert s.suspects == []
    assert s.unused == []
    assert max(s.photo_rms_px.values()) < 1e-6


def test_jacobian_matches_finite_differences(room):
    prob: Problem = small_survey_problem(*room, CAM)
    assert jacobian_error(prob) < 1e-4


def test_moved_marker_is_named_and_surveyed_back(room):
    truth, poses = room
    tape, _ = survey_with_marker_7_moved(truth, poses, CAM)
    tape_err = np.subtract(tape.placements[7].translation_mm, truth.placements[7].translation_mm)
    assert np.linalg.norm(tape_err) > 80


def test_marker_missing_from_the_map_is_added_at_its_true_place(room):
    truth, poses = room
    tape = with_placements(truth, {i: p for i, p in truth.placements.items() if i != 5})
    s = fidlearn.survey(photos(truth, poses, 0.1, seed=2), tape, CAM, map_sigma_mm=1.0)
    assert s.added_ids == (5,)
    assert corner_error_mm(s.marker_map, truth, [5]) < 3.0
    assert np.all(s.marker_position_std_mm[5] < 3.0)


def test_gauge_held_by_the_tape(room):
    truth, poses = room
    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=0.0, seed=6)
    s = fidlearn.survey(photos(truth, poses), tape, CAM, map_sigma_mm=20)
    # noise-free photos fix the shape; the tape decides where it sits: the mean top-left corner
    got = np.array([s.marker_map.placements[i].translation_mm for i in truth.ids])
    taped = np.array([tape.placements[i].translation_mm for i in truth.ids])
    true = np.array([truth.placements[i].translation_mm for i in truth.ids])
    assert np.linalg.norm((got - taped).mean(axis=0)) < 2.0
    assert np.linalg.norm((true - taped).mean(axis=0)) > 5.0  # the gauge came from the tape, not from the truth
    d_got = np.linalg.norm(got[:, None] - got[None], axis=2)
    d_true = np.linalg.norm(true[:, None] - true[None], axis=2)
    # the shape is the photos' (to 0.2 mm: corners are never trusted beyond 0.02 px, so the tape pulls a little)
    assert np.abs(d_got - d_true).max() < 0.2


def test_gauge_held_by_fixed_ids(room):
    truth, poses = room
    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=1.0, seed=7)
    s = fidlearn.survey(photos(truth, poses, 0.1), tape, CAM, map_sigma_mm=20, fixed_ids=2)
    assert s.fixed_ids == (2,)
    assert s.marker_map.placements[2] == tape.placements[2]
    assert np.all(s.marker_position_std_mm[2] == 0)
    assert not np.any(s.marker_covariance[2])


def test_survey_saves_a_map_in_its_units_with_a_note(room, tmp_path):
    truth, poses = room
    tape = with_placements(truth, truth.placements, units="cm")
    s = fidlearn.survey(photos(truth, poses[:8], 0.1), tape, CAM, map_sigma_mm=10)
    path = s.save(tmp_path / "surveyed.json")
    d = json.loads(path.read_text())
    assert d["units"] == "cm"
    assert d["surveyed"]["photos_used"] == 8
    back = MarkerMap.load(path)
    assert corner_error_mm(back, s.marker_map) < 1e-6
    assert s.position_ellipsoid_contains(0, truth.placements[0].translation_mm, 0.999)
    pose = fidlearn.estimate_pose(photos(truth, poses[:1])[0], back, CAM)
    assert np.linalg.norm(pose.position_mm - poses[0][:3, 3]) < 20


def test_a_survey_by_the_photos_alone_saves_a_map_that_loads_back(room, tmp_path):
    """map_sigma_mm=inf has no JSON number: the note says null, and the map reader takes the file back."""
    truth, poses = room
    s = fidlearn.survey(photos(truth, poses[:8], 0.1), truth, CAM, map_sigma_mm=math.inf, fixed_ids=[0])
    path = s.save(tmp_path / "surveyed.json")
    assert json.loads(path.read_text())["surveyed"]["map_sigma_mm"] is None
    assert corner_error_mm(MarkerMap.load(path), s.marker_map) < 1e-6


def test_marker_seen_in_one_photo_is_named_with_what_to_take(room):
    truth, poses = room
    frames = photos(truth, poses)
    k = next(n for n, f in enumerate(frames) if any(d.id == 4 for d in f))
    frames = [f if n == k else [d for d in f if d.id != 4] for n, f in enumerate(frames)]
    tape = with_placements(truth, {i: p for i, p in truth.placements.items() if i != 4})
    with pytest.warns(FidlearnWarning, match="marker 4 is not in the map and is seen in only one photo"):
        s = fidlearn.survey(frames, tape, CAM)
    assert 4 in s.unplaced
    assert "take another photo" in s.unplaced[4]
    assert 4 not in s.marker_map


def test_photo_sharing_no_marker_is_left_out_with_the_reason(room):
    truth, poses = room
    frames = photos(truth, poses[:5]) + [[Detection(300, [[10, 10], [60, 10], [60, 60], [10, 60]])]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FidlearnWarning)
        s = fidlearn.survey(frames, truth, CAM)
    assert s.unused[0][0] == "photo 5"
    assert "shares no marker with the map" in s.unused[0][1]


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"images": "a.png"}, SurveyError, "images must be a list of photos"),
        ({"images": "one"}, SurveyError, "at least 2 photos"),
        ({"images": [1, 2]}, ImageError, r"images\[0\] is a int"),
        ({"map_sigma_mm": -1}, SurveyError, "map_sigma_mm must be above 0"),
        ({"map_sigma_mm": "ten"}, SurveyError, "map_sigma_mm must be a length"),
        ({"fixed_ids": [99]}, SurveyError, "fixed_ids has marker 99, which is not in the map"),
        ({"fixed_ids": ["a"]}, SurveyError, "fixed_ids must be marker ids"),
        ({"fixed_ids": [True, 1]}, SurveyError, "fixed_ids must be marker ids"),
        ({"map_sigma_mm": math.inf}, SurveyError, "nothing ties the photos to the world"),
        ({"corner_sigma_px": 0}, SurveyError, "corner_sigma_px must be a number of pixels above 0"),
    ],
)
def test_bad_options_say_what_to_do(room, kwargs, error, match):
    truth, poses = room
    args = {"images": photos(truth, poses[:3]), "map_sigma_mm": 10.0}
    if kwargs.get("images") == "one":
        kwargs = {"images": photos(truth, poses[:1])}
    args.update(kwargs)
    images = args.pop("images")
    with pytest.raises(error, match=match):
        fidlearn.survey(images, truth, CAM, **args)


def test_too_few_located_photos(room):
    truth, poses = room
    frames = photos(truth, poses[:1]) + [[Detection(300, [[10, 10], [60, 10], [60, 60], [10, 60]])]]
    with pytest.raises(SurveyError, match=r"only 1 of 2 photos give a camera pose.*photo 1: shares no marker"):
        fidlearn.survey(frames, truth, CAM)


@pytest.mark.parametrize(("units", "guess"), [("mm", "in"), ("m", "mm")])
def test_map_in_the_wrong_units_is_refused(room, units, guess):
    truth, poses = room
    # the numbers were written in `guess` but the file says `units`
    scale = fidlearn.markermap.UNITS_TO_MM
    pl = {
        i: fidlearn.MarkerPlacement(i, tuple(v / scale[guess] * scale[units] for v in p.translation_mm), p.rotation_deg)
        for i, p in truth.placements.items()
    }
    wrong = with_placements(truth, pl, units=units)
    with pytest.raises(MapError, match=rf"look wrong; the distances fit units '{guess}'"):
        fidlearn.survey(photos(truth, poses[:4]), wrong, CAM)


def test_bundled_photos_name_the_moved_marker_and_survey_the_room():
    from fidlearn import data_path

    folder = data_path("survey")
    truth = MarkerMap.load(folder / "true_map.json")
    tape = MarkerMap.load(folder / "tape_map.json")
    paths = sorted(folder.glob("photo_*.jpg"))
    s = fidlearn.survey(paths, tape, folder / "camera.json", map_sigma_mm=20)
    assert s.suspect_ids == [7]
    assert s.marker_map.units == "cm"
    seen = [i for i in truth.ids if i not in s.unseen_ids]
    got = np.concatenate([s.marker_map.corners()[i] for i in seen])
    true = np.concatenate([truth.corners()[i] for i in seen])
    assert rigid_rms_mm(got, true) < 1.0
    assert len(s.camera_poses) == len(paths)
    assert max(s.photo_rms_px.values()) < 0.5


def test_photos_of_two_sizes_or_one_file_twice_are_named_as_such():
    """Half the photos at 640x360: the gross test, run on one K for both sizes, blamed a correct tape. One file
    given twice counted its corners twice and lost one of its camera poses."""
    import cv2  # noqa: PLC0415

    from fidlearn import data_path  # noqa: PLC0415

    folder = data_path("survey")
    paths = sorted(folder.glob("photo_*.jpg"))[:6]
    images = [cv2.imread(str(p)) for p in paths]
    images[:3] = [cv2.resize(im, (640, 360)) for im in images[:3]]
    with (
        pytest.warns(fidlearn.FidlearnWarning),
        pytest.raises(SurveyError, match=r"different sizes \(640x360, 1280x720\)"),
    ):
        fidlearn.survey(images, folder / "tape_map.json", folder / "camera.json")
    with pytest.raises(SurveyError, match="photos 0 and 2 are one file"):
        fidlearn.survey([paths[0], paths[1], paths[0]], folder / "tape_map.json", folder / "camera.json")


def rigid_rms_mm(a: np.ndarray, b: np.ndarray) -> float:
    """RMS distance (mm) of points a from points b after the rigid motion that best lays a on b (Kabsch)."""
    ca, cb = a - a.mean(axis=0), b - b.mean(axis=0)
    u, _, vt = np.linalg.svd(ca.T @ cb)
    d = np.sign(np.linalg.det(u @ vt))
    R = (u @ np.diag([1, 1, d]) @ vt).T
    return float(np.sqrt(np.mean(np.sum((ca @ R.T - cb) ** 2, axis=1))))


def test_a_marker_in_one_photo_is_never_named_a_suspect(room):
    truth, poses = room
    frames = photos(truth, poses, 0.05, seed=3)
    k = next(n for n, f in enumerate(frames) if any(d.id == 3 for d in f))
    frames = [f if n == k else [d for d in f if d.id != 3] for n, f in enumerate(frames)]
    tape = tape_measured(truth, sigma_mm=5.0, sigma_deg=0.5, moved={3: (0.0, 100.0, 0.0)}, seed=8)
    s = fidlearn.survey(frames, tape, CAM, map_sigma_mm=5)
    assert s.photos_per_marker[3] == 1
    assert 3 not in s.suspect_ids  # one photo cannot dispute the tape
    assert s.tests[3][1] > 3.4  # though the test alone would have named it


def test_the_rotation_residual_is_exact_for_tiny_rotations():
    """A marker's rotation off its tape value by 1e-7 rad: cv2.Rodrigues alone gives zero below about 1e-5 rad."""
    from fidlearn import frames
    from fidlearn.survey._geometry import exp_so3, log_so3

    w = np.array([1e-7, -2e-7, 3e-7])
    np.testing.assert_allclose(log_so3(exp_so3(w)), w, rtol=1e-6, atol=0)
    np.testing.assert_allclose(log_so3(frames.rot_z(0.3)), [0, 0, 0.3], atol=1e-12)


def test_markers_no_chain_of_photos_links_to_the_fixed_one_are_refused_by_the_photos_alone(room):
    """Photos of markers 4-6 and photos of markers 7-9, none of both: with map_sigma_mm=inf and marker 4 fixed,
    nothing places 7-9 (they would keep their tape placement with a standard deviation of 0 mm or of kilometres)."""
    truth, poses = room
    frames = photos(truth, poses, 0.1, seed=1)
    apart = [[d for d in f if d.id in group] for group in ((4, 5, 6), (7, 8, 9)) for f in frames]
    apart = [f for f in apart if len(f) >= 2]
    with pytest.raises(SurveyError, match=r"only the fixed markers \(4\) hold the map, and no chain of photos links "):
        fidlearn.survey(apart, truth, CAM, map_sigma_mm=math.inf, fixed_ids=[4])
    s = fidlearn.survey(apart, truth, CAM, map_sigma_mm=math.inf, fixed_ids=[4, 8])
    assert corner_error_mm(s.marker_map, truth, [5, 6, 7, 9]) < 5.0


def test_a_photo_whose_markers_no_other_photo_shows_leaves_the_photos_alone_adjusted(room):
    """Photo 2 alone shows markers 4-6: the gross test's adjustment of the photos alone (where nothing holds that
    photo's camera) is still made, and no solver warning ("Matrix is exactly singular") reaches the user."""
    from fidlearn.survey._gross import gross_test
    from fidlearn.survey._inputs import _read_photos

    truth, poses = room
    frames = photos(truth, poses, 0.1, seed=1)
    frames = [f if n == 2 else [d for d in f if d.id not in (4, 5, 6)] for n, f in enumerate(frames)]
    assert sorted(d.id for d in frames[2]) == [4, 5, 6]
    tape = tape_measured(truth, sigma_mm=20.0, sigma_deg=2.0, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gross = gross_test(_read_photos(frames, tape, CAM, None), tape, None)
        s = fidlearn.survey(frames, tape, CAM)
    tape_error = {
        i: np.linalg.norm(np.subtract(tape.placements[i].translation_mm, truth.placements[i].translation_mm))
        for i in gross.residual_mm
    }
    assert max(abs(gross.residual_mm[i] - tape_error[i]) for i in tape_error) < 15.0
    assert s.photos_per_marker[4] == 1


def test_a_marker_in_no_photo_of_a_survey_by_the_photos_alone_is_not_called_exact(room, tmp_path):
    """With map_sigma_mm=inf the tape's placement of a marker no photo shows is not known at all: its standard
    deviation is inf (it was 0 mm, a fixed marker's), and the note writes null (the file loads back)."""
    truth, poses = room
    frames = photos(truth, poses[:8], 0.1, seed=1, drop=(9, 10))
    s = fidlearn.survey(frames, truth, CAM, map_sigma_mm=math.inf, fixed_ids=[0])
    assert s.unseen_ids == (9, 10)
    assert np.all(np.isinf(s.marker_position_std_mm[9]))
    assert np.all(s.marker_position_std_mm[0] == 0)
    assert s.position_ellipsoid_contains(9, [0.0, 0.0, 0.0])
    assert "   inf       -      0  in no photo: the tape's" in s.table()
    change = next(c for c in s.tag_changes() if c.id == 9)
    assert math.isinf(change.distance_std_mm)
    assert math.isinf(change.angle_std_deg)
    path = s.save(tmp_path / "surveyed.json")
    assert json.loads(path.read_text())["surveyed"]["position_std_mm"]["10"] == [None, None, None]
    assert corner_error_mm(MarkerMap.load(path), s.marker_map) < 1e-6
