"""The survey's gross test on the rendered room (``data/survey``, with its truth): tape placements metres off.

A marker whose tape placement is off by metres (a typo) is named, placed by the photos alone and
never drags the others: the survey is the one without that marker's tape entry. A map whose taped
markers cannot agree is refused, naming them.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import fidlearn
from fidlearn import MarkerMap, MarkerPlacement, data_path
from fidlearn.cli import main
from fidlearn.errors import SurveyError
from fidlearn.images import load_image

FOLDER = data_path("survey")
SIGMA = 20.0


@pytest.fixture(scope="module")
def room():
    tape = MarkerMap.load(FOLDER / "tape_map.json")
    truth = MarkerMap.load(FOLDER / "true_map.json")
    camera = fidlearn.Camera.load(FOLDER / "camera.json")
    dets = [fidlearn.detect_markers(load_image(p), dictionary=tape.dictionary) for p in photos()]
    base = fidlearn.survey(dets, tape, camera, map_sigma_mm=SIGMA)
    return tape, truth, camera, dets, base


def photos():
    return sorted(FOLDER.glob("photo_*.jpg"))


def moved(tape: MarkerMap, moves: dict) -> MarkerMap:
    pl = dict(tape.placements)
    for i, d in moves.items():
        pl[i] = MarkerPlacement(i, tuple(np.add(pl[i].translation_mm, d)), pl[i].rotation_deg)
    return MarkerMap(pl, tape.marker_size_mm, dictionary=tape.dictionary, units=tape.units, source=tape.source)


def without(tape: MarkerMap, ids) -> MarkerMap:
    pl = {i: p for i, p in tape.placements.items() if i not in ids}
    return MarkerMap(pl, tape.marker_size_mm, dictionary=tape.dictionary, units=tape.units, source=tape.source)


def position(m: MarkerMap, i: int) -> np.ndarray:
    return np.asarray(m.placements[i].translation_mm, float)


def aligned_error_mm(surveyed: MarkerMap, truth: MarkerMap, i: int) -> float:
    """Marker i's top-left corner from the truth after the rigid motion that lays the other markers on the truth."""
    others = [j for j in truth.ids if j != i]
    a = np.array([position(surveyed, j) for j in others])
    b = np.array([position(truth, j) for j in others])
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(u @ vt))
    R = (u @ np.diag([1, 1, d]) @ vt).T
    return float(np.linalg.norm(R @ (position(surveyed, i) - ca) + cb - position(truth, i)))


@pytest.mark.parametrize(
    ("marker", "move"), [(3, (0.0, 0.0, 10_000.0)), (5, (1000.0, 0.0, 0.0)), (10, (0.0, -1000.0, 0.0))]
)
def test_a_marker_metres_off_is_named_placed_by_the_photos_and_drags_nothing(room, marker, move):
    tape, truth, camera, dets, base = room
    s = fidlearn.survey(dets, moved(tape, {marker: move}), camera, map_sigma_mm=SIGMA)
    assert s.gross_ids == (marker,)
    assert s.suspect_ids[0] == marker  # the bundled 100 mm error is still named
    assert 7 in s.suspect_ids
    assert s.tape_residual_mm[marker] == pytest.approx(np.linalg.norm(move), rel=0.05)
    assert s.gross_threshold_mm < 0.5 * np.linalg.norm(move)
    # the survey is exactly the one without that marker's tape entry: the typo drags nothing
    clean = fidlearn.survey(dets, without(tape, [marker]), camera, map_sigma_mm=SIGMA)
    for i in truth.ids:
        assert np.linalg.norm(position(s.marker_map, i) - position(clean.marker_map, i)) < 0.01
    # the others' errors: those of the survey without the typo, and never more than the tape's gauge moves them
    for i in truth.ids:
        if i != marker:
            err = np.linalg.norm(position(s.marker_map, i) - position(truth, i))
            err0 = np.linalg.norm(position(base.marker_map, i) - position(truth, i))
            assert abs(err - err0) < 10.0, (i, err, err0)
    # placed within the photos' accuracy: relative to the other markers, a few mm from the truth
    assert aligned_error_mm(s.marker_map, truth, marker) < 5.0
    assert aligned_error_mm(s.marker_map, truth, marker) < aligned_error_mm(base.marker_map, truth, marker) + 3.0
    assert np.linalg.norm(position(s.marker_map, marker) - position(truth, marker)) < 60.0


