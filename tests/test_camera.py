"""Camera: projection against OpenCV, files (JSON and FileStorage), rescaling, and every camera mistake."""

import json
import shutil

import cv2
import numpy as np
import pytest

from fidlearn import Camera, _lens, frames
from fidlearn.data import data_path
from fidlearn.errors import CameraError, FidlearnWarning

K = np.array([[800.0, 0, 639.5], [0, 805.0, 359.5], [0, 0, 1]])
DIST = np.array([-0.21, 0.07, 0.001, -0.0005, -0.01])


@pytest.fixture
def cam():
    return Camera(K, DIST, (1280, 720))


def test_project_hand_computed_without_distortion():
    cam = Camera(K, None, (1280, 720))
    # camera at the origin looking along world +Z (T_world_camera = I): u = fx X / Z + cx
    px = cam.project([[100.0, -50.0, 1000.0]], np.eye(4))
    assert np.allclose(px, [[800 * 0.1 + 639.5, 805 * -0.05 + 359.5]])


def test_project_agrees_with_cv2_projectPoints_with_distortion(cam):
    T_world_camera = frames.make_transform(frames.rotation_from_rpy_deg(-100, 5, 80), [2500.0, -300.0, 400.0])
    rng = np.random.default_rng(1)
    pts = rng.uniform([-200, -800, 0], [200, 800, 900], size=(50, 3))
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(T_world_camera))
    expected, _ = cv2.projectPoints(pts, rvec, tvec, K, DIST)
    assert np.allclose(cam.project(pts, T_world_camera), expected.reshape(-1, 2), atol=1e-9)


def test_points_in_front(cam):
    assert cam.points_in_front([[0, 0, 100.0], [0, 0, -100.0]], np.eye(4)).tolist() == [True, False]


def test_undistort_inverts_distortion(cam):
    pts = cam.project(np.array([[100.0, 80, 1000], [-300, 200, 1500]]), np.eye(4))
    ideal = Camera(K, None, (1280, 720)).project(np.array([[100.0, 80, 1000], [-300, 200, 1500]]), np.eye(4))
    assert np.allclose(cam.undistort_points(pts), ideal, atol=1e-3)


def test_json_round_trip(cam, tmp_path):
    path = cam.save(tmp_path / "camera.json")
    back = Camera.load(path)
    assert np.array_equal(back.K, cam.K)
    assert np.array_equal(back.dist, cam.dist)
    assert back.image_size == (1280, 720)
    assert json.loads(path.read_text())["image_size"] == [1280, 720]


@pytest.mark.parametrize("suffix", [".yml", ".xml"])
def test_filestorage_round_trip(cam, tmp_path, suffix):
    path = cam.save(tmp_path / f"camera{suffix}")
    back = Camera.load(path)
    assert np.allclose(back.K, cam.K)
    assert np.allclose(back.dist, cam.dist)
    assert back.image_size == (1280, 720)


def test_loads_opencv_tutorial_yaml(tmp_path):
    path = tmp_path / "tutorial_camera_params.yml"
    shutil.copy(data_path("real", "opencv_aruco_photo", "tutorial_camera_params.yml"), path)
    with pytest.raises(CameraError, match="no image_width/image_height; pass image_size"):
        Camera.load(path)
    cam = Camera.load(path, image_size=(640, 480))
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (628.158, 628.156, 324.099, 260.908)
    assert np.allclose(cam.dist, [0.0995485, -0.206384, 0.00754589, 0.00336531, 0])


def test_scaled_keeps_the_geometry(cam):
    half = cam.scaled((640, 360))
    assert half.fx == pytest.approx(400)
    assert half.fy == pytest.approx(402.5)
    assert half.cx == pytest.approx(319.5)  # centre stays the centre
    assert half.cy == pytest.approx(179.5)
    # the same 3D point lands at half the pixel coordinates (+ the pixel-centre shift)
    p = np.array([[120.0, -40, 900]])
    assert np.allclose((cam.project(p, np.eye(4)) + 0.5) / 2 - 0.5, half.project(p, np.eye(4)))
    assert cam.scaled((1280, 720)) is cam


def test_scaled_refuses_another_aspect_ratio(cam):
    with pytest.raises(
        CameraError,
        match=r"calibrated at 1280x720 .* cannot be used on 640x480 .* calibrate at the resolution you run at",
    ):
        cam.scaled((640, 480))


def test_for_image_warns_when_it_rescales(cam):
    with pytest.warns(FidlearnWarning, match="rescaled to 640x360"):
        small = cam.for_image(np.zeros((360, 640), np.uint8))
    assert small.image_size == (640, 360)


def test_from_fov():
    cam = Camera.from_fov(90, (640, 480))
    assert cam.fx == pytest.approx(320)
    assert cam.fov_deg[0] == pytest.approx(90)


