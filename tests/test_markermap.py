"""World map: the seed's known corners, walls and floors, file layouts, and every map mistake."""

import json

import numpy as np
import pytest

from fidlearn import MarkerMap
from fidlearn.data import data_path
from fidlearn.errors import MapError

SEED_BARE = {
    "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
    "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
    "2": {"translation": [0, 0.5, 0.75], "rotation": [0, 0, 0]},
}


def corners_of(placement, units="mm", size=80):
    return MarkerMap.from_dict({"7": placement}, units=units, marker_size_mm=size).corners()[7]


def test_seed_example_in_feet():
    m = MarkerMap.from_dict(SEED_BARE, units="ft", marker_size_mm=80)
    assert m.corners()[0].tolist() == [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]]
    assert np.allclose(m.corners()[2][0], [0, 152.4, 228.6])
    assert m.is_coplanar()


def test_shipped_world_map_is_the_seed_example():
    m = MarkerMap.load(data_path("world_map.json"))
    assert (m.units, m.marker_size_mm, m.dictionary, m.ids) == ("ft", 80.0, "ARUCO_ORIGINAL", [0, 1, 2])
    assert m.corners()[0].tolist() == [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]]
    assert np.allclose(m.corners()[2][0], [0, 152.4, 228.6])


def test_south_wall_yaw_180_runs_tr_to_minus_y():
    c = corners_of({"translation": [3000, 500, 1000], "rotation": [0, 0, 180]})
    assert c.tolist() == [[3000, 500, 1000], [3000, 420, 1000], [3000, 420, 920], [3000, 500, 920]]


def test_pitch_minus_90_lies_on_the_floor_facing_up():
    m = MarkerMap.from_dict(
        {"5": {"translation": [1000, 0, 0], "rotation": [0, -90, 0]}}, units="mm", marker_size_mm=80
    )
    c = m.corners()[5]
    assert np.allclose(c[:, 2], 0)  # all four corners on the floor
    assert np.allclose(m.normal(5), [0, 0, 1])  # printed face looks up
    # TL -> TR still runs along +Y; "down the marker" (TL -> BL) now runs along +X
    assert np.allclose(c, [[1000, 0, 0], [1000, 80, 0], [1080, 80, 0], [1080, 0, 0]])


def test_default_rotation_faces_plus_x_and_square_has_the_stated_side():
    m = MarkerMap.from_dict({"3": {"translation": [0, 100, 500]}}, units="mm", marker_size_mm=150)
    c = m.corners()[3]
    sides = np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1)
    assert np.allclose(sides, 150)
    assert np.allclose(m.normal(3), [1, 0, 0])
    T = m.T_world_marker(3)
    assert np.allclose(T[:3, 3], c.mean(axis=0))


@pytest.mark.parametrize(("units", "factor"), [("mm", 1), ("cm", 10), ("m", 1000), ("in", 25.4), ("ft", 304.8)])
def test_units(units, factor):
    c = corners_of({"translation": [1, 2, 3], "rotation": [0, 0, 0]}, units=units)
    assert np.allclose(c[0], np.array([1, 2, 3]) * factor)


def test_two_walls_are_not_coplanar():
    d = dict(SEED_BARE)
    d["9"] = {"translation": [1, 0, 1], "rotation": [0, 0, 90]}  # on the side wall at y = 0, facing +Y
    m = MarkerMap.from_dict(d, units="ft", marker_size_mm=80)
    assert not m.is_coplanar()
    assert m.planarity_mm() > 50


def test_full_layout_round_trip(tmp_path):
    m = MarkerMap.from_dict(SEED_BARE, units="ft", marker_size_mm=80, dictionary="DICT_ARUCO_ORIGINAL")
    path = m.save(tmp_path / "map.json")
    m2 = MarkerMap.load(path)
    assert m2.units == "ft"
    assert m2.dictionary == "ARUCO_ORIGINAL"
    for i in m.ids:
        assert np.allclose(m.corners()[i], m2.corners()[i])


def test_save_corners_writes_the_seed_corner_layout(tmp_path):
    m = MarkerMap.from_dict(SEED_BARE, units="ft", marker_size_mm=80)
    out = m.save_corners(tmp_path / "corners.json")
    d = json.loads(out.read_text())
    assert list(d) == ["0", "1", "2"]
    assert d["0"] == [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]]


def test_bare_layout_loads_from_file_with_caller_units(tmp_path):
    p = tmp_path / "seed.json"
    p.write_text(json.dumps(SEED_BARE))
    m = MarkerMap.load(p, units="ft", marker_size_mm=80)
    assert m.ids == [0, 1, 2]


def write(tmp_path, text, name="map.json"):
    p = tmp_path / name
    p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
    return p


