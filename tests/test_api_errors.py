"""One error type: every mistake a caller can make in the library raises a FidlearnError.

Every public function and class of ``fidlearn`` (``fidlearn.__all__``) and of ``fidlearn.frames``
is called from a valid baseline with one argument at a time replaced by a wrong type or value
(None, text, NaN, infinity, a negative or a huge number, an empty or a wrongly shaped array, a
nested list, a bytes object). Whatever happens, the only exception allowed out is a
:class:`FidlearnError` (whose message the other tests check); a ``TypeError``, ``ValueError``,
``cv2.error`` or ``AttributeError`` escaping is a bug.
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest

import fidlearn
from fidlearn import Camera, Detection, FidlearnError, MarkerMap, frames
from fidlearn.images import Frame
from fidlearn.synthetic import visible_markers

WORLD = MarkerMap.load(fidlearn.data_path("world_map.json"))
CAMERA = Camera.load(fidlearn.data_path("scenes/camera.json"))
T = fidlearn.look_at([1000, 190, 230], [0, 190, 230])
SCENE = fidlearn.render_scene(WORLD, CAMERA, T, supersample=1)
IMAGE, TRUTH = SCENE.image, SCENE.truth
DETECTIONS = [Detection(i, c) for i, c in TRUTH.items()]

BAD = {
    "None": None,
    "text": "abc",
    "empty text": "",
    "bytes": b"\x00\x01",
    "nan": float("nan"),
    "inf": float("inf"),
    "-1": -1,
    "huge int": 10**40,
    "huge float": 1e300,
    "True": True,
    "empty list": [],
    "nested list": [[1, 2], [3]],
    "wrong shape": np.zeros((2, 5)),
    "object": object(),
    "dict": {"a": 1},
}

#: A valid call of each public callable: the argument lists the test mutates one item at a time.
BASELINES = {
    "Camera": ((CAMERA.K, CAMERA.dist, CAMERA.image_size), {}),
    "MarkerMap.from_dict": (
        ({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}},),
        {"units": "ft", "marker_size_mm": 80},
    ),
    "compose": ((T, np.eye(4)), {}),
    "invert_transform": ((T,), {}),
    "make_transform": ((np.eye(3), [1, 2, 3]), {}),
    "rotation_from_rpy_deg": ((10, 20, 30), {}),
    "rpy_deg_from_rotation": ((T[:3, :3],), {}),
    "rvec_tvec_from_transform": ((T,), {}),
    "transform_from_rvec_tvec": (([0.1, 0.2, 0.3], [1, 2, 3]), {}),
    "transform_points": ((T, np.zeros((2, 3))), {}),
    "detect_markers": ((IMAGE,), {}),
    "detect_markers_with_rejected": ((IMAGE,), {}),
    "draw_detections": ((IMAGE, DETECTIONS), {}),
    "render_scene": ((CAMERA.scaled((320, 180)), WORLD, T), {"supersample": 1}),
    "look_at": (([1000, 0, 300], [0, 0, 300]), {}),
    "estimate_pose": ((DETECTIONS, WORLD, CAMERA), {}),
    "locate": ((IMAGE, WORLD, CAMERA), {}),
    "trajectory_poses": ((WORLD,), {"n_frames": 3}),
    "predict_accuracy": ((WORLD, CAMERA, T), {}),
    "rot_x": ((0.3,), {}),
    "rot_y": ((0.3,), {}),
    "rot_z": ((0.3,), {}),
    "check_rotation": ((np.eye(3),), {}),
    "check_transform": ((T,), {}),
    "rotation_angle_deg": ((np.eye(3), T[:3, :3]), {}),
    "quaternion_from_matrix": ((T[:3, :3],), {}),
    "matrix_from_quaternion": (([0.0, 0.0, 0.6, 0.8],), {}),
    "compare_calibrations": (
        (CAMERA, Camera(CAMERA.K * [[1.001], [1.0], [1.0]], CAMERA.dist, CAMERA.image_size)),
        {"grid": (8, 6), "tolerance_px": 1.0, "inflate": True},
    ),
    "Camera.project": ((np.zeros((2, 3)), T), {}),
    "Camera.undistort_points": ((np.zeros((2, 2)) + 100,), {}),
    "Camera.scaled": (((640, 360),), {}),
    "Camera.from_fov": ((60, (640, 480)), {}),
    "MarkerMap.corners": ((), {}),
    "track": (
        ([Frame("scene.png", IMAGE, "scene.png", "image")], WORLD, CAMERA),
        {"fps": 30.0, "refine": None, "T_camera_base": None, "odometry": None, "process_noise": (500.0, 1.0)},
    ),
    "smooth": (
        ([fidlearn.estimate_pose(DETECTIONS, WORLD, CAMERA), None], [0.0, 0.1]),
        {"process_noise": (500.0, 1.0)},
    ),
    "survey": (
        (
            [
                [
                    Detection(i, c)
                    for i, c in visible_markers(WORLD, CAMERA, fidlearn.look_at(eye, [0, 190, 230])).items()
                ]
                for eye in ([1000, 190, 230], [900, -100, 300], [1100, 450, 200])
            ],
            WORLD,
            CAMERA,
        ),
        {"map_sigma_mm": 10.0, "fixed_ids": None, "corner_sigma_px": None},
    ),
}


def _callable(name: str):
    if name.startswith("Camera."):
        attr = getattr(Camera, name.split(".", 1)[1])
        return attr if name == "Camera.from_fov" else getattr(CAMERA, name.split(".", 1)[1])
    if name == "MarkerMap.from_dict":
        return MarkerMap.from_dict
    if name == "MarkerMap.corners":
        return WORLD.corners
    return getattr(fidlearn, name, None) or getattr(frames, name)


def cases():
    for name, (args, kwargs) in BASELINES.items():
        for k in range(len(args)):
            for label, bad in BAD.items():
                yield pytest.param(name, k, None, bad, id=f"{name}-arg{k}-{label}")
        for key in kwargs:
            for label, bad in BAD.items():
                yield pytest.param(name, None, key, bad, id=f"{name}-{key}-{label}")


def test_every_public_callable_has_a_baseline():
    names = {n for n in fidlearn.__all__ if inspect.isfunction(getattr(fidlearn, n))} | set(frames.__all__)
    skip = {
        "data_dir",
        "data_path",
        "render_calibration_views",
        "render_trajectory",
        "calibrate_checkerboard",
        "calibrate_charuco",
        "markers_pdf",
        "board_pdf",
        "plan_room",
    }  # covered by their own hostile tests
    missing = sorted(names - set(BASELINES) - skip)
    assert not missing, f"no baseline for {missing}: add one so its arguments are attacked too"


@pytest.mark.parametrize(("name", "position", "keyword", "bad"), list(cases()))
def test_wrong_arguments_raise_only_fidlearn_errors(name, position, keyword, bad):
    f = _callable(name)
    args, kwargs = BASELINES[name]
    args, kwargs = list(args), dict(kwargs)
    if position is not None:
        args[position] = bad
    else:
        kwargs[keyword] = bad
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            out = f(*args, **kwargs)
        except FidlearnError as exc:
            assert str(exc).strip(), "an error must say what is wrong"
            return
        except Exception as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{name}({', '.join(map(repr, args))[:200]}) raised {type(exc).__name__}: {exc}")
    if isinstance(out, np.ndarray) and out.dtype.kind == "f":
        assert np.all(np.isfinite(out)), f"{name} accepted {bad!r} and returned NaN or infinity without a word"
