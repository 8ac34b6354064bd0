"""fidlearn.boards: the Board value, its checks, its text form, its points and OpenCV's board."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import Board, BoardError, CalibrationError, PrintError, data_path
from fidlearn._cv_charuco import charuco_detector, detect_charuco
from fidlearn.boards import parse_grid


def test_checkerboard_object_points_by_hand():
    board = Board.checkerboard((9, 6), square_size_mm=25)
    pts = board.object_points()
    assert pts.shape == (54, 3)
    # row by row, x along a row: point k is inner corner (k % 9, k // 9), 25 mm apart, z = 0
    assert pts[0].tolist() == [0.0, 0.0, 0.0]
    assert pts[1].tolist() == [25.0, 0.0, 0.0]
    assert pts[8].tolist() == [200.0, 0.0, 0.0]
    assert pts[9].tolist() == [0.0, 25.0, 0.0]
    assert pts[10].tolist() == [25.0, 25.0, 0.0]
    assert pts[53].tolist() == [200.0, 125.0, 0.0]
    assert board.squares == (10, 7)
    assert board.inner_corners == (9, 6)
    assert board.describe() == "checkerboard 9x6 inner corners, 25 mm squares"


def test_checkerboard_points_are_what_opencv_finds_on_a_real_photo():
    """OpenCV's right01.jpg: 9x6 inner corners; the points pair with the found corners one to one."""
    gray = cv2.imread(str(data_path("real", "opencv_checkerboard_right", "right01.jpg")), cv2.IMREAD_GRAYSCALE)
    board = Board.checkerboard("9x6", 25)
    ok, corners = cv2.findChessboardCorners(gray, board.inner_corners)
    assert ok
    assert len(corners) == len(board.object_points())