def test_repr_is_readable(cam):
    assert repr(cam).startswith("Camera(1280x720, fx=800.00, fy=805.00, cx=639.50, cy=359.50, dist=[-0.21")


GOOD = {"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist(), "image_size": [1280, 720]}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"camera_matrix": [[800, 0], [0, 800]]}, r"camera_matrix has shape \(2, 2\), expected 3x3"),
        (
            {"camera_matrix": [[0, 0, 640], [0, 800, 360], [0, 0, 1]]},
            "focal lengths fx=0, fy=800; both must be positive",
        ),
        ({"camera_matrix": [[800, 0, 0], [0, 800, 0], [640, 360, 1]]}, "it looks transposed"),
        ({"camera_matrix": [[800, 0, 640], [0, "x", 360], [0, 0, 1]]}, "camera_matrix is not numeric"),
        ({"camera_matrix": [[800, 0, 640], [0, 800, 360], [0, 0, 1.8e304]]}, "holds 1.8e.304, beyond any camera"),
        (
            {"camera_matrix": [[800, 0, 640], [0, 800, 360], [0, 0, 2]]},
            r"got \[\[800, 0, 640\], \[0, 800, 360\], \[0, 0, 2\]\]",
        ),
        ({"camera_matrix": [[1e-300, 0, 639.5], [0, 1e-300, 359.5], [0, 0, 1]]}, "at least 1 pixel is a camera's"),
        ({"dist_coeffs": [0.1, 0.2, 0.3]}, "dist_coeffs has 3 values; OpenCV takes 4, 5, 8, 12 or 14"),
        ({"dist_coeffs": [0.1, 0.2, 0.0, 0.0, 0.0, 0.1]}, "dist_coeffs has 6 values"),
        ({"image_size": [1280]}, r"image_size must be \[width, height\]"),
        ({"image_size": [1280, -720]}, "two positive whole numbers"),
        ({"image_size": None}, r"image_size must be \[width, height\]"),
        ({"image_size": "64"}, r"image_size must be \[width, height\] in pixels, got '64'"),  # not 6 x 4
        ({"image_size": ["1280", "720"]}, r"image_size must be \[width, height\]"),
        ({"image_size": [True, True]}, r"image_size must be \[width, height\]"),
        ({"image_size": [320, 180]}, r"principal point \(639.5, 359.5\) lies outside the 320x180 .*about 1280x720"),
    ],
)
def test_camera_file_errors(tmp_path, change, message):
    d = dict(GOOD, **change)
    p = tmp_path / "camera.json"
    p.write_text(json.dumps(d))
    with pytest.raises(CameraError, match=message) as info:
        Camera.load(p)
    assert str(p) in str(info.value)


def test_a_camera_files_errors_name_the_file_and_its_record_of_what_made_it_stays_one_line(tmp_path):
    """The file's "source" (free text: what made the camera) is a record, not the file's name in an error; a
    100,000-character one with a terminal escape is kept as one printable line of 300 characters at most."""
    p = tmp_path / "camera.json"
    p.write_text(json.dumps({**GOOD, "camera_matrix": [[0, 0, 640], [0, 800, 360], [0, 0, 1]], "source": "my rig"}))
    with pytest.raises(CameraError, match=f"^{p}: camera_matrix has focal lengths fx=0"):
        Camera.load(p)
    p.write_text(json.dumps({**GOOD, "source": "x" * 100_000 + "\x1b[31m"}))
    cam = Camera.load(p)
    assert len(cam.source) == 300
    assert cam.source.isprintable()
    p.write_text(json.dumps({**GOOD, "source": "my rig"}))
    assert Camera.load(p).source == "my rig"


def test_camera_file_nan_and_missing_fields(tmp_path):
    p = tmp_path / "camera.json"
    p.write_text(json.dumps(GOOD).replace("-0.21", "NaN"))
    with pytest.raises(CameraError, match="contains NaN, which is not a number"):
        Camera.load(p)
    p.write_text(json.dumps({"camera_matrix": K.tolist()}))
    with pytest.raises(CameraError, match="missing field image_size"):
        Camera.load(p)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty"),
        ("%YAML:1.0\ncamera_matrix: [1, 2\n", "not a readable OpenCV FileStorage file|cannot open it"),
        ("%YAML:1.0\nimage_width: 640\nimage_height: 480\n", "no camera_matrix field"),
    ],
)
def test_filestorage_errors(tmp_path, text, message):
    p = tmp_path / "camera.yml"
    p.write_text(text)
    with pytest.raises(CameraError, match=message):
        Camera.load(p)


def test_repr_names_the_file_not_its_absolute_path(cam, tmp_path):
    back = Camera.load(cam.save(tmp_path / "camera.json"))
    assert "source='camera.json'" in repr(back)
    assert str(tmp_path) not in repr(back)


