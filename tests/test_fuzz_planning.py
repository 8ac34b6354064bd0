"""Every public function of ``fidlearn.planning`` under wrong input: a FidlearnError or a right answer, nothing else.

Each function is called from a valid baseline with one argument at a time replaced by each of the wrong
values of :data:`BAD` (wrong types, NaN, infinity, 1e300, 10^40, wrong shapes, empty and ragged lists). The
only exception allowed out is a :class:`~fidlearn.FidlearnError`; a RuntimeWarning (an overflow, an invalid
value) counts as a failure too, since the command line would print it as a stray line. Then the huge sizes: a
grid, a search, a board, a set of views or of markers too large to handle is refused before the work starts.
The baselines are small (a few grid places, a 4x3-point board), so the whole file runs in seconds.
"""

from __future__ import annotations

import importlib
import itertools
import math
import time
import warnings

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, FidlearnError, MarkerMap, look_at
from fidlearn.planning import (
    coach,
    coach_calibration,
    default_area,
    default_step,
    flip_probability,
    noise_from_pose,
    plan_room,
    predict_accuracy,
    suggest_markers,
)
from fidlearn.planning import noise as noise_module

coach_module = importlib.import_module("fidlearn.planning.coach")  # the module: the package's `coach` is the function

WORLD = MarkerMap.load(fidlearn.data_path("world_map.json"))
CAMERA = Camera.load(fidlearn.data_path("scenes/camera.json"))
T_SEE = look_at([1000, 190, 230], [0, 190, 230])
AREA = (600.0, -400.0, 1600.0, 800.0)  # 2 x 2 places of 500 mm, in front of the markers

#: The wrong values, each put in place of one argument.
BAD = [
    None,
    "x",
    "",
    b"x",
    math.nan,
    math.inf,
    -math.inf,
    -1,
    0,
    1e300,
    10**40,
    True,
    [],
    [[1, 2], [3]],
    np.zeros((2, 5)),
    object(),
    {},
]

# A small board seen three times (corners, their pixels, its poses), as a Calibration holds them.
_BOARD = np.array([[i * 30.0, j * 30.0, 0.0] for j in range(3) for i in range(4)])
_POSES = {
    f"v{k}": fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(r, p, 0), [t, -40, 400])
    for k, (r, p, t) in enumerate([(20, 0, -60), (0, 25, 0), (-20, -20, -30)])
}
_CAL_CAMERA = Camera.load(fidlearn.data_path("calibration/camera_true.json"))
_PIXELS = {n: _CAL_CAMERA.project(_BOARD, fidlearn.invert_transform(T)) for n, T in _POSES.items()}
_BOARDS = {n: _BOARD for n in _POSES}


def _pose_and_noise_inputs():
    """A pose from four markers of a wall (a rendered-free prediction of the corners), for noise_from_pose."""
    m = MarkerMap.from_dict(
        {
            str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]}
            for k, (y, z) in enumerate([(0, 300), (300, 300), (0, 0), (300, 0)])
        },
        units="mm",
        marker_size_mm=100,
    )
    T = look_at([900, 150, 150], [0, 150, 150])
    rng = np.random.default_rng(3)
    dets = [fidlearn.Detection(i, CAMERA.project(m.marker_corners(i), T) + rng.normal(0, 0.2, (4, 2))) for i in m.ids]
    return fidlearn.estimate_pose(dets, m, CAMERA), m


POSE, FOUR = _pose_and_noise_inputs()
_Q = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]])

