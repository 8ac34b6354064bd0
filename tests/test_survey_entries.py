"""fidlearn.survey of a map with rigid entries (a ChArUco board on the wall, a bundle of two markers), with the truth.

The room is ``fidlearn.synthetic.board_survey_room``: the survey room with marker 1 replaced by a ChArUco board
(5 x 7 squares of 100 mm, markers 20-36) and marker 8 by a bundle (markers 40 and 41 on one plate). An entry is
one placement in the adjustment: its markers are surveyed together and cannot drift apart.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from helpers import corner_error_mm, jacobian_error, projected_photos

import fidlearn
from fidlearn import frames
from fidlearn._map_parse import id_ranges
from fidlearn.cli.survey import suspect_lines
from fidlearn.markermap import MarkerMap
from fidlearn.survey._entries import entry_groups, member_covariance
from fidlearn.survey._geometry import exp_so3
from fidlearn.survey._solve import build_problem
from fidlearn.survey._survey import _read_photos, initial_values
from fidlearn.synthetic import board_survey_room, survey_walk, tape_measured

CAM = fidlearn.Camera.from_fov(70, (1280, 720), dist=[-0.1, 0.02, 0.001, -0.001, 0.0])
BOARD_IDS = list(range(20, 37))


def taped(truth: MarkerMap, sigma_mm: float, seed: int, board_moved=(0.0, 0.0, 0.0), exact=()) -> MarkerMap:
    """The tape (single markers and each entry as one object off by ``sigma_mm``), the ``exact`` markers not."""
    tape = tape_measured(truth, sigma_mm=sigma_mm, sigma_deg=1.0, moved={"wall board": board_moved}, seed=seed)
    singles = {i: (truth.placements[i] if i in exact else p) for i, p in tape.placements.items() if i not in tape.owner}
    return MarkerMap(singles, truth.marker_size_mm, source="tape", entries=list(tape.entries.values()))


@pytest.fixture(scope="module")
def room():
    truth = board_survey_room()
    return truth, survey_walk(truth, CAM, n_photos=24, seed=2)


def test_noise_free_room_with_a_board_and_a_bundle_is_surveyed_exactly(room, tmp_path):
    truth, poses = room
    tape = taped(truth, 20.0, seed=3, exact=(0,))
    s = fidlearn.survey(projected_photos(truth, CAM, poses), tape, CAM, map_sigma_mm=math.inf, fixed_ids=[0])
    assert set(s.marker_map.entries) == {"wall board", "dock"}
    assert s.marker_map.owner == truth.owner
    assert corner_error_mm(s.marker_map, truth) < 1e-6
    board = s.marker_map.entries["wall board"]
    assert np.allclose(board.translation_mm, truth.entries["wall board"].translation_mm, atol=1e-6)
    assert (board.counts, board.square_size_mm, board.first_id) == ((5, 7), 100.0, 20)
    assert s.suspects == []
    assert s.unused == []
    assert s.added_ids == ()
    assert max(s.photo_rms_px.values()) < 1e-6
    assert all(s.photos_per_marker[i] >= 2 for i in (20, 40, 41))
    back = MarkerMap.load(s.save(tmp_path / "surveyed.json"))
    assert back.owner == s.marker_map.owner  # the entries written back as entries
    assert corner_error_mm(back, truth) < 1e-6


def test_a_board_is_one_placement_in_the_adjustment_and_its_jacobian_is_right(room):
    truth, poses = room
    tape = taped(truth, 20.0, seed=4)
    ph = _read_photos(projected_photos(truth, CAM, poses[:8], 0.2), tape, CAM, None)
    placed, _ = initial_values(ph, tape)
    groups = entry_groups(tape)
    placed.update({n: (frames.rotation_from_rpy_deg(*e.rotation_deg), np.asarray(e.translation_mm)) for n, e in
                   tape.entries.items()})  # fmt: skip
    singles = sorted({i for p in ph for i in p.corners if i not in tape.owner})
    slots = ["wall board", "dock", *singles[1:], singles[0]]
    opts = {"marker_size_mm": tape.marker_size_mm, "sigma_px": 0.3, "sigma_mm": 20.0, "sigma_rot_rad": 0.1,
            "groups": groups}  # fmt: skip
    prob = build_problem(ph, slots, len(slots) - 1, placed, {i: placed[i] for i in slots[:3]}, opts)
    assert prob.n_params == 6 * (len(ph) + len(slots) - 1)
    assert prob.local.shape == (len(slots), 4 * 17, 3)
    assert set(prob.obs_marker[prob.obs_corner >= 8]) == {0}  # the board's 17 markers, the dock's 2, a marker's 1
    assert set(prob.obs_marker[prob.obs_corner >= 4]) == {0, 1}
    assert jacobian_error(prob) < 1e-4


def test_a_moved_board_is_named_as_one_and_put_back_by_the_photos(room):
    truth, poses = room
    tape = taped(truth, 10.0, seed=5, board_moved=(0.0, 60.0, -80.0))  # 100 mm in the wall's plane
    s = fidlearn.survey(projected_photos(truth, CAM, poses, 0.1, seed=6), tape, CAM)  # the tape's sigma learnt
    assert set(s.suspect_ids) == set(BOARD_IDS)
    assert {round(x.distance_mm) for x in s.suspects} == {round(s.suspects[0].distance_mm)}  # one test, the board's
    assert s.suspects[0].distance_mm == pytest.approx(100.0, abs=15.0)
    got = np.asarray(s.marker_map.entries["wall board"].translation_mm)
    assert np.linalg.norm(got - truth.entries["wall board"].translation_mm) < 10.0
    assert 10.0 / 2 < s.map_sigma_mm < 10.0 * 2
    (line,) = suspect_lines(s)  # the board once, not its 17 markers one by one
    assert line == (
        f"board 'wall board' (markers 20-36) is {s.suspects[0].distance_mm:.0f} mm from where the map says "
        f"({s.suspects[0].sigmas:.0f} sigma): measure it again"
    )


def test_a_fixed_board_marker_holds_its_board_at_the_tapes_placement(room):
    truth, poses = room
    tape = taped(truth, 20.0, seed=7)
    singles = {i: p for i, p in tape.placements.items() if i not in tape.owner}
    entries = [truth.entries["wall board"], tape.entries["dock"]]
    tape = MarkerMap(singles, tape.marker_size_mm, dictionary=tape.dictionary, entries=entries)
    s = fidlearn.survey(projected_photos(truth, CAM, poses, 0.1, seed=8), tape, CAM, map_sigma_mm=math.inf,
                        fixed_ids=[25])  # fmt: skip
    assert s.marker_map.entries["wall board"] == truth.entries["wall board"]
    assert corner_error_mm(s.marker_map, truth) < 2.0
    assert not np.any(s.marker_covariance[20])
    assert not np.any(s.marker_covariance[36])
    assert np.all(s.marker_position_std_mm[40] > 0)


def test_each_board_markers_covariance_is_its_boards_carried_to_its_corner():
    """The member's top-left corner ``p + R q`` under a small left rotation and shift, against ``member_covariance``."""
    truth = board_survey_room()
    g = entry_groups(truth)["wall board"]
    R = frames.rotation_from_rpy_deg(10.0, -20.0, 30.0)
    m = 7

    def corner(d: np.ndarray) -> np.ndarray:
        return d[3:] + exp_so3(d[:3]) @ R @ g.local[4 * m]

    J = np.zeros((6, 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = 1e-6
        J[3:, k] = (corner(d) - corner(-d)) / 2e-6
    J[:3, :3] = np.eye(3)
    C = np.diag([1e-4, 2e-4, 3e-4, 4.0, 5.0, 6.0])
    assert np.allclose(member_covariance(C, R, g, m), J @ C @ J.T, rtol=1e-6, atol=1e-9)


def test_a_board_taped_a_metre_off_is_one_gross_entry_placed_by_the_photos(room):
    """17 markers moved as one object are one of the gross test's votes, not a majority that refuses the tape."""
    truth, poses = room
    tape = taped(truth, 10.0, seed=9, board_moved=(0.0, 1000.0, 300.0))
    s = fidlearn.survey(projected_photos(truth, CAM, poses, 0.1, seed=10), tape, CAM)
    assert set(s.gross_ids) == set(BOARD_IDS) - {i for i in BOARD_IDS if i not in s.tape_residual_mm}
    assert set(s.suspect_ids) == set(BOARD_IDS)
    assert len({s.tape_residual_mm[i] for i in s.gross_ids}) == 1  # one residual, the board's
    got = np.asarray(s.marker_map.entries["wall board"].translation_mm)
    assert np.linalg.norm(got - truth.entries["wall board"].translation_mm) < 10.0
    assert not set(s.suspect_ids) - set(BOARD_IDS)


def test_id_ranges_are_written_as_people_write_them():
    assert id_ranges([20, 21, 22, 25, 27, 28]) == "20-22, 25, 27-28"
    assert id_ranges([3]) == "3"


def test_a_gross_board_is_started_from_the_photos_alone_even_its_marker_in_one_photo(room):
    """The tape a metre off is left out whole; a marker seen once is placed with its board, without a warning."""
    truth, poses = room
    photos = projected_photos(truth, CAM, poses, 0.1, seed=11)
    once = next(k for k, f in enumerate(photos) if any(d.id == 36 for d in f))
    photos = [f if k == once else [d for d in f if d.id != 36] for k, f in enumerate(photos)]
    tape = taped(truth, 10.0, seed=9, board_moved=(0.0, 1000.0, 300.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "marker 36 is not in the map" warning: it is placed with its board
        s = fidlearn.survey(photos, tape, CAM)
    assert s.photos_per_marker[36] == 1
    got = np.asarray(s.marker_map.entries["wall board"].translation_mm)
    assert np.linalg.norm(got - truth.entries["wall board"].translation_mm) < 10.0
    assert "placed by the photos" in s.table().splitlines()[1 + s.marker_map.ids.index(20)]


def test_a_gross_bundle_whose_photos_show_one_marker_is_placed_by_that_marker(room):
    truth, poses = room
    photos = [[d for d in f if d.id != 41] for f in projected_photos(truth, CAM, poses, 0.1, seed=12)]
    tape = tape_measured(truth, sigma_mm=10.0, sigma_deg=1.0, moved={"dock": (800.0, 0.0, 400.0)}, seed=13)
    s = fidlearn.survey(photos, tape, CAM)
    assert 40 in s.gross_ids
    assert {40, 41} <= set(s.suspect_ids)
    assert s.photos_per_marker[41] == 0
    assert corner_error_mm(s.marker_map, truth, ids=[40, 41]) < 10.0


def test_a_fixed_marker_of_a_gross_board_is_refused_with_its_board_named(room):
    truth, poses = room
    tape = taped(truth, 10.0, seed=9, board_moved=(0.0, 1000.0, 300.0))
    with pytest.raises(fidlearn.errors.SurveyError, match="entry 'wall board', held by fixed marker 20, is 1"):
        fidlearn.survey(projected_photos(truth, CAM, poses, 0.1, seed=10), tape, CAM, fixed_ids=[20])


def test_a_fisheye_survey_places_the_board_exactly():
    """The entries' corners go through the lens model as any marker's: a fisheye's noise-free photos, exact."""
    fe = fidlearn.Camera([[500.0, 0.0, 640.0], [0.0, 500.0, 360.0], [0.0, 0.0, 1.0]], [-0.03, -0.02, 0.002, 0.001],
                         (1280, 720), model="fisheye")  # fmt: skip
    truth = board_survey_room()
    poses = survey_walk(truth, fe, n_photos=16, seed=4)
    tape = taped(truth, 20.0, seed=14, exact=(0,))
    s = fidlearn.survey(projected_photos(truth, fe, poses), tape, fe, map_sigma_mm=math.inf, fixed_ids=[0])
    assert corner_error_mm(s.marker_map, truth) < 1e-6
    assert set(s.marker_map.entries) == {"wall board", "dock"}


def taped_apart(truth: MarkerMap, sigma_mm: float, seed: int, board_moved) -> MarkerMap:
    """A tape drawn otherwise than ``tape_measured``'s: the single markers first, then each entry from its own draws."""
    singles = {i: p for i, p in truth.placements.items() if i not in truth.owner}
    tape = tape_measured(MarkerMap(singles, truth.marker_size_mm), sigma_mm=sigma_mm, sigma_deg=1.0, seed=seed)
    rng = np.random.default_rng(seed)
    entries = []
    for name, e in truth.entries.items():
        move = rng.normal(0, sigma_mm, 3) - (np.asarray(board_moved) if name == "wall board" else 0.0)
        rot = tuple(float(v) for v in np.asarray(e.rotation_deg) + rng.normal(0, 1.0, 3))
        entries.append(dataclasses.replace(e, translation_mm=tuple(np.add(e.translation_mm, move)), rotation_deg=rot))
    return MarkerMap(tape.placements, truth.marker_size_mm, source="tape", entries=entries)


def test_a_photo_the_tape_map_cannot_locate_joins_after_the_first_adjustment():
    """Photo 6 shows the board (taped 100 mm off) beside eight other markers: no pose from the tape, one after."""
    truth = board_survey_room()
    poses = survey_walk(truth, CAM, n_photos=16, seed=2)
    tape = taped_apart(truth, 10.0, seed=5, board_moved=(0.0, 60.0, -80.0))
    photos = projected_photos(truth, CAM, poses, 0.1, seed=1)
    with pytest.raises(fidlearn.errors.PoseError, match="do not fit the map"):
        fidlearn.estimate_pose(photos[6], tape, CAM)
    s = fidlearn.survey(photos, tape, CAM)
    assert s.unused == []
    assert len(s.camera_poses) == 16
    assert np.linalg.norm(s.camera_poses["photo 6"][:3, 3] - poses[6][:3, 3]) < 30.0
    assert set(s.suspect_ids) == set(BOARD_IDS)
