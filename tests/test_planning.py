"""Predicted accuracy: against Monte-Carlo trials of estimate_pose, a hand-computed case, and the plan."""

from __future__ import annotations

import argparse
import math

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, Detection, FidlearnError, MarkerMap, estimate_pose, look_at, predict_accuracy
from fidlearn._staged import outputs_together
from fidlearn.cli import plan as command
from fidlearn.errors import TransformError
from fidlearn.planning import noise, plan_room, suggest_markers
from fidlearn.planning.predict import flip_probability


@pytest.fixture(scope="module")
def world():
    return MarkerMap.load(fidlearn.data_path("world_map.json"))


@pytest.fixture(scope="module")
def camera():
    return Camera.load(fidlearn.data_path("scenes/camera.json"))


def one_marker(size_mm: float = 160.0) -> MarkerMap:
    # rotation [0, 0, 0]: in the YZ plane facing +X, centre at (0, 0, 1000)
    return MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": size_mm,
            "markers": {"0": {"translation": [0, -size_mm / 2, 1000 + size_mm / 2], "rotation": [0, 0, 0]}},
        }
    )


def _sample_positions(world, camera, T, sigma, n, seed):
    # corners drawn with the noise the prediction assumes: each marker's corners jointly
    # Gaussian with the covariance of noise.corner_covariance (one side's two corners share its line)
    rng = np.random.default_rng(seed)
    p = predict_accuracy(world, camera, T, corner_sigma_px=sigma)
    truth = {i: camera.project(world.marker_corners(i), T) for i in p.marker_ids}
    root = {i: np.linalg.cholesky(noise.corner_covariance(truth[i], sigma)) for i in p.marker_ids}
    out = []
    for _ in range(n):
        dets = [Detection(i, truth[i] + (root[i] @ rng.normal(size=8)).reshape(4, 2)) for i in p.marker_ids]
        out.append(estimate_pose(dets, world, camera, corner_sigma_px=sigma, reject_outliers=False).position_mm)
    return p, np.array(out)


@pytest.mark.parametrize(
    ("eye", "target", "sigma"),
    [
        ([1000, 190, 230], [0, 190, 230], 0.3),  # face-on, 1 m
        ([1500, -600, 420], [0, 190, 230], 0.5),  # oblique, 1.7 m
        ([700, 900, 150], [0, 190, 300], 1.0),  # close, from the side
    ],
)
def test_predicted_covariance_equals_the_sample_covariance(world, camera, eye, target, sigma):
    T = look_at(eye, target)
    p, C = _sample_positions(world, camera, T, sigma, 400, seed=1)
    assert not p.flip_likely
    sample = np.cov((C - T[:3, 3]).T)
    # per axis within 15 % (400 trials: the sample std itself scatters by about 3.5 %)
    np.testing.assert_allclose(np.sqrt(np.diag(sample)), p.position_std_mm, rtol=0.15)
    measured_median = float(np.median(np.linalg.norm(C - T[:3, 3], axis=1)))
    assert measured_median == pytest.approx(p.position_error_mm, rel=0.15)


def test_one_marker_on_its_axis_matches_the_hand_computed_depth_error():
    # A square of side s seen face-on at distance Z by a pinhole camera: its apparent side
    # h = f s / Z, and depth decouples from the other five parameters by symmetry, so
    # sigma_Z = Z sigma_h / h. The side is the distance between two opposite sides' fitted lines,
    # whose offsets are each known to sigma / 2 (noise.corner_covariance: a corner's variance is
    # the offset's plus 3 times as much from the slope); two such measures (across and down),
    # so sigma_h = sqrt(2 (sigma / 2)^2 / 2) = sigma / 2 and sigma_Z = sigma Z^2 / (2 f s).
    # (Four independent corners would give sigma Z^2 / (sqrt(2) f s).)
    cam = Camera(np.array([[800.0, 0, 639.5], [0, 800.0, 359.5], [0, 0, 1]]), np.zeros(5), (1280, 720))
    s, sigma = 160.0, 0.5
    for Z in (1000.0, 2000.0, 4000.0):
        T = look_at([Z, 0, 1000], [0, 0, 1000])
        p = predict_accuracy(one_marker(s), cam, T, corner_sigma_px=sigma)
        assert p.marker_ids == [0]
        assert p.side_px[0] == pytest.approx(800 * s / Z, rel=1e-9)
        assert p.position_std_mm[0] == pytest.approx(sigma * Z**2 / (2 * 800 * s), rel=1e-6)


