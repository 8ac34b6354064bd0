"""The calibration coach: its covariance against OpenCV's, its flags on seeded bad sets, its next view."""

from __future__ import annotations

import dataclasses
import glob
import importlib
import math

import cv2
import numpy as np
import pytest
from matplotlib.colors import to_rgba

import fidlearn
from fidlearn import Camera, _stats, frames
from fidlearn.errors import CalibrationError
from fidlearn.planning import bent_board
from fidlearn.planning.coach import GOOD_UNCERTAINTY_PX, bent_views, coach, coach_calibration, uncertainty_map
from fidlearn.planning.figure import coach_figure

coach_module = importlib.import_module("fidlearn.planning.coach")  # the module: its name is taken by the function
CAMERA = Camera.load(fidlearn.data_path("calibration/camera_true.json"))
BOARD = np.array([[i * 25.0, j * 25.0, 0.0] for j in range(6) for i in range(9)])


def board_pose(rng, region=None, tilt_max_deg=40.0):
    centre = BOARD.mean(axis=0)
    while True:
        if region is None:
            u, v = rng.uniform(0.1, 0.9) * CAMERA.width, rng.uniform(0.1, 0.9) * CAMERA.height
        else:
            u, v = (region % 3 + rng.uniform()) / 3 * CAMERA.width, (region // 3 + rng.uniform()) / 3 * CAMERA.height
        ray = cv2.undistortPoints(np.array([[[u, v]]]), CAMERA.K, CAMERA.dist).reshape(2)
        C = np.array([ray[0], ray[1], 1.0]) * rng.uniform(400, 800)
        axis = rng.normal(size=2)
        R = cv2.Rodrigues(np.array([*(axis / np.linalg.norm(axis)), 0.0]) * math.radians(rng.uniform(0, tilt_max_deg)))[
            0
        ]
        T = frames.make_transform(R, C - R @ centre)
        px = CAMERA.project(frames.transform_points(T, BOARD), np.eye(4))
        if (
            np.all(frames.transform_points(T, BOARD)[:, 2] > 0)
            and np.all(px >= 0)
            and np.all(px[:, 0] <= CAMERA.width - 1)
            and np.all(px[:, 1] <= CAMERA.height - 1)
        ):
            return T


def judge(rng, poses, other_sizes=0, bend_view=None, sigma=0.1):
    observed = []
    for k, T in enumerate(poses):
        pts = BOARD.copy()
        if k == bend_view:  # a print lifted off its backing: a 4 mm bow
            pts[:, 2] = 16.0 * ((pts[:, 0] - pts[:, 0].mean()) / np.ptp(pts[:, 0])) ** 2
        observed.append(
            CAMERA.project(frames.transform_points(T, pts), np.eye(4)) + rng.normal(0, sigma, (len(pts), 2))
        )
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [BOARD.astype(np.float32)] * len(observed),
        [o.astype(np.float32) for o in observed],
        CAMERA.image_size,
        None,
        None,
    )
    cam = Camera(K, dist.ravel(), CAMERA.image_size)
    names = [f"view {i}" for i in range(len(observed))]
    T = {n: frames.transform_from_rvec_tvec(r, t) for n, r, t in zip(names, rvecs, tvecs)}
    return coach(
        cam,
        {n: BOARD for n in names},
        dict(zip(names, observed)),
        T,
        corner_sigma_px=rms / math.sqrt(2),
        other_sizes=other_sizes,
    )


@pytest.fixture(scope="module")
def bundled():
    views = sorted(glob.glob(str(fidlearn.data_path("calibration")) + "/view_*.png"))
    return fidlearn.calibrate_checkerboard(views, (9, 6), 25.0)


def test_the_intrinsics_standard_deviations_equal_opencvs(bundled):
    c = coach_calibration(bundled)
    std = np.sqrt(np.diag(c.covariance))
    for k, name in enumerate(["fx", "fy", "cx", "cy"]):
        assert std[k] == pytest.approx(bundled.std_intrinsics[name], rel=0.05)
    assert c.flags == []  # the bundled set is a good one
    assert c.good_fraction == 1.0
    assert c.uncertainty_px.max() < GOOD_UNCERTAINTY_PX


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_seeded_bad_sets_are_flagged_and_a_good_set_is_not(seed):
    rng = np.random.default_rng(seed)
    good = judge(rng, [board_pose(rng, region=k % 9) for k in range(20)])
    assert good.flags == []
    face_on = judge(rng, [board_pose(rng, tilt_max_deg=5) for _ in range(20)])
    assert any("every view is face-on" in f for f in face_on.flags)
    left = judge(rng, [board_pose(rng, region=k % 3 * 3) for k in range(20)])  # the left column only
    assert any("no board point in the top right, right, bottom right" in f for f in left.flags)
    few = judge(rng, [board_pose(rng, region=k) for k in range(6)])
    assert any("only 6 views" in f for f in few.flags)
    mixed = judge(rng, [board_pose(rng, region=k % 9) for k in range(20)], other_sizes=2)
    assert any("2 photos were taken at another resolution" in f for f in mixed.flags)
    bent = judge(rng, [board_pose(rng, region=k % 9) for k in range(20)], bend_view=7)
    # view 7 alone: its pull on the intrinsics does not make the other views look bent
    assert any("does not look flat in view 7 (4." in f for f in bent.flags)  # its 4 mm bow, measured


