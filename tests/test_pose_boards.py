"""The pose with a ChArUco board entry: its chess corners join the marker corners (known answers)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, MarkerMap, estimate_pose, locate
from fidlearn.detection import Detection
from fidlearn.errors import PoseError
from fidlearn.synthetic import render_scene

BOARD = {
    "type": "charuco",
    "translation": [0, 0, 1000],
    "rotation": [0, 0, 0],
    "squares": [5, 7],
    "square_mm": 40,
    "marker_mm": 28,
    "dictionary": "6X6_250",
}
CAMERA = Camera.from_fov(60, (1280, 960))


def board_map() -> MarkerMap:
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": 28, "boards": {"table": BOARD}})


def look_at(C, target) -> np.ndarray:
    """T_world_camera of a camera at ``C`` looking at ``target``, image y towards world -Z."""
    z = np.subtract(target, C) / np.linalg.norm(np.subtract(target, C))
    x = np.cross([0.0, 0.0, -1.0], z)
    x /= np.linalg.norm(x)
    return fidlearn.make_transform(np.column_stack([x, np.cross(z, x), z]), C)


def render(
    m: MarkerMap, T_world_camera: np.ndarray, seed: int = 0, printed=None, noise_gray: float = 1.5
) -> np.ndarray:
    """The board entry seen by CAMERA: OpenCV's board image warped by the known homography (3x supersampled).

    ``printed``: the board as printed (an OpenCV board of the same squares), when it differs from the entry's.
    """
    entry = m.entries["table"]
    px_per_mm = 5
    W, H = 5 * 40 * px_per_mm, 7 * 40 * px_per_mm
    image = (printed or entry.cv_board()).generateImage((W, H), marginSize=0, borderBits=1)
    T_world_board = fidlearn.make_transform(entry.R_world_board, entry.translation_mm)
    T_camera_board = np.linalg.inv(T_world_camera) @ T_world_board
    H_cam = CAMERA.K @ T_camera_board[:3][:, [0, 1, 3]]  # board mm (z = 0) -> camera px
    A = np.array([[1 / px_per_mm, 0, 0.5 / px_per_mm], [0, 1 / px_per_mm, 0.5 / px_per_mm], [0, 0, 1]])
    S = np.array([[3.0, 0, 1], [0, 3.0, 1], [0, 0, 1]])  # camera px -> 3x supersampled px (pixel centres)
    w, h = CAMERA.image_size
    big = cv2.warpPerspective(image, S @ H_cam @ A, (3 * w, 3 * h), flags=cv2.INTER_LINEAR, borderValue=200)
    out = cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA).astype(float)
    out += np.random.default_rng(seed).normal(0, noise_gray, out.shape)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("C", [[650, 250, 950], [900, -150, 700]])
def test_locate_with_the_board_entry_uses_its_chess_corners(C):
    m = board_map()
    T = look_at(C, [0, 100, 860])
    image = render(m, T)
    pose = locate(image, m, CAMERA)
    assert pose.method.endswith("+chess")
    assert len(pose.marker_ids) == 17
    err = np.linalg.norm(pose.position_mm - T[:3, 3])
    assert err < 1.0, err  # about 1 m away
    assert pose.position_ellipsoid_contains(T[:3, 3], 0.99)
    angle = np.degrees(np.linalg.norm(cv2.Rodrigues(pose.T_world_camera[:3, :3].T @ T[:3, :3])[0]))
    assert angle < 0.1, angle
    # the same markers as single markers: no chess corners
    singles = MarkerMap(m.placements, 28, dictionary="6X6_250", units="mm")
    assert "+chess" not in locate(image, singles, CAMERA).method


def test_one_chess_corner_placed_wrong_is_left_out_and_any_picture_gives_them():
    """One of 24 chess corners 5.7 px off, beside corners good to a few hundredths: it widened its own yardstick
    and pulled the first fit, and moved the pose by 35 mm. Pictures of one channel or of floats, which detection
    reads, raised cv2.error where the chess corners were read."""
    from fidlearn.pose._locate import chess_corners_seen  # noqa: PLC0415

    cam = Camera.from_fov(60, (640, 480))
    board = {**BOARD, "translation": [0, 0, 500]}
    m = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 28, "boards": {"b": board}})
    T = fidlearn.look_at([700, 100, 360], [0, 100, 360], roll_deg=90)
    image = render_scene(m, cam, T, seed=3, blur_px=0.5, noise_std_gray=0.0).image
    dets = fidlearn.detect_markers(image, "6X6_250")
    ids, px = chess_corners_seen(image, m, dets)["b"]
    moved = px.copy()
    moved[list(ids).index(21)] += (-4.0, -4.0)  # it moved the pose by 35 mm
    pose = fidlearn.estimate_pose(dets, m, cam, board_corners={"b": (ids, moved)})
    assert pose.method.endswith("+chess")
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 1.0
    for picture in (image[:, :, None], np.dstack([image] * 3) / 255.0, image.astype(np.uint16) * 257):
        assert locate(picture, m, cam).method.endswith("+chess")


def test_a_rendered_charuco_entry_has_its_chess_squares():
    """render_scene drew a ChArUco entry's markers alone: OpenCV then interpolated chess corners 5-7 px off."""
    from fidlearn.pose._locate import chess_corners_seen  # noqa: PLC0415

    m = board_map()
    T = look_at([650, 250, 950], [0, 100, 860])
    image = render_scene(m, CAMERA, T, seed=3, blur_px=0.5, noise_std_gray=1.0).image
    dets = fidlearn.detect_markers(image, "6X6_250")
    assert len(dets) == 17
    ids, px = chess_corners_seen(image, m, dets)["table"]
    assert len(ids) == 24
    np.testing.assert_allclose(px, CAMERA.project(m.chess_corners()["table"][ids], T), atol=0.15)
    for d in dets:
        np.testing.assert_allclose(
            d.corners_px, CAMERA.project(m.marker_corners(m.key(d.id, d.dictionary)), T), atol=0.2
        )
    assert np.linalg.norm(locate(image, m, CAMERA).position_mm - T[:3, 3]) < 1.0


