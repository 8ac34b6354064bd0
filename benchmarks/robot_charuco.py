"""Real photos of a ChArUco board held by an industrial robot, and the board poses measured from them.

The data is ``data/real/robot_charuco`` (see data/README.md): 16 photos (1600x1200) from a static
camera, the robot's flange pose for each, the published intrinsics (no distortion). The board's
frame is OpenCV's ``CharucoBoard``'s: origin at its top-left outer corner, x along the first row of
squares, y down the board, z into it; mm. Every pose here is ``T_camera_board`` (mm).

Ways to measure a photo's board pose, all on the same camera:

* ``fidlearn``: :func:`fidlearn.estimate_pose` on the markers :func:`fidlearn.detect_markers`
  finds, against the board's markers as a marker map (what :func:`fidlearn.locate` does);
* ``opencv_markers``: plain ``cv2.solvePnP`` on the same marker corners (``SOLVEPNP_ITERATIVE`` or
  ``SOLVEPNP_IPPE``), what a user would write;
* ``fidlearn_entry``: :func:`fidlearn.locate` with the board as one ChArUco entry of the map, whose chess
  corners join the marker corners;
* ``charuco``: OpenCV's ChArUco chess corners (``CharucoDetector``, interpolated from the markers)
  and ``cv2.solvePnP``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

import fidlearn
from fidlearn import Camera, MarkerMap, frames
from fidlearn.calibration import calibrate_charuco, camera_with_uncertainty
from fidlearn.calibration.quality import MIN_GOOD_VIEWS
from fidlearn.data import data_path
from fidlearn.detection import detect_markers, load_image
from fidlearn.markermap_entries import BOARD_TO_WORLD
from fidlearn.planning.coach import intrinsics_information, uncertainty_map

from .handeye import invert, transform

SQUARES = (5, 7)
SQUARE_MM, MARKER_MM, DICTIONARY = 36.195, 18.256, "6X6_250"
FOLDER = "real/robot_charuco"
N_PHOTOS = 16
IMAGE_SIZE = (1600, 1200)
#: A marker's local axes (right, down, out of its face) are world +Y, -Z, +X in a ``MarkerMap``
#: at rotation 0; on the board they are +x, +y, -z.
R_BOARD_MARKER = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
#: The board's centre (its frame, mm), the point whose position error is reported.
CENTRE_MM = np.array([SQUARES[0] * SQUARE_MM / 2, SQUARES[1] * SQUARE_MM / 2, 0.0])
#: Fewest ChArUco corners for a calibration view or a ChArUco pose.
MIN_CORNERS = 6


@cache
def board() -> cv2.aruco.CharucoBoard:
    """The robot's board: 5 x 7 squares of 36.195 mm, 18.256 mm ``DICT_6X6_250`` markers (mm)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    return cv2.aruco.CharucoBoard(SQUARES, SQUARE_MM, MARKER_MM, dictionary)


def chess_corners_mm() -> np.ndarray:
    """The board's 24 chess corners (24, 3), its frame, mm."""
    return np.asarray(board().getChessboardCorners(), dtype=float).reshape(-1, 3)


def board_map() -> MarkerMap:
    """The board's 17 markers at their nominal places as a marker map in the board's frame (mm)."""
    b = board()
    corners = np.asarray(b.getObjPoints(), dtype=float).reshape(-1, 4, 3)
    rpy = [float(a) for a in frames.rpy_deg_from_rotation(R_BOARD_MARKER)]
    markers = {
        str(int(i)): {"translation": [float(v) for v in c[0]], "rotation": rpy}
        for i, c in zip(np.asarray(b.getIds()).ravel(), corners)
    }
    return MarkerMap.from_dict(
        {"units": "mm", "marker_size_mm": MARKER_MM, "dictionary": DICTIONARY, "markers": markers},
        source="robot ChArUco board 5x7",
    )


@cache
def board_entry_map() -> MarkerMap:
    """The board as one ChArUco entry of a map whose world is the board's frame (rotation: the board's axes)."""
    rpy = [float(v) for v in frames.rpy_deg_from_rotation(BOARD_TO_WORLD.T)]
    entry = {"type": "charuco", "translation": [0, 0, 0], "rotation": rpy, "squares": list(SQUARES)}
    entry.update(square_mm=SQUARE_MM, marker_mm=MARKER_MM, dictionary=DICTIONARY)
    return MarkerMap.from_dict(
        {"units": "mm", "marker_size_mm": MARKER_MM, "boards": {"robot": entry}}, source="robot ChArUco board entry"
    )