def test_charuco_points_ids_and_markers_as_opencv_gives_them():
    board = Board.charuco(squares=(5, 7), square_size_mm=36.195, marker_size_mm=18.256, dictionary="DICT_6X6_250")
    assert board.dictionary == "6X6_250"
    assert board.inner_corners == (4, 6)
    cv_board = board.cv_board()
    chess = np.asarray(cv_board.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
    # corner id i is object point i; the first chess corner is one square in from the board's outer corner
    np.testing.assert_allclose(board.object_points(), chess, atol=1e-4)
    np.testing.assert_allclose(board.object_points()[0], [36.195, 36.195, 0.0])
    np.testing.assert_allclose(board.object_points()[23], [4 * 36.195, 6 * 36.195, 0.0])
    # 17 markers, ids 0..16; marker 0 in the white square (1, 0), inset (36.195 - 18.256) / 2 = 8.9695 mm
    assert np.asarray(cv_board.getIds()).ravel().tolist() == list(range(17))
    first = np.asarray(cv_board.getObjPoints()[0], dtype=np.float64).reshape(4, 3)
    np.testing.assert_allclose(first[0], [36.195 + 8.9695, 8.9695, 0.0], atol=1e-4)
    np.testing.assert_allclose(first[2], [36.195 + 8.9695 + 18.256, 8.9695 + 18.256, 0.0], atol=1e-4)
    # the layout before OpenCV 4.6 (even row count): marker 0 in square (0, 0)
    legacy = Board.charuco((5, 6), 40, 20).cv_board(legacy=True)
    np.testing.assert_allclose(np.asarray(legacy.getObjPoints()[0]).reshape(4, 3)[0], [10.0, 10.0, 0.0])


def test_charuco_corner_ids_found_on_a_real_photo():
    """OpenCV's tutorial photo img_00.jpg (5x7 squares, 6X6_250): each found id pairs with its object point."""
    board = Board.charuco((5, 7), 40, 20)
    gray = cv2.imread(str(data_path("real", "opencv_charuco", "img_00.jpg")), cv2.IMREAD_GRAYSCALE)
    corners, ids, n_markers = detect_charuco(charuco_detector(board.cv_board()), gray)
    assert n_markers >= 10
    assert len(ids) >= 12
    assert set(ids.tolist()) <= set(range(24))
    obj, _ = board.cv_board().matchImagePoints(corners.reshape(-1, 1, 2).astype(np.float32), ids.reshape(-1, 1))
    np.testing.assert_allclose(np.asarray(obj).reshape(-1, 3), board.object_points()[ids], atol=1e-4)


@pytest.mark.parametrize(
    ("text", "counts", "kw", "squares", "kind"),
    [
        ("9x6", "inner", {}, (10, 7), "checkerboard"),
        (" 9 X 6 ", "inner", {}, (10, 7), "checkerboard"),
        ("5x7", "squares", {"marker_size_mm": 20}, (5, 7), "charuco"),
        ("4x6", "inner", {"charuco": True, "marker_size_mm": 20}, (5, 7), "charuco"),
    ],
)
def test_parse_the_command_line_form(text, counts, kw, squares, kind):
    board = Board.parse(text, 40, counts=counts, **kw)
    assert (board.squares, board.kind) == (squares, kind)


def test_parse_grid():
    assert parse_grid("640x480", "--size") == (640, 480)
    with pytest.raises(BoardError, match=r"--size '640' is not COLUMNSxROWS; write it like 9x6"):
        parse_grid("640", "--size")


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Board.checkerboard((9.5, 6), 25), r"two whole numbers .*e\.g\. \(9, 6\)"),
        (lambda: Board.checkerboard((1, 6), 25), r"at least 2x2 inner corners, got 1x6"),
        (lambda: Board.checkerboard((9, 6), 0), r"square_size_mm must be positive.*measure one printed square"),
        (lambda: Board.checkerboard((9, 6), "25"), r"must be a number of millimetres"),
        (lambda: Board.checkerboard((60, 60), 25), r"3600 inner corners, more than 2500"),
        (lambda: Board.charuco((5, 7), 40, 40), r"marker_size_mm \(40\) must be smaller than square_size_mm \(40\)"),
        (lambda: Board.charuco((20, 20), 10, 5, "4X4_50"), r"needs 200 markers but 4X4_50 has only 50"),
        (lambda: Board("charuco", (5, 7), 40), r"needs marker_size_mm \(command line: --marker-mm\)"),
        (lambda: Board("checkerboard", (10, 7), 25, 12), r"a checkerboard has no markers"),
        (lambda: Board("hexagon", (10, 7), 25), r"use Board.checkerboard"),
        (lambda: Board.parse("9x6", 25, dictionary="6X6_250"), r"give its marker size too"),
        (lambda: Board.checkerboard((9, 6), 25).cv_board(), r"a checkerboard has no cv2.aruco board"),
    ],
)
def test_bad_boards_say_how_to_mend(make, message):
    with pytest.raises(BoardError, match=message) as info:
        make()
    # the same board is calibrated with and printed: both families catch it
    assert isinstance(info.value, CalibrationError)
    assert isinstance(info.value, PrintError)


@pytest.mark.parametrize(
    "board",
    [
        Board.checkerboard((9, 6), 25),
        Board.checkerboard("3x2", 12.5),
        Board.charuco((5, 7), 36.195, 18.256),
        Board.charuco((8, 11), 15, 11, "APRILTAG_36h11"),
    ],
)
def test_a_board_is_read_back_from_its_description(board):
    assert Board.from_description(board.describe()) == board
    # a camera file's source names the board amid other words
    source = f"calibrate_charuco: 12 of 13 views of a {board.describe()}, legacy layout, RMS 0.210 px, OpenCV 4.10.0"
    assert Board.from_description(source) == board


@pytest.mark.parametrize(
    ("text", "error", "message"),
    [
        ("a board on the wall", BoardError, "names no board"),
        ("checkerboard 1x6 inner corners, 25 mm squares", BoardError, "at least 2x2 inner corners"),
        ("ChArUco 5x7 squares, 40 mm squares, 50 mm markers, 6X6_250", BoardError, "must be smaller"),
    ],
)
def test_a_description_that_names_no_board_says_so(text, error, message):
    with pytest.raises(error, match=message):
        Board.from_description(text)


def test_a_board_is_a_frozen_value():
    a, b = Board.checkerboard((9, 6), 25), Board("checkerboard", (10, 7), 25.0)
    assert a == b
    assert hash(a) == hash(b)
    with pytest.raises(AttributeError):
        a.square_size_mm = 30  # type: ignore[misc]
