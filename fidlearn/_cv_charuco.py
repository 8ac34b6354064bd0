"""OpenCV's ChArUco board and detector, the same from OpenCV 4.8 to 5.x (see :mod:`fidlearn._cv`).

``cv2.aruco.calibrateCameraCharuco`` is gone: the corners come from ``cv2.aruco.CharucoDetector``,
whose ``detectBoard`` returns ``None`` for nothing found and ids shaped (N, 1) before OpenCV 5,
(N,) from 5.0; these helpers always give arrays.
"""

from __future__ import annotations

import numpy as np

from ._cv import _ARUCO, get_dictionary, require_aruco

__all__ = ["charuco_board", "charuco_detector", "detect_charuco", "interpolate_charuco"]


def charuco_board(
    squares_xy: tuple[int, int], square_size: float, marker_size: float, dictionary: str, legacy: bool = False
):
    """A ``cv2.aruco.CharucoBoard``; ``legacy=True`` for boards made before OpenCV 4.6 with an even row count.

    Parameters
    ----------
    squares_xy : (int, int)
        Squares along x and y.
    square_size, marker_size : float
        Side of a chess square and of a marker (any unit, the same for both; fidlearn uses mm).
    dictionary : str
        The markers' dictionary.
    legacy : bool
        The marker layout of OpenCV before 4.6.

    Returns
    -------
    cv2.aruco.CharucoBoard
    """
    require_aruco()
    board = _ARUCO.CharucoBoard(
        tuple(int(v) for v in squares_xy), float(square_size), float(marker_size), get_dictionary(dictionary)
    )
    if legacy:
        board.setLegacyPattern(True)
    return board


def charuco_detector(board):
    """A ``cv2.aruco.CharucoDetector`` for a board.

    Parameters
    ----------
    board : cv2.aruco.CharucoBoard

    Returns
    -------
    cv2.aruco.CharucoDetector
    """
    require_aruco()
    return _ARUCO.CharucoDetector(board)


def detect_charuco(detector, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Run a ``CharucoDetector``: chess corners (N, 2) float64 px, their ids (N,) int64, and how many markers were seen.

    ``detectBoard`` returns ``None`` for nothing found and ids shaped (N, 1)
    before OpenCV 5, (N,) from 5.0; this always gives arrays.

    Parameters
    ----------
    detector : cv2.aruco.CharucoDetector
    gray : ndarray, shape (H, W), uint8

    Returns
    -------
    corners : ndarray, shape (N, 2), float64
        Chess corners, pixels.
    ids : ndarray, shape (N,), int64
        Their ids on the board.
    n_markers : int
        Markers seen.
    """
    corners, ids, _marker_corners, marker_ids = detector.detectBoard(gray)
    n_markers = 0 if marker_ids is None else int(np.asarray(marker_ids).size)
    if ids is None or corners is None or len(corners) == 0:
        return np.zeros((0, 2)), np.zeros((0,), dtype=np.int64), n_markers
    return (
        np.asarray(corners, dtype=np.float64).reshape(-1, 2),
        np.asarray(ids).reshape(-1).astype(np.int64),
        n_markers,
    )


def interpolate_charuco(board, gray: np.ndarray, marker_corners: list, marker_ids) -> tuple[np.ndarray, np.ndarray]:
    """A ChArUco board's chess corners interpolated from markers already detected, refined on the image.

    ``CharucoDetector.detectBoard`` with the markers given (it then detects none itself): the same call on
    OpenCV 4.8 to 5.x; its ids shaped (N, 1) before 5.0 and (N,) from 5.0, ``None`` for none.

    Parameters
    ----------
    board : cv2.aruco.CharucoBoard
    gray : ndarray, shape (H, W), uint8
    marker_corners : list of ndarray, shape (4, 2)
        The board's detected markers, pixels, TL, TR, BR, BL.
    marker_ids : sequence of int
        Their ids.

    Returns
    -------
    corners : ndarray, shape (N, 2), float64
        Chess corners, pixels.
    ids : ndarray, shape (N,), int64
        Their ids on the board.
    """
    require_aruco()
    if not len(marker_corners):
        return np.zeros((0, 2)), np.zeros((0,), dtype=np.int64)
    mc = [np.asarray(c, dtype=np.float32).reshape(1, 4, 2) for c in marker_corners]
    mi = np.asarray(marker_ids, dtype=np.int32).reshape(-1, 1)
    corners, ids, _, _ = _ARUCO.CharucoDetector(board).detectBoard(gray, markerCorners=mc, markerIds=mi)
    if ids is None or corners is None or len(corners) == 0:
        return np.zeros((0, 2)), np.zeros((0,), dtype=np.int64)
    return np.asarray(corners, dtype=np.float64).reshape(-1, 2), np.asarray(ids).reshape(-1).astype(np.int64)