@pytest.mark.slow
def test_the_bend_test_is_an_f_test_at_its_stated_false_alarm_rate():
    # the textbook 95 % quantiles of F(3, nu), and chi-square(3) / 3 for a large nu
    for nu, f95 in ((10, 3.71), (20, 3.10), (120, 2.68)):
        assert _stats.f_isf(0.05, 3, nu) == pytest.approx(f95, abs=0.005)
    assert 3 * _stats.f_isf(0.05, 3, 20000) == pytest.approx(7.815, abs=0.01)
    # flat boards, Gaussian noise: at a false-alarm rate of 0.2 per set (0.01 per view, 20 views)
    # about 1 - 0.99^20 = 18 % of the sets have a view called bent; 40 sets, binomial bounds
    rng = np.random.default_rng(11)
    poses = [board_pose(rng, region=k % 9) for k in range(20)]
    names = [f"view {i}" for i in range(20)]
    flagged = 0
    for _ in range(40):
        observed = [
            CAMERA.project(frames.transform_points(T, BOARD), np.eye(4)) + rng.normal(0, 0.1, (54, 2)) for T in poses
        ]
        _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
            [BOARD.astype(np.float32)] * 20, [o.astype(np.float32) for o in observed], CAMERA.image_size, None, None
        )
        cam = Camera(K, dist.ravel(), CAMERA.image_size)
        T = {n: frames.transform_from_rvec_tvec(r, t) for n, r, t in zip(names, rvecs, tvecs)}
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(bent_board, "BENT_FALSE_ALARM", 0.2)
            mp.setattr(bent_board, "BENT_MIN_SAG_MM", 0.0)  # the statistical test alone
            flagged += bool(bent_views(cam, dict.fromkeys(names, BOARD), dict(zip(names, observed)), T))
    assert 1 <= flagged <= 14


def test_opencvs_right02_is_called_bent_and_its_noisiest_photos_are_not():
    # OpenCV's right02.jpg was taken with left02.jpg, whose board is bent. The calibration drops
    # right02 as an outlier view by default; kept, it is called bent (F 14 against a limit of 8).
    # right05 and right13 have 2 to 3 times the median view's residuals, but no bow explains
    # them beyond their own noise (F 4 and 2): noisy photos, not bent ones.
    views = sorted(glob.glob(str(fidlearn.data_path("real", "opencv_checkerboard_right")) + "/right*.jpg"))
    kept = fidlearn.calibrate_checkerboard(views, (9, 6), 25.0, reject_outliers=False)
    bent = bent_views(kept.camera, kept.board_points_mm, kept.image_points_px, kept.T_camera_board)
    assert any(n.endswith("right02.jpg") for n in bent)
    cal = fidlearn.calibrate_checkerboard(views, (9, 6), 25.0)
    bent = bent_views(cal.camera, cal.board_points_mm, cal.image_points_px, cal.T_camera_board)
    assert not any(n.endswith(("right05.jpg", "right13.jpg")) for n in bent)


def test_the_next_view_helps_more_than_a_random_one():
    rng = np.random.default_rng(5)
    poses = [board_pose(rng) for _ in range(5)]
    first = judge(np.random.default_rng(1), poses)
    assert first.next_view is not None
    assert "put the board" in str(first.next_view)
    coached = judge(np.random.default_rng(1), poses + [first.next_view.T_camera_board])
    randoms = [judge(np.random.default_rng(1), poses + [board_pose(rng)]) for _ in range(5)]
    assert np.mean(coached.uncertainty_px**2) < min(np.mean(r.uncertainty_px**2) for r in randoms)


