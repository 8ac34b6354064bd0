"""The fisheye lens (OpenCV's Kannala-Brandt model, ``cv2.fisheye``) beside the pinhole one: projection against
OpenCV, the exact inverse across a 160-degree picture, undistorted pictures and their maps, camera files."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from fidlearn import Camera, _lens, frames
from fidlearn.errors import CameraError

#: ROS's fisheye calibration of the lens in data/real/fisheye_checkerboard (mono set): about 160 degrees at 800x503.
K_FE = np.array([[290.050152, 0.0, 399.938345], [0.0, 289.392837, 273.885669], [0.0, 0.0, 1.0]])
D_FE = np.array([-0.030464, -0.019695, 0.002098, 0.001030])
SIZE = (800, 503)


@pytest.fixture
def fish():
    return Camera(K_FE, D_FE, SIZE, model="fisheye")


def _picture(size, steps=(81, 51)):
    w, h = size
    u, v = np.meshgrid(np.linspace(-0.5, w - 0.5, steps[0]), np.linspace(-0.5, h - 0.5, steps[1]))
    return np.stack([u.ravel(), v.ravel()], axis=1)


def test_project_is_opencvs_fisheye_projectPoints_to_1e_9_px(fish):
    rng = np.random.default_rng(3)
    T = frames.transform_from_rvec_tvec(rng.normal(0, 0.3, 3), rng.normal(0, 100, 3))
    pts = np.column_stack([rng.uniform(-3000, 3000, (400, 2)), rng.uniform(300, 2000, 400)])  # up to 85 degrees
    world = frames.transform_points(T, pts)
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(T))
    by_opencv = cv2.fisheye.projectPoints(world.reshape(-1, 1, 3), rvec, tvec, K_FE, D_FE)[0].reshape(-1, 2)
    np.testing.assert_allclose(fish.project(world, T), by_opencv, rtol=0, atol=1e-9)
    # the pinhole reading of the same four numbers (k1 k2 p1 p2) is another lens altogether
    pinhole = Camera(K_FE, D_FE, SIZE)
    assert np.abs(pinhole.project(world, T) - by_opencv).max() > 100


def test_undistortion_is_the_exact_inverse_across_the_whole_picture(fish):
    px = _picture(SIZE)
    ideal = fish.undistort_points(px)
    seen = np.isfinite(ideal[:, 0])
    # the picture's left and right edges and corners see 90 degrees off the axis and more: no pinhole ray
    assert 0.7 < seen.mean() < 0.95
    assert seen[len(px) // 2]
    theta = np.degrees(_lens.fisheye_angles(px, K_FE, D_FE)[0])
    assert np.all(theta[seen] < 90)
    assert np.all(theta[~seen] >= 90)
    assert theta.max() < 120
    rays = np.column_stack([(ideal[seen] - fish.K[:2, 2]) / [fish.fx, fish.fy], np.ones(seen.sum())])
    back = fish.project(rays, np.eye(4))
    assert np.abs(back - px[seen]).max() < 1e-9
    assert np.hypot(*((ideal[seen] - fish.K[:2, 2]) / [fish.fx, fish.fy]).T).max() > 10  # 84 degrees and more
    fast = fish.undistort_points(px[seen], exact=False)  # cv2.fisheye.undistortPoints
    by_opencv = cv2.fisheye.undistortPoints(px[seen].reshape(-1, 1, 2), K_FE, D_FE, P=K_FE).reshape(-1, 2)
    np.testing.assert_allclose(fast, by_opencv, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("dist", [D_FE, [0.1, -0.2, 0.05, -0.01], [0.0] * 4])
def test_opencvs_fast_undistortion_is_nan_where_no_ray_in_front_reaches(dist):
    # OpenCV answers a pixel past 90 degrees with the mirror image of a ray in front, across the picture
    fish = Camera(K_FE, dist, SIZE, model="fisheye")
    px = _picture(SIZE, (161, 101))
    exact, fast = fish.undistort_points(px), fish.undistort_points(px, exact=False)
    assert np.isnan(exact).any()
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(exact))
    seen = np.isfinite(exact[:, 0])
    assert np.abs(fast[seen] - exact[seen]).max() < 1e-5
    if dist is D_FE:  # the real lens sees its left edge's middle 90.4 degrees off the axis
        assert np.isnan(fish.undistort_points([[-0.5, K_FE[1, 2]]], exact=False)).all()


def test_a_pixel_no_ray_in_front_reaches_is_nan():
    # a lens whose picture reaches beyond 90 degrees: its corner pixels have no pinhole ray
    wide = Camera([[200, 0, 399.5], [0, 200, 251.5], [0, 0, 1]], [0.0, 0.0, 0.0, 0.0], SIZE, model="fisheye")
    out = wide.undistort_points([[399.5, 251.5], [-0.5, -0.5], [399.5 + 200 * 1.2, 251.5]])
    assert np.isnan(out[1]).all()
    assert np.isfinite(out[[0, 2]]).all()
    h, v = wide.fov_deg  # equidistant without distortion: angle = distance / f
    assert h == pytest.approx(np.degrees(800 / 200), abs=1e-6)
    assert v == pytest.approx(np.degrees(503 / 200), abs=1e-6)


def test_fov_of_the_real_lens(fish):
    h, v = fish.fov_deg
    assert 175 < h < 185
    assert 95 < v < 110
    assert Camera(K_FE, D_FE, SIZE).fov_deg[0] == pytest.approx(108.1, abs=0.1)  # the pinhole reading


@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.0])
def test_fisheye_maps_are_opencvs(alpha):
    # a fisheye of 120 x 70 degrees: its edges within 80 degrees of the axis, where OpenCV's choice holds
    fish = Camera([[400, 0, 399.5], [0, 390, 251.5], [0, 0, 1]], D_FE, SIZE, model="fisheye")
    ideal = fish.undistorted(alpha)
    newK = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(fish.K, D_FE, SIZE, np.eye(3), balance=alpha)
    np.testing.assert_allclose(ideal.K[:, [0, 2]], newK[:, [0, 2]], rtol=1e-12)
    assert not ideal.has_distortion
    assert ideal.model == "pinhole"
    assert ideal.image_size == SIZE
    mx, my = fish.undistort_maps(alpha)
    cx, cy = cv2.fisheye.initUndistortRectifyMap(fish.K, D_FE, np.eye(3), ideal.K, SIZE, cv2.CV_32FC1)
    assert mx.dtype == np.float32
    assert mx.shape == (503, 800)
    assert max(np.abs(mx - cx).max(), np.abs(my - cy).max()) < 2e-3  # float32 rounding of OpenCV's maps


@pytest.mark.parametrize("new_size", [SIZE, (400, 300)])
def test_undistorting_a_180_degree_fisheye_crops_to_the_picture_around_its_middle(fish, new_size):
    # the real lens sees its left and right edges 90 degrees off the axis: no ideal pinhole point there
    w, h = new_size
    for alpha, widest_deg in ((0.0, 130.0), (0.5, 150.0), (1.0, 160.0 + 1e-9)):
        ideal = fish.undistorted(alpha, new_size)
        assert abs(ideal.cx - (w - 1) / 2) < 0.01 * w  # centred across the width, as the lens is
        assert abs(ideal.cy - (h - 1) / 2) < 0.15 * h
        assert 120.0 < ideal.fov_deg[0] < widest_deg  # at most 80 degrees each side
        mx, my = fish.undistort_maps(alpha, new_size)
        inside = (mx >= -0.5) & (mx <= SIZE[0] - 0.5) & (my >= -0.5) & (my <= SIZE[1] - 0.5)
        if alpha == 0.0:
            assert inside.all()  # only pixels with picture behind them
        else:
            assert 0.7 < inside.mean() < 1.0


def test_a_fisheye_past_180_degrees_undistorts_within_80_degrees_of_its_axis():
    # an equidistant lens of 229 degrees across a 800 x 600 picture (its corners beyond what it sees)
    wide = Camera([[200, 0, 399.5], [0, 200, 299.5], [0, 0, 1]], [0.0] * 4, (800, 600), model="fisheye")
    ideal = wide.undistorted(1.0)
    assert ideal.fov_deg[1] == pytest.approx(160.0, abs=0.05)  # up to 80 degrees along both axes
    assert 160.0 < ideal.fov_deg[0] < 170.0
    mx, my = wide.undistort_maps(0.0)
    assert ((mx >= -0.5) & (mx <= 799.5) & (my >= -0.5) & (my <= 599.5)).all()


@pytest.mark.parametrize("n", [4, 5, 8, 12, 14])
@pytest.mark.parametrize("alpha", [0.0, 1.0])
def test_pinhole_maps_are_opencvs(n, alpha):
    dist = [-0.2, 0.05, 0.001, -0.001, -0.003, 0.05, -0.01, 0.002, 0.001, -0.0005, 0.0008, 0.0003, 0.01, -0.008][:n]
    cam = Camera.from_fov(90, (640, 480), dist=dist)
    ideal = cam.undistorted(alpha, (320, 240))
    newK, _ = cv2.getOptimalNewCameraMatrix(cam.K, cam.dist, (640, 480), alpha, (320, 240))
    np.testing.assert_allclose(ideal.K, newK, rtol=1e-12)
    mx, my = cam.undistort_maps(alpha, (320, 240))
    cx, cy = cv2.initUndistortRectifyMap(cam.K, cam.dist, None, newK, (320, 240), cv2.CV_32FC1)
    assert max(np.abs(mx - cx).max(), np.abs(my - cy).max()) < 2e-3


@pytest.mark.parametrize("alpha", [0.0, 1.0])
def test_undistort_image_puts_each_point_where_the_ideal_camera_sees_it(alpha):
    # a fisheye of 120 x 70 degrees (OpenCV's choice of the new camera is erratic for a picture beyond 180)
    fish = Camera([[400, 0, 399.5], [0, 400, 251.5], [0, 0, 1]], D_FE, SIZE, model="fisheye")
    # soft dots drawn where the fisheye sees points up to 45 degrees off the axis
    angles = np.radians([[20, 0], [0, 25], [-45, 10], [30, -20], [-25, -22]])
    pts = np.column_stack([np.tan(angles), np.ones(len(angles))]) * 1000.0
    px = fish.project(pts, np.eye(4))
    u, v = np.meshgrid(np.arange(800.0), np.arange(503.0))
    image = np.zeros((503, 800))
    for x, y in px:
        image += np.exp(-((u - x) ** 2 + (v - y) ** 2) / (2 * 2.0**2))
    image = (200 * image).astype(np.float32)
    ideal = fish.undistorted(alpha)
    out = fish.undistort_image(image, alpha)
    mx, my = cv2.fisheye.initUndistortRectifyMap(fish.K, D_FE, np.eye(3), ideal.K, SIZE, cv2.CV_32FC1)
    assert np.abs(out - cv2.remap(image, mx, my, cv2.INTER_LINEAR)).max() < 0.5  # OpenCV's own undistortion
    for want in ideal.project(pts, np.eye(4)):
        x0, y0 = np.round(want).astype(int)
        win = out[y0 - 4 : y0 + 5, x0 - 4 : x0 + 5].astype(float)
        win = np.where(win > 0.3 * win.max(), win, 0.0)  # the dot's core
        got = np.array(
            [(win * u[y0 - 4 : y0 + 5, x0 - 4 : x0 + 5]).sum(), (win * v[y0 - 4 : y0 + 5, x0 - 4 : x0 + 5]).sum()]
        )
        assert np.hypot(*(got / win.sum() - want)) < 0.3


def test_scaled_keeps_the_model(fish):
    half = fish.scaled((400, 252), tol=0.01)
    assert half.model == "fisheye"
    assert np.array_equal(half.dist, fish.dist)
    assert "model='fisheye'" in repr(fish)
    assert "model" not in repr(Camera(K_FE, None, SIZE))


def test_json_round_trip_and_old_files_are_pinhole(fish, tmp_path):
    back = Camera.load(fish.save(tmp_path / "fish.json"))
    assert back.model == "fisheye"
    assert np.array_equal(back.K, fish.K)
    assert np.array_equal(back.dist, fish.dist)
    assert json.loads((tmp_path / "fish.json").read_text())["model"] == "fisheye"
    old = {"camera_matrix": K_FE.tolist(), "dist_coeffs": [0.1, 0, 0, 0, 0], "image_size": [800, 503]}
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert Camera.load(tmp_path / "old.json").model == "pinhole"
    assert "model" not in Camera.load(tmp_path / "old.json").to_dict()


@pytest.mark.parametrize("suffix", [".yml", ".xml"])
def test_filestorage_round_trip_and_opencvs_sample_file(fish, tmp_path, suffix):
    back = Camera.load(fish.save(tmp_path / f"fish{suffix}"))
    assert back.model == "fisheye"
    assert np.array_equal(back.dist, fish.dist)
    assert back.image_size == SIZE
    # a file as OpenCV's calibration sample writes it (fisheye_model: 1), written by OpenCV itself
    fs = cv2.FileStorage(str(tmp_path / f"sample{suffix}"), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 800)
    fs.write("image_height", 503)
    fs.write("flags", 0)
    fs.write("fisheye_model", 1)
    fs.write("camera_matrix", K_FE)
    fs.write("distortion_coefficients", D_FE.reshape(4, 1))
    fs.release()
    sample = Camera.load(tmp_path / f"sample{suffix}")
    assert sample.model == "fisheye"
    assert np.array_equal(sample.dist, D_FE)
    assert Camera.load(Camera(K_FE, D_FE, SIZE).save(tmp_path / f"pin{suffix}")).model == "pinhole"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: Camera(K_FE, D_FE, SIZE, model="equidistant"), "is 'fisheye'"),
        (lambda: Camera(K_FE, D_FE, SIZE, model=None), "model must be 'pinhole'"),
        (lambda: Camera(K_FE, [0.1, 0, 0, 0, 0], SIZE, model="fisheye"), "4 distortion coefficients"),
        (lambda: Camera(K_FE, D_FE, SIZE, model="fisheye").undistorted(1.5), "alpha must be"),
        (lambda: Camera(K_FE, D_FE, SIZE, model="fisheye").undistorted(True), "alpha must be"),
        (lambda: Camera(K_FE, D_FE, SIZE).undistort_image(np.zeros((480, 640))), "camera.for_image"),
        (lambda: Camera(K_FE, D_FE, SIZE).undistort_image([1, 2]), "picture array"),
        (lambda: Camera.from_dict({"camera_matrix": K_FE, "image_size": SIZE, "lens_model": "fisheye"}), "model"),
    ],
)
def test_bad_input_says_what_to_do(call, message):
    with pytest.raises(CameraError, match=message):
        call()


def test_filestorage_with_a_bad_fisheye_flag_is_refused(tmp_path):
    text = (
        "%YAML:1.0\n---\nimage_width: 800\nimage_height: 503\nfisheye_model: 2\n"
        "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
        "   data: [290., 0., 400., 0., 290., 274., 0., 0., 1.]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n   data: [0., 0., 0., 0.]\n"
    )
    (tmp_path / "c.yml").write_text(text)
    with pytest.raises(CameraError, match="fisheye_model must be 0"):
        Camera.load(tmp_path / "c.yml")


@pytest.mark.parametrize(
    ("dist", "model", "ros_model"),
    [
        ([0.1, -0.2, 0.001, 0.002, 0.05], "pinhole", "plumb_bob"),
        ([0.1, -0.2, 0.001, 0.002, 0.05, 0.01, 0.02, 0.03], "pinhole", "rational_polynomial"),
        (D_FE, "fisheye", "equidistant"),
    ],
)
def test_ros_camera_info_round_trips_each_model(tmp_path, dist, model, ros_model):
    from fidlearn.ros import camera_info_yaml, load_camera_info, save_camera_info

    cam = Camera(K_FE, dist, SIZE, model=model)
    assert f"distortion_model: {ros_model}\n" in camera_info_yaml(cam)
    back = load_camera_info(save_camera_info(cam, tmp_path / "camera_info.yaml"))
    assert back.model == model
    assert np.array_equal(back.dist, cam.dist)
    assert np.array_equal(back.K, cam.K)


def test_ros_equidistant_as_ross_calibrator_writes_it():
    from fidlearn.ros import camera_from_camera_info

    text = (
        "image_width: 800\nimage_height: 503\ncamera_name: narrow_stereo\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [290.050152, 0.000000, 399.938345, 0.000000, 289.392837, 273.885669, 0.000000, 0.000000, 1.000000]\n"
        "distortion_model: equidistant\ndistortion_coefficients:\n  rows: 1\n  cols: 4\n"
        "  data: [-0.030464, -0.019695, 0.002098, 0.001030]\n"
    )
    cam = camera_from_camera_info(text)
    assert cam.model == "fisheye"
    np.testing.assert_array_equal(cam.dist, D_FE)
    from fidlearn.errors import RosFormatError

    with pytest.raises(RosFormatError, match="equidistant has 4 coefficients"):
        camera_from_camera_info(text.replace("cols: 4", "cols: 5").replace("0.001030]", "0.001030, 0.0]"))
