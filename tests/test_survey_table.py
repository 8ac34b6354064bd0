"""Survey.table(): the per-marker table ``fidlearn survey`` prints, against a room surveyed exactly."""

from __future__ import annotations

import math

import pytest

import fidlearn
from fidlearn import MarkerMap
from fidlearn.detection import Detection
from fidlearn.synthetic import survey_room, survey_walk, visible_markers

CAM = fidlearn.Camera.from_fov(70, (1280, 720))


@pytest.fixture(scope="module")
def surveyed():
    truth = survey_room()
    poses = survey_walk(truth, CAM, n_photos=20, seed=1)
    seen = [visible_markers(truth, CAM, T) for T in poses]
    photos = [[Detection(i, c) for i, c in v.items()] for v in seen]
    tape = MarkerMap(
        {i: p for i, p in truth.placements.items() if i != 5}, truth.marker_size_mm, dictionary=truth.dictionary
    )
    s = fidlearn.survey(photos, tape, CAM, map_sigma_mm=math.inf, fixed_ids=[0])
    counts = {i: sum(i in v for v in seen) for i in truth.ids}
    return s, truth, counts


def test_the_table_has_a_line_per_marker_with_the_known_numbers(surveyed):
    s, truth, counts = surveyed
    lines = s.table().splitlines()
    assert lines[0] == ("  id        tape x, y, z (mm)    surveyed x, y, z (mm)    diff    std   resid photos  note")
    assert len(lines) == 1 + len(s.marker_map)
    rows = {int(line[:4]): line for line in lines[1:]}
    assert sorted(rows) == sorted(truth.ids)
    for i, row in rows.items():
        surveyed = [float(v) for v in row[30:54].split(",")]  # where the (noise-free) photos put it: the truth
        assert surveyed == pytest.approx(truth.placements[i].translation_mm, abs=0.5)
        assert int(row[78:84]) == counts[i]
        if i != 5:
            assert float(row[55:62]) == 0.0  # tape and photos agree exactly
            assert row[70:77].strip() == "-"
    assert rows[0].endswith("  fixed")
    assert rows[0][4:29].strip() == "0, 700, 1700"
    assert float(rows[0][63:69]) == 0.0
    assert rows[5][4:29].strip() == "-"
    assert rows[5][55:62].strip() == "-"
    assert rows[5].endswith("added from the photos")
    assert rows[1].endswith("  ")  # no note: the marker is well seen
    assert not s.table().endswith("\n")