def test_a_marker_100_mm_off_is_named_by_the_sigma_test_not_the_gross_one(room):
    tape, truth, camera, dets, base = room
    assert base.suspect_ids == [7]
    assert base.gross_ids == ()
    assert 60 < base.tape_residual_mm[7] < 160  # the bundled marker 7: 100 mm off
    others = [v for i, v in base.tape_residual_mm.items() if i != 7]
    assert max(others) < 80
    assert base.gross_threshold_mm >= 15 * SIGMA
    s = fidlearn.survey(dets, moved(tape, {3: (0.0, 100.0, 0.0)}), camera, map_sigma_mm=SIGMA)
    assert s.gross_ids == ()
    assert sorted(s.suspect_ids) == [3, 7]


def test_two_markers_metres_off_are_both_named(room):
    tape, truth, camera, dets, _ = room
    s = fidlearn.survey(dets, moved(tape, {5: (0.0, 1000.0, 0.0), 9: (0.0, 0.0, -3000.0)}), camera, map_sigma_mm=SIGMA)
    assert s.gross_ids == (5, 9)
    assert s.suspect_ids[:2] == [9, 5]
    for i in (5, 9):
        assert aligned_error_mm(s.marker_map, truth, i) < 5.0


def test_a_map_without_an_agreeing_majority_is_refused_naming_the_markers(room):
    tape, _, camera, dets, _ = room
    bad = moved(tape, {i: (0.0, 0.0, 2000.0 * (i + 1)) for i in range(7)})
    with pytest.raises(
        SurveyError,
        match=r"at most 5 of the 12 taped markers .*\[7, 8, 9, 10, 11\].*no majority; "
        r"markers \[0, 1, 2, 3, 4, 5, 6\] are off",
    ):
        fidlearn.survey(dets, bad, camera, map_sigma_mm=SIGMA)


def test_a_fixed_marker_metres_off_is_refused(room):
    tape, _, camera, dets, _ = room
    with pytest.raises(SurveyError, match=r"fixed marker 3 is 10\d\d mm from where the photos put it"):
        fidlearn.survey(dets, moved(tape, {3: (1000.0, 0.0, 0.0)}), camera, map_sigma_mm=SIGMA, fixed_ids=[3])


def test_cli_names_the_typo_and_shows_the_robust_residuals(capsys, tmp_path):
    d = json.loads((FOLDER / "tape_map.json").read_text())  # units cm
    d["markers"]["3"]["translation"][2] += 1000.0  # 10 m
    (tmp_path / "typo.json").write_text(json.dumps(d))
    out_path = tmp_path / "s.json"
    argv = ["survey", FOLDER, "--camera", FOLDER / "camera.json", "--map", tmp_path / "typo.json"]
    code = main([str(a) for a in [*argv, "--map-sigma-mm", "20", "-o", out_path]])
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = out.splitlines()
    assert "resid" in lines[1]
    row = next(line for line in lines if line.split()[:1] == ["3"])
    assert "SUSPECT, far off: placed by the photos" in row
    assert 9500 < float(row.split()[-11]) < 10500  # the robust residual, mm
    assert "marker 3 is" in out
    assert "marker 7 is" in out
    truth = MarkerMap.load(FOLDER / "true_map.json")
    got = MarkerMap.load(out_path)
    assert np.linalg.norm(position(got, 3) - position(truth, 3)) < 60