def test_corner_covariance_is_that_of_four_fitted_lines_and_their_intersections():
    # Known answer from first principles: edge points spread evenly along each side of a square
    # (201 per side, from corner to corner), each off by independent Gaussian noise across the
    # side; a least-squares line per side, corners where neighbouring lines meet. Their sample
    # covariance over 4000 trials is the model's (entries within 0.06 of the largest).
    rng = np.random.default_rng(5)
    L, n, trials, e_sigma = 40.0, 201, 4000, 0.2
    q = np.array([[0.0, 0.0], [L, 0.0], [L, L], [0.0, L]])
    t = np.linspace(0.0, 1.0, n) - 0.5
    # per side: offset a and slope b of the fitted line (distance off the side at position t L)
    off = rng.normal(0.0, e_sigma, (trials, 4, n))
    b = np.sum(off * t, axis=2) / np.sum(t**2) / L
    a = off.mean(axis=2)
    d_start, d_end = a - b * L / 2, a + b * L / 2  # the line's shift at the side's two ends
    side = np.roll(q, -1, axis=0) - q
    normal = np.column_stack([-side[:, 1], side[:, 0]]) / L
    corners = np.zeros((trials, 4, 2))
    for k in range(4):  # corner k: end of side k - 1 and start of side k
        A = np.array([normal[k - 1], normal[k]])
        corners[:, k] = np.linalg.solve(A, np.stack([d_end[:, k - 1], d_start[:, k]])).T
    sample = np.cov(corners.reshape(trials, 8).T)
    model = noise.corner_covariance(q, math.sqrt(np.trace(sample) / 8))
    assert np.abs(sample - model).max() < 0.06 * model.max()
    # the marker's centre: half the variance four independent corners would give
    centre = np.tile([0.25, 0.0], 4)
    assert centre @ model @ centre == pytest.approx(0.5 * np.trace(model) / 8 / 4, rel=1e-9)


def test_one_marker_face_on_and_far_is_flagged_as_a_likely_flip_and_a_tilted_view_is_not():
    cam = Camera(np.array([[800.0, 0, 639.5], [0, 800.0, 359.5], [0, 0, 1]]), np.zeros(5), (1280, 720))
    face_on = predict_accuracy(one_marker(80), cam, look_at([3000, 0, 1000], [0, 0, 1000]), corner_sigma_px=0.5)
    assert face_on.flip_probability == 0.0  # the two solutions meet: one answer, however noisy
    far = predict_accuracy(one_marker(80), cam, look_at([2000, 600, 1000], [0, 0, 1000]), corner_sigma_px=0.5)
    assert far.flip_likely
    assert 0.1 < far.flip_probability < 0.5
    near = predict_accuracy(one_marker(80), cam, look_at([600, 600, 1000], [0, 0, 1000]), corner_sigma_px=0.5)
    assert not near.flip_likely
    world = MarkerMap.load(fidlearn.data_path("two_walls_map.json"))
    seen_two_walls = [
        predict_accuracy(world, cam, look_at(e, [0, 0, 300]), corner_sigma_px=0.5)
        for e in ([1500, 1500, 400], [2000, 1000, 300])
    ]
    for p in seen_two_walls:
        if (
            not world.is_coplanar()
            and len(p.marker_ids) > 1
            and not MarkerMap({i: world.placements[i] for i in p.marker_ids}, world.marker_size_mm).is_coplanar()
        ):
            assert p.flip_probability == 0.0


