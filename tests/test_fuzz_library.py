"""Hostile arguments for the tracker, the ROS files, the camera, the synthetic renderer and the webcam.

Each public callable of ``fidlearn.filtering``, ``fidlearn.ros``, ``fidlearn.Camera`` (constructor,
``load``, ``scaled``, ``project``, ``undistort_points``), ``fidlearn.tracking``, the render functions
of ``fidlearn.synthetic`` and the webcam's decoder and message handler is called from a valid
baseline with one argument at a time replaced by a wrong value: a wrong type, NaN, infinity,
1e300, 10^40, a wrong shape, a huge size. The only exception allowed out is a
:class:`FidlearnError` whose message is not empty, and an accepted value may not give NaN or
infinity back. The files these read (camera_info YAML, odometry CSV, mount JSON) are mutated value
by value. Sizes are small and every case is bounded: a size or count that would take minutes is
refused up front (the limit named), so the whole file runs in seconds.
"""

from __future__ import annotations

import dataclasses
import json
import re
import struct
import time
import warnings
import zlib

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import Board, Camera, Detection, FidlearnError, MarkerMap, ros, synthetic
from fidlearn._webcam import MAX_FRAME_SIDE_PX, decode_frame
from fidlearn.errors import ImageError, TrackingError, WebcamError
from fidlearn.filtering import PoseTracker, smooth
from fidlearn.tracking import MarkerTracker

WORLD = MarkerMap.load(fidlearn.data_path("world_map.json"))
CAM = Camera.from_fov(60, (160, 120))
T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
POSE = fidlearn.estimate_pose([Detection(i, CAM.project(c, T)) for i, c in WORLD.corners().items()], WORLD, CAM)
IMAGE = synthetic.render_scene(WORLD, CAM, T, supersample=1).image
ODO = (np.eye(4), np.eye(6) * 0.01)

BAD = {
    "None": None,
    "text": "abc",
    "bytes": b"\x00\x01",
    "nan": float("nan"),
    "inf": float("inf"),
    "-inf": -float("inf"),
    "-1": -1,
    "huge int": 10**40,
    "1e300": 1e300,
    "True": True,
    "empty list": [],
    "ragged list": [[1, 2], [3]],
    "wrong shape": np.zeros((2, 5)),
    "nan matrix": np.full((4, 4), np.nan),
    "object": object(),
    "dict": {"a": 1},
}


def _tracker() -> PoseTracker:
    tracker = PoseTracker(WORLD, CAM)
    tracker.update(POSE, 0.0)
    return tracker


def _odometry() -> ros.Odometry:
    return ros.Odometry([0.0, 1.0], [np.eye(4), fidlearn.make_transform(np.eye(3), [100, 0, 0])])


