"""``fidlearn plan`` with a camera's real noise: the marker shift and the markers' size error, passed through
to the prediction, and refused when out of range (status 2, one line on stderr, no picture)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap, data_path
from fidlearn.cli import main
from fidlearn.planning import plan_room, suggest_markers

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
    assert code == 0
    assert out.exists()
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
    ("extra", "match"),
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
    assert len(lines) == 1, stderr
    assert lines[0].startswith("error:"), stderr
    assert match in lines[0], stderr
    assert not out.exists()
    assert not list(tmp_path.iterdir())


def test_a_size_error_that_is_not_a_number_is_refused_by_the_parser(capsys, tmp_path):
    code, _, stderr, out = _plan(capsys, tmp_path, "--marker-size-rel-std", "1%")
    lines = stderr.strip().splitlines()
    assert code == 2
    assert len(lines) == 1
    assert "--marker-size-rel-std: invalid float value: '1%'" in lines[0]
    assert not out.exists()


def test_suggestions_are_made_with_the_size_error(capsys, tmp_path):
    def within(text: str) -> int:
        return int(re.search(r"within 3 mm: (\d+) % of the area", text).group(1))

    code, plain, _, _ = _plan(capsys, tmp_path, "--target-mm", "3", "--suggest")
    assert code == 0
    assert "suggestion: print the markers at 120 mm" in plain
    code, sized, _, _ = _plan(capsys, tmp_path, "--target-mm", "3", "--suggest", "--marker-size-rel-std", "0.01")
    # 1 % of the size is 1 % of the distance whatever the size: a larger print no longer helps, more markers do
    assert code == 0
    assert within(sized) < within(plain)
    assert "suggestion: print the markers" not in sized
    assert "suggestion: add marker" in sized


@pytest.fixture
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
    assert code == 0, stderr
    assert out.exists(), stderr
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
    assert ok.all()
    assert _median(stdout) == pytest.approx(float(np.median(plan.toward_mm)), abs=0.051)
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
        assert code == 2, stderr
        assert len(lines) == 1, stderr
        assert lines[0].startswith("error:"), stderr
        assert match in lines[0], stderr
        assert not out.exists()
    # a photo of the three markers of the bundled map: too few to tell a shift from the pose
    out = tmp_path / "three.png"
    scene = data_path("scenes/scene_00.png")
    code = main(["plan", str(MAP), "--camera", str(CAMERA), "-o", str(out), "--noise-from", str(scene)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(lines) == 1
    assert f"--noise-from {scene}: the pose used 3 markers" in lines[0]
    assert not out.exists()


def _apply(world: MarkerMap, lines: list[str]) -> dict:
    """The map in the full layout (mm) with the printed suggestions applied: a larger print, and each added
    marker where its line says its centre is, turned as the marker it is beside."""
    d = {
        "units": "mm",
        "marker_size_mm": world.marker_size_mm,
        "dictionary": world.dictionary,
        "markers": {
            str(i): {
                "translation": world.marker_corners(i)[0].tolist(),
                "rotation": world.to_dict()["markers"][str(i)]["rotation"],
            }
            for i in world.ids
        },
    }
    for line in lines:
        size = re.search(r"print the markers at (\d+) mm", line)
        added = re.search(
            r"add marker (\d+) beside marker (\d+) at \[(-?\d+), (-?\d+), (-?\d+)\] mm \(its centre\)", line
        )
        if size:
            d["marker_size_mm"] = float(size.group(1))
        elif added:
            new, ref = added.group(1), added.group(2)
            current = MarkerMap.from_dict(d)
            corners = current.marker_corners(int(ref))
            centre = np.array([float(added.group(k)) for k in (3, 4, 5)])
            top_left = centre - (corners.mean(axis=0) - corners[0])  # same turn and size as its neighbour
            d["markers"][new] = {"translation": top_left.tolist(), "rotation": d["markers"][ref]["rotation"]}
        else:
            raise AssertionError(f"a suggestion the test cannot apply: {line}")
    return d


def test_the_suggestions_applied_to_the_map_give_what_they_promise(capsys, tmp_path):
    """One grid and one baseline: the first suggestion starts from the plan's own share within the target, and a
    new plan of the map with every suggestion applied (from the printed words) ends where the last one said,
    within one grid place's share (a centre printed to the millimetre)."""
    grid = ["--step-mm", "500", "--headings", "0", "--target-mm", "5"]
    out = tmp_path / "plan.png"
    assert main(["plan", str(MAP), "--camera", str(CAMERA), *grid, "--suggest", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "6x5 places, 500 mm apart, camera at 300 mm" in text  # the step and the height, each named
    share = int(re.search(r"within 5 mm: (\d+) % of the area", text).group(1))
    steps = re.findall(r"suggestion: (.*): (\d+) % -> (\d+) % within 5 mm", text)
    assert len(steps) >= 2
    assert int(steps[0][1]) == share
    assert all(int(a[2]) == int(b[1]) for a, b in zip(steps, steps[1:]))  # each starts where the last ended
    promised = int(steps[-1][2])
    world = MarkerMap.load(MAP)
    # the command says what the library finds with the same options
    library = suggest_markers(world, Camera.load(CAMERA), 5.0, step_mm=500)
    assert [(s.text, round(100 * s.fraction_before), round(100 * s.fraction_after)) for s in library] == [
        (text, int(a), int(b)) for text, a, b in steps
    ]
    applied = tmp_path / "applied.json"
    applied.write_text(json.dumps(_apply(world, [s[0] for s in steps])))
    same = re.search(r"to check: plan the changed map on the same places, (.*)", text).group(1).split()
    assert same[0] == "--area"
    assert same[2:] == ["--step-mm", "500", "--height-mm", "300"]
    assert (
        main(["plan", str(applied), "--camera", str(CAMERA), *grid, *same[:2], "-o", str(tmp_path / "again.png")]) == 0
    )
    again = capsys.readouterr().out
    assert "6x5 places, 500 mm apart" in again  # the same grid (the changed map's own default area is larger)
    reached = int(re.search(r"within 5 mm: (\d+) % of the area", again).group(1))
    assert abs(reached - promised) <= 100 / 30 + 1  # one place of 30, and the rounding of both percentages
    assert promised > share + 20
