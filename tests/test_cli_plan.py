"""``fidlearn plan`` with a camera's real noise: the marker shift and the markers' size error, passed through
to the prediction, and refused when out of range (status 2, one line on stderr, no picture)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, data_path
from fidlearn.cli import main
from fidlearn.planning import plan_room

MAP, CAMERA = data_path("world_map.json"), data_path("scenes/camera.json")
COARSE = ["--step-mm", "500", "--headings", "0", "--corner-sigma-px", "0.2"]


def _plan(capsys, tmp_path, *extra):
    out = tmp_path / "plan.png"
    code = main(["plan", str(MAP), "--camera", str(CAMERA), *COARSE, "-o", str(out), *extra])
    stdout, stderr = capsys.readouterr()
    return code, stdout, stderr, out


def _median(stdout: str) -> float:
    return float(re.search(r"looking at the markers: median ([0-9.]+) mm", stdout).group(1))


def test_the_shift_and_the_size_error_reach_the_prediction(capsys, tmp_path):
    code, plain, _, out = _plan(capsys, tmp_path)
    assert code == 0 and out.exists()
    code, noisy, _, _ = _plan(capsys, tmp_path, "--marker-shift-px", "0.15", "--marker-size-rel-std", "0.01")
    assert code == 0
    # the figures printed are those of plan_room with the same options
    world, camera = MarkerMap.load(MAP), Camera.load(CAMERA)
    for text, kw in ((plain, {}), (noisy, {"marker_shift_px": 0.15, "marker_size_rel_std": 0.01})):
        plan = plan_room(world, camera, step_mm=500, headings=0, corner_sigma_px=0.2, **kw)
        ok = np.isfinite(plan.toward_mm)
        assert _median(text) == pytest.approx(float(np.median(plan.toward_mm[ok])), abs=0.051)
    assert _median(noisy) > 1.3 * _median(plain)  # 1 % of 1 to 3 m is 10 to 30 mm: it dominates here


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--marker-shift-px", "-0.1"], "--marker-shift-px -0.1: give a number of pixels, 0 or more"),
        (["--marker-shift-px", "nan"], "--marker-shift-px nan"),
        (["--marker-size-rel-std", "-0.01"], "--marker-size-rel-std -0.01: give a fraction"),
        (["--marker-size-rel-std", "1"], "0.01 for 1 %"),
        (["--marker-size-rel-std", "inf"], "--marker-size-rel-std inf"),
        (["--corner-sigma-px", "0"], "--corner-sigma-px 0.0: give a positive number"),
    ],
)
def test_bad_noise_options_end_with_status_2_and_one_line(capsys, tmp_path, extra, match):
    code, stdout, stderr, out = _plan(capsys, tmp_path, *extra)
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and match in lines[0], stderr
    assert not out.exists() and not list(tmp_path.iterdir())


def test_a_size_error_that_is_not_a_number_is_refused_by_the_parser(capsys, tmp_path):
    code, _, stderr, out = _plan(capsys, tmp_path, "--marker-size-rel-std", "1%")
    lines = stderr.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "--marker-size-rel-std: invalid float value: '1%'" in lines[0]
    assert not out.exists()


def test_suggestions_are_made_with_the_size_error(capsys, tmp_path):
    def within(text: str) -> int:
        return int(re.search(r"within 3 mm: (\d+) % of the area", text).group(1))

    code, plain, _, _ = _plan(capsys, tmp_path, "--target-mm", "3", "--suggest")
    assert code == 0 and "suggestion: print the markers at 120 mm" in plain
    code, sized, _, _ = _plan(capsys, tmp_path, "--target-mm", "3", "--suggest", "--marker-size-rel-std", "0.01")
    # 1 % of the size is 1 % of the distance whatever the size: a larger print no longer helps, more markers do
    assert code == 0 and within(sized) < within(plain)
    assert "suggestion: print the markers" not in sized and "suggestion: add marker" in sized


@pytest.fixture()
def board_files(tmp_path):
    """The ChArUco board of OpenCV's photos, its published camera as a fidlearn camera file, and a photo."""
    camera = tmp_path / "camera.json"
    Camera.load(data_path("real/opencv_charuco/tutorial_camera_charuco.yml"), image_size=(640, 480)).save(camera)
    return data_path("real/opencv_charuco/board_map.json"), camera, data_path("real/opencv_charuco/img_00.jpg")