#: name: (callable factory, args, kwargs): one valid call of each, mutated one argument at a time.
BASELINES = {
    "PoseTracker": (lambda: PoseTracker, (WORLD, CAM), {"process_noise": (500.0, 1.0), "T_camera_base": np.eye(4)}),
    "PoseTracker.update": (lambda: _tracker().update, (POSE, 0.1), {"odometry": ODO}),
    "PoseTracker.predict": (lambda: _tracker().predict, (0.2,), {}),
    "smooth": (lambda: smooth, ([POSE, None, POSE], [0.0, 0.1, 0.2]), {"process_noise": (500.0, 1.0)}),
    "TrackedPose.position_ellipsoid_contains": (
        lambda: _tracker().last.position_ellipsoid_contains,
        ([1000, 150, 250],),
        {"probability": 0.95},
    ),
    "ros_pose": (lambda: ros.ros_pose, (POSE, 1.5), {"frame_id": "map"}),
    "ros_covariance": (lambda: ros.ros_covariance, (POSE.covariance,), {}),
    "tum_line": (lambda: ros.tum_line, (1.5, T), {}),
    "camera_info_yaml": (lambda: ros.camera_info_yaml, (CAM,), {"camera_name": "cam"}),
    "camera_from_camera_info": (lambda: ros.camera_from_camera_info, (ros.camera_info_yaml(CAM),), {"source": "x"}),
    "load_camera_info": (lambda: ros.load_camera_info, ("no_such_file.yaml",), {}),
    "read_odometry_csv": (lambda: ros.read_odometry_csv, ("no_such_file.csv",), {"drift": 0.02}),
    "read_mount_json": (lambda: ros.read_mount_json, ("no_such_file.json",), {}),
    "Odometry": (lambda: ros.Odometry, ([0.0, 1.0], [np.eye(4), np.eye(4)]), {"drift": 0.02}),
    "Odometry.between": (lambda: _odometry().between, (0.25, 0.75), {}),
    "Odometry.pose_at": (lambda: _odometry().pose_at, (0.5,), {}),
    "Camera": (lambda: Camera, (CAM.K, CAM.dist, CAM.image_size), {"source": "x"}),
    "Camera.load": (lambda: Camera.load, ("no_such_camera.json",), {"image_size": None}),
    "Camera.scaled": (lambda: CAM.scaled, ((320, 240),), {"tol": 0.01}),
    "Camera.project": (lambda: CAM.project, (np.array([[0.0, 0.0, 1000.0]]), np.eye(4)), {}),
    "Camera.undistort_points": (lambda: CAM.undistort_points, (np.array([[80.0, 60.0]]),), {}),
    "MarkerTracker": (
        lambda: MarkerTracker,
        (WORLD, CAM),
        {"full_every": 30, "search_px": 10.0, "refine": "subpix", "detector_params": None, "corner_sigma_px": 0.3},
    ),
    "MarkerTracker.locate": (lambda: MarkerTracker(WORLD, CAM).locate, (IMAGE,), {}),
    "render_scene": (
        lambda: synthetic.render_scene,
        (WORLD, CAM, T),
        {"seed": 0, "noise_std_gray": 1.0, "blur_px": 0.5, "supersample": 1},
    ),
    "render_trajectory": (
        lambda: synthetic.render_trajectory,
        (WORLD, CAM, 2),
        {"seed": 0, "supersample": 1, "frames_to_render": [1]},
    ),
    "render_trajectory(poses=...)": (
        lambda: synthetic.render_trajectory,
        (WORLD, CAM),
        {"poses": [T, T], "supersample": 1},
    ),
    "render_calibration_views": (
        lambda: synthetic.render_calibration_views,
        (Camera.from_fov(60, (320, 240)),),
        {"n_views": 2, "board": Board.checkerboard((5, 4), 25.0), "seed": 0, "supersample": 1, "views": [0]},
    ),
    "decode_frame": (lambda: decode_frame, (cv2.imencode(".png", IMAGE)[1].tobytes(), 160, 120), {}),
}


def cases():
    for name, (_, args, kwargs) in BASELINES.items():
        for k in range(len(args)):
            for label, bad in BAD.items():
                yield pytest.param(name, k, None, bad, id=f"{name}-arg{k}-{label}")
        for key in kwargs:
            for label, bad in BAD.items():
                yield pytest.param(name, None, key, bad, id=f"{name}-{key}-{label}")


def _finite(out) -> bool:
    if isinstance(out, float):
        return np.isfinite(out)
    if isinstance(out, np.ndarray) and out.dtype.kind == "f":
        return bool(np.all(np.isfinite(out)))
    if isinstance(out, Camera):
        return _finite(out.K) and _finite(out.dist)
    return True


