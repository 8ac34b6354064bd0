"""Marker detection: ids and corners against known answers (published photos, synthetic truth)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, MarkerPlacement, _cv, _cv_charuco, data_path
from fidlearn._detector import _DETECTOR_CACHE, _detector_fields
from fidlearn.detection import (
    DEFAULT_DETECTOR_PARAMS,
    DEFAULT_REFINE,
    REFINE_METHODS,
    Detection,
    _detector,
    as_gray,
    detect_markers,
    detect_markers_with_rejected,
    load_image,
    refine_corners_edges,
)
from fidlearn.drawing import draw_detections
from fidlearn.errors import DictionaryError, FidlearnError, ImageError
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

PHOTO_IDS = [23, 40, 62, 98, 124, 203]  # published: opencv_contrib aruco tutorial, DICT_6X6_250
MARKER_MM = 80.0


@pytest.fixture(scope="module")
def photo() -> np.ndarray:
    return load_image(data_path("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"))


def plain_opencv(gray: np.ndarray, dictionary: str) -> dict[int, np.ndarray]:
    """OpenCV's detector with its default parameters (no refinement), called directly."""
    det = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, "DICT_" + dictionary)), cv2.aruco.DetectorParameters()
    )
    corners, ids, _ = det.detectMarkers(gray)
    return {int(i): np.asarray(c, float).reshape(4, 2) for i, c in zip(np.ravel(ids), corners)}


def radial_unit(corners: np.ndarray) -> np.ndarray:
    """(..., 4, 2) unit vectors from each marker's centre to its corners."""
    r = corners - corners.mean(axis=-2, keepdims=True)
    return r / np.linalg.norm(r, axis=-1, keepdims=True)


# ----------------------------------------------------------------------------------------------
# The real photo
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("refine", REFINE_METHODS)
def test_photo_gives_the_published_ids(photo, refine):
    dets = detect_markers(photo, "6X6_250", refine=refine)
    assert [d.id for d in dets] == PHOTO_IDS
    assert all(
        isinstance(d, Detection) and d.corners_px.shape == (4, 2) and d.corners_px.dtype == np.float64 for d in dets
    )


def test_wrong_dictionary_finds_only_the_known_false_marker_on_the_box(photo):
    # DICT_4X4_50 misreads a pattern printed on the cardboard box (top of the picture) as id 17,
    # on OpenCV 4.14 and 5.0 alike; none of the real markers (all on the paper) comes out.
    dets = detect_markers(photo, "4X4_50")
    assert [d.id for d in dets] == [17]
    assert not set(d.id for d in dets) & set(PHOTO_IDS)
    assert dets[0].center[1] < 120  # the box; the paper starts below y = 125
    assert detect_markers(photo, "ARUCO_ORIGINAL") == []


def test_default_corners_agree_with_plain_opencv_within_a_pixel(photo):
    gray = as_gray(photo)
    ref = plain_opencv(gray, "6X6_250")
    dets = detect_markers(photo, "6X6_250")
    diff = np.array([d.corners_px - ref[d.id] for d in dets])
    dist = np.linalg.norm(diff, axis=2)
    assert dist.mean() < 0.75
    assert dist.max() < 1.25
    # The difference is OpenCV's known bias: its unrefined contour runs through the outermost dark
    # pixels, about half a pixel inside the edge, so the edge fit moves corners outwards.
    outward = (diff * radial_unit(np.array([ref[d.id] for d in dets]))).sum(axis=2).mean()
    assert 0.2 < outward < 0.8
    # "none" is exactly OpenCV's own answer
    assert all(np.array_equal(d.corners_px, ref[d.id]) for d in detect_markers(photo, "6X6_250", refine="none"))


def test_bgr_gray_bgra_and_16_bit_give_the_same_answer(photo):
    gray = cv2.cvtColor(photo, cv2.COLOR_BGR2GRAY)
    variants = [
        gray,
        photo,
        cv2.cvtColor(photo, cv2.COLOR_BGR2BGRA),
        gray[:, :, None],
        gray.astype(np.uint16) << 8,
    ]
    answers = [detect_markers(v, "6X6_250") for v in variants]
    for dets in answers[1:]:
        assert [d.id for d in dets] == PHOTO_IDS
        for a, b in zip(answers[0], dets):
            np.testing.assert_array_equal(a.corners_px, b.corners_px)