def test_map_or_image_given_as_the_camera_says_so(tmp_path):
    # Swapped arguments: the errors were "missing field camera_matrix" and "not UTF-8 text (byte 0
    # is 0x89); save the camera as UTF-8 JSON" for a PNG.
    with pytest.raises(
        CameraError,
        match=r"world_map.json: missing field camera_matrix: "
        r"this is a world map \(marker placements\), not a camera file",
    ):
        Camera.load(data_path("world_map.json"))
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}}))
    with pytest.raises(CameraError, match=r"this is a world map"):
        Camera.load(bare)
    with pytest.raises(CameraError, match=r"scene_00.png: this is an image, not a camera file"):
        Camera.load(data_path("scenes", "scene_00.png"))


def test_width_and_height_swapped_says_so():
    # Camera(K, dist, image.shape[:2]) is the learner's usual slip: the error spoke of aspect
    # ratios and sensor crops, and sent them to recalibrate.
    image = np.zeros((480, 640), np.uint8)
    cam = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, image.shape[:2])
    with pytest.raises(CameraError, match=r"width and height are swapped.*\(image.shape\[1\], image.shape\[0\]\)"):
        cam.for_image(image)
    ok = Camera(cam.K, None, (image.shape[1], image.shape[0]))
    assert ok.for_image(image) is ok


def _wide_lens_and_grid():
    lens = Camera.from_fov(90, (1280, 720), dist=[-0.4, 0.16, 0.001, -0.001, -0.02])
    u, v = np.meshgrid(np.linspace(-0.5, 1279.5, 160), np.linspace(-0.5, 719.5, 90))  # the whole picture, edges too
    return lens, np.stack([u.ravel(), v.ravel()], axis=1)


def test_exact_undistortion_inverts_projection_over_a_wide_lens_picture():
    lens, px = _wide_lens_and_grid()
    xy = _lens.undistort_exact(px, lens.K, lens.dist)
    pts = np.column_stack([xy * 1000.0, np.full(len(xy), 1000.0)])  # the rays at 1 m depth
    reprojected = lens.project(pts, np.eye(4))  # OpenCV's projectPoints
    np.testing.assert_allclose(reprojected, px, rtol=0, atol=1e-8)
    np.testing.assert_allclose(_lens.undistort_exact(reprojected, lens.K, lens.dist), xy, rtol=0, atol=1e-9)
    ideal_px = xy @ lens.K[:2, :2].T + lens.K[:2, 2]
    np.testing.assert_allclose(lens.undistort_points(px), ideal_px, rtol=0, atol=1e-8)
    # OpenCV's default stops early: over a pixel off at this lens's corners, which the exact default is not
    assert np.abs(lens.undistort_points(px, exact=False) - ideal_px).max() > 1.0


def test_exact_undistortion_agrees_with_opencvs_iteration_run_to_tight_criteria():
    lens, px = _wide_lens_and_grid()
    by_opencv = _lens.undistort_cv_iter(px, lens.K, lens.dist, max_count=500, eps=1e-15)
    np.testing.assert_allclose(_lens.undistort_exact(px, lens.K, lens.dist), by_opencv, rtol=0, atol=1e-9)


def test_sizes_images_and_pictures_that_are_not_are_refused_with_the_fix(cam, tmp_path):
    path = cam.save(tmp_path / "camera.json")
    with pytest.raises(CameraError, match=r"image_size must be \[width, height\] in pixels, got 1280"):
        Camera.load(path, image_size=1280)
    with pytest.raises(CameraError, match=r"got '1280x720'"):
        Camera.load(path, image_size="1280x720")
    for bad in (None, np.zeros(10), "640x360"):
        with pytest.raises(CameraError, match=r"image_size must be \[width, height\]"):
            cam.for_image(bad)
    with pytest.raises(CameraError, match=r"an array of shape \(2, 2, 2, 2\)"):
        cam.for_image(np.zeros((2, 2, 2, 2)))
    for dtype in (np.int64, bool):
        with pytest.raises(CameraError, match=f"image is of type {np.dtype(dtype)}; a picture is uint8"):
            cam.undistort_image(np.zeros((720, 1280), dtype))
    assert cam.undistort_image(np.zeros((720, 1280), np.uint16)).dtype == np.uint16


def test_brackets_in_comments_and_quotes_and_aligned_matrix_rows_are_not_nesting(tmp_path):
    """The guard against deeply nested files (OpenCV's parser recurses once per level) counts a file's structure:
    not the brackets of a comment or a quoted string, nor the indentation of a matrix's continued data line."""
    path = tmp_path / "camera.yml"
    path.write_text(
        "%YAML:1.0\nimage_width: 640\nimage_height: 480\n# notes: [[[[[[[[[[[[[[[[[[\n"
        "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 600., 0., 319.5,\n"
        + " "
        * 44
        + "0., 600., 239.5, 0., 0., 1. ]\n"
        'note: "[[[[[[[[[[[[[[[[[[[[[[[["\n'
    )
    assert Camera.load(path).K.tolist() == [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]]