def _call_expecting_only_fidlearn_errors(f, args, kwargs, what: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.monotonic()
        try:
            out = f(*args, **kwargs)
        except FidlearnError as exc:
            assert str(exc).strip(), "an error must say what is wrong"
            return None
        except Exception as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{what} raised {type(exc).__name__}: {exc}")
        finally:
            assert time.monotonic() - start < 20, f"{what} took minutes instead of refusing up front"
    assert _finite(out), f"{what} returned NaN or infinity without a word"
    return out


def test_every_baseline_works():
    for _name, (factory, args, kwargs) in BASELINES.items():
        if "no_such" in str(args[0]):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            factory()(*args, **kwargs)  # raises if the baseline itself is wrong


@pytest.mark.parametrize(("name", "position", "keyword", "bad"), list(cases()))
def test_wrong_arguments_raise_only_fidlearn_errors(name, position, keyword, bad):
    factory, args, kwargs = BASELINES[name]
    args, kwargs = list(args), dict(kwargs)
    if position is not None:
        args[position] = bad
    else:
        kwargs[keyword] = bad
    _call_expecting_only_fidlearn_errors(factory(), args, kwargs, f"{name}(... {bad!r:.60} ...)")


# -- the cases the hostile tester found --------------------------------------------------------------
def test_a_pose_with_a_3x3_covariance_is_a_tracking_error():
    flat = dataclasses.replace(POSE, covariance=np.eye(3))
    with pytest.raises(TrackingError, match="covariance must be a 6x6 array"):
        PoseTracker(WORLD, CAM).update(flat, 0.0)
    with pytest.raises(TrackingError, match="got shape \\(3, 3\\)"):
        _tracker().update(flat, 0.1)
    with pytest.raises(TrackingError, match="symmetric positive semi-definite"):
        smooth([dataclasses.replace(POSE, covariance=-np.eye(6))], [0.0])


def test_a_gap_of_1e300_seconds_is_a_tracking_error_and_1e10_works():
    with pytest.raises(TrackingError, match="at most 1e\\+12"):
        smooth([POSE, None, POSE], [0.0, 5e299, 1e300])
    out = smooth([POSE, None, POSE], [0.0, 5e9, 1e10])
    assert all(np.isfinite(p.covariance).all() for p in out)
    np.testing.assert_allclose(out[2].position_mm, POSE.position_mm, atol=1e-6)


def test_render_sizes_that_take_minutes_are_refused_naming_the_limit():
    big = Camera.from_fov(60, (8000, 6000))
    with pytest.raises(FidlearnError, match="more than the limit of 40 million \\(MAX_RENDER_SAMPLES"):
        synthetic.render_scene(WORLD, big, T, supersample=1)
    with pytest.raises(FidlearnError, match="MAX_RENDER_SAMPLES_ALL"):
        synthetic.render_trajectory(WORLD, Camera.from_fov(60, (640, 480)), 100_000, supersample=4)
    with pytest.raises(FidlearnError, match="MAX_RENDER_SAMPLES_ALL"):
        synthetic.render_calibration_views(Camera.from_fov(60, (640, 480)), n_views=100_000)


# -- files, value by value ---------------------------------------------------------------------------
VALUES = ["1e999", "-1e999", "nan", "9x400", "1e300", "0", "-5", "4.5", "[1, 2]", "{a: 1}", "", "[", "{", "'640'"]


def camera_info_cases():
    text = ros.camera_info_yaml(Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [0.1, 0, 0, 0, 0], (640, 480)))
    values = list(re.finditer(r"(?<=: )[^\n\[]+|(?<=[\[,] )[^,\]\n]+|(?<=\[)[^,\]\n]+", text))
    for m in values[::2]:  # every other value: all the fields, a sample of the matrices' numbers
        for v in VALUES:
            yield pytest.param(text[: m.start()] + v + text[m.end() :], id=f"{text[: m.start()][-12:]!r}={v!r}")


@pytest.mark.parametrize("text", list(camera_info_cases()))
def test_camera_info_values_raise_only_fidlearn_errors(text):
    _call_expecting_only_fidlearn_errors(ros.camera_from_camera_info, [text], {}, "camera_from_camera_info")


ODOMETRY = "t_s,x_m,y_m,z_m,qx,qy,qz,qw\n0.0,0,0,0,0,0,0,1\n1.0,0.1,0,0,0,0,0,1\n"


@pytest.mark.parametrize("column", range(8))
def test_odometry_csv_values_raise_only_fidlearn_errors(tmp_path, column):
    for v in VALUES + ["1e20", "-1e308"]:
        rows = ODOMETRY.splitlines()
        cells = rows[2].split(",")
        cells[column] = v
        rows[2] = ",".join(cells)
        path = tmp_path / "odom.csv"
        path.write_text("\n".join(rows) + "\n")
        odo = _call_expecting_only_fidlearn_errors(ros.read_odometry_csv, [path], {}, f"odometry {v!r}")
        if odo is not None:
            _call_expecting_only_fidlearn_errors(odo.between, [0.0, 1.0], {}, f"odometry {v!r} between")


def mount_cases():
    base = {"units": "mm", "camera_in_base": {"translation": [200, 0, 300], "rpy_deg": [0, 0, 0]}}
    hostile = [None, "abc", 1e300, [1e300, 0, 0], ["a", 0, 0], [0, 0], {"a": 1}, [float("nan")] * 3, True]
    for v in hostile:
        yield pytest.param({**base, "units": v}, id=f"units={v!r:.20}")
        yield pytest.param({**base, "camera_axes": v}, id=f"camera_axes={v!r:.20}")
        for key in ("translation", "rpy_deg"):
            yield pytest.param({**base, "camera_in_base": {**base["camera_in_base"], key: v}}, id=f"{key}={v!r:.20}")
        yield pytest.param({"units": "mm", "T_camera_base": v}, id=f"T_camera_base={v!r:.20}")
    yield pytest.param([base], id="a list")
    yield pytest.param({**base, "axes": "optical"}, id="misspelt axes")