def test_charuco_marker_corners_fit_the_board_geometry():
    """Known answer for real photos: a flat board's marker corners map by one homography.

    After undistorting with the tutorial's calibration, a homography from the board
    (CharucoBoard 5x7, 40 mm squares, 20 mm markers, DICT_6X6_250) must fit the
    detected corners. The default refinement fits it twice as well as OpenCV's
    unrefined and sub-pixel corners (0.43 px RMS against 0.95 and 0.83 px on OpenCV 5.0),
    and 0.37 px when the edge is placed half-way in light (``gamma=2.2``).
    """
    cam = Camera.load(data_path("real", "opencv_charuco", "tutorial_camera_charuco.yml"))
    board = _cv_charuco.charuco_board((5, 7), 40.0, 20.0, "6X6_250")
    obj = {
        int(i): np.asarray(o, float).reshape(4, 3)[:, :2]
        for i, o in zip(np.ravel(board.getIds()), board.getObjPoints())
    }
    rms, shift = {}, []
    for name in ("img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg", "chocclusion_original.jpg"):
        image = load_image(data_path("real", "opencv_charuco", name))
        per = {}
        for refine in ("none", "subpix", DEFAULT_REFINE, "apriltag", "gamma"):
            if refine == "gamma":  # the edge half-way in light, for this camera's sRGB-like curve
                dets = [d for d in detect_markers(image, "6X6_250", refine="none") if d.id in obj]
                fine = refine_corners_edges(as_gray(image), np.stack([d.corners_px for d in dets]), 8, gamma=2.2)
                dets = [Detection(d.id, c) for d, c in zip(dets, fine)]
            else:
                dets = [d for d in detect_markers(image, "6X6_250", refine=refine) if d.id in obj]
            assert len(dets) >= 13
            P = np.concatenate([obj[d.id] for d in dets])
            Q = cv2.undistortPoints(
                np.concatenate([d.corners_px for d in dets]).reshape(-1, 1, 2), cam.K, cam.dist, P=cam.K
            ).reshape(-1, 2)
            H, _ = cv2.findHomography(P, Q, 0)
            res = Q - cv2.perspectiveTransform(P.reshape(-1, 1, 2), H).reshape(-1, 2)
            rms.setdefault(refine, []).append(res)
            per[refine] = {d.id: d.corners_px for d in dets}
        shift += [per["apriltag"][i] - per[DEFAULT_REFINE][i] for i in per[DEFAULT_REFINE] if i in per["apriltag"]]
    rms = {k: float(np.sqrt((np.concatenate(v) ** 2).sum(1).mean())) for k, v in rms.items()}
    assert rms[DEFAULT_REFINE] < 0.5
    assert rms[DEFAULT_REFINE] < 0.6 * rms["none"]
    assert rms[DEFAULT_REFINE] < 0.6 * rms["subpix"]
    # This camera encodes light with a gamma curve: the edge half-way in light fits better still.
    assert rms["gamma"] < 0.92 * rms[DEFAULT_REFINE]
    # The AprilTag refinement reports corners shifted by about half a pixel down and right.
    dx, dy = np.concatenate(shift).mean(axis=0)
    assert 0.3 < dx < 0.6
    assert 0.3 < dy < 0.6


# ----------------------------------------------------------------------------------------------
# Synthetic scenes with known corners
# ----------------------------------------------------------------------------------------------


def wall(dictionary: str = "ARUCO_ORIGINAL", n_cols: int = 3, n_rows: int = 2) -> MarkerMap:
    pitch = 1.75 * MARKER_MM
    pl = {}
    for r in range(n_rows):
        for c in range(n_cols):
            i = 3 + r * n_cols + c
            pl[i] = MarkerPlacement(i, (0.0, c * pitch, 1000.0 - r * pitch), (0.0, 0.0, 0.0))
    return MarkerMap(pl, MARKER_MM, dictionary=dictionary)