#: (function, baseline keyword arguments) for every public function of fidlearn.planning and its modules.
CASES = {
    "predict_accuracy": (
        predict_accuracy,
        {
            "marker_map": WORLD,
            "camera": CAMERA,
            "T_world_camera": T_SEE,
            "corner_sigma_px": 0.2,
            "marker_shift_px": 0.1,
            "marker_size_rel_std": 0.01,
            "marker_size_rel_std_each": 0.01,
            "marker_size_rel_error": -0.01,
        },
    ),
    "flip_probability": (
        flip_probability,
        {
            "points_world": WORLD.marker_corners(0),
            "points_px": CAMERA.project(WORLD.marker_corners(0), T_SEE),
            "camera": CAMERA,
            "corner_sigma_px": np.full(4, 0.2),
        },
    ),
    "corner_sigma_px": (noise_module.corner_sigma_px, {"side_px": 30.0}),
    "min_perimeter_px": (noise_module.min_perimeter_px, {"image_size": (1280, 720)}),
    "corner_covariance": (noise_module.corner_covariance, {"corners_px": _Q, "corner_sigma_px": 0.1}),
    "marker_shift_covariance": (noise_module.marker_shift_covariance, {"shift_px": 0.1}),
    "noise_from_pose": (noise_from_pose, {"pose": POSE, "marker_map": FOUR, "camera": CAMERA}),
    "plan_room": (
        plan_room,
        {
            "marker_map": WORLD,
            "camera": CAMERA,
            "height_mm": 300.0,
            "area": AREA,
            "look_at_mm": [0, 190, 230],
            "step_mm": 500.0,
            "headings": 2,
            "corner_sigma_px": 0.2,
            "progress": lambda _done, _total: None,
            "marker_shift_px": 0.1,
            "marker_size_rel_std": 0.01,
            "marker_size_rel_std_each": 0.0,
            "marker_size_rel_error": 0.0,
        },
    ),
    "suggest_markers": (
        suggest_markers,
        {
            "marker_map": WORLD,
            "camera": CAMERA,
            "target_mm": 2.0,
            "height_mm": 300.0,
            "area": AREA,
            "look_at_mm": None,
            "step_mm": 500.0,
            "max_markers": 1,
            "size_factors": (1.5,),
            "corner_sigma_px": 0.2,
            "marker_shift_px": 0.0,
            "marker_size_rel_std": 0.0,
        },
    ),
    "default_area": (default_area, {"marker_map": WORLD}),
    "default_step": (default_step, {"area": AREA}),
    "coach": (
        coach,
        {
            "camera": _CAL_CAMERA,
            "board_points_mm": _BOARDS,
            "image_points_px": _PIXELS,
            "T_camera_board": _POSES,
            "corner_sigma_px": 0.2,
            "other_sizes": 0,
        },
    ),
    "uncertainty_map": (
        coach_module.uncertainty_map,
        {"camera": _CAL_CAMERA, "covariance": np.eye(9) * 1e-4, "distance_mm": 400.0, "grid": (4, 3)},
    ),
    "intrinsics_information": (
        coach_module.intrinsics_information,
        {"camera": _CAL_CAMERA, "board_points_mm": _BOARDS, "T_camera_board": _POSES},
    ),
    "bent_views": (
        coach_module.bent_views,
        {"camera": _CAL_CAMERA, "board_points_mm": _BOARDS, "image_points_px": _PIXELS, "T_camera_board": _POSES},
    ),
}


