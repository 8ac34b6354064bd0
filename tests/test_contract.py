"""The public contract of /work/shared/DESIGN.md ("Public contract"): names, parameter names, CLI commands.

Other tools, the notebooks and the course's checks call these names; renaming one breaks them.
Each test asserts what DESIGN.md promises, and a few known answers so that a name that exists
but does something else is caught too (the seed map's corners, a pose rendered from a known place).
"""

from __future__ import annotations

import inspect
import subprocess
import sys

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import cli

SEED_CORNERS_0 = [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]]  # DESIGN.md, mm


def params(fn) -> list[str]:
    return [p for p in inspect.signature(fn).parameters if p not in ("self", "cls")]


def starts_with(fn, names: list[str]) -> None:
    got = params(fn)
    assert got[: len(names)] == names, f"{fn.__qualname__}{inspect.signature(fn)}: expected parameters {names} first"


@pytest.mark.parametrize(
    "name",
    [
        "Camera",
        "MarkerMap",
        "Detection",
        "detect_markers",
        "estimate_pose",
        "locate",
        "Pose",
        "calibrate_checkerboard",
        "calibrate_charuco",
        "Calibration",
        "FidlearnError",
        "PoseTracker",
        "smooth",
        "survey",
        "Survey",
    ],
)
def test_name_importable_from_fidlearn(name):
    assert hasattr(fidlearn, name), f"fidlearn.{name} is missing"
    assert name in fidlearn.__all__, f"{name} is not in fidlearn.__all__"


def test_error_classes_are_fidlearn_errors():
    for name in (
        "MapError",
        "CameraError",
        "ImageError",
        "DictionaryError",
        "NoMarkersError",
        "CalibrationError",
        "PoseError",
        "TransformError",
        "TrackingError",
        "RosFormatError",
    ):
        assert issubclass(getattr(fidlearn, name), fidlearn.FidlearnError), name


def test_camera_signatures():
    starts_with(fidlearn.Camera, ["K", "dist", "image_size"])
    starts_with(fidlearn.Camera.load, ["path"])
    starts_with(fidlearn.Camera.save, ["path"])
    starts_with(fidlearn.Camera.project, ["points_world", "T_world_camera"])
    starts_with(fidlearn.Camera.scaled, ["image_size"])


def test_camera_behaves_as_described(tmp_path):
    cam = fidlearn.Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, (640, 480))
    # a point 1 m straight ahead of a camera at the origin lands on the principal point
    np.testing.assert_allclose(cam.project(np.array([[0.0, 0.0, 1000.0]]), np.eye(4)), [[319.5, 239.5]])
    back = fidlearn.Camera.load(cam.save(tmp_path / "camera.json"))
    np.testing.assert_array_equal(back.K, cam.K)
    assert back.image_size == (640, 480)
    half = cam.scaled((320, 240))
    assert half.image_size == (320, 240)
    assert half.fx == pytest.approx(300.0)
    assert half.cx == pytest.approx((319.5 + 0.5) / 2 - 0.5)  # pixel centres at integers


def test_markermap_signatures():
    starts_with(fidlearn.MarkerMap.load, ["path", "units", "marker_size_mm"])
    load = inspect.signature(fidlearn.MarkerMap.load).parameters
    assert load["units"].default is None
    assert load["marker_size_mm"].default is None
    starts_with(fidlearn.MarkerMap.from_dict, ["d"])
    assert {"units", "marker_size_mm"} <= set(params(fidlearn.MarkerMap.from_dict))
    starts_with(fidlearn.MarkerMap.save_corners, ["path"])


def test_markermap_behaves_as_described(tmp_path):
    seed = {"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}}  # the seed's bare layout
    m = fidlearn.MarkerMap.from_dict(seed, units="ft", marker_size_mm=80)
    corners = m.corners()
    assert set(corners) == {0}
    assert corners[0].shape == (4, 3)
    np.testing.assert_allclose(corners[0], SEED_CORNERS_0)
    world = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    np.testing.assert_allclose(world.corners()[0], SEED_CORNERS_0)
    out = world.save_corners(tmp_path / "corners.json")
    assert out.is_file()


def test_detection_signatures():
    starts_with(fidlearn.detect_markers, ["image", "dictionary", "refine"])
    assert inspect.signature(fidlearn.detect_markers).parameters["dictionary"].default == "ARUCO_ORIGINAL"
    starts_with(fidlearn.Detection, ["id", "corners_px"])
    d = fidlearn.Detection(3, [[0, 0], [1, 0], [1, 1], [0, 1]])
    assert d.corners_px.shape == (4, 2)  # one name for the pixel corners
    assert not hasattr(d, "corners")


def test_pose_signatures():
    starts_with(fidlearn.estimate_pose, ["detections", "marker_map", "camera", "method"])
    assert inspect.signature(fidlearn.estimate_pose).parameters["method"].default == "auto"
    starts_with(fidlearn.locate, ["image", "marker_map", "camera"])


def test_calibration_signatures():
    starts_with(fidlearn.calibrate_checkerboard, ["images", "pattern_size", "square_size_mm"])
    assert callable(fidlearn.calibrate_charuco)


@pytest.fixture(scope="module")
def scene():
    """A picture of the seed's map from a known pose, with its camera and map."""
    cam = fidlearn.Camera.from_fov(60, (640, 480))
    world = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    T = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [900.0, 190.0, 230.0])
    image = fidlearn.render_scene(world, cam, T).image
    return image, world, cam, T