def view(side_px: float, az_deg: float = 20.0, el_deg: float = -10.0, roll_deg: float = 0.0, size=(640, 480)):
    cam = Camera.from_fov(60.0, size)
    centre = np.array([0.0, 0.875 * 2 * MARKER_MM + MARKER_MM / 2, 1000.0 - 0.875 * MARKER_MM - MARKER_MM / 2])
    dist = cam.fx * MARKER_MM / side_px
    az, el = np.radians(az_deg), np.radians(el_deg)
    eye = centre + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return cam, look_at(eye, centre, roll_deg=roll_deg)


@pytest.mark.parametrize(("side_px", "seed"), [(30, 1), (45, 2), (80, 3)])
def test_synthetic_corners_match_the_truth(side_px, seed):
    mm = wall()
    cam, T = view(side_px, az_deg=25.0, el_deg=-15.0, roll_deg=20.0 * seed)
    scene = render_scene(mm, cam, T, seed=seed, blur_px=0.8, noise_std_gray=1.5, gradient=0.2)
    image, truth = scene.image, scene.truth
    assert len(truth) == 6
    dets = detect_markers(image)  # ARUCO_ORIGINAL, the default refinement
    assert [d.id for d in dets] == sorted(truth)
    err = np.array([d.corners_px - truth[d.id] for d in dets])
    rms = np.sqrt((err**2).sum(2).mean())
    # Measured (docs/corner_refinement.md): 0.02-0.05 px RMS from 30 px up; bound with margin.
    assert rms < 0.12
    assert np.abs(err.reshape(-1, 2).mean(axis=0)).max() < 0.05  # no constant shift
    truths = np.array([truth[d.id] for d in dets])
    assert abs((err * radial_unit(truths)).sum(2).mean()) < 0.05  # neither inwards nor outwards
    # OpenCV's unrefined corners on the same picture sit about 0.5-0.8 px inside.
    plain = np.array([d.corners_px - truth[d.id] for d in detect_markers(image, refine="none")])
    assert np.sqrt((plain**2).sum(2).mean()) > 3 * rms


def test_gamma_moves_edges_outwards_on_linear_pictures():
    # The renderer's gray levels are proportional to light: gamma 2.2 puts the edge where a sRGB
    # camera would, which on these pictures is outside the true edge.
    cam, T = view(45)
    scene = render_scene(wall(), cam, T, seed=6, blur_px=0.7, noise_std_gray=1.0)
    image, truth = scene.image, scene.truth
    dets = detect_markers(image, refine="none")
    C = np.stack([d.corners_px for d in dets])
    truths = np.array([truth[d.id] for d in dets])
    out = ((refine_corners_edges(image, C, 7, gamma=2.2) - truths) * radial_unit(truths)).sum(2).mean()
    linear = ((refine_corners_edges(image, C, 7) - truths) * radial_unit(truths)).sum(2).mean()
    assert abs(linear) < 0.05
    assert 0.3 < out < 1.2


@pytest.mark.parametrize("roll_deg", [90.0, 180.0, 270.0])
def test_rolled_camera_still_reports_each_markers_own_top_left_first(roll_deg):
    cam, T = view(50, roll_deg=roll_deg)
    scene = render_scene(wall(), cam, T, seed=4, blur_px=0.6, noise_std_gray=1.0)
    image, truth = scene.image, scene.truth
    dets = detect_markers(image)
    assert [d.id for d in dets] == sorted(truth)
    for d in dets:
        assert np.abs(d.corners_px - truth[d.id]).max() < 0.25, (d, truth[d.id])


def test_rotating_the_image_permutes_nothing(photo):
    # np.rot90 turns the picture 90 degrees counter-clockwise: pixel (x, y) goes to (y, W - 1 - x).
    gray = as_gray(photo)
    W = gray.shape[1]
    before = {d.id: d.corners_px for d in detect_markers(gray, "6X6_250")}
    after = {d.id: d.corners_px for d in detect_markers(np.rot90(gray), "6X6_250")}
    assert sorted(after) == PHOTO_IDS
    for i, c in before.items():
        expected = np.column_stack([c[:, 1], W - 1 - c[:, 0]])  # same corner order: TL stays first
        assert np.abs(after[i] - expected).max() < 0.3, i