def test_the_flip_probability_predicts_how_often_estimate_pose_picks_the_wrong_branch():
    cam = Camera(np.array([[800.0, 0, 639.5], [0, 800.0, 359.5], [0, 0, 1]]), np.zeros(5), (1280, 720))
    m = one_marker(80)
    T = look_at([2000, 600, 1000], [0, 0, 1000])
    sigma = 0.5
    p = predict_accuracy(m, cam, T, corner_sigma_px=sigma)
    rng = np.random.default_rng(3)
    truth = cam.project(m.marker_corners(0), T)
    wrong = 0
    n = 300
    P = m.marker_corners(0)
    rvec0, tvec0 = fidlearn.rvec_tvec_from_transform(fidlearn.invert_transform(T))
    for _ in range(n):
        noisy = truth + rng.normal(0, sigma, (4, 2))
        pose = estimate_pose([Detection(0, noisy)], m, cam, corner_sigma_px=sigma)
        # the minimum of the true basin: Levenberg-Marquardt started at the truth
        rvec, _ = cv2.solvePnPRefineLM(
            P, noisy, cam.K, cam.dist, rvec0.copy().reshape(3, 1), tvec0.copy().reshape(3, 1)
        )
        R_basin = cv2.Rodrigues(rvec)[0].T  # R_world_camera
        wrong += fidlearn.frames.rotation_angle_deg(pose.T_world_camera[:3, :3], R_basin) > 5.0
    # binomial tolerance on 300 trials, plus the first-order model's own slack
    assert abs(wrong / n - p.flip_probability) < 0.08 + 3 * math.sqrt(p.flip_probability * (1 - p.flip_probability) / n)


def test_markers_out_of_sight_say_why(world, camera):
    p = predict_accuracy(world, camera, look_at([1000, 190, 230], [2000, 190, 230]))  # looking away
    assert not p.possible
    assert p.position_error_mm == math.inf
    assert "behind the camera" in p.reason
    far = predict_accuracy(world, camera, look_at([20000, 190, 230], [0, 190, 230]))
    assert not far.possible
    assert "too small" in far.reason
    assert "no pose" in repr(far)


def test_detection_limits_follow_the_measured_rules():
    assert noise.min_perimeter_px((640, 480)) == noise.DECODE_MIN_PERIMETER_PX
    assert noise.min_perimeter_px((1920, 1080)) == pytest.approx(0.03 * 1.14 * 1920)
    assert noise.corner_sigma_px(5.0) == noise.NOISE_SIGMA_PX[0]  # held outside the table
    assert noise.corner_sigma_px(1000.0) == noise.NOISE_SIGMA_PX[-1]


def test_flip_probability_is_zero_for_points_off_a_plane(camera):
    P = np.array([[0, 0, 0], [0, 100, 0], [0, 100, -100], [0, 0, -100], [100, 0, 0], [100, 100, -50.0]])
    T = look_at([1500, 50, -50], [0, 50, -50])
    px = camera.project(P, T)
    assert flip_probability(P, px, camera, np.full(6, 0.5)) == 0.0


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.eye(3), "shape"),
        ("pose", "4x4"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "reflection"),
    ],
)
def test_bad_poses_are_refused(world, camera, bad, match):
    with pytest.raises(TransformError, match=match):
        predict_accuracy(world, camera, bad)


@pytest.mark.parametrize("sigma", [0, -1, float("nan"), "0.3", True])
def test_bad_corner_sigma_is_refused(world, camera, sigma):
    with pytest.raises(FidlearnError, match="corner_sigma_px"):
        predict_accuracy(world, camera, look_at([1000, 190, 230], [0, 190, 230]), corner_sigma_px=sigma)