def test_a_board_is_in_the_picture_only_with_its_outer_row_of_squares():
    """Hand-computed: fx = fy = 500 px, no distortion, 640x480; the 9x6 board of 25 mm squares face-on on the
    axis. Its inner corners span 200 x 125 mm, the print 250 x 175 mm: the print's half-width of 125 mm fits
    the picture's 319.5 px from 391 mm / 2 = 195.6 mm on, its inner corners already from 156.5 mm."""
    camera = Camera(np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]]), np.zeros(5), (640, 480))
    face_on = lambda d: frames.make_transform(np.eye(3), [0.0, 0.0, d] - BOARD.mean(axis=0))  # noqa: E731
    edge = 125.0 * 500.0 / 319.5
    for d, inside in [(edge - 1.0, False), (edge + 1.0, True), (160.0, False), (600.0, True)]:
        assert coach_module._board_in_picture(camera, BOARD, face_on(d)) is inside, d
    outline = coach_module._printed_outline(BOARD)
    np.testing.assert_allclose(outline.min(axis=0), [-25, -25, 0])
    np.testing.assert_allclose(outline.max(axis=0), [225, 150, 0])


def test_the_next_view_shows_the_whole_print_and_says_its_distance_in_cm(bundled):
    verdict = coach_calibration(bundled)
    view = verdict.next_view
    px = bundled.camera.project(
        frames.transform_points(view.T_camera_board, coach_module._printed_outline(BOARD)), np.eye(4)
    )
    assert np.all(px >= 0)
    assert np.all(px <= np.array(bundled.camera.image_size) - 1)
    assert view.distance_mm < 995
    assert f"about {view.distance_mm / 10:.0f} cm away" in str(view)
    far = dataclasses.replace(view, distance_mm=1234.0)
    assert "about 1.2 m away" in str(far)


def test_uncertainty_scales_with_the_covariance_and_vanishes_without_it():
    n = 4 + len(CAMERA.dist)
    assert np.all(uncertainty_map(CAMERA, np.zeros((n, n)), 600.0) == 0)
    cov = np.diag([0.3, 0.3, 0.2, 0.2, 1e-5, 1e-4, 1e-7, 1e-7, 1e-4])
    np.testing.assert_allclose(uncertainty_map(CAMERA, 4 * cov, 600.0), 2 * uncertainty_map(CAMERA, cov, 600.0))


def test_a_principal_point_error_alone_is_absorbed_by_the_pose():
    # a shift of (cx, cy) moves every pixel alike: a small turn of the camera undoes it up to
    # second order, so the coach does not count it against the calibration
    pinhole = Camera(np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]), np.zeros(5), (640, 480))
    cov = np.zeros((9, 9))
    cov[2, 2] = cov[3, 3] = 1.0  # cx and cy uncertain by 1 px
    assert uncertainty_map(pinhole, cov, 600.0).max() < 0.2
    cov_fx = np.zeros((9, 9))
    cov_fx[0, 0] = 1.0  # fx by 1 px: a scale, not absorbed at the edges
    u = uncertainty_map(pinhole, cov_fx, 600.0)
    assert u[:, [0, -1]].min() > 0.2
    assert u[:, [0, -1]].min() > 3 * u[:, 3:5].max()


def test_coach_refuses_an_empty_set_and_a_bad_sigma():
    with pytest.raises(CalibrationError, match="no views"):
        coach(CAMERA, {}, {}, {}, corner_sigma_px=0.1)
    with pytest.raises(CalibrationError, match="corner_sigma_px"):
        coach(CAMERA, {"a": BOARD}, {"a": BOARD[:, :2]}, {"a": np.eye(4)}, corner_sigma_px=0)


def test_coach_figure_draws(bundled):
    c = coach_calibration(bundled)
    fig = coach_figure(c, bundled.camera)
    assert "under 0.3 px over 100 %" in fig._suptitle.get_text()


def test_calibrate_prints_the_coach_and_draws_its_report(tmp_path, capsys):
    from fidlearn import cli

    status = cli.main(
        [
            "calibrate",
            str(fidlearn.data_path("calibration")),
            "--pattern",
            "9x6",
            "--square-mm",
            "25",
            "-o",
            str(tmp_path / "cam.json"),
            "--report",
            str(tmp_path / "report.png"),
        ]
    )
    out = capsys.readouterr().out
    assert status == 0
    assert "calibration coach: reprojection uncertainty: median" in out
    assert "next photo: put the board" in out
    assert (tmp_path / "report.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.json", "report.png"]