def test_inverted_markers_refine_too():
    cam, T = view(45)
    scene = render_scene(wall(), cam, T, seed=5, blur_px=0.7, noise_std_gray=1.5)
    image, truth = scene.image, scene.truth
    dets = detect_markers(255 - image, detector_params={"detectInvertedMarker": True})
    assert [d.id for d in dets] == sorted(truth)
    err = np.array([d.corners_px - truth[d.id] for d in dets])
    assert np.sqrt((err**2).sum(2).mean()) < 0.12


def test_edge_refinement_takes_hundreds_of_markers_at_once():
    # cv2.remap refuses maps of 32767 rows or more: 600 markers x 4 sides x 16 profiles would be 38400
    marker = _cv.generate_marker("ARUCO_ORIGINAL", 7, 70)
    image = cv2.GaussianBlur(cv2.copyMakeBorder(marker, 30, 30, 30, 30, cv2.BORDER_CONSTANT, value=235), (0, 0), 0.8)
    truth = np.array([[0, 0], [70, 0], [70, 70], [0, 70]], float) + 30 - 0.5
    start = np.stack([d.corners_px for d in detect_markers(image, refine="none")] * 600)
    fine = refine_corners_edges(image, start, 7)
    assert fine.shape == (600, 4, 2)
    assert np.abs(fine - truth).max() < 0.02


def test_edge_refinement_keeps_corners_it_cannot_fit():
    flat = np.full((100, 100), 128, np.uint8)
    quad = np.array([[[30.0, 30.0], [70.0, 30.0], [70.0, 70.0], [30.0, 70.0]]])
    np.testing.assert_array_equal(refine_corners_edges(flat, quad, 7), quad)
    assert refine_corners_edges(flat, np.zeros((0, 4, 2)), 7).shape == (0, 4, 2)


# ----------------------------------------------------------------------------------------------
# Dictionaries, parameters, the detector cache
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(_cv.DICTIONARIES))
def test_every_predefined_dictionary_detects_its_own_last_marker(name):
    last = _cv.dictionary_size(name) - 1
    cells = _cv.dictionary_marker_bits(name) + 2
    marker = _cv.generate_marker(name, last, 20 * cells)
    image = cv2.copyMakeBorder(marker, 60, 60, 60, 60, cv2.BORDER_CONSTANT, value=255)
    dets = detect_markers(image, name)
    assert [d.id for d in dets] == [last]
    # the marker's outer corners in pixel-centre coordinates: -0.5 .. side - 0.5 inside the border
    side = 20 * cells
    truth = np.array([[0, 0], [side, 0], [side, side], [0, side]], float) + 60 - 0.5
    assert np.abs(dets[0].corners_px - truth).max() < 0.1


@pytest.mark.parametrize("spelling", ["6X6_250", "DICT_6X6_250", "6x6_250", "dict_6x6_250", " 6X6_250 "])
def test_dictionary_names_are_readable_in_any_case_with_or_without_prefix(photo, spelling):
    assert [d.id for d in detect_markers(photo, spelling)] == PHOTO_IDS


def test_unknown_dictionary_is_a_clear_error(photo):
    with pytest.raises(DictionaryError, match=r"unknown ArUco dictionary '6X6_2500'.*did you mean.*6X6_250"):
        detect_markers(photo, "6X6_2500")
    with pytest.raises(DictionaryError, match="not a non-empty string"):
        detect_markers(photo, "")


def test_unknown_refinement_and_parameter_are_clear_errors(photo):
    with pytest.raises(FidlearnError, match=r"unknown corner refinement 'subpixel'; use one of 'none', 'subpix'"):
        detect_markers(photo, "6X6_250", refine="subpixel")
    with pytest.raises(FidlearnError, match="DetectorParameters has no field 'winSize'"):
        detect_markers(photo, "6X6_250", detector_params={"winSize": 3})
    with pytest.raises(FidlearnError, match=r"detector parameter markerBorderBits=1.5: .*integer"):
        detect_markers(photo, "6X6_250", detector_params={"markerBorderBits": 1.5})
    with pytest.raises(FidlearnError, match="values must be numbers or booleans"):
        detect_markers(photo, "6X6_250", detector_params={"minMarkerPerimeterRate": [0.1]})
    with pytest.raises(FidlearnError, match="must be None, a dict of field overrides"):
        detect_markers(photo, "6X6_250", detector_params=[("minMarkerPerimeterRate", 0.1)])