@pytest.mark.parametrize("separation_mm", [5.0, 10.0])
def test_a_rendered_grid_board_keeps_each_markers_border(separation_mm):
    """Each marker's white margin of a cell covered its neighbour's black border when the gap was narrower
    (4.6 px off at 5 mm)."""
    grid = {
        "type": "grid",
        "translation": [0, 0, 500],
        "markers": [3, 2],
        "marker_mm": 40,
        "separation_mm": separation_mm,
        "dictionary": "4X4_50",
    }
    m = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 40, "boards": {"g": grid}})
    cam = Camera.from_fov(60, (640, 480))
    T = fidlearn.look_at([500, 60, 450], [0, 60, 450])
    image = render_scene(m, cam, T, seed=1, blur_px=0.5, noise_std_gray=1.0).image
    dets = fidlearn.detect_markers(image, "4X4_50")
    assert len(dets) == 6
    for d in dets:
        np.testing.assert_allclose(d.corners_px, cam.project(m.marker_corners(m.key(d.id, d.dictionary)), T), atol=0.2)


def chess_corner_pose(image: np.ndarray, m: MarkerMap) -> np.ndarray:
    """The camera's position (mm) from OpenCV's ChArUco corners (``CharucoDetector``) and ``cv2.solvePnP``."""
    corners, ids, _, _ = cv2.aruco.CharucoDetector(m.entries["table"].cv_board()).detectBoard(image)
    obj = m.chess_corners()["table"][np.ravel(ids)]
    _, rvec, tvec = cv2.solvePnP(obj, corners.reshape(-1, 2), CAMERA.K, np.zeros(5), flags=cv2.SOLVEPNP_ITERATIVE)
    return -cv2.Rodrigues(rvec)[0].T @ tvec.ravel()


@pytest.mark.parametrize("marker_scale", [1.0, 1.04])
def test_board_entry_pose_is_at_least_as_accurate_as_the_chess_corner_pose(marker_scale):
    # the markers printed as the entry says, or 4 % bigger (ink, the printer: on the robot's photos the markers'
    # apparent size is up to 5 % off the board's) with the chess corners where the board puts them
    m = board_map()
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    printed = cv2.aruco.CharucoBoard((5, 7), 40, 28 * marker_scale, dictionary)
    errs = []
    for k, C in enumerate(([650, 250, 950], [900, -150, 700], [1100, 100, 1150], [600, -250, 1050])):
        T = look_at(C, [0, 100, 860])
        image = render(m, T, seed=k, printed=printed)
        entry = locate(image, m, CAMERA)
        assert entry.method.endswith("+chess")
        markers = estimate_pose(fidlearn.detect_markers(image, "6X6_250"), m, CAMERA)
        found = (entry.position_mm, chess_corner_pose(image, m), markers.position_mm)
        errs.append([np.linalg.norm(p - T[:3, 3]) for p in found])
    entry_err, chess_err, markers_err = np.array(errs).T
    assert np.median(entry_err) <= 0.7 * np.median(chess_err), errs  # the markers add to the chess corners
    assert np.sqrt(np.mean(entry_err**2)) <= np.sqrt(np.mean(chess_err**2)), errs
    if marker_scale != 1.0:  # the markers alone are misled by their size; the entry is not
        assert np.median(entry_err) < 0.5 * np.median(markers_err), errs