def _read_pairs(path) -> dict[str, float]:
    out = {}
    for line in path.read_text().splitlines():
        key, sep, value = line.partition(":")
        if sep and value.strip():
            try:
                out[key.strip()] = float(value)
            except ValueError:
                continue
    return out


def robot_pose(i: int) -> np.ndarray:
    """The robot's flange in its base for photo ``i`` (4, 4; metres in the file, mm here).

    Parameters
    ----------
    i : int
        Photo number, 0 to 15.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    v = _read_pairs(data_path(FOLDER, f"{i}.yaml"))
    R = Rotation.from_quat([v["qx"], v["qy"], v["qz"], v["qw"]]).as_matrix()
    return transform(R, 1000.0 * np.array([v["x"], v["y"], v["z"]]))


def published_camera() -> Camera:
    """The intrinsics published with the photos (``intrinsics`` in ``cal_data.yaml``), with no distortion."""
    v = _read_pairs(data_path(FOLDER, "cal_data.yaml"))
    K = [[v["fx"], 0.0, v["cx"]], [0.0, v["fy"], v["cy"]], [0.0, 0.0, 1.0]]
    return Camera(K, None, IMAGE_SIZE, source="published intrinsics (cal_data.yaml), no distortion")


@cache
def photo(i: int) -> np.ndarray:
    """Photo ``i`` as fidlearn reads it (grey, uint8: the set is stored grey)."""
    return load_image(data_path(FOLDER, f"{i}.png"))


def gray(i: int) -> np.ndarray:
    """Photo ``i`` in gray, as OpenCV's detectors see it."""
    image = photo(i)
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


@cache
def charuco_corners(i: int) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's ChArUco chess corners in photo ``i``: pixels (N, 2) and their ids (N,) (uncalibrated detector)."""
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board()).detectBoard(gray(i))
    if ids is None:
        return np.zeros((0, 2)), np.zeros(0, dtype=int)
    return np.asarray(corners, dtype=float).reshape(-1, 2), np.asarray(ids).ravel().astype(int)


@cache
def markers(i: int) -> tuple:
    """fidlearn's detections of the board's markers in photo ``i`` (default corner refinement)."""
    return tuple(detect_markers(photo(i), DICTIONARY, ids=list(range(17))))


def opencv_calibration(photos=range(N_PHOTOS)) -> tuple[Camera, float]:
    """A plain OpenCV calibration from the photos' ChArUco corners: the camera and its RMS (px).

    ``cv2.calibrateCamera`` with 5 distortion coefficients and no flags, on every photo with at
    least :data:`MIN_CORNERS` corners.
    """
    obj, img = [], []
    for i in photos:
        corners, ids = charuco_corners(i)
        if len(ids) >= MIN_CORNERS:
            obj.append(chess_corners_mm()[ids].astype(np.float32))
            img.append(corners.astype(np.float32))
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, IMAGE_SIZE, None, None)
    return Camera(K, np.ravel(dist), IMAGE_SIZE, source=f"cv2.calibrateCamera, {len(obj)} photos"), float(rms)


def fidlearn_calibration(photos=range(N_PHOTOS), with_uncertainty: bool = False) -> tuple[Camera, float]:
    """fidlearn's calibration from the photos (:func:`fidlearn.calibration.calibrate_charuco`) and its RMS (px);
    ``with_uncertainty``: the camera carries its intrinsics' covariance (``camera_with_uncertainty``)."""
    board_spec = fidlearn.Board.charuco(SQUARES, SQUARE_MM, MARKER_MM, DICTIONARY)
    result = calibrate_charuco([photo(i) for i in photos], board_spec, min_corners=MIN_CORNERS)
    camera = camera_with_uncertainty(result) if with_uncertainty else result.camera
    return camera, float(result.rms_px)


@cache
def _views_information() -> tuple:
    """fidlearn's calibration of every photo: its camera, RMS, each photo's information on the intrinsics (its
    board pose marginalised out, ``coach.intrinsics_information``) and the views' median distance (mm)."""
    board_spec = fidlearn.Board.charuco(SQUARES, SQUARE_MM, MARKER_MM, DICTIONARY)
    cal = calibrate_charuco([photo(i) for i in range(N_PHOTOS)], board_spec, min_corners=MIN_CORNERS)
    info = {
        int(name.split()[-1]): intrinsics_information(cal.camera, {name: cal.board_points_mm[name]}, {name: T})
        for name, T in cal.T_camera_board.items()
    }
    distance = float(np.median([np.linalg.norm(T[:3, 3]) for T in cal.T_camera_board.values()]))
    return cal.camera, cal.rms_px, info, distance


