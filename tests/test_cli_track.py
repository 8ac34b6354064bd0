"""``fidlearn locate --track`` and ``fidlearn camera export|import``, as a user runs them, against known answers."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import assert_user_error
from helpers import run_cli as run

import fidlearn
from fidlearn import data_path, frames
from fidlearn.filtering._so3 import rotation_from_xyzw

RECORD = json.loads(data_path("trajectory", "poses.json").read_text())
SHOTS = [(data_path("trajectory", f["image"]), np.array(f["T_world_camera"])) for f in RECORD["frames"]]
CAMERA = data_path("trajectory", "camera.json")
MAP = data_path("world_map.json")


@pytest.fixture(scope="module")
def frames_dir(tmp_path_factory):
    """The first 20 frames of the bundled drive, in a folder of their own."""
    d = tmp_path_factory.mktemp("drive")
    for path, _ in SHOTS[:20]:
        (d / path.name).write_bytes(path.read_bytes())
    return d


def test_track_jsonl_agrees_with_the_library_and_the_truth(capsys, tmp_path, frames_dir):
    out = tmp_path / "track.jsonl"
    code, stdout, err = run(capsys, "locate", frames_dir, "--camera", CAMERA, "--map", MAP, "--track", "-o", out)
    assert code == 0, err
    assert "20 frames tracked: 1 started, 19 measured" in stdout
    recs = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(recs) == 20
    assert recs[0]["status"] == "started"
    assert recs[1]["t_s"] == pytest.approx(1 / 30)
    # the library, frame by frame: fidlearn.locate then PoseTracker.update
    m, cam = fidlearn.MarkerMap.load(MAP), fidlearn.Camera.load(CAMERA)
    tracker = fidlearn.PoseTracker(m, cam)
    for k, (rec, (path, truth)) in enumerate(zip(recs, SHOTS)):
        lib = tracker.update(fidlearn.locate(fidlearn.images.load_image(path), m, cam), k / 30)
        np.testing.assert_allclose(rec["T_world_body"], lib.T_world_camera, atol=1e-6)
        # 2.2 m away, one frame is up to 39 mm off (and states 20-60 mm per axis). The track starts at rest and,
        # with frames that noisy, needs about 6 frames to learn the speed: up to 43 mm behind meanwhile, then
        # at most 24 mm off
        error = np.linalg.norm(np.array(rec["position_mm"]) - truth[:3, 3])
        assert error < (50.0 if k < 6 else 30.0)


def test_track_tum_and_ros_with_a_mount(capsys, tmp_path, frames_dir):
    mount = tmp_path / "mount.json"
    mount.write_text(
        json.dumps({"units": "mm", "camera_in_base": {"translation": [200, 0, 300], "rpy_deg": [0, 0, 0]}})
    )
    T_camera_base = fidlearn.ros.read_mount_json(mount)
    tum, ros = tmp_path / "track.txt", tmp_path / "track.jsonl"
    common = ["locate", frames_dir, "--camera", CAMERA, "--map", MAP, "--track", "--mount", mount]
    assert run(capsys, *common, "--format", "tum", "-o", tum)[0] == 0
    assert run(capsys, *common, "--format", "ros", "-o", ros)[0] == 0
    rows = [r.split() for r in tum.read_text().splitlines()[1:]]
    msgs = [json.loads(line) for line in ros.read_text().splitlines()]
    assert len(rows) == len(msgs) == 20
    for k, (row, msg, (_, truth)) in enumerate(zip(rows, msgs, SHOTS)):
        v = np.array(row, dtype=float)
        p, q = msg["pose"]["pose"]["position"], msg["pose"]["pose"]["orientation"]
        assert msg["child_frame_id"] == "base_link"
        assert msg["header"]["frame_id"] == "map"
        np.testing.assert_allclose(v[1:4], [p["x"], p["y"], p["z"]], atol=1e-9)
        np.testing.assert_allclose(v[4:], [q["x"], q["y"], q["z"], q["w"]], atol=1e-11)
        true_base = truth @ T_camera_base
        # metres in the file; the base is 0.36 m from the camera: up to 47 mm off while the track, started at
        # rest, learns the speed (6 frames, as above), at most 27 mm after
        error = np.linalg.norm(v[1:4] * 1000 - true_base[:3, 3])
        assert error < (55.0 if k < 6 else 35.0)
        assert frames.rotation_angle_deg(rotation_from_xyzw(v[4:]), true_base[:3, :3]) < 2.0
        assert len(msg["pose"]["covariance"]) == 36


def test_track_with_odometry(capsys, tmp_path, frames_dir):
    odo = tmp_path / "odom.csv"
    lines = ["t_s,x_m,y_m,z_m,qx,qy,qz,qw"]
    for k, (_, T) in enumerate(SHOTS[:20]):  # the camera itself as the base, its true path
        q = fidlearn.ros.ros_pose(fidlearn.TrackedPose(0.0, T, np.eye(6), "measured"))["pose"]["pose"]
        o, p = q["orientation"], q["position"]
        lines.append(f"{k / 30},{p['x']},{p['y']},{p['z']},{o['x']},{o['y']},{o['z']},{o['w']}")
    odo.write_text("\n".join(lines) + "\n")
    out = tmp_path / "t.jsonl"
    code, stdout, err = run(
        capsys, "locate", frames_dir, "--camera", CAMERA, "--map", MAP, "--track", "--odometry", odo, "-o", out
    )
    assert code == 0, err
    recs = [json.loads(line) for line in out.read_text().splitlines()]
    for rec, (_, truth) in zip(recs, SHOTS):
        assert np.linalg.norm(np.array(rec["position_mm"]) - truth[:3, 3]) < 35.0
    # the odometry is the true path: the scale learnt is 1 within its (shrunk) uncertainty, and said
    last = recs[-1]
    assert abs(last["odometry_scale"] - 1.0) < 3 * last["odometry_scale_std"] < 3 * 0.05
    # the same odometry on another clock (Unix seconds): no frame can use it, and nothing is written
    odo.write_text(
        "\n".join([lines[0]] + [f"{1.7e9 + float(r.split(',', 1)[0])},{r.split(',', 1)[1]}" for r in lines[1:]]) + "\n"
    )
    out.unlink()
    code, _, err = run(
        capsys, "locate", frames_dir, "--camera", CAMERA, "--map", MAP, "--track", "--odometry", odo, "-o", out
    )
    assert_user_error(code, err, "no frame had odometry; record it over the video, or start the video's clock")
    assert not out.exists()
    assert f"odometry scale learnt from the poses: {last['odometry_scale']:.4f}" in stdout


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        (["--odometry", "odom.csv"], "add --track"),
        (["--track", "--format", "tum"], "give -o FILE"),
        (["--track", "-o", "track.csv"], "name the file .jsonl or .json"),
        (["--track", "--format", "tum", "-o", "t.jsonl"], "name the file .txt or .tum"),
        (["--track", "--fps", "0"], "--fps"),
        (["--fps", "10"], "--fps belongs to tracking: add --track"),
        (["--odometry-drift", "0.5"], "--odometry-drift belongs to tracking: add --track"),
        (["--track", "--json", "p.jsonl"], "--json and --annotate are for untracked runs"),
        (["--track", "--mount", "missing.json"], "missing.json"),
    ],
)
def test_track_bad_inputs(capsys, tmp_path, frames_dir, monkeypatch, extra, fragment):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "locate", frames_dir, "--camera", CAMERA, "--map", MAP, *extra)
    assert_user_error(code, err, fragment)
    assert not list(tmp_path.glob("t*"))
    assert not list(tmp_path.glob(".*"))


def test_track_output_may_not_be_an_input(capsys, frames_dir):
    target = frames_dir / "frame_000.png"
    code, _, err = run(capsys, "locate", frames_dir, "--camera", CAMERA, "--map", MAP, "--track", "-o", CAMERA)
    assert_user_error(code, err, "is one of the inputs")
    assert target.exists()


def test_camera_export_import_round_trip(capsys, tmp_path):
    ci, back = tmp_path / "camera_info.yaml", tmp_path / "camera.json"
    code, out, err = run(capsys, "camera", "export", CAMERA, "--ros", ci, "--camera-name", "front")
    assert code == 0, err
    assert "camera_name: front\n" in ci.read_text()
    assert "distortion_model: plumb_bob\n" in ci.read_text()
    assert run(capsys, "camera", "import", ci, "-o", back)[0] == 0
    a, b = fidlearn.Camera.load(CAMERA), fidlearn.Camera.load(back)
    assert (a.K == b.K).all()
    assert (a.dist == b.dist).all()
    assert a.image_size == b.image_size


def test_camera_bad_inputs(capsys, tmp_path):
    bad = tmp_path / "camera_info.yaml"
    bad.write_text("image_width: 640\nimage_height: 480\n")
    code, _, err = run(capsys, "camera", "import", bad, "-o", tmp_path / "c.json")
    assert_user_error(code, err, "camera_matrix")
    assert not (tmp_path / "c.json").exists()
    code, _, err = run(capsys, "camera", "export", CAMERA, "--ros", tmp_path / "c.txt")
    assert_user_error(code, err, ".yaml or .yml")
    cam14 = tmp_path / "c14.json"
    fidlearn.Camera.from_fov(60, (640, 480), dist=[0.0] * 14).save(cam14)
    code, _, err = run(capsys, "camera", "export", cam14, "--ros", tmp_path / "c.yaml")
    assert_user_error(code, err, "no ROS distortion model")
    assert not (tmp_path / "c.yaml").exists()
    code, _, err = run(capsys, "camera", "export", CAMERA, "--ros", CAMERA.with_suffix(".yaml"), "--camera-name", "a b")
    assert_user_error(code, err, "camera_name")