def projected(m: MarkerMap, T: np.ndarray, rng, sigma_m: float, sigma_c: float):
    dets = [
        Detection(k.id, CAMERA.project(c, T) + rng.normal(0, sigma_m, (4, 2)), dictionary="6X6_250")
        for k, c in m.corners().items()
    ]
    chess = m.chess_corners()["table"]
    return dets, {"table": (np.arange(len(chess)), CAMERA.project(chess, T) + rng.normal(0, sigma_c, (len(chess), 2)))}


def test_chess_corners_covariance_holds_the_truth_95_percent():
    m = board_map()
    T = look_at([800, 300, 1000], [0, 100, 860])
    rng = np.random.default_rng(3)
    inside, errs, errs_markers = [], [], []
    for _ in range(100):
        dets, chess = projected(m, T, rng, 0.5, 0.1)
        pose = estimate_pose(dets, m, CAMERA, board_corners=chess)
        errs.append(np.linalg.norm(pose.position_mm - T[:3, 3]))
        inside.append(pose.position_ellipsoid_contains(T[:3, 3]))
        errs_markers.append(np.linalg.norm(estimate_pose(dets, m, CAMERA).position_mm - T[:3, 3]))
    share = np.mean(inside)
    assert 0.88 <= share <= 0.99, share
    assert np.median(errs) < 0.6 * np.median(errs_markers)  # chess corners 5x more precise: a better pose


def test_board_corners_bad_input_says_what_to_give():
    m = board_map()
    dets, chess = projected(m, look_at([800, 300, 1000], [0, 100, 860]), np.random.default_rng(0), 0.1, 0.1)
    with pytest.raises(PoseError, match="ChArUco boards are \\['table'\\]"):
        estimate_pose(dets, m, CAMERA, board_corners={"desk": chess["table"]})
    with pytest.raises(PoseError, match="ids run 0 to 23"):
        estimate_pose(dets, m, CAMERA, board_corners={"table": (np.arange(24) + 1, chess["table"][1])})
    few = {"table": (np.arange(3), chess["table"][1][:3])}  # too few chess corners: the markers' pose
    assert "+chess" not in estimate_pose(dets, m, CAMERA, board_corners=few).method


def test_locate_with_a_bundle_of_markers_on_one_object():
    from fidlearn.synthetic import render_scene

    bundle = {
        "translation": [0, 0, 1000],
        "markers": {
            "1": {"translation": [0, 0, 0]},
            "2": {"translation": [0, 200, 0], "rotation": [0, -10, 0]},
            "3": {"translation": [-50, 100, -150], "size_mm": 80},
        },
    }
    m = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 100,
            "markers": {"0": {"translation": [0, -300, 1200]}},
            "bundles": {"dock": bundle},
        }  # fmt: skip
    )
    np.testing.assert_allclose(m.corners()[3][0], [-50, 100, 850])
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1500, 0, 900])
    pose = locate(render_scene(m, CAMERA, T).image, m, CAMERA)
    assert pose.marker_ids == (0, 1, 2, 3)
    assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 1.5  # 1.5 m away
    assert pose.position_ellipsoid_contains(T[:3, 3], 0.99)


def test_marker_tracker_uses_the_board_entrys_chess_corners_as_locate_does():
    m = board_map()
    T = look_at([650, 250, 950], [0, 100, 860])
    image = render(m, T)
    tracker = fidlearn.MarkerTracker(m, CAMERA)
    first = tracker.locate(image)  # a full-frame detection
    second = tracker.locate(image)  # windows around the predicted markers
    assert not tracker.last_full
    reference = locate(image, m, CAMERA)
    for pose in (first, second):
        assert pose.method.endswith("+chess")
        assert np.linalg.norm(pose.position_mm - T[:3, 3]) < 1.0
        np.testing.assert_allclose(pose.position_mm, reference.position_mm, atol=0.05)
