"""The limits and helpers the ``fidlearn`` command uses, under their public names, do what they say."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fidlearn
from fidlearn import FidlearnError, SurveyError, data_path, io
from fidlearn.grading import lms_path, read_roster
from fidlearn.planning import MAX_NOISE_PX, predict_accuracy
from fidlearn.survey import MAX_MAP_SIGMA_MM, MAX_PHOTOS, MIN_MAP_SIGMA_MM

WORLD = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAMERA = fidlearn.Camera.from_fov(60, (640, 480))
T = fidlearn.look_at([1200, 200, 250], [0, 200, 250])


def test_the_noise_limit_is_the_one_predictions_refuse_beyond():
    assert MAX_NOISE_PX == 100.0
    predict_accuracy(WORLD, CAMERA, T, corner_sigma_px=MAX_NOISE_PX)
    with pytest.raises(FidlearnError, match="up to 100"):
        predict_accuracy(WORLD, CAMERA, T, corner_sigma_px=MAX_NOISE_PX * 1.01)


def test_the_survey_limits_are_the_ones_survey_refuses_beyond():
    assert (MAX_PHOTOS, MIN_MAP_SIGMA_MM, MAX_MAP_SIGMA_MM) == (400, 0.01, 1e5)
    with pytest.raises(SurveyError, match=f"at most {MAX_PHOTOS} photos, got {MAX_PHOTOS + 1}"):
        fidlearn.survey([[]] * (MAX_PHOTOS + 1), WORLD, CAMERA)
    for sigma in (MIN_MAP_SIGMA_MM / 2, MAX_MAP_SIGMA_MM * 2):
        with pytest.raises(SurveyError, match="map_sigma_mm must be above 0, from 0.01 to 100000 mm"):
            fidlearn.survey([[], []], WORLD, CAMERA, map_sigma_mm=sigma)


def test_roster_and_gradebook_paths():
    assert read_roster(["# class A", "Alice", "", "Carol Smith"], "roster.txt") == ["alice", "carol_smith"]
    assert lms_path(Path("out") / "grades.csv", "canvas") == Path("out") / "grades.canvas.csv"
    assert lms_path("grades.csv", "moodle") == Path("grades.moodle.csv")


def test_staged_outputs_appear_together(tmp_path):
    with io.StagedOutputs() as outputs:
        assert io.current_outputs() is outputs
        io.write_json_atomic(tmp_path / "a.json", {"x": [1, 2]})
        io.atomic_write(tmp_path / "b.bin", lambda tmp: tmp.write_bytes(b"\x00\x01"))
        assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == []  # not yet
    assert (tmp_path / "a.json").read_text() == '{\n  "x": [\n    1,\n    2\n  ]\n}\n'
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.bin"]  # no temporary file left
    assert io.current_outputs() is None


def test_reading_is_bounded_and_pictures_are_sized_from_their_headers(tmp_path):
    (tmp_path / "big.txt").write_bytes(b"x" * 101)
    with pytest.raises(FidlearnError, match="big.txt"):
        io.read_bytes(tmp_path / "big.txt", FidlearnError, "note", 100)
    _, data = io.read_bytes(data_path("scenes", "scene_00.png"), FidlearnError, "picture", io.MAX_IMAGE_BYTES)
    assert io.image_size_from_header(data) == ("PNG", 1280, 720)
    assert io.read_json(data_path("scenes", "camera.json"), FidlearnError, "camera")["image_size"] == [1280, 720]
    assert np.isclose(io.MAX_IMAGE_PIXELS, 1e8)
