"""The commands on a robot builder's own files: what the error messages name is accepted, views the
--look-at form cannot aim, odometry without a mount, and a map written for the wrong dictionary in --track."""

from __future__ import annotations

import json

import pytest
from helpers import assert_user_error, run_cli

from fidlearn import MarkerMap, data_path, frames, synthetic
from fidlearn.camera import Camera
from fidlearn.images import write_image

MAP, CAMERA = data_path("world_map.json"), data_path("scenes/camera.json")
YAML_WITHOUT_SIZE = """%YAML:1.0
---
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [962.5, 0., 641.3, 0., 961.8, 357.9, 0., 0., 1.]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [-0.06, 0.045, 0.0003, -0.0002, -0.01]
"""
SEED_MAP = {
    "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
    "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
}


def _frames(folder, marker_map, xs):
    """Pictures of ``marker_map`` from 1.3 m in front of the north wall, stepping along -X by ``xs``."""
    folder.mkdir()
    camera = Camera.load(CAMERA)
    for k, x in enumerate(xs):
        T = frames.look_at([x, 150, 300], [0, 150, 300])
        write_image(folder / f"f_{k}.png", synthetic.render_scene(marker_map, camera, T, seed=k).image)
    return folder


def test_plan_takes_the_image_size_and_the_dictionary_its_errors_ask_for(capsys, tmp_path):
    (tmp_path / "camera.yaml").write_text(YAML_WITHOUT_SIZE)
    (tmp_path / "map.json").write_text(json.dumps(SEED_MAP))
    argv = ["plan", tmp_path / "map.json", "--camera", tmp_path / "camera.yaml", "--units", "ft"]
    argv += ["--marker-size-mm", "80", "--step-mm", "500", "--headings", "0", "-o", tmp_path / "plan.png"]
    code, _, err = run_cli(capsys, *argv)
    assert_user_error(code, err, "--image-size WxH")
    code, out, err = run_cli(capsys, *argv, "--image-size", "1280x720", "--dictionary", "4X4_50")
    assert code == 0, err
    assert "a pose is possible" in out
    assert (tmp_path / "plan.png").exists()


@pytest.mark.parametrize(
    ("option", "said"),
    [
        (["--headings", "-3"], "--headings must be a whole number from 0 to 360, got -3"),
        (["--height-mm", "nan"], "--height-mm must be a finite number of mm"),
        (["--step-mm", "1"], "use a larger --step-mm or a smaller area"),
    ],
)
def test_plan_errors_name_the_options_not_the_librarys_arguments(capsys, tmp_path, option, said):
    argv = ["plan", data_path("world_map.json"), "--camera", data_path("scenes", "camera.json")]
    code, _, err = run_cli(capsys, *argv, "-o", tmp_path / "plan.png", *option)
    assert_user_error(code, err, said)
    assert "height_mm" not in err
    assert "step_mm" not in err
    assert not (tmp_path / "plan.png").exists()


@pytest.mark.parametrize(
    ("look_at", "pose"), [("1000,150,0", "1000,150,250,180,0,YAW"), ("1000,150,900", "1000,150,250,0,0,YAW")]
)
def test_render_looking_straight_down_or_up_names_the_pose_to_give(capsys, tmp_path, look_at, pose):
    out = tmp_path / "scene.png"
    argv = ["render", "--map", MAP, "--camera", CAMERA, "--from", "1000,150,250", "--look-at", look_at, "-o", out]
    code, _, err = run_cli(capsys, *argv)
    assert_user_error(code, err, "looks straight", f"give --pose {pose} instead")
    assert not out.exists()
    code, _, err = run_cli(capsys, *argv[:5], "--pose", pose.replace("YAW", "0"), "-o", out)  # the pose it names
    assert code == 0, err
    assert out.exists()


def test_render_from_the_point_it_looks_at_is_one_line(capsys, tmp_path):
    argv = ["render", "--map", MAP, "--camera", CAMERA, "--from", "1,2,3", "--look-at", "1,2,3"]
    code, _, err = run_cli(capsys, *argv, "-o", tmp_path / "a.png")
    assert_user_error(code, err, "--from 1,2,3 and --look-at 1,2,3 are the same point")


def test_odometry_without_a_mount_is_said_to_be_the_cameras_own(capsys, tmp_path):
    folder = _frames(tmp_path / "drive", MarkerMap.load(MAP), [1300, 1250])
    (tmp_path / "odom.csv").write_text("t_s,x_m,y_m,z_m,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n0.1,0.05,0,0,0,0,0,1\n")
    argv = ["locate", folder, "--camera", CAMERA, "--map", MAP, "--track", "--fps", "10"]
    argv += ["--odometry", tmp_path / "odom.csv"]
    code, _, err = run_cli(capsys, *argv)
    assert code == 0, err
    assert "warning: odometry without --mount: it was taken as the camera's own motion in its optical frame" in err
    mount = {"units": "mm", "camera_in_base": {"translation": [200, 0, 300], "rpy_deg": [0, 0, 0]}}
    (tmp_path / "mount.json").write_text(json.dumps(mount))
    code, out, err = run_cli(capsys, *argv, "--mount", tmp_path / "mount.json")
    assert code == 0, err
    assert "odometry without --mount" not in err
    assert "1 started, 1 measured" in out  # the base moved 50 mm forward, as the frames show


def test_track_names_the_dictionary_the_frames_show(capsys, tmp_path):
    shown = MarkerMap.from_dict({"units": "ft", "marker_size_mm": 80, "dictionary": "4X4_50", "markers": SEED_MAP})
    folder = _frames(tmp_path / "drive", shown, [900])
    (tmp_path / "map.json").write_text(json.dumps({**json.loads(MAP.read_text()), "dictionary": "ARUCO_ORIGINAL"}))
    code, _, err = run_cli(capsys, "locate", folder, "--camera", CAMERA, "--map", tmp_path / "map.json", "--track")
    assert code == 0, err
    assert "markers of another dictionary (4X4_50: ids 0, 1): a detector finds only its own" in err
    assert 'write "dictionary": "4X4_50" in the map' in err


def test_markers_takes_the_marker_size_option_a_map_error_names(capsys, tmp_path):
    (tmp_path / "map.json").write_text(json.dumps(SEED_MAP))
    argv = ["markers", "--map", tmp_path / "map.json", "--units", "ft", "-o", tmp_path / "m.pdf"]
    assert_user_error(*run_cli(capsys, *argv)[::2], "--marker-size-mm")
    code, out, err = run_cli(capsys, *argv, "--marker-size-mm", "60")
    assert code == 0, err
    assert "2 markers of 60 mm (ARUCO_ORIGINAL)" in out