def test_plan_on_one_marker_on_its_axis_grows_with_the_cube_of_the_distance():
    # One marker seen face-on: a tilt theta changes its picture only through perspective, by about
    # f s^2 theta / (2 Z^2) px, so sigma_theta ~ sigma Z^2 / (f s^2); the camera's sideways error is
    # Z sigma_theta ~ Z^3, and it dominates the depth error (~ Z^2, test above): slope 3 in log-log.
    # Corners good to 0.02 px keep the tilt within a few degrees, where the linearization holds.
    cam = Camera(np.array([[800.0, 0, 639.5], [0, 800.0, 359.5], [0, 0, 1]]), np.zeros(5), (1280, 720))
    m = one_marker(160)
    plan = plan_room(
        m,
        cam,
        height_mm=1000,
        area=(500, -125, 4500, 125),
        step_mm=250,
        headings=0,
        corner_sigma_px=0.02,
        look_at_mm=[0, 0, 1000],
    )
    assert plan.toward_mm.shape == (1, 16)
    on_axis = plan.toward_mm[0]
    for x, err in zip(plan.x_mm, on_axis):
        assert (
            err == predict_accuracy(m, cam, look_at([x, 0, 1000], [0, 0, 1000]), corner_sigma_px=0.02).position_error_mm
        )
    slope = np.polyfit(np.log(plan.x_mm), np.log(on_axis), 1)[0]
    assert slope == pytest.approx(3.0, abs=0.1)
    assert plan.fraction_within(float(on_axis[7])) == pytest.approx(8 / 16)


def test_plan_headings_and_the_area_behind_the_wall(world, camera):
    plan = plan_room(world, camera, area=(-1000, -500, 2000, 900), step_mm=500, headings=8)
    behind = plan.x_mm < 0
    assert np.all(np.isinf(plan.toward_mm[:, behind]))
    assert np.all(plan.seen_fraction[:, behind] == 0)
    front = ~behind
    assert np.all(np.isfinite(plan.toward_mm[:, front]))
    finite = np.isfinite(plan.worst_mm)
    assert np.all(plan.worst_mm[finite] >= plan.median_mm[finite])


def test_suggestions_reach_more_of_the_area(world, camera):
    steps = suggest_markers(world, camera, 5.0, area=(100, -1000, 3000, 1400), step_mm=500)
    assert steps, "a 5 mm target over 3 m is not met by three 80 mm markers: something must help"
    for s in steps:
        assert s.fraction_after > s.fraction_before
    # each promise is what a new plan of the changed map says, with the same options (looking at its markers)
    before = plan_room(world, camera, area=(100, -1000, 3000, 1400), step_mm=500, headings=0)
    assert steps[0].fraction_before == before.fraction_within(5.0)
    for s in steps:
        again = plan_room(s.marker_map, camera, area=(100, -1000, 3000, 1400), step_mm=500, headings=0)
        assert again.fraction_within(5.0) == s.fraction_after


def test_suggestions_beside_a_board_or_a_larger_marker_go_where_they_say(camera):
    """A map of one grid board: the reference marker is a board's (it raised KeyError: '0'). A reference of its
    own size (300 mm beside the map's 80): the new marker is where the text says (it was 155 mm off)."""
    board = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 150,
            "boards": {
                "wall": {
                    "type": "grid",
                    "translation": [0, 600, 1500],
                    "markers": [3, 2],
                    "marker_mm": 150,
                    "separation_mm": 30,
                    "first_id": 0,
                }  # fmt: skip
            },
        }
    )
    (step,) = suggest_markers(board, camera, 2.0, step_mm=500, height_mm=1200, max_markers=1, size_factors=())
    new = max(step.marker_map.ids)
    np.testing.assert_allclose(step.marker_map.normal(new), board.normal(0), atol=1e-9)
    big = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80,
            "markers": {"0": {"translation": [0, 0, 1500], "size_mm": 300}, "1": {"translation": [0, 1500, 1500]}},
        }
    )
    area = (300, -1000, 3000, 2500)
    for step in suggest_markers(
        big, camera, 3.0, step_mm=500, height_mm=1200, area=area, max_markers=1, size_factors=()
    ):
        new = max(step.marker_map.ids)
        said = [float(v) for v in step.text.split(" at [")[1].split("]")[0].split(",")]
        np.testing.assert_allclose(step.marker_map.marker_corners(new).mean(axis=0), said, atol=0.5)
        assert step.marker_map.marker_size(new) == 80
        # the promise is plan_room's, flip and missed markers included
        again = plan_room(step.marker_map, camera, area=area, step_mm=500, height_mm=1200, headings=0)
        assert again.fraction_within(3.0) == step.fraction_after


