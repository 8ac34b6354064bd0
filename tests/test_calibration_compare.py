"""Two calibrations compared across the picture, and an uncertainty that covers what views share.

Known answers: a pure focal-length change moves every pixel by ``e (x - cx)``; a principal-point
shift is almost a rotation of the camera; the propagated noise matches a Monte Carlo of the
calibration's covariance; simulated sets with a per-view error have ``k^2`` well above 1 and the
inflated standard deviations cover their spread, white ones do not; on real photos the halves
of one set agree within 2 of their stated noise.
"""

from __future__ import annotations

import shutil

import cv2
import matplotlib.pyplot as plt
import numpy as np
import pytest

from fidlearn import Board, Camera, calibrate_checkerboard, compare_calibrations, frames
from fidlearn.calibration import Calibration, intrinsics_uncertainty
from fidlearn.calibration import compare as compare_module
from fidlearn.cli import main
from fidlearn.data import data_path
from fidlearn.errors import CalibrationError

BOARD = Board.checkerboard((9, 6), 25)
TRUE = Camera.load(data_path("calibration", "camera_true.json"))
VIEWS = sorted(data_path("calibration").glob("view_*.png"))
RIGHT = sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))


@pytest.fixture(scope="module")
def halves():
    return calibrate_checkerboard(VIEWS[0::2], board=BOARD), calibrate_checkerboard(VIEWS[1::2], board=BOARD)


def test_a_focal_length_change_moves_each_pixel_by_its_distance_from_the_centre():
    # the principal point at the picture's centre (pixel centres at integers): the grid is symmetric about it
    a = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, (640, 480))
    b = Camera([[606, 0, 319.5], [0, 606, 239.5], [0, 0, 1]], None, (640, 480))
    c = compare_calibrations(a, b, grid=(9, 7))
    expected = 0.01 * (c.grid_px - [319.5, 239.5])  # the rotation fitted is none: the change is symmetric
    np.testing.assert_allclose(c.difference_px, expected, atol=1e-6)
    assert c.rotation_deg < 1e-6
    assert c.verdict == "cannot tell"
    assert c.expected_px is None
    assert c.ratio is None


def test_a_principal_point_shift_is_taken_as_a_turn_of_the_camera():
    a = Camera([[600, 0, 320], [0, 600, 240], [0, 0, 1]], None, (640, 480))
    b = Camera([[600, 0, 326], [0, 600, 240], [0, 0, 1]], None, (640, 480))
    c = compare_calibrations(a, b)
    assert c.rotation_deg == pytest.approx(np.degrees(np.arctan(6 / 600)), rel=0.05)
    # what is left grows as (x / f)^2 from the centre, the fit spreading it: 6 px everywhere becomes
    # 0.77 px RMS, 0.23 px in the middle
    assert c.rms_difference_px < 1.0
    near = np.hypot(*(c.grid_px - [320, 240]).transpose(2, 0, 1)) < 60
    assert np.all(c.difference_norm_px[near] < 0.3)


def test_halves_of_one_synthetic_set_agree_and_match_the_true_camera(halves):
    c = compare_calibrations(*halves)
    assert c.verdict == "agree", c
    assert 0.3 < c.ratio < 2.0
    # the truth, taken as exact: the calibration's own noise is the yardstick
    t = compare_calibrations(halves[0], TRUE)
    assert t.verdict == "agree"
    assert "taken as exact" in t.reason
    assert np.all(np.isfinite(c.expected_px))
    assert c.expected_px.shape == (24, 32)