def _call(function, kwargs):
    """``function(**kwargs)``: its answer, or None for a FidlearnError; anything else (a RuntimeWarning too) flies."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            return function(**kwargs)
        except FidlearnError as exc:
            assert str(exc).strip(), "an error without a message"
            return None


def _finite_answer(answer) -> None:
    """An accepted call gives numbers, not NaN (inf stays allowed: 'no pose here')."""
    for value in answer if isinstance(answer, (list, tuple)) else [answer]:
        if isinstance(value, (float, np.ndarray)) and np.asarray(value).dtype.kind == "f":
            assert not np.isnan(value).any(), answer


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_baseline_works(name):
    function, kwargs = CASES[name]
    answer = _call(function, kwargs)
    assert answer is not None, f"{name}: the baseline itself is refused"
    _finite_answer(answer)


@pytest.mark.parametrize(
    ("name", "argument"), [(name, arg) for name, (_, kwargs) in sorted(CASES.items()) for arg in kwargs]
)
def test_one_wrong_argument_at_a_time(name, argument):
    function, kwargs = CASES[name]
    for bad in BAD:
        answer = _call(function, {**kwargs, argument: bad})
        if answer is not None:
            _finite_answer(answer)


def test_the_methods_of_the_results():
    plan = plan_room(WORLD, CAMERA, area=AREA, step_mm=500, headings=0)
    for bad in BAD:
        _call(plan.fraction_within, {"error_mm": bad})
        _call(plan.fraction_within, {"error_mm": 5.0, "which": bad})
    verdict = coach(_CAL_CAMERA, _BOARDS, _PIXELS, _POSES, corner_sigma_px=0.2)
    for bad in BAD:
        text = _call(verdict.report, {"omit": bad})
        assert text is None or text.startswith("reprojection uncertainty")


def test_coach_calibration_takes_only_a_calibration():
    for bad in BAD:
        assert _call(coach_calibration, {"calibration": bad}) is None


def test_noise_from_residuals_wrong_shapes_and_values():
    M = 4
    good = {"residuals_px": np.zeros((M, 4, 2)), "jacobian": np.ones((8 * M, 6)), "corners_px": np.tile(_Q, (M, 1, 1))}
    for argument in good:
        for bad in BAD:
            _call(noise_module.noise_from_residuals, {**good, argument: bad})


# -- huge sizes: refused before the work ------------------------------------------------------------------
def _refused_fast(function, kwargs, match: str, seconds: float = 2.0) -> None:
    start = time.monotonic()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(FidlearnError, match=match):
            function(**kwargs)
    assert time.monotonic() - start < seconds


def test_huge_grids_and_searches_are_refused_up_front():
    base = {"marker_map": WORLD, "camera": CAMERA, "headings": 0}
    _refused_fast(plan_room, {**base, "area": AREA, "step_mm": 1e-300}, "more than 40000")
    _refused_fast(plan_room, {**base, "area": (-1e9, -1e9, 1e9, 1e9), "step_mm": 1.0}, "more than 40000")
    _refused_fast(plan_room, {**base, "area": (0, 0, 1e300, 1e300)}, "at most 1e\\+09")
    _refused_fast(plan_room, {**base, "headings": 10**9}, "headings")
    sug = {"marker_map": WORLD, "camera": CAMERA, "target_mm": 1.0, "area": AREA, "step_mm": 500.0}
    _refused_fast(suggest_markers, {**sug, "size_factors": itertools.count(2)}, "size_factors")
    _refused_fast(suggest_markers, {**sug, "size_factors": [1.5] * 10**6}, "size_factors")
    _refused_fast(suggest_markers, {**sug, "max_markers": 10**9}, "max_markers")
    wide = {**sug, "area": (100.0, -20000.0, 600.0, 20000.0), "step_mm": 40.0}  # 12 x 1000 places
    _refused_fast(suggest_markers, wide, "places along the walls")
    _refused_fast(suggest_markers, {**sug, "area": (100.0, -3000.0, 3100.0, 3000.0), "step_mm": 100.0}, "predictions")


def test_huge_boards_views_and_marker_sets_are_refused_up_front():
    many = np.zeros((20_000, 3))
    _refused_fast(
        flip_probability,
        {"points_world": many, "points_px": many[:, :2], "camera": CAMERA, "corner_sigma_px": np.ones(20_000)},
        "4 to 10000",
    )
    big = np.array([[i, j, 0.0] for j in range(100) for i in range(100)])
    _refused_fast(
        coach,
        {
            "camera": _CAL_CAMERA,
            "board_points_mm": {"a": big},
            "image_points_px": {"a": big[:, :2]},
            "T_camera_board": {"a": _POSES["v0"]},
            "corner_sigma_px": 0.2,
        },
        "from 4 to 5000",
    )
    views = {f"v{k}": _POSES["v0"] for k in range(1001)}
    _refused_fast(
        coach,
        {
            "camera": _CAL_CAMERA,
            "board_points_mm": dict.fromkeys(views, _BOARD),
            "image_points_px": dict.fromkeys(views, _PIXELS["v0"]),
            "T_camera_board": views,
            "corner_sigma_px": 0.2,
        },
        "more than 1000",
    )
    M = 10_000
    _refused_fast(
        noise_module.noise_from_residuals,
        {"residuals_px": np.zeros((M, 4, 2)), "jacobian": np.zeros((8 * M, 6)), "corners_px": np.zeros((M, 4, 2))},
        "more than 200",
    )
    _refused_fast(
        coach_module.uncertainty_map,
        {"camera": _CAL_CAMERA, "covariance": np.eye(9), "distance_mm": 400.0, "grid": (10**6, 10**6)},
        "grid",
    )


def test_a_far_look_at_point_is_a_direction():
    """The cameras all look the same way, as at a point a million km off; no overflow, no warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        far = plan_room(WORLD, CAMERA, area=AREA, step_mm=500, headings=0, look_at_mm=[-1e300, 0, 0])
        near = plan_room(WORLD, CAMERA, area=AREA, step_mm=500, headings=0, look_at_mm=[-1e12, 0, 0])
    np.testing.assert_allclose(far.toward_mm, near.toward_mm, rtol=1e-6)