def _board_plan(capsys, tmp_path, world, camera, *extra):
    out = tmp_path / "out" / "plan.png"
    out.parent.mkdir(exist_ok=True)
    # the board's markers face -Z: cameras 400 mm in front of it, over the board
    where = ["--height-mm", "-400", "--area", "0,0,200,280", "--step-mm", "100", "--headings", "0"]
    code = main(["plan", str(world), "--camera", str(camera), *where, "-o", str(out), *extra])
    stdout, stderr = capsys.readouterr()
    return code, stdout, stderr, out


def test_noise_measured_on_a_photo_is_said_and_used(capsys, tmp_path, board_files):
    from fidlearn import detect_markers, estimate_pose
    from fidlearn.images import load_image
    from fidlearn.planning import noise

    world_path, camera_path, photo = board_files
    code, stdout, stderr, out = _board_plan(capsys, tmp_path, world_path, camera_path, "--noise-from", str(photo))
    assert code == 0 and out.exists(), stderr
    world, camera = MarkerMap.load(world_path), Camera.load(camera_path)
    pose = estimate_pose(detect_markers(load_image(photo), world.dictionary), world, camera)
    measured = noise.noise_from_pose(pose, world, camera)
    assert (
        f"noise measured on {photo} (17 markers): corner noise {measured.corner_sigma_px:.2f} px, marker shift "
        f"{measured.marker_shift_px:.2f} px (per axis), marker size spread "
        f"{100 * measured.marker_size_rel_std_each:.1f} %; the markers look "
        f"{-100 * measured.marker_size_rel_error:.1f} % smaller than the map says"
    ) in stdout
    assert measured.marker_size_rel_error < -0.01  # the markers of these photos look 1.3 % smaller than printed
    plan = plan_room(world, camera, height_mm=-400, area=(0, 0, 200, 280), step_mm=100, headings=0, **measured.kwargs())
    ok = np.isfinite(plan.toward_mm)
    assert ok.all() and _median(stdout) == pytest.approx(float(np.median(plan.toward_mm)), abs=0.051)
    plain = plan_room(world, camera, height_mm=-400, area=(0, 0, 200, 280), step_mm=100, headings=0)
    assert _median(stdout) > 2 * float(np.median(plain.toward_mm))  # a real photo's noise, not the renders'


def test_noise_from_a_photo_that_cannot_give_it_ends_with_status_2_and_one_line(capsys, tmp_path, board_files):
    world, camera, photo = board_files
    small = tmp_path / "small.png"
    import cv2

    cv2.imwrite(str(small), cv2.resize(cv2.imread(str(photo)), (320, 240)))
    cases = [
        (["--noise-from", str(photo), "--corner-sigma-px", "0.2"], "leave out --corner-sigma-px"),
        (["--noise-from", str(small)], "the photo is 320x240 and the camera 640x480"),
        (["--noise-from", str(tmp_path / "none.jpg")], "none.jpg"),
    ]
    for extra, match in cases:
        code, stdout, stderr, out = _board_plan(capsys, tmp_path, world, camera, *extra)
        lines = stderr.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("error:") and match in lines[0], stderr
        assert not out.exists()
    # a photo of the three markers of the bundled map: too few to tell a shift from the pose
    out = tmp_path / "three.png"
    scene = data_path("scenes/scene_00.png")
    code = main(["plan", str(MAP), "--camera", str(CAMERA), "-o", str(out), "--noise-from", str(scene)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and f"--noise-from {scene}: the pose used 3 markers" in lines[0]
    assert not out.exists()