@pytest.mark.parametrize("mount", list(mount_cases()))
def test_mount_values_raise_only_fidlearn_errors(tmp_path, mount):
    path = tmp_path / "mount.json"
    path.write_text(json.dumps(mount))
    _call_expecting_only_fidlearn_errors(ros.read_mount_json, [path], {}, f"mount {mount!r:.80}")


def test_a_misspelt_mount_key_names_it_and_the_expected_ones(tmp_path):
    path = tmp_path / "mount.json"
    path.write_text(
        json.dumps({"units": "mm", "camera_in_base": {"translation": [0, 0, 0], "rpy_deg": [0, 0, 0]}, "axes": "link"})
    )
    with pytest.raises(
        FidlearnError, match="unknown key 'axes': did you mean 'camera_axes'\\?; a mount file has units, "
    ):
        ros.read_mount_json(path)


# -- the webcam's message handler --------------------------------------------------------------------
def _png_claiming(width: int, height: int) -> bytes:
    """A 74-byte PNG whose header claims ``width`` x ``height`` pixels."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 10)) + chunk(b"IEND", b"")


GOOD_PNG = cv2.imencode(".png", np.zeros((48, 64, 3), np.uint8))[1].tobytes()
GOOD_JPEG = cv2.imencode(".jpg", np.zeros((48, 64, 3), np.uint8))[1].tobytes()
MESSAGE_FIELDS = {
    "width": ["64", "nan", float("nan"), float("inf"), [64], None, True, -1, 0, 1e300, 10**40, 64.0, {"a": 1}],
    "height": ["48", float("nan"), float("inf"), [48], -48, 10**40, 48.5],
    "seq": ["1", [1], {"a": 1}, float("nan"), None],
    "id": ["1", [1], {"a": 1}, float("nan"), None],
    "kind": [None, ["stream"], {"a": 1}, 7],
    "failed": [["denied"], {"a": 1}, "nonsense", 1],
}
BUFFERS = {
    "100000x100000 PNG": [_png_claiming(100000, 100000)],
    "9000x9000 PNG": [_png_claiming(9000, 9000)],
    "64x48 header, bad data": [_png_claiming(64, 48)],
    "empty": [b""],
    "cut PNG": [GOOD_PNG[: len(GOOD_PNG) // 2]],
    "cut JPEG": [GOOD_JPEG[:-10]],
    "text": ["text"],
    "None": [None],
    "a number": [42],
    "no list": None,
    "a string for the list": "x",
    "GIF": [b"GIF89a" + bytes([64, 0, 48, 0]) + b"\0" * 20],
}


def _webcam():
    from fidlearn.widgets import Webcam

    cam = Webcam()
    sent = []
    cam.send = lambda content, buffers=None: sent.append(content)  # noqa: ARG005 (Widget.send's signature)
    seen = []
    cam.on_frame(lambda frame: seen.append(frame.shape))
    cam.start()
    return cam, sent, seen


def webcam_cases():
    for kind in ("stream", "snap"):
        for field, values in MESSAGE_FIELDS.items():
            for v in values:
                yield pytest.param(kind, {field: v}, [GOOD_PNG], id=f"{kind}-{field}={v!r:.20}")
        for label, buffers in BUFFERS.items():
            yield pytest.param(kind, {}, buffers, id=f"{kind}-{label}")
    for content in (None, [], "frame", {"type": ["frame"]}, {"type": "frame", "kind": {}}):
        yield pytest.param(None, content, [GOOD_PNG], id=f"content={content!r:.20}")


@pytest.mark.parametrize(("kind", "change", "buffers"), list(webcam_cases()))
def test_a_malformed_browser_message_is_dropped_and_the_next_frame_delivered(kind, change, buffers):
    import asyncio

    cam, sent, seen = _webcam()
    content = {"type": "frame", "kind": kind, "seq": 1, "id": 1, "width": 64, "height": 48}
    content = {**content, **change} if kind is not None else change
    loop = asyncio.new_event_loop()
    try:
        future = loop.create_future()
        cam._pending[1] = future
        cam._on_message(cam, content, buffers)  # never raises
        if future.done() and future.exception() is not None:
            assert isinstance(future.exception(), FidlearnError)  # the snapshot ends with the reason
    finally:
        loop.close()
    if kind == "stream" and not seen:
        assert cam.frames_dropped == 1
        assert cam.drop_reason
        assert sent  # the browser may send the next frame
        assert sent[-1]["type"] == "ack"
    cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 2, "width": 64, "height": 48}, [GOOD_PNG])
    assert seen[-1] == (48, 64, 3)
    assert cam.streaming


def test_a_header_claiming_100000_pixels_a_side_is_refused_before_decoding():
    with pytest.raises(ImageError, match=f"100000x100000 pixels; a frame is 1 to {MAX_FRAME_SIDE_PX} px a side"):
        decode_frame(_png_claiming(100000, 100000))
    with pytest.raises(ImageError, match="announced a frame width of 'nan'"):
        decode_frame(GOOD_PNG, "nan", 48)
    np.testing.assert_array_equal(decode_frame(GOOD_PNG, 64, 48), np.zeros((48, 64, 3), np.uint8))


def test_removing_an_unknown_callback_is_a_webcam_error():
    cam, _, _ = _webcam()
    with pytest.raises(WebcamError, match="was not registered"):
        cam.on_frame(print, remove=True)


STATE_UPDATES = [
    {"status": "sleeping"},
    {"status": ["streaming"]},
    {"actual_width": "abc"},
    {"actual_width": float("nan")},
    {"error": 5},
    {"width": "abc"},
    {"height": 10**40},
    {"max_fps": "nan"},
    {"streaming": "yes"},
    {"stream_format": "webp"},
    {7: 1},
]


@pytest.mark.parametrize("update", STATE_UPDATES, ids=[repr(u)[:30] for u in STATE_UPDATES])
def test_a_malformed_state_update_from_the_browser_is_dropped_and_the_widget_unchanged(update):
    cam, _, seen = _webcam()
    before = {k: getattr(cam, k) for k in ("status", "actual_width", "width", "height", "max_fps", "streaming")}
    cam.set_state(update)  # what the comm does with the browser's state message: never raises
    assert cam.frames_dropped == 1
    assert "the browser set" in cam.drop_reason or "not a name" in cam.drop_reason
    assert {k: getattr(cam, k) for k in before} == before
    cam.set_state({"status": "streaming", "actual_width": 64})  # a good update still applies
    assert cam.status == "streaming"
    assert cam.actual_width == 64
    cam._on_message(cam, {"type": "frame", "kind": "stream", "seq": 2, "width": 64, "height": 48}, [GOOD_PNG])
    assert seen == [(48, 64, 3)]


@pytest.mark.parametrize("label", list(BAD))
def test_the_ros_writers_raise_only_fidlearn_errors_and_write_nothing(tmp_path, monkeypatch, label):
    monkeypatch.chdir(tmp_path)  # a path of "abc" is a file name: written here, nowhere else
    bad = BAD[label]
    calls = [
        (ros.write_tum, [tmp_path / "a.txt", bad], {}),
        (ros.write_tum, [tmp_path / "b.txt", [_tracker().last]], {"body": bad}),
        (ros.write_tum, [bad, [_tracker().last]], {}),
        (ros.save_camera_info, [bad, tmp_path / "c.yaml"], {}),
        (ros.save_camera_info, [CAM, tmp_path / "d.yaml"], {"camera_name": bad}),
        (ros.ros_pose, [POSE], {"body": bad}),
    ]
    for f, args, kwargs in calls:
        out = _call_expecting_only_fidlearn_errors(f, args, kwargs, f"{f.__name__}(... {bad!r:.40} ...)")
        if out is None and f is not ros.ros_pose and isinstance(args[0], type(tmp_path)):
            assert not args[0].exists()  # nothing half-written
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left


@pytest.mark.parametrize("label", list(BAD))
def test_snapshot_and_the_pacer_refuse_wrong_arguments_with_webcam_errors(label):
    import asyncio

    from fidlearn._webcam import FramePacer

    cam, _, _ = _webcam()
    bad = BAD[label]
    for f, args in ((lambda t: asyncio.run(cam.snapshot(timeout_s=t)), [bad]), (FramePacer(5).wait_s, [bad, 1.0])):
        _call_expecting_only_fidlearn_errors(f, args, {}, f"webcam {bad!r:.40}")