def test_cameras_carrying_their_uncertainty_compare_as_their_calibrations(halves, tmp_path):
    """A camera file written from camera_with_uncertainty keeps the covariance: compared, it brings it, as the
    calibration it came from does (it was taken as exact, and two of them gave "cannot tell")."""
    from fidlearn.calibration import camera_with_uncertainty  # noqa: PLC0415

    files = [camera_with_uncertainty(h).save(tmp_path / f"{k}.json") for k, h in enumerate(halves)]
    cams = [Camera.load(f) for f in files]
    as_files, as_calibrations = compare_calibrations(*cams), compare_calibrations(*halves)
    assert as_files.verdict == as_calibrations.verdict == "agree"
    assert as_files.ratio == pytest.approx(as_calibrations.ratio, rel=1e-6)
    bare = compare_calibrations(halves[0].camera, halves[1].camera)
    assert bare.verdict == "cannot tell"
    assert "neither camera carries its uncertainty" in bare.reason


def test_another_camera_differs_beyond_noise(halves):
    other = Camera(TRUE.K * [[1.01], [1.01], [1]], TRUE.dist, TRUE.image_size)
    c = compare_calibrations(halves[0], other)
    assert c.verdict == "differ beyond noise"
    assert c.ratio > 5


def test_the_propagated_noise_matches_a_monte_carlo_of_the_covariance(halves):
    cal = halves[0]
    u = intrinsics_uncertainty(cal)
    c = compare_calibrations(cal, cal.camera, grid=(8, 6))  # only a's covariance counts
    # the same comparison, a's intrinsics drawn from its covariance (b exact, the fit's weights held)
    cams = (cal.camera, cal.camera)
    px = c.grid_px.reshape(-1, 2)
    index = np.array([("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3").index(n) for n in u.names])
    weights = compare_module._weights(cams, ((index, u.covariance), None), px)
    theta = compare_module._params(cal.camera)
    rng = np.random.default_rng(3)
    draws = []
    for dx in rng.multivariate_normal(np.zeros(len(index)), u.covariance, size=300):
        t = theta.copy()
        t[index] += dx
        draws.append(compare_module._difference(t, theta, *cams, px, weights)[0])
    spread = np.sqrt(np.mean(np.sum(np.array(draws) ** 2, axis=2), axis=0)).reshape(c.expected_px.shape)
    np.testing.assert_allclose(spread, c.expected_px, rtol=0.2)


def _simulated_set(rng, per_view_fx: float, n_views: int = 12, noise_px: float = 0.1) -> Calibration:
    """A calibration of points: the true camera's views of the board, each seen through its own fx."""
    obj = np.array([[25.0 * i, 25.0 * j, 0] for j in range(6) for i in range(9)], dtype=np.float32)
    objs, imgs, poses = [], [], []
    for _k in range(n_views):
        ang = np.radians(rng.uniform(-35, 35, size=3) * [1, 1, 0.5])
        R = frames.rotation_from_rpy_deg(*np.degrees(ang))
        centre = np.array([rng.uniform(-120, 120), rng.uniform(-90, 90), rng.uniform(450, 650)])
        T = frames.make_transform(R, centre - R @ [100, 62.5, 0])
        K = TRUE.K * [[1 + per_view_fx * rng.standard_normal()], [1], [1]]  # a view's own error
        rvec, tvec = frames.rvec_tvec_from_transform(T)
        px = cv2.projectPoints(obj.astype(float), rvec, tvec, K, TRUE.dist)[0].reshape(-1, 2)
        objs.append(obj.reshape(-1, 1, 3))
        imgs.append((px + noise_px * rng.standard_normal(px.shape)).astype(np.float32).reshape(-1, 1, 2))
        poses.append(T)
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(objs, imgs, TRUE.image_size, None, None)
    names = [f"view {k}" for k in range(n_views)]
    return Calibration(
        Camera(K, dist.ravel(), TRUE.image_size),
        float(rms),
        {},
        names,
        {},
        [],
        T_camera_board={n: frames.transform_from_rvec_tvec(r, t) for n, r, t in zip(names, rvecs, tvecs)},
        image_points_px={n: i.reshape(-1, 2).astype(float) for n, i in zip(names, imgs)},
        board_points_mm={n: o.reshape(-1, 3).astype(float) for n, o in zip(names, objs)},
    )


