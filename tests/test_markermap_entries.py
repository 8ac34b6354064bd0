"""Boards and bundles as rigid entries of a world map: their corners, the file round trip, the bad entries."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import FidlearnError, MarkerMap
from fidlearn.errors import MapError
from fidlearn.markermap import BoardEntry, BundleEntry, MarkerKey, MarkerPlacement

CHARUCO = {
    "type": "charuco",
    "translation": [0, 100, 1000],
    "rotation": [0, 0, 0],
    "squares": [5, 7],
    "square_mm": 40,
    "marker_mm": 20,
    "dictionary": "6X6_250",
    "first_id": 10,
}
GRID = {
    "type": "grid",
    "translation": [0, -600, 1000],
    "rotation": [0, 0, 180],
    "markers": [3, 2],
    "marker_mm": 50,
    "separation_mm": 10,
    "dictionary": "4X4_50",
}
DOCK = {
    "translation": [500, 0, 0],
    "rotation": [0, 0, 90],
    "markers": {"4X4_50:30": {"translation": [0, 10, 20], "size_mm": 50}, "5": {"translation": [0, 100, 20]}},
}


def full_map(**extra) -> dict:
    d = {"units": "mm", "marker_size_mm": 80, "markers": {"0": {"translation": [0, 0, 0]}}}
    d.update(extra)
    return d


def test_charuco_board_markers_and_chess_corners_are_opencvs_geometry_in_the_world():
    m = MarkerMap.from_dict(full_map(boards={"table": CHARUCO}))
    board = cv2.aruco.CharucoBoard((5, 7), 40, 20, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    obj = np.asarray(board.getObjPoints()).reshape(-1, 4, 3)
    # rotation 0: board x -> world +Y, board y -> world -Z, from the board's top-left corner
    for k in range(17):
        x, y = obj[k, :, 0], obj[k, :, 1]
        expected = np.column_stack([np.zeros(4), 100 + x, 1000 - y])
        np.testing.assert_allclose(m.corners()[MarkerKey(10 + k, "6X6_250")], expected, atol=1e-9)
    chess = m.chess_corners()["table"]
    assert chess.shape == (24, 3)
    np.testing.assert_allclose(chess[0], [0, 140, 960])  # the first inner corner, one square in each way
    np.testing.assert_allclose(chess[5], [0, 180, 920])  # 4 corners a row: corner 5 is the second of row 2
    assert len(m) == 18
    assert m.owner[MarkerKey(10, "6X6_250")] == "table"
    assert 0 not in m.owner


def test_grid_board_yaw_180_faces_minus_x():
    m = MarkerMap.from_dict(full_map(boards={"grid": GRID}))
    c = m.corners()[MarkerKey(1, "4X4_50")]  # second marker of the first row: 60 mm along the board's x
    np.testing.assert_allclose(c, [[0, -660, 1000], [0, -710, 1000], [0, -710, 950], [0, -660, 950]], atol=1e-9)
    np.testing.assert_allclose(m.normal(MarkerKey(1, "4X4_50")), [-1, 0, 0], atol=1e-12)
    assert m.chess_corners() == {}


def test_bundle_markers_placed_by_the_bundles_pose():
    m = MarkerMap.from_dict(full_map(bundles={"dock": DOCK}))
    # yaw 90: the bundle's +Y is world -X; marker 30's top-left at (0, 10, 20) in the bundle
    np.testing.assert_allclose(
        m.corners()[MarkerKey(30, "4X4_50")], [[490, 0, 20], [440, 0, 20], [440, 0, -30], [490, 0, -30]], atol=1e-9
    )
    np.testing.assert_allclose(m.corners()[5][0], [400, 0, 20], atol=1e-9)
    assert m.marker_size(5) == 80  # no size of its own: the map's
    assert isinstance(m.entries["dock"], BundleEntry)


def test_round_trip_keeps_entries_and_corners(tmp_path):
    m = MarkerMap.from_dict(
        full_map(units="cm", boards={"table": {**CHARUCO, "legacy": True}, "grid": GRID}, bundles={"dock": DOCK})
    )
    path = m.save(tmp_path / "map.json")
    back = MarkerMap.load(path)
    assert back.to_dict() == m.to_dict()
    assert list(back.to_dict()["markers"]) == ["0"]  # the entries' markers are written in their entries only
    assert set(back.entries) == {"table", "grid", "dock"}
    assert back.entries["table"].legacy
    for key, c in m.corners().items():
        np.testing.assert_allclose(back.corners()[key], c, atol=1e-9)
    np.testing.assert_allclose(back.chess_corners()["table"], m.chess_corners()["table"])
    assert isinstance(back.entries["grid"], BoardEntry)
    assert back.entries["grid"].separation_mm == 10


def test_legacy_pattern_moves_the_markers_of_an_even_row_board():
    square = {**CHARUCO, "squares": [5, 6]}
    new = MarkerMap.from_dict(full_map(boards={"b": square})).corners()
    old = MarkerMap.from_dict(full_map(boards={"b": {**square, "legacy": True}})).corners()
    assert not np.allclose(new[MarkerKey(10, "6X6_250")], old[MarkerKey(10, "6X6_250")])


def test_a_board_alone_needs_no_single_markers():
    m = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 20, "boards": {"table": CHARUCO}})
    assert len(m) == 17
    assert m.is_coplanar()


@pytest.mark.parametrize(
    ("entries", "words"),
    [
        ({"boards": {"b": {**CHARUCO, "first_id": 0, "dictionary": "ARUCO_ORIGINAL"}}}, "is also a single marker"),
        ({"boards": {"b": CHARUCO, "c": {**CHARUCO, "first_id": 20}}}, "also entry 'b'"),
        ({"boards": {"b": {**CHARUCO, "dictionary": "6X6_999"}}}, "unknown ArUco dictionary"),
        ({"boards": {"b": {**CHARUCO, "squares": [2, 7]}}}, "each at least 3"),
        ({"boards": {"b": {**CHARUCO, "squares": [5.5, 7]}}}, "two whole numbers"),
        ({"boards": {"b": {**CHARUCO, "marker_mm": 40}}}, "must be smaller than square_mm"),
        ({"boards": {"b": {**CHARUCO, "first_id": 240}}}, "lower first_id"),
        ({"boards": {"b": {**CHARUCO, "type": "april"}}}, '"charuco" or "grid"'),
        ({"boards": {"b": {**CHARUCO, "type": ["charuco"]}}}, '"charuco" or "grid"'),
        ({"boards": {"b": {**CHARUCO, "marker_mm": 10**400}}}, "marker_mm must be a positive length"),
        ({"boards": {"b": {**CHARUCO, "squars": [5, 7]}}}, "did you mean"),
        ({"boards": {"b": {**GRID, "separation_mm": -1}}}, "separation_mm"),
        ({"bundles": {"d": {**DOCK, "markers": {}}}}, "its markers in its own frame"),
        ({"bundles": {"d": DOCK}, "boards": {"d": CHARUCO}}, "used twice"),
        ({"bundles": {"d": {**DOCK, "markers": {"0": {"translation": [0, 0, 0]}}}}}, "is also a single marker"),
    ],
)
def test_bad_entries_say_how_to_mend_them(entries, words):
    with pytest.raises(MapError, match=words) as info:
        MarkerMap.from_dict(full_map(**entries), source="room.json")
    assert isinstance(info.value, FidlearnError)
    assert "room.json" in str(info.value)


@pytest.mark.parametrize(
    ("entry", "words"),
    [
        (BoardEntry("g", "grid", (0, 0, 0), (0, 0, 0), (2, 2), 40.0, "4X4_50"), "separation_mm must be a positive"),
        (BoardEntry("c", "charuco", (0, 0, 0), (0, 0, 0), (5, 5), 40.0, "4X4_50", 30.0), "must be smaller than"),
    ],
)
def test_a_board_made_in_python_is_checked_as_a_files_is(entry, words):
    """It raised a bare AssertionError (no separation) or OpenCV's SystemError (a marker bigger than its square)."""
    with pytest.raises(MapError, match=words):
        MarkerMap({0: MarkerPlacement(0, (0, 0, 0), (0, 0, 0))}, 80, entries=[entry])


def test_an_empty_dictionary_name_is_refused_not_taken_for_the_default():
    with pytest.raises(MapError, match="dictionary name '' is not a non-empty string"):
        MarkerMap.from_dict(
            {"units": "mm", "marker_size_mm": 80, "dictionary": "", "markers": {"0": {"translation": [0, 0, 0]}}}
        )


def test_two_entries_of_one_name_are_refused_in_python_as_in_a_file():
    """The constructor keys entries by name: a second entry of the same name would drop the first's markers."""
    dock = BundleEntry("dock", (0, 0, 0), (0, 0, 0), (MarkerPlacement(1, (0, 0, 0), (0, 0, 0)),))
    other = BundleEntry("dock", (500, 0, 0), (0, 0, 0), (MarkerPlacement(2, (0, 0, 0), (0, 0, 0)),))
    single = {0: MarkerPlacement(0, (0, 0, 0), (0, 0, 0))}
    with pytest.raises(MapError, match="two boards or bundles are named 'dock'"):
        MarkerMap(single, 80, entries=[dock, other])
    assert MarkerMap(single, 80, entries=[dock]).ids == [0, 1]