def _coverage_before(camera, image_points_px, grid):
    """The coach's own grid count as it was before it shared fidlearn.calibration.quality.coverage_grid."""
    cols, rows = grid
    out = np.zeros((rows, cols), dtype=int)
    for pts in image_points_px.values():
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        c = np.clip(((pts[:, 0] + 0.5) * cols // camera.width).astype(int), 0, cols - 1)
        r = np.clip(((pts[:, 1] + 0.5) * rows // camera.height).astype(int), 0, rows - 1)
        np.add.at(out, (r, c), 1)
    return out


def _ninths_before(points_px, image_size):
    """The command line's 3x3 count as it was before (coverage_grid's default grid)."""
    w, h = image_size
    grid = np.zeros((3, 3), dtype=int)
    for pts in points_px:
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        col = np.clip(((pts[:, 0] + 0.5) * 3 // w).astype(int), 0, 2)
        row = np.clip(((pts[:, 1] + 0.5) * 3 // h).astype(int), 0, 2)
        np.add.at(grid, (row, col), 1)
    return grid


@pytest.mark.parametrize("grid", [(3, 3), (8, 6), (1, 1), (5, 2)])
def test_one_coverage_grid_serves_the_coach_and_the_command_line(grid):
    from fidlearn.calibration.quality import coverage_grid
    from fidlearn.planning.coach import _coverage

    rng = np.random.default_rng(7)
    views = {f"v{k}": rng.uniform(-0.5, [CAMERA.width - 0.5, CAMERA.height - 0.5], size=(54, 2)) for k in range(12)}
    views["edges"] = np.array([[-0.5, -0.5], [CAMERA.width - 0.5, CAMERA.height - 0.5], [CAMERA.width / 3 - 0.5, 0]])
    np.testing.assert_array_equal(_coverage(CAMERA, views, grid), _coverage_before(CAMERA, views, grid))
    np.testing.assert_array_equal(
        coverage_grid(views.values(), CAMERA.image_size, grid), _coverage_before(CAMERA, views, grid)
    )
    np.testing.assert_array_equal(
        coverage_grid(views.values(), CAMERA.image_size), _ninths_before(views.values(), CAMERA.image_size)
    )


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes for leg in [ax.get_legend()] if leg is not None for t in leg.get_texts()]


def test_the_coach_figure_names_only_what_it_draws(bundled):
    """The line at GOOD_UNCERTAINTY_PX is named in a legend only when it is drawn; no label names a line that is not."""
    c = coach_calibration(bundled)  # the bundled 20 views: under 0.3 px everywhere, no line to draw
    assert c.uncertainty_px.max() < GOOD_UNCERTAINTY_PX
    fig = coach_figure(c, bundled.camera)
    texts = [fig.axes[1].get_ylabel(), fig._suptitle.get_text(), *_legend_texts(fig)]
    assert not any("line" in t for t in texts)
    assert _legend_texts(fig) == []
    assert not fig.axes[0].collections  # no contour
    # the same verdict with a worse right half: the line is drawn, and the legend names it, in its colour
    worse = c.uncertainty_px.copy()
    worse[:, worse.shape[1] // 2 :] = 2 * GOOD_UNCERTAINTY_PX
    fig = coach_figure(dataclasses.replace(c, uncertainty_px=worse), bundled.camera)
    ax = fig.axes[0]
    assert len(ax.collections) == 1  # the contour
    assert _legend_texts(fig) == [f"{GOOD_UNCERTAINTY_PX} px"]
    (handle,) = ax.get_legend().legend_handles
    np.testing.assert_allclose(to_rgba(handle.get_color()), ax.collections[0].get_edgecolor()[0])
    assert "line" not in fig.axes[1].get_ylabel()


def test_calibrate_with_few_views_gives_one_warning_with_one_advice(tmp_path, capsys):
    from fidlearn import cli

    photos = sorted(fidlearn.data_path("calibration").glob("view_*.png"))[:5]
    out = tmp_path / "camera.json"
    assert cli.main(["calibrate", *map(str, photos), "--pattern", "9x6", "--square-mm", "25", "-o", str(out)]) == 0
    stdout, stderr = capsys.readouterr()
    said = (stdout + stderr).splitlines()
    few = [ln for ln in said if "views" in ln and "warning:" in ln]
    assert len(few) == 1
    assert few[0].strip() == "warning: only 5 views were used; take at least 10 (15 to 25 is usual)"


def test_the_next_view_places_the_whole_board_when_the_first_view_shows_part_of_it(bundled):
    """A ChArUco view may show a few corners only: the next photo was planned for that patch of the board
    (its centre, its outline), when the first view showed part of it, and the whole board fell off the picture."""
    whole = coach_calibration(bundled)
    first = bundled.used[0]
    part = np.arange(len(BOARD)).reshape(6, 9)[:2, :3].ravel()  # six corners at one end of the board
    points = {**bundled.board_points_mm, first: bundled.board_points_mm[first][part]}
    pixels = {**bundled.image_points_px, first: bundled.image_points_px[first][part]}
    verdict = coach(
        bundled.camera, points, pixels, bundled.T_camera_board, corner_sigma_px=bundled.rms_px / math.sqrt(2)
    )
    view = verdict.next_view
    assert coach_module._board_in_picture(bundled.camera, BOARD, view.T_camera_board)
    assert (view.where, view.tilt) == (whole.next_view.where, whole.next_view.tilt)