def test_detect_gray_and_bgr_tl_tr_br_bl(scene):
    image, world, cam, T = scene
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    for im in (gray, cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)):
        dets = fidlearn.detect_markers(im, dictionary="ARUCO_ORIGINAL")
        assert [d.id for d in dets] == [0, 1, 2]
        for d in dets:
            assert isinstance(d, fidlearn.Detection)
            assert d.corners_px.shape == (4, 2)
            assert d.corners_px.dtype == np.float64
            truth = cam.project(world.corners()[d.id], T)  # TL, TR, BR, BL
            np.testing.assert_allclose(d.corners_px, truth, atol=0.3)


def test_pose_fields(scene):
    image, world, cam, T = scene
    pose = fidlearn.locate(image, world, cam)
    assert isinstance(pose, fidlearn.Pose)
    assert pose.T_world_camera.shape == (4, 4)
    assert pose.T_camera_world.shape == (4, 4)
    np.testing.assert_allclose(pose.T_world_camera @ pose.T_camera_world, np.eye(4), atol=1e-9)
    np.testing.assert_allclose(pose.position_mm, T[:3, 3], atol=3.0)
    np.testing.assert_allclose(pose.rpy_deg, [-90, 0, 90], atol=0.3)
    R, _ = cv2.Rodrigues(np.asarray(pose.rvec, float).reshape(3, 1))
    np.testing.assert_allclose(R, pose.T_camera_world[:3, :3], atol=1e-9)
    np.testing.assert_allclose(np.ravel(pose.tvec), pose.T_camera_world[:3, 3], atol=1e-9)
    assert list(pose.marker_ids) == [0, 1, 2]
    assert 0 <= pose.reprojection_rms_px < 0.5
    assert pose.ambiguous in (True, False)
    assert pose.covariance.shape == (6, 6)
    dets = fidlearn.detect_markers(image)
    again = fidlearn.estimate_pose(dets, world, cam, method="auto")
    np.testing.assert_allclose(again.T_world_camera, pose.T_world_camera, atol=1e-6)


def test_calibration_fields():
    cal = fidlearn.calibrate_checkerboard(fidlearn.data_path("real", "opencv_checkerboard_right"), (9, 6), 25.0)
    assert isinstance(cal, fidlearn.Calibration)
    assert isinstance(cal.camera, fidlearn.Camera)
    assert cal.camera.image_size == (640, 480)
    assert cal.camera.fx == pytest.approx(542, rel=0.01)  # data/README.md: fx about 542
    assert 0 < cal.rms_px < 0.6
    assert len(cal.per_view_rms_px) >= 10
    for item in cal.rejected:  # (image, reason)
        image, reason = item
        assert isinstance(reason, str)
        assert reason


CLI_COMMANDS = ["corners", "calibrate", "locate", "markers", "board", "render", "doctor", "survey"]


def test_cli_subcommands_exist():
    sub = next(a for a in cli.build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert set(CLI_COMMANDS) <= set(sub.choices)


@pytest.mark.parametrize(
    ("command", "options"),
    [
        ("corners", ["--units", "--marker-size-mm", "--output"]),
        ("calibrate", ["--pattern", "--square-mm", "--output"]),
        ("locate", ["--camera", "--map", "--json", "--annotate"]),
        ("markers", ["--ids", "--size-mm", "--output"]),
        ("board", ["--pattern", "--square-mm", "--output"]),
        ("survey", ["--camera", "--map", "--output", "--map-sigma-mm", "--fixed", "--plot"]),
    ],
)
def test_cli_options_exist(command, options):
    sub = next(a for a in cli.build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    have = {s for a in sub.choices[command]._actions for s in a.option_strings}
    assert set(options) <= have, f"fidlearn {command} lacks {set(options) - have}"
    assert "-o" in have or command in ("locate",)


def test_python_dash_m_fidlearn(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "fidlearn",
            "corners",
            str(fidlearn.data_path("world_map.json")),
            "-o",
            str(tmp_path / "c.json"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    import json

    np.testing.assert_allclose(json.loads((tmp_path / "c.json").read_text())["0"], SEED_CORNERS_0)


def test_user_error_is_status_2_one_line(tmp_path, capsys):
    status = cli.main(["corners", str(tmp_path / "missing.json"), "-o", str(tmp_path / "c.json")])
    err = capsys.readouterr().err
    assert status == 2
    assert err.startswith("error: ")
    assert err.count("\n") == 1
    assert not (tmp_path / "c.json").exists()


def test_pose_tracker_signatures():
    starts_with(fidlearn.PoseTracker, ["marker_map", "camera"])
    assert {"process_noise", "T_camera_base"} <= set(params(fidlearn.PoseTracker))
    starts_with(fidlearn.PoseTracker.update, ["image_or_detections", "t_s", "odometry"])
    starts_with(fidlearn.PoseTracker.predict, ["t_s"])
    starts_with(fidlearn.smooth, ["poses", "times_s"])