@pytest.mark.parametrize(
    ("text", "kwargs", "message"),
    [
        (
            '{"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},',
            {},
            r"map.json: invalid JSON at line 1, column \d+",
        ),
        (
            '{"0": {"translation": [0,0,1]}, "0": {"translation": [1,1,1]}}',
            dict(units="ft", marker_size_mm=80),
            'key "0" appears twice',
        ),
        (
            '{"a": {"translation": [0, 0, 1]}}',
            dict(units="ft", marker_size_mm=80),
            "marker id 'a' is not a whole number",
        ),
        (
            '{"1.5": {"translation": [0, 0, 1]}}',
            dict(units="ft", marker_size_mm=80),
            "marker id '1.5' is not a whole number",
        ),
        ('{"-1": {"translation": [0, 0, 1]}}', dict(units="ft", marker_size_mm=80), "marker id -1 is negative"),
        (
            '{"0": {"translation": [0, 1]}}',
            dict(units="ft", marker_size_mm=80),
            r"marker 0: translation has 2 values, expected 3 \[x, y, z\] in ft",
        ),
        (
            '{"3": {"translation": [0, 0, 1], "rotation": [0, 90]}}',
            dict(units="ft", marker_size_mm=80),
            r"marker 3: rotation has 2 values, expected 3 \[roll, pitch, yaw\] in degrees",
        ),
        (
            '{"0": {"translation": [0, NaN, 1]}}',
            dict(units="ft", marker_size_mm=80),
            "contains NaN, which is not a number",
        ),
        ('{"0": {"translation": [0, Infinity, 1]}}', dict(units="ft", marker_size_mm=80), "contains Infinity"),
        ('{"0": {"translation": [0, 1e400, 1]}}', dict(units="ft", marker_size_mm=80), "expected finite numbers"),
        (
            '{"0": {"translation": [0, "1", 1]}}',
            dict(units="ft", marker_size_mm=80),
            "contains '1', which is not a number",
        ),
        (
            '{"units": "yards", "marker_size_mm": 80, "markers": {"0": {"translation": [0, 0, 1]}}}',
            {},
            "unknown units 'yards'; use one of mm, cm, m, in, ft",
        ),
        ('{"0": {"translation": [0, 0, 1]}}', dict(marker_size_mm=80), "no units: .* fidlearn never guesses"),
        ('{"units": "ft", "markers": {"0": {"translation": [0, 0, 1]}}}', {}, "no marker size"),
        (
            '{"units": "ft", "marker_size_mm": 0, "markers": {"0": {"translation": [0, 0, 1]}}}',
            {},
            "marker_size_mm is 0; it must be positive",
        ),
        (
            '{"units": "ft", "marker_size_mm": -80, "markers": {"0": {"translation": [0, 0, 1]}}}',
            {},
            "marker_size_mm is -80; it must be positive",
        ),
        (
            '{"units": "ft", "marker_size_mm": 80, "dictionary": "ARUCO_BOGUS", '
            '"markers": {"0": {"translation": [0, 0, 1]}}}',
            {},
            "unknown ArUco dictionary 'ARUCO_BOGUS'",
        ),
        (
            '{"units": "ft", "marker_size_mm": 80, "dictionary": "4X4_50", '
            '"markers": {"77": {"translation": [0, 0, 1]}}}',
            {},
            "marker id 77 does not exist in dictionary 4X4_50, which has ids 0 to 49",
        ),
        ('{"units": "ft", "marker_size_mm": 80, "markers": {}}', {}, "the map has no markers"),
        (
            '{"units": "ft", "marker_size_mm": 80, "markers": {"0": {"translation": [0, 0, 1]}}}',
            dict(units="m"),
            "the file says units = 'ft' but 'm' was given",
        ),
        (
            '{"0": {"translation": [0, 0, 1], "rotaton": [0, 0, 0]}}',
            dict(units="ft", marker_size_mm=80),
            "unknown field 'rotaton'",
        ),
        ('{"0": {"rotation": [0, 0, 0]}}', dict(units="ft", marker_size_mm=80), 'no "translation"'),
        ("[1, 2, 3]", dict(units="ft", marker_size_mm=80), "expected a JSON object"),
        ("", {}, "the file is empty"),
        (b"\xff\xfe\x00garbage", {}, "not UTF-8 text"),
    ],
)
def test_map_errors_name_the_file_the_field_and_the_fix(tmp_path, text, kwargs, message):
    p = write(tmp_path, text)
    with pytest.raises(MapError, match=message) as info:
        MarkerMap.load(p, **kwargs)
    assert str(p) in str(info.value)


def test_missing_map_file(tmp_path):
    with pytest.raises(MapError, match="no such file"):
        MarkerMap.load(tmp_path / "nope.json", units="ft", marker_size_mm=80)


def test_numpy_numbers_are_numbers():
    m = MarkerMap.from_dict(
        {"4": {"translation": list(np.array([0.0, 1.0, 2.0])), "rotation": [np.int64(0), 0, np.float32(90)]}},
        units="m",
        marker_size_mm=np.int64(40),
    )
    assert m.marker_size_mm == 40.0
    assert np.allclose(m.corners()[4][0], [0, 1000, 2000])


def test_camera_file_given_as_the_map_says_so():
    # A camera file has no "units": the error said "no units", which sends the user to edit the
    # wrong file. Swapped --camera/--map is the commonest slip on the command line.
    with pytest.raises(MapError, match=r"camera.json: this is a camera file \(it has camera_matrix\), not a world map"):
        MarkerMap.load(data_path("scenes", "camera.json"))


def test_corner_file_given_as_the_map_says_so(tmp_path):
    corners = tmp_path / "corners.json"
    MarkerMap.load(data_path("world_map.json")).save_corners(corners)
    with pytest.raises(MapError, match=r"corners.json: this is a corner file .* not a world map"):
        MarkerMap.load(corners)
    with pytest.raises(MapError, match=r"this is a corner file"):
        MarkerMap.load(corners, units="mm", marker_size_mm=80)


def test_marker_size_in_metres_is_refused():
    # "marker_size_mm": 0.08 (metres, as OpenCV's tutorials write sizes) loaded as 0.08 mm
    # markers and put every pose 1000 times too close.
    with pytest.raises(MapError, match=r"marker_size_mm is 0.08, under 1 mm; if that is metres, write it in mm \(80\)"):
        MarkerMap.from_dict({"units": "m", "marker_size_mm": 0.08, "markers": {"0": {"translation": [0, 0, 1]}}})
    assert MarkerMap.from_dict({"0": {"translation": [0, 0, 1]}}, units="m", marker_size_mm=1).marker_size_mm == 1
