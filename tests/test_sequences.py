"""fidlearn.sequences: each frame's pose (FrameLocator) and the tracked run (fidlearn.track), against known poses."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import fidlearn
import fidlearn.cli
from fidlearn import CameraError, FidlearnWarning, TrackingError, data_path
from fidlearn.images import Frame, expand_inputs, load_image, read_frames, write_image
from fidlearn.ros import Odometry
from fidlearn.sequences import NO_MARKER, FrameLocator, check_picture_sizes, track

SCENES = json.loads(data_path("scenes", "poses.json").read_text())
SCENE = data_path("scenes", "scene_00.png")
SCENE_T = np.array(SCENES["images"][0]["T_world_camera"])
WORLD = fidlearn.MarkerMap.load(data_path("world_map.json"))
CAMERA = fidlearn.Camera.load(data_path("scenes", "camera.json"))
DRIVE = json.loads(data_path("trajectory", "poses.json").read_text())
DRIVE_SHOTS = [(data_path("trajectory", f["image"]), np.array(f["T_world_camera"])) for f in DRIVE["frames"]][:8]
DRIVE_CAMERA = fidlearn.Camera.load(data_path("trajectory", "camera.json"))


def picture(path, image=None) -> Frame:
    return Frame(path.name, load_image(path) if image is None else image, str(path), "image")


def test_a_picture_is_located_where_it_was_rendered():
    located = FrameLocator(WORLD, CAMERA).locate(picture(SCENE))
    assert located.reason == ""
    assert located.pose is not None
    assert np.linalg.norm(located.pose.position_mm - SCENE_T[:3, 3]) < 5.0
    assert located.pose.marker_ids == (0, 1, 2)
    assert sorted(d.id for d in located.detections) == [0, 1, 2]
    assert located.camera is CAMERA  # the camera's own resolution: no rescaling


def test_the_library_and_the_locator_agree():
    expected = fidlearn.locate(load_image(SCENE), WORLD, CAMERA)
    got = FrameLocator(WORLD, CAMERA).locate(picture(SCENE)).pose
    np.testing.assert_allclose(got.T_world_camera, expected.T_world_camera, atol=1e-9)


def test_the_camera_is_rescaled_once_per_resolution():
    half = load_image(SCENE)[::2, ::2].copy()  # 640 x 360: the same aspect ratio
    locator = FrameLocator(WORLD, CAMERA)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cams = [locator.camera_for(Frame(f"half{k}.png", half, f"half{k}.png", "image")) for k in range(3)]
    said = [str(w.message) for w in caught if issubclass(w.category, FidlearnWarning)]
    assert said == [
        "camera calibrated at 1280x720 rescaled to 640x360; calibrating at the resolution you run at is more accurate"
    ]
    assert cams[0] is cams[1] is cams[2]
    assert cams[0].image_size == (640, 360)
    np.testing.assert_allclose(cams[0].K[:2], CAMERA.K[:2] / 2, atol=0.5)


def test_another_aspect_ratio_is_refused_naming_the_frame():
    square = np.zeros((500, 500), np.uint8)
    with pytest.raises(CameraError, match=r"^square\.png: .*1280x720"):
        FrameLocator(WORLD, CAMERA).locate(Frame("square.png", square, "square.png", "image"))


def test_a_frame_without_the_maps_markers_says_so():
    blank = np.full((720, 1280), 200, np.uint8)
    located = FrameLocator(WORLD, CAMERA).locate(Frame("blank.png", blank, "blank.png", "image"))
    assert (located.pose, located.reason, located.seen_ids) == (None, NO_MARKER, [])


def test_picture_sizes_are_checked_from_their_headers(tmp_path):
    write_image(tmp_path / "a.png", np.zeros((360, 640), np.uint8))  # rescalable
    check_picture_sizes(expand_inputs([tmp_path], videos=True), CAMERA, 1e8)
    write_image(tmp_path / "b.png", np.zeros((480, 640), np.uint8))  # 4:3
    with pytest.raises(CameraError, match=r"^b\.png: "):
        check_picture_sizes(expand_inputs([tmp_path], videos=True), CAMERA, 1e8)
    check_picture_sizes(expand_inputs([tmp_path], videos=True), CAMERA, 1e5)  # larger pictures left to load_image


def drive_frames():
    return read_frames([("image", path) for path, _ in DRIVE_SHOTS])


def test_track_follows_the_drive():
    steps = list(track(drive_frames(), WORLD, DRIVE_CAMERA, fps=10))
    assert [s.located.frame.name for s in steps] == [p.name for p, _ in DRIVE_SHOTS]
    assert [s.t_s for s in steps] == pytest.approx([k / 10 for k in range(len(DRIVE_SHOTS))])
    assert steps[0].tracked.status == "started"
    for step, (_, T) in zip(steps, DRIVE_SHOTS):
        assert step.tracked is not None
        assert np.linalg.norm(step.tracked.position_mm - T[:3, 3]) < 30.0  # the drive's poses, as rendered


def test_track_gives_what_a_pose_tracker_gives():
    tracker = fidlearn.PoseTracker(WORLD, DRIVE_CAMERA)
    expected = [tracker.update(fidlearn.locate(load_image(p), WORLD, DRIVE_CAMERA), k / 10) for k, (p, _) in
                enumerate(DRIVE_SHOTS[:4])]  # fmt: skip
    got = [
        s.tracked for s in track(read_frames([("image", p) for p, _ in DRIVE_SHOTS[:4]]), WORLD, DRIVE_CAMERA, fps=10)
    ]
    for a, b in zip(got, expected):
        assert a.status == b.status
        np.testing.assert_allclose(a.T_world_camera, b.T_world_camera, atol=1e-9)


def test_track_bridges_with_odometry_and_waits_for_the_first_pose():
    blank = Frame("blank.png", np.full((480, 640), 200, np.uint8), "blank.png", "image")
    run = [blank] + [Frame(p.name, load_image(p), str(p), "image") for p, _ in DRIVE_SHOTS[:3]] + [blank]
    Ts = [T for _, T in DRIVE_SHOTS[:3]]
    base = [Ts[0], Ts[0], Ts[1], Ts[2], Ts[2] @ fidlearn.make_transform(np.eye(3), [0, 0, 10])]
    odometry = Odometry([k / 10 for k in range(5)], base, drift=0.02)
    steps = list(track(run, WORLD, DRIVE_CAMERA, fps=10, odometry=odometry))
    assert steps[0].tracked is None  # nothing to track yet
    assert steps[0].located.reason == NO_MARKER
    assert [s.tracked.status for s in steps[1:]] == ["started", "measured", "measured", "odometry"]


def test_track_checks_its_arguments_at_the_call():
    with pytest.raises(TrackingError, match="fps must be a positive number"):
        track([], WORLD, CAMERA, fps=0)
    with pytest.raises(TrackingError, match="read_odometry_csv"):
        track([], WORLD, CAMERA, odometry=[[0, 0]])
    with pytest.raises(TrackingError, match="iterable of fidlearn.images.Frame"):
        track(3, WORLD, CAMERA)
    steps = track([load_image(SCENE)], WORLD, CAMERA)  # an image, not a Frame: said when reached
    with pytest.raises(TrackingError, match="frame 0 is a ndarray, not a fidlearn.images.Frame"):
        next(steps)


def test_locate_track_prints_what_fidlearn_track_gives(tmp_path, capsys):
    folder = tmp_path / "drive"
    folder.mkdir()
    for path, _ in DRIVE_SHOTS:
        (folder / path.name).write_bytes(path.read_bytes())
    out = tmp_path / "track.jsonl"
    argv = ["locate", folder, "--map", data_path("world_map.json"), "--camera", data_path("trajectory", "camera.json")]
    assert fidlearn.cli.main([str(a) for a in argv] + ["--track", "--fps", "10", "-o", str(out)]) == 0
    capsys.readouterr()
    records = [json.loads(line) for line in out.read_text().splitlines()]
    steps = list(track(read_frames(expand_inputs([folder], videos=True)), WORLD, DRIVE_CAMERA, fps=10))
    assert [r["frame"] for r in records] == [s.located.frame.name for s in steps]
    for r, s in zip(records, steps):
        assert (r["t_s"], r["status"]) == (s.t_s, s.tracked.status)
        np.testing.assert_allclose(r["T_world_body"], s.tracked.T_world_camera, atol=1e-9)