def test_a_place_straight_above_the_point_looked_at_is_planned():
    """Four floor markers and the default look-at point under a grid place: the view is vertical, and the
    plan used to stop there ('the view direction is parallel to up')."""
    cam = Camera.from_fov(70, (1280, 720))
    floor = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 150,
            "markers": {
                str(k): {"translation": [x, y, 0], "rotation": [0, -90, 0]}
                for k, (x, y) in enumerate([(800, 800), (800, 1550), (1550, 800), (1550, 1550)])
            },
        }
    )
    plan = plan_room(floor, cam, area=(0, 0, 2500, 2500), step_mm=500, height_mm=2000, headings=0)
    assert np.isfinite(plan.toward_mm).all()


def test_suggestions_on_an_area_smaller_than_the_room_grid(camera):
    """A desk of 400 x 300 mm in front of one 40 mm marker: the default grid is a quarter of the shorter side
    (75 mm), not the room's 500 mm, and the first added marker goes beside it on its wall."""
    small = one_marker(40.0)
    area = (300, -200, 700, 100)
    steps = suggest_markers(small, camera, 1.0, height_mm=1000, area=area, max_markers=1)
    assert steps
    assert steps[0].fraction_after > steps[0].fraction_before
    added = steps[-1].marker_map
    new = max(added.ids)
    np.testing.assert_allclose(added.normal(new), small.normal(0), atol=1e-9)  # on the same wall
    assert added.marker_corners(new).mean(axis=0)[0] == pytest.approx(0.0, abs=1e-6)
    again = plan_room(added, camera, height_mm=1000, area=area, headings=0)  # plan_room's default grid is the same
    assert again.step_mm == 75.0
    assert again.toward_mm.shape == (4, 5)
    assert again.fraction_within(1.0) == steps[-1].fraction_after


def _run_plan(argv):
    """The plan command's ``run`` as ``fidlearn.cli.main`` calls it: its outputs committed together."""
    p = argparse.ArgumentParser()
    command.add_arguments(p)
    with outputs_together():
        return command.run(p.parse_args(argv))


def test_plan_command_writes_the_picture_and_says_the_figures(tmp_path, capsys):
    out = tmp_path / "plan.png"
    rc = _run_plan(
        [
            str(fidlearn.data_path("world_map.json")),
            "--camera",
            str(fidlearn.data_path("scenes/camera.json")),
            "--step-mm",
            "500",
            "--headings",
            "4",
            "--target-mm",
            "10",
            "-o",
            str(out),
        ]
    )
    assert rc == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "a pose is possible at" in text
    assert "within 10 mm" in text
    assert [p.name for p in tmp_path.iterdir()] == ["plan.png"]


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--suggest"], "--suggest needs --target-mm"),
        (["--area", "1,2,3"], "expected 4 numbers"),
        (["--area", "5,0,1,1"], "x0 < x1"),
        (["--target-mm", "-3"], "positive"),
        (["--step-mm", "0"], "--step-mm 0.0: give a positive number of mm"),
        (["--step-mm", "nan"], "--step-mm nan: give a positive number of mm"),
        (["--area", "0,0,200,280", "--step-mm", "250"], "the area is only 200 x 280 mm; give a step of 200 mm or less"),
    ],
)
def test_plan_command_refuses_bad_options(tmp_path, extra, match):
    with pytest.raises(FidlearnError, match=match):
        _run_plan(
            [
                str(fidlearn.data_path("world_map.json")),
                "--camera",
                str(fidlearn.data_path("scenes/camera.json")),
                "-o",
                str(tmp_path / "p.png"),
                *extra,
            ]
        )
    assert not list(tmp_path.iterdir())