def test_detector_is_built_once_per_dictionary_refinement_and_parameters(photo):
    first = _detector("6X6_250", "edges", None)[0]
    assert _detector("6X6_250", "edges", None)[0] is first
    assert _detector("6X6_250", "subpix", None)[0] is not first
    as_dict = _detector("6X6_250", "none", {"minMarkerPerimeterRate": 0.05})[0]
    assert _detector("6X6_250", "none", {"minMarkerPerimeterRate": 0.05})[0] is as_dict
    assert _detector("6X6_250", "edges", None)[1:] == (8, False)  # 6 bits + 2 border cells; not inverted
    assert _detector("6X6_250", "edges", {"detectInvertedMarker": True})[2] is True
    assert len(_DETECTOR_CACHE) <= 16
    # parameters as an OpenCV object work and are honoured: markers this small are dropped
    params = cv2.aruco.DetectorParameters()
    params.minMarkerPerimeterRate = 0.25  # perimeter at least 0.25 * 640 = 160 px: only id 40 (44 px side)
    assert [d.id for d in detect_markers(photo, "6X6_250", detector_params=params)] == [40]
    assert [d.id for d in detect_markers(photo, "6X6_250", detector_params={"minMarkerPerimeterRate": 0.25})] == [40]


# ----------------------------------------------------------------------------------------------
# fidlearn's detector parameters
# ----------------------------------------------------------------------------------------------


def test_fidlearn_defaults_sit_under_a_dict_of_overrides_and_never_change_an_opencv_object():
    opencv = _cv.detector_parameter_fields(None)
    ours = _detector_fields(None)
    assert {k for k in ours if ours[k] != opencv[k]} == set(DEFAULT_DETECTOR_PARAMS)
    assert all(ours[k] == pytest.approx(v) for k, v in DEFAULT_DETECTOR_PARAMS.items())
    one = _detector_fields({"minMarkerDistanceRate": 0.1})
    assert one["minMarkerDistanceRate"] == pytest.approx(0.1)
    assert one["adaptiveThreshWinSizeStep"] == ours["adaptiveThreshWinSizeStep"]
    assert _detector_fields(cv2.aruco.DetectorParameters()) == opencv


def test_opencv_defaults_given_as_an_object_give_opencvs_corners_refined_exactly_as_before(photo):
    """The edges refinement is unchanged: on OpenCV's own unrefined corners it gives the same numbers."""
    gray = as_gray(photo)
    plain = plain_opencv(gray, "6X6_250")
    dets = detect_markers(photo, "6X6_250", detector_params=cv2.aruco.DetectorParameters())
    assert [d.id for d in dets] == sorted(plain) == PHOTO_IDS
    expected = refine_corners_edges(gray, np.stack([plain[d.id] for d in dets]), 8, inverted=False)
    np.testing.assert_allclose(np.stack([d.corners_px for d in dets]), expected, rtol=0, atol=1e-9)


def test_a_row_of_far_markers_with_one_cell_margins_at_their_rendered_corners():
    """A row of nine 80 mm ARUCO_ORIGINAL markers with one-cell white margins, seen from 4.9 m at 1920x1080
    (frame 5 of 20 of benchmarks/bench_speed.py's video). fidlearn's defaults find all nine, each at its rendered
    corners; OpenCV's find fewer: the two farthest (22 px) need ``perspectiveRemovePixelPerCell`` 8."""
    s = 5 / 19
    eye = [5600 - 2500 * s, 700 + 1300 * s + 150 * np.sin(3 * s), 1300 + 10 * np.sin(7 * s)]
    T = look_at(eye, [0.0, 1300 + 400 * np.sin(2.5 * s), 1250 - 250 * s], roll_deg=3 * np.sin(5 * s))
    cam = Camera([[1371.0, 0, 961.3], [0, 1371.0, 538.2], [0, 0, 1]], [-0.08, 0.05, 3e-4, -2e-4, -0.01], (1920, 1080))
    row = {18 + c: MarkerPlacement(18 + c, (0.0, c * 450.0 - 200.0, 1800.0), (0.0, 0.0, 0.0)) for c in range(9)}
    m = MarkerMap(row, MARKER_MM, dictionary="ARUCO_ORIGINAL")
    scene = render_scene(m, cam, T, seed=5, blur_px=0.5, noise_std_gray=1.5, gradient=0.1, supersample=2)
    image, truth = scene.image, scene.truth
    assert sorted(truth) == list(range(18, 27))
    dets = detect_markers(image)
    assert [d.id for d in dets] == list(range(18, 27))
    assert len(plain_opencv(image, "ARUCO_ORIGINAL")) < 9
    assert max(np.abs(d.corners_px - truth[d.id]).max() for d in dets) < 0.3
    assert [d.id for d in detect_markers(image, ids=m.ids)] == [d.id for d in dets]
    coarse = detect_markers(image, detector_params={"perspectiveRemovePixelPerCell": 4})
    assert len(coarse) < 9
    assert max(np.abs(d.corners_px - truth[d.id]).max() for d in coarse) < 0.3