def predicted_uncertainty_px(photos) -> float:
    """The mean over the picture of fidlearn's predicted reprojection uncertainty (px per axis) of a calibration
    from ``photos`` (those with a calibration view): ``coach.uncertainty_map`` at the views' median distance, the
    covariance ``rms^2`` times the inverse of their summed information."""
    camera, rms, info, distance = _views_information()
    total = sum(info[i] for i in photos if i in info) + 1e-9 * np.eye(4 + len(camera.dist))
    return float(np.mean(uncertainty_map(camera, rms**2 * np.linalg.pinv(total), distance)))


def coached_photos(n: int = MIN_GOOD_VIEWS) -> list[int]:
    """``n`` photos chosen by fidlearn's own predicted uncertainty, the robot unused: one at a time, the photo that
    most lowers :func:`predicted_uncertainty_px` of those chosen before it."""
    usable = list(_views_information()[2])
    chosen: list[int] = []
    while len(chosen) < min(n, len(usable)):
        rest = [i for i in usable if i not in chosen]
        chosen.append(min(rest, key=lambda i: predicted_uncertainty_px([*chosen, i])))
    return sorted(chosen)


@dataclass(frozen=True)
class Measured:
    """One photo's board pose by one method.

    Attributes
    ----------
    T_camera_board : ndarray (4, 4) or None
        The pose (mm), None when the method found none.
    pose : fidlearn.Pose or None
        fidlearn's full result (covariance, rejected markers), for the fidlearn method only.
    n_points : int
        Corners the pose was computed from.
    """

    T_camera_board: np.ndarray | None
    pose: object = None
    n_points: int = 0


def fidlearn_pose(i: int, camera: Camera, **kw) -> Measured:
    """fidlearn's pose of the board in photo ``i`` (:func:`fidlearn.estimate_pose`, keywords passed on)."""
    try:
        pose = fidlearn.estimate_pose(list(markers(i)), board_map(), camera, **kw)
    except fidlearn.FidlearnError:
        return Measured(None)
    return Measured(invert(pose.T_world_camera), pose, 4 * len(pose.marker_ids))


def fidlearn_entry_pose(i: int, camera: Camera) -> Measured:
    """:func:`fidlearn.locate` of photo ``i`` with the board as a ChArUco map entry (its chess corners used)."""
    try:
        pose = fidlearn.locate(photo(i), board_entry_map(), camera)
    except fidlearn.FidlearnError:
        return Measured(None)
    return Measured(invert(pose.T_world_camera), pose, 4 * len(pose.marker_ids))


def _solve(obj: np.ndarray, img: np.ndarray, camera: Camera, flag: int) -> Measured:
    dist = np.zeros(5) if camera.dist is None else camera.dist
    ok, rvec, tvec = cv2.solvePnP(obj, img, camera.K, dist, flags=flag)
    if not ok:
        return Measured(None)
    return Measured(transform(cv2.Rodrigues(rvec)[0], tvec), None, len(obj))


def opencv_marker_pose(i: int, camera: Camera, flag: int = cv2.SOLVEPNP_ITERATIVE) -> Measured:
    """Plain ``cv2.solvePnP`` on the marker corners fidlearn detected in photo ``i``."""
    found = [d for d in markers(i) if 0 <= d.id < 17]
    if not found:
        return Measured(None)
    objp = np.asarray(board().getObjPoints(), dtype=float).reshape(-1, 4, 3)
    obj = np.concatenate([objp[d.id] for d in found])
    img = np.concatenate([np.asarray(d.corners_px, dtype=float) for d in found])
    return _solve(obj, img, camera, flag)


def charuco_pose(i: int, camera: Camera) -> Measured:
    """OpenCV's ChArUco-corner pose of photo ``i``: interpolated chess corners and ``cv2.solvePnP``."""
    corners, ids = charuco_corners(i)
    if len(ids) < MIN_CORNERS:
        return Measured(None, None, len(ids))
    return _solve(chess_corners_mm()[ids], corners, camera, cv2.SOLVEPNP_ITERATIVE)