def test_plan_command_says_when_no_suggestion_is_needed(tmp_path, capsys):
    args = [str(fidlearn.data_path("world_map.json")), "--camera", str(fidlearn.data_path("scenes/camera.json"))]
    near = ["--area", "200,-200,700,600", "--step-mm", "250", "--headings", "0", "--suggest", "-o"]
    assert _run_plan([*args, *near, str(tmp_path / "p.png"), "--target-mm", "100"]) == 0
    text = capsys.readouterr().out
    assert "within 100 mm: 100 % of the area" in text
    assert "suggestion: none needed; looking at the markers, the whole area is within 100 mm" in text
    far = ["--area", "1500,-500,3000,1000", "--step-mm", "500", "--headings", "0", "--suggest", "-o"]
    assert _run_plan([*args, *far, str(tmp_path / "q.png"), "--target-mm", "5"]) == 0
    text = capsys.readouterr().out
    assert "none needed" not in text
    assert "suggestion: " in text
    assert "within 5 mm: 100 %" not in text


def test_plan_figure_draws_each_marker_as_seen_from_above():
    """A marker on a wall is a bar (its outline from above has no area), one on the floor a square of its size."""
    from matplotlib.patches import Polygon

    from fidlearn.planning.figure import plan_figure

    both = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 100.0,
            "markers": {
                "0": {"translation": [0, -50, 1050], "rotation": [0, 0, 0]},  # on the wall X = 0, facing +X
                "1": {"translation": [1000, 0, 0], "rotation": [0, -90, 0]},  # on the floor, facing up
            },
        }
    )
    np.testing.assert_allclose(both.normal(1), [0, 0, 1], atol=1e-9)
    plan = plan_room(both, Camera.from_fov(60, (640, 480)), height_mm=1500, area=(100, -500, 1500, 500), headings=0)
    ax = plan_figure(plan, both).axes[0]
    outlines = [p.get_xy()[:4] for p in ax.patches if isinstance(p, Polygon)]
    areas = sorted(abs(cv2.contourArea(v.astype(np.float32))) for v in outlines)
    assert areas == pytest.approx([0.0, 100.0 * 100.0], abs=1.0)
    assert sorted(t.get_text().strip() for t in ax.texts if t.get_text().strip()) == ["0", "1"]
    # one arrow along a normal: the wall marker's, +X; the floor marker's points up, out of the picture
    (arrow,) = [t for t in ax.texts if getattr(t, "arrow_patch", None) is not None]
    assert arrow.xy[0] > arrow.xyann[0]
    assert arrow.xy[1] == pytest.approx(arrow.xyann[1])


def test_plan_command_refuses_to_write_over_its_input(tmp_path):
    m = tmp_path / "map.png"
    m.write_text((fidlearn.data_path("world_map.json")).read_text())
    before = m.read_bytes()
    with pytest.raises(FidlearnError, match="one of the inputs"):
        _run_plan([str(m), "--camera", str(fidlearn.data_path("scenes/camera.json")), "-o", str(m)])
    assert m.read_bytes() == before


def test_a_grazing_marker_whose_planar_solution_is_nan_has_no_flip():
    """OpenCV's IPPE returns NaN for a marker seen at a grazing angle: no second solution, no crash."""
    from fidlearn import Camera, MarkerMap, MarkerPlacement, look_at, predict_accuracy

    cam = Camera.from_fov(66, (1280, 960), dist=[-0.053, 0.019, 0, 0, 0])
    m = MarkerMap(
        {
            0: MarkerPlacement(0, (0, -1390, 460), (0, 0, 0)),
            1: MarkerPlacement(1, (0, 170, 1600), (0, 0, 0)),
            2: MarkerPlacement(2, (0, 1730, 460), (0, 0, 0)),
        },
        80,
    )
    centre = np.mean([m.marker_corners(i).mean(axis=0) for i in m.ids], axis=0)
    p = predict_accuracy(m, cam, look_at([715, -765, 420], centre))
    assert p.possible
    assert 0.0 <= p.flip_probability <= 0.5