def test_rejected_candidates_on_request(photo):
    found = detect_markers_with_rejected(photo, "6X6_250")
    dets, rejected = found.detections, found.rejected
    assert [d.id for d in dets] == PHOTO_IDS
    assert len(rejected) > 0
    assert all(r.shape == (4, 2) for r in rejected)


# ----------------------------------------------------------------------------------------------
# Images that are not images
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (None, "expected a numpy array"),
        ("photo.jpg", "expected a numpy array"),
        (np.zeros((0, 0), np.uint8), "the image is empty"),
        (np.zeros((48, 64, 2), np.uint8), r"shape \(48, 64, 2\) is not an image"),
        (np.zeros((4, 48, 64, 3), np.uint8), "is not an image"),
        (np.zeros((48, 64), np.int32), "pixel type int32 is not supported"),
        (np.full((48, 64), 2.0), r"float image must hold values in \[0, 1\]"),
        (np.zeros((4, 4), np.uint8), "too small to hold a marker"),
    ],
)
def test_non_images_raise_image_error(bad, message):
    with pytest.raises(ImageError, match=message):
        detect_markers(bad)


# ----------------------------------------------------------------------------------------------
# Drawing
# ----------------------------------------------------------------------------------------------


def test_draw_detections_marks_outline_id_and_named_corners(photo):
    dets = detect_markers(photo, "6X6_250")
    before = photo.copy()
    out = draw_detections(photo, dets)
    np.testing.assert_array_equal(photo, before)  # the input is untouched
    assert out.shape == photo.shape
    assert out.dtype == np.uint8
    changed = np.any(out != photo, axis=2)
    assert changed.sum() > 3000
    for d in dets:  # every corner is drawn over, and the first one (TL) is red
        for x, y in np.round(d.corners_px).astype(int):
            assert changed[y, x]
        x, y = np.round(d.corners_px[0]).astype(int)
        b, g, r = out[y, x].astype(int)
        assert r > 200
        assert g < 60
        assert b < 60
    assert changed[:, :].sum() < 0.25 * changed.size  # a figure, not a repaint
    gray_out = draw_detections(as_gray(photo), dets, corner_labels=False, show_ids=False)
    assert gray_out.shape == photo.shape
    assert np.any(gray_out != cv2.cvtColor(as_gray(photo), cv2.COLOR_GRAY2BGR))
    # nothing to draw: a plain BGR copy
    np.testing.assert_array_equal(draw_detections(photo, []), photo)


def test_draw_detections_labels_make_the_winding_visible(photo):
    dets = detect_markers(photo, "6X6_250")
    plain = draw_detections(photo, dets, corner_labels=False)
    labelled = draw_detections(photo, dets)
    diff = np.any(plain != labelled, axis=2)
    # each corner name sits just outside its corner, away from the marker's centre
    for d in dets:
        for p in d.corners_px:
            away = p - d.center
            q = np.round(p + 10.0 * away / np.linalg.norm(away)).astype(int)
            win = diff[max(q[1] - 6, 0) : q[1] + 7, max(q[0] - 8, 0) : q[0] + 9]
            assert win.any()