def test_white_noise_leaves_the_covariance_alone_and_a_per_view_error_inflates_it_enough():
    rng = np.random.default_rng(11)
    white = [intrinsics_uncertainty(_simulated_set(rng, 0.0)).k2 for _ in range(8)]
    assert 0.6 < np.mean(white) < 1.4  # E[k^2] = 1 exactly with white noise
    z_white, z_honest, k2 = [], [], []
    for _ in range(25):
        cal = _simulated_set(rng, 0.01)  # each view's focal length 1 % off, at random
        u = intrinsics_uncertainty(cal)
        for name, error in (("fx", cal.camera.fx - TRUE.fx), ("cx", cal.camera.cx - TRUE.cx)):
            z_white.append(error / u.white_std[name])
            z_honest.append(error / u.std[name])
        k2.append(u.k2)
    assert np.median(k2) > 10  # measured 23
    # OpenCV's standard deviations are several times too small (measured 4.8), the inflated ones cover
    # the spread (measured 1.0)
    assert np.sqrt(np.mean(np.square(z_white))) > 3
    assert 0.6 < np.sqrt(np.mean(np.square(z_honest))) < 1.6


@pytest.mark.parametrize("split", ["alternate", "first and last"])
def test_halves_of_opencvs_real_set_agree_within_twice_their_stated_noise(split):
    # measured: the views share 2.3-2.9 times the variance white noise would give (k^2)
    parts = (RIGHT[0::2], RIGHT[1::2]) if split == "alternate" else (RIGHT[:6], RIGHT[6:])
    a, b = (calibrate_checkerboard(p, board=BOARD) for p in parts)
    assert intrinsics_uncertainty(a).k2 > 1.5
    assert intrinsics_uncertainty(b).k2 > 1.5
    c = compare_calibrations(a, b)
    assert c.ratio < 2.0, c
    assert c.verdict != "differ beyond noise", c


def test_bad_inputs_say_what_to_do(halves):
    with pytest.raises(CalibrationError, match="one resolution"):
        compare_calibrations(halves[0], TRUE.scaled((1280, 960)))
    with pytest.raises(CalibrationError, match="Calibration or a Camera"):
        compare_calibrations(halves[0], "camera.json")
    with pytest.raises(CalibrationError, match="grid"):
        compare_calibrations(halves[0], TRUE, grid=(1, 5))
    with pytest.raises(CalibrationError, match="camera file"):
        intrinsics_uncertainty(TRUE)


def test_the_plot_shows_both_maps(halves):
    fig = compare_calibrations(*halves).plot()
    assert len(fig.axes) == 4  # two heat maps and their colour bars
    assert "agree" in fig._suptitle.get_text()
    plt.close(fig)


