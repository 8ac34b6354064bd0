"""A beginner's first hour on the command line: the usual mistakes each get a message that names the fix."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import frames
from fidlearn.detection import dictionaries_in
from fidlearn.synthetic import render_scene
from tests.helpers import run_cli

CAMERA = fidlearn.data_path("scenes", "camera.json")
MAP = fidlearn.data_path("world_map.json")


def _map_of(dictionary: str) -> fidlearn.MarkerMap:
    d = json.loads(MAP.read_text())
    d["dictionary"] = dictionary
    return fidlearn.MarkerMap.from_dict(d)


def _scene(path, dictionary: str) -> None:
    """The bundled map's markers printed from ``dictionary``, seen from 1 m in front of the wall."""
    camera = fidlearn.Camera.load(CAMERA)
    pose = frames.look_at([1000, 190, 230], [0, 190, 230])
    cv2.imwrite(str(path), render_scene(_map_of(dictionary), camera, pose).image)


def test_photo_of_4x4_markers_with_a_map_of_original_markers_names_the_dictionary(tmp_path, capsys):
    _scene(tmp_path / "wall.png", "4X4_50")
    code, out, err = run_cli(capsys, "locate", tmp_path / "wall.png", "--camera", CAMERA, "--map", MAP)
    assert code == 0
    assert "no known marker" in out
    assert err.count("warning: ") == 1, err
    assert "4X4_50: ids 0, 1, 2" in err
    assert '"dictionary": "4X4_50"' in err
    assert "--dictionary 4X4_50" in err


def test_a_picture_with_the_maps_markers_gets_no_dictionary_warning(tmp_path, capsys):
    blank = np.full((720, 1280), 200, np.uint8)
    cv2.imwrite(str(tmp_path / "blank.png"), blank)
    _scene(tmp_path / "wall.png", "ARUCO_ORIGINAL")
    code, out, err = run_cli(
        capsys, "locate", tmp_path / "blank.png", tmp_path / "wall.png", "--camera", CAMERA, "--map", MAP
    )
    assert code == 0
    assert err == ""
    assert "1 located" in out


def test_dictionaries_in_names_the_smallest_dictionary_of_the_family(tmp_path):
    _scene(tmp_path / "wall.png", "6X6_250")
    image = fidlearn.detection.load_image(tmp_path / "wall.png")
    assert dictionaries_in(image, exclude="ARUCO_ORIGINAL") == {"6X6_50": [0, 1, 2]}
    assert dictionaries_in(image, exclude=["6X6_1000"]) == {}


@pytest.mark.parametrize("exclude", ["NO_SUCH", ["4X4_50", "5x5"]])
def test_dictionaries_in_refuses_an_unknown_name(exclude):
    with pytest.raises(fidlearn.FidlearnError, match="dictionary"):
        dictionaries_in(np.zeros((50, 50), np.uint8), exclude=exclude)


def _write_map(path, rotations, **extra) -> None:
    markers = {str(k): {"translation": [0, k, 1], "rotation": r} for k, r in enumerate(rotations)}
    path.write_text(json.dumps({"units": "ft", "marker_size_mm": 80, "markers": markers, **extra}))


def test_rotation_in_radians_is_named_with_its_degrees(tmp_path, capsys):
    _write_map(tmp_path / "map.json", [[0, 0, 1.57], [0, 0, 3.1416]])
    code, out, err = run_cli(capsys, "corners", tmp_path / "map.json", "-o", tmp_path / "corners.json")
    assert code == 0
    assert "corners of 2 markers" in out
    assert err.count("warning: ") == 1, err
    assert "[0, 0, 1.57] and 1 more looks like radians" in err
    assert "write [0, 0, 90]" in err


@pytest.mark.parametrize(
    "rotations",
    [[[0, 0, 90], [0, -90, 0], [0, 0, 180]], [[0.5, 0, 90], [2, 0, 0]], [[0.0003, 0.0002, 0.0001]], [[0, 0, 1.6]]],
)
def test_rotations_in_degrees_are_not_taken_for_radians(tmp_path, rotations):
    _write_map(tmp_path / "map.json", rotations)
    fidlearn.MarkerMap.load(tmp_path / "map.json")  # FidlearnWarning is an error in the tests


def test_a_surveyed_map_may_hold_any_small_tilt(tmp_path):
    _write_map(tmp_path / "map.json", [[0, 0, 1.57]], surveyed={"photos": 20})
    fidlearn.MarkerMap.load(tmp_path / "map.json")
    _write_map(tmp_path / "map.json", [[0, 0, 1.57]])
    with pytest.warns(fidlearn.FidlearnWarning, match="looks like radians"):
        fidlearn.MarkerMap.load(tmp_path / "map.json")


def test_other_dictionaries_are_searched_once_a_run(tmp_path, capsys, monkeypatch):
    import fidlearn.detection as detection

    searched = []
    real = detection.detect_markers

    def counting(image, dictionary="ARUCO_ORIGINAL", *args, **kw):
        searched.append(dictionary)
        return real(image, dictionary, *args, **kw)

    monkeypatch.setattr(detection, "detect_markers", counting)
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"blank_{k}.png"), np.full((720, 1280), 200, np.uint8))
    code, out, err = run_cli(capsys, "locate", tmp_path, "--camera", CAMERA, "--map", MAP)
    assert code == 0
    assert out.count("no known marker") == 3
    assert err == ""
    assert sorted(searched) == sorted(n for n in detection._FAMILIES if n != "ARUCO_ORIGINAL")