def test_truncated_image_is_one_clear_error_without_opencv_log_lines(tmp_path, capfd):
    # OpenCV printed "[ WARN:0@0.2] global grfmt_png.cpp:793 ... PNG input buffer is incomplete"
    # on file descriptor 2 before fidlearn's own error: two messages for one mistake.
    good = tmp_path / "good.png"
    cv2.imwrite(str(good), np.full((64, 64), 128, np.uint8))
    cut = tmp_path / "cut.png"
    cut.write_bytes(good.read_bytes()[:60])
    capfd.readouterr()
    with pytest.raises(ImageError, match=r"cut.png: the PNG file is cut short \(it has no end chunk\)"):
        load_image(cut)
    assert capfd.readouterr().err == ""  # refused from the file's structure, before OpenCV sees it
    half = tmp_path / "half.jpg"
    cv2.imwrite(str(half), np.full((64, 64), 128, np.uint8))
    half.write_bytes(half.read_bytes()[: len(half.read_bytes()) // 2])
    with pytest.raises(ImageError, match=r"half.jpg: the JPEG file is cut short"):
        load_image(half)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("bits", [10, 12, 16])
def test_16_bit_pictures_of_fewer_bits_keep_their_contrast(bits):
    # A 10- or 12-bit camera's frames saved as 16-bit PNG were shifted by 8 bits into a black
    # 0..3 / 0..15 picture: no marker found, no error. They are scaled by the bits they use.
    gray = (np.arange(64 * 64).reshape(64, 64) % 256).astype(np.uint8)
    deep = (gray.astype(np.uint16) << (bits - 8)) | (gray.astype(np.uint16) >> (16 - bits))
    np.testing.assert_array_equal(as_gray(deep), gray)
    marker = np.pad(_cv.generate_marker("ARUCO_ORIGINAL", 7, 120), 40, constant_values=255)
    deep_marker = marker.astype(np.uint16) << (bits - 8)
    assert [d.id for d in detect_markers(deep_marker)] == [7]


# -- looking only for a map's markers ----------------------------------------------------------
def test_ids_restriction_finds_the_same_markers_with_the_same_corners():
    from fidlearn.data import data_path as _dp
    from fidlearn.detection import load_image as _load

    img = _load(_dp("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"))
    every = {d.id: d.corners_px for d in detect_markers(img, "6X6_250")}
    some = detect_markers(img, "6X6_250", ids=[203, 40, 62])
    assert [d.id for d in some] == [40, 62, 203]
    for d in some:
        assert np.array_equal(d.corners_px, every[d.id])
    assert detect_markers(img, "6X6_250", ids=[1, 2, 3]) == []


def test_ids_restriction_on_a_rendered_scene_matches_the_truth():
    import fidlearn

    m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    cam = fidlearn.Camera.from_fov(60, (640, 480))
    scene = fidlearn.render_scene(m, cam, fidlearn.look_at([1500, 200, 300], [0, 200, 250]), seed=3)
    img, truth = scene.image, scene.truth
    dets = detect_markers(img, m.dictionary, ids=m.ids)
    assert [d.id for d in dets] == sorted(truth)
    for d in dets:
        assert np.sqrt(np.mean((d.corners_px - truth[d.id]) ** 2)) < 0.3


@pytest.mark.parametrize(
    ("ids", "error", "message"),
    [
        ([], FidlearnError, "ids must be whole marker ids"),
        ([0, 1.5], FidlearnError, "ids must be whole marker ids"),
        ("012", FidlearnError, "ids must be whole marker ids"),
        ([0, 250], DictionaryError, "dictionary 6X6_250 has ids 0 to 249"),
        ([-1], DictionaryError, "has ids 0 to 249"),
    ],
)
def test_ids_restriction_rejects_bad_ids(ids, error, message):
    img = np.full((64, 64), 255, np.uint8)
    with pytest.raises(error, match=message):
        detect_markers(img, "6X6_250", ids=ids)


@pytest.mark.parametrize(
    ("mid", "corners", "message"),
    [
        (1.7, np.zeros((4, 2)), "id must be a whole marker id, got 1.7"),
        ("3", np.zeros((4, 2)), "id must be a whole marker id"),
        (-2, np.zeros((4, 2)), "id -2 is negative"),
        (3, np.zeros((3, 2)), r"corners have shape \(3, 2\), expected \(4, 2\)"),
        (3, [["a", 1]] * 4, "corners must be numbers"),
        (3, [[10, 30, 30, 10], [10, 10, 30, 30]], r"shape \(2, 4\), .*: one row per corner, transpose it"),
    ],
)
def test_detection_refuses_what_is_not_a_detection(mid, corners, message):
    from fidlearn.errors import DetectionError

    with pytest.raises(DetectionError, match=message):
        Detection(mid, corners)


def test_detection_accepts_numpy_ids_and_flat_corners():
    d = Detection(np.int32(5), np.arange(8.0))
    assert d.id == 5
    assert type(d.id) is int
    assert d.corners_px.shape == (4, 2)
    assert Detection(4.0, np.zeros((1, 4, 2))).id == 4


def test_one_return_type_and_corners_px(photo):
    """detect_markers always returns the list; the rejected candidates come from their own function."""
    dets = detect_markers(photo, "6X6_250")
    assert isinstance(dets, list)
    found = detect_markers_with_rejected(photo, "6X6_250")
    with_rejected, rejected = found.detections, found.rejected
    assert [d.id for d in with_rejected] == [d.id for d in dets]
    for a, b in zip(dets, with_rejected):
        np.testing.assert_array_equal(a.corners_px, b.corners_px)
    assert all(np.asarray(q).shape == (4, 2) for q in rejected)
    with pytest.raises(TypeError):
        detect_markers(photo, "6X6_250", return_rejected=True)


def test_detection_corners_have_one_name():
    quad = [[10, 10], [30, 10], [30, 30], [10, 30]]
    for d in (Detection(5, quad), Detection(5, corners_px=quad), Detection(id=5, corners_px=quad)):
        assert d.corners_px.shape == (4, 2)
        assert d.corners_px.dtype == np.float64
        np.testing.assert_array_equal(d.corners_px, quad)
    assert not hasattr(Detection(5, quad), "corners")  # the former name is gone: corners_px only
    with pytest.raises(TypeError, match="corners"):
        Detection(5, corners=quad)
    with pytest.raises(FidlearnError, match="corners_px missing"):
        Detection(5)


def test_with_corners_keeps_the_marker_and_takes_the_new_corners():
    """The trusted copy ``estimate_pose`` and ``locate`` make of a moved marker: same id and dictionary."""
    d = Detection(7, [[10, 10], [30, 10], [30, 30], [10, 30]], "4X4_50")
    moved = np.array([[11.0, 10.5], [31.0, 10.5], [31.0, 30.5], [11.0, 30.5]])
    m = d._with_corners(moved)
    assert (m.id, m.dictionary) == (7, "4X4_50")
    assert m.corners_px is moved
    assert m.side_px == 20.0
    assert d.corners_px[0].tolist() == [10.0, 10.0]  # the original is untouched


@pytest.mark.parametrize(
    ("change", "error", "message"),
    [
        ({"gray": np.zeros((64, 64, 3), np.uint8)}, "ImageError", "gray must be a uint8 picture"),
        ({"gray": np.zeros((64, 64)) + 0.5}, "ImageError", "float64 array"),
        ({"gray": [[0] * 64] * 64}, "ImageError", "got a list"),
        ({"cells": 0}, "DetectionError", "cells must be a whole number >= 3"),
        ({"gamma": 0}, "DetectionError", "gamma must be a finite number above 0"),
        ({"n_samples": 1}, "DetectionError", "n_samples must be a whole number >= 3"),
        ({"corners": np.full((1, 4, 2), np.nan)}, "DetectionError", "corners must be finite"),
    ],
)
def test_the_edge_refinement_says_what_it_cannot_use(change, error, message):
    """A BGR picture, cells or gamma of 0 and one sample raised ValueError, ZeroDivisionError or IndexError; a
    float picture in [0, 1] came back unrefined without a word."""
    from fidlearn import errors

    args = {
        "gray": np.full((64, 64), 255, np.uint8),
        "corners": np.array([[[20, 20], [40, 20], [40, 40], [20, 40]]], float),
        "cells": 8,
    }
    args.update(change)
    with pytest.raises(getattr(errors, error), match=message):
        refine_corners_edges(**args)