def test_cli_compares_two_folders_and_writes_the_plot(capsys, tmp_path):
    for k, view in enumerate(VIEWS):
        (tmp_path / ("a" if k % 2 == 0 else "b")).mkdir(exist_ok=True)
        shutil.copy(view, tmp_path / ("a" if k % 2 == 0 else "b") / view.name)
    plot = tmp_path / "diff.png"
    code = main(
        ["compare-calibrations", str(tmp_path / "a"), str(tmp_path / "b")]
        + ["--pattern", "9x6", "--square-mm", "25", "--report", str(plot)]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "verdict: agree" in out
    assert plot.stat().st_size > 0


def test_cli_refuses_a_folder_without_its_board_before_any_work(capsys, tmp_path):
    (tmp_path / "photos").mkdir()
    code = main(["compare-calibrations", str(data_path("calibration", "camera_true.json")), str(tmp_path / "photos")])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    assert captured.err.startswith("error: B ")


FISHEYE = data_path("real", "fisheye_checkerboard")


def test_a_fisheye_focal_length_change_moves_each_pixel_by_its_distance_from_the_centre():
    # equidistant: r = f theta, so a focal length 1 % longer moves every pixel 1 % further out; the picture's
    # corners, 104 degrees off the axis, have no ray a pinhole-style x/z can carry: left out
    K = np.array([[250.0, 0, 399.5], [0, 250.0, 251.5], [0, 0, 1]])
    a = Camera(K, [0.0] * 4, (800, 504), model="fisheye")
    b = Camera([[252.5, 0, 399.5], [0, 252.5, 251.5], [0, 0, 1]], [0.0] * 4, (800, 504), model="fisheye")
    c = compare_calibrations(a, b, grid=(9, 7))
    theta = np.hypot(*(c.grid_px - [399.5, 251.5]).transpose(2, 0, 1)) / 250.0
    inside = theta < np.radians(89.0)
    np.testing.assert_allclose(c.difference_px[inside], 0.01 * (c.grid_px[inside] - [399.5, 251.5]), atol=1e-6)
    assert np.all(np.isnan(c.difference_px[theta > np.radians(91.0)]))
    assert c.rotation_deg < 1e-4  # none: arccos near 1 is good to about 1e-6 degrees


def _fisheye_set(views: dict) -> Calibration:
    """A fisheye Calibration of stored corners {name: (48, 2) px} of data/real/fisheye_checkerboard."""
    from fidlearn.calibration.run import _calibrate_points

    obj = np.zeros((48, 3))
    obj[:, :2] = np.mgrid[0:6, 0:8].T.reshape(-1, 2) * 25.0
    img = [np.asarray(v, float) for v in views.values()]
    rms, K, dist, rotations, tvecs, _, per_view = _calibrate_points(
        [obj] * len(img), img, (800, 503), 0, None, "fisheye"
    )
    T = {n: frames.make_transform(R, np.ravel(t)) for n, R, t in zip(views, rotations, tvecs)}
    return Calibration(
        camera=Camera(K, dist, (800, 503), model="fisheye"),
        rms_px=rms,
        per_view_rms_px=dict(zip(views, per_view)),
        used=list(views),
        std_intrinsics=None,
        rejected=[],
        T_camera_board=T,
        image_points_px=dict(zip(views, img)),
        board_points_mm={n: obj for n in views},
    )


def test_a_fisheye_calibrations_white_uncertainty_is_opencvs():
    cal = calibrate_checkerboard(
        sorted((FISHEYE / "mono").glob("*.png")), board=Board.checkerboard((6, 8), 25), model="fisheye"
    )
    u = intrinsics_uncertainty(cal)
    assert u.names == ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")
    for name, std in cal.std_intrinsics.items():  # the same Schur complement, reached another way
        assert u.white_std[name] == pytest.approx(std, rel=1e-6)
    assert u.inflation > 2  # six real views of a wide lens share far more than white noise


def test_a_fixed_aspect_ratio_ties_fx_to_fy_in_the_uncertainty_as_opencv_does():
    """With CALIB_FIX_ASPECT_RATIO fx = a fy: OpenCV states fy's deviation (1.06 px on these photos) and none for
    fx. The uncertainty took fx as held and fy alone as free (0.27 px, 4 times too certain); it now moves fx with
    fy, and the camera's covariance gives fx a times fy's deviation, fully correlated."""
    from fidlearn.calibration import camera_with_uncertainty  # noqa: PLC0415

    cal = calibrate_checkerboard(RIGHT, board=BOARD, flags=cv2.CALIB_FIX_ASPECT_RATIO, reject_outliers=False)
    u = intrinsics_uncertainty(cal)
    assert u.names[:2] == ("fy", "cx")
    assert u.white_std["fy"] == pytest.approx(cal.std_intrinsics["fy"], rel=1e-6)
    cov = camera_with_uncertainty(cal).intrinsics_covariance
    a = cal.camera.fx / cal.camera.fy
    assert np.sqrt(cov[0, 0]) == pytest.approx(a * np.sqrt(cov[1, 1]), rel=1e-12)
    assert cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(cov[0, 2:], a * cov[1, 2:], rtol=1e-12)


def test_two_copies_of_a_fisheye_lens_differ_beyond_noise_and_two_halves_of_one_agree():
    import json

    sets = json.loads((FISHEYE / "corners.json").read_text())["sets"]
    left = list(sets["left"].items())
    even, odd = _fisheye_set(dict(left[0::2])), _fisheye_set(dict(left[1::2]))
    halves = compare_calibrations(even, odd, tolerance_px=2.0)
    assert halves.verdict == "agree", halves  # 0.6 times the noise
    # the right camera of the stereo pair: its principal point 3 to 4 px from the left one's
    pair = compare_calibrations(_fisheye_set(sets["left"]), _fisheye_set(sets["right"]), tolerance_px=2.0)
    assert pair.verdict == "differ beyond noise", pair  # 2.9 times
    assert 0.5 < pair.rms_difference_px < 3.0


def test_a_face_on_set_keeps_the_large_uncertainty_of_its_distortion_coefficients():
    """Every view face-on: the focal length and k2, k3 are barely observed. OpenCV's deviations say so
    (k3 about 1e6); the uncertainty with what the views share beyond noise said k3 was known to about 2,
    its weak directions cut off by the pseudo-inverse (k3's column is 1e5 times fx's)."""
    from fidlearn.calibration.run import _calibrate_points

    rng = np.random.default_rng(4)
    obj = np.array([[25.0 * i, 25.0 * j, 0] for j in range(6) for i in range(9)])
    views = {}
    for k in range(12):
        T = frames.make_transform(
            frames.rot_z(rng.uniform(-0.3, 0.3)),
            [rng.uniform(-160, -40), rng.uniform(-120, -10), rng.uniform(450, 650)],
        )
        rvec, tvec = frames.rvec_tvec_from_transform(T)
        px = cv2.projectPoints(obj, rvec, tvec, TRUE.K, TRUE.dist)[0].reshape(-1, 2)
        views[f"view {k}"] = px + 0.05 * rng.standard_normal(px.shape)
    rms, K, dist, rotations, tvecs, std_from, per_view = _calibrate_points(
        [obj] * len(views), list(views.values()), TRUE.image_size, 0, None
    )
    cal = Calibration(
        camera=Camera(K, dist, TRUE.image_size),
        rms_px=rms,
        per_view_rms_px=dict(zip(views, per_view)),
        used=list(views),
        std_intrinsics=None,
        rejected=[],
        T_camera_board={n: frames.make_transform(R, np.ravel(t)) for n, R, t in zip(views, rotations, tvecs)},
        image_points_px=views,
        board_points_mm={n: obj for n in views},
        _std_from=std_from,
    )
    assert cal.std_intrinsics["fx"] > 50  # the focal length is not observed
    u = intrinsics_uncertainty(cal)
    for name, std in cal.std_intrinsics.items():
        assert u.white_std[name] == pytest.approx(std, rel=1e-3), name
        assert u.std[name] >= 0.999 * std, name


def test_cli_says_which_camera_file_brings_its_uncertainty(halves, capsys, tmp_path):
    """The command said "no uncertainty" of every camera file, also of one written by fidlearn calibrate, whose
    covariance the comparison uses."""
    from fidlearn.calibration import camera_with_uncertainty  # noqa: PLC0415

    carried = camera_with_uncertainty(halves[0]).save(tmp_path / "a.json")
    code = main(["compare-calibrations", str(carried), str(data_path("calibration", "camera_true.json"))])
    out = capsys.readouterr().out
    assert code == 0
    assert "A: Camera(" in out
    assert "(a camera file: with its calibration's uncertainty)" in out
    assert out.count("(a camera file: no uncertainty)") == 1
    assert "b is a camera without uncertainty, taken as exact" in out
