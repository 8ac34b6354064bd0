"""The command line, used as a user uses it.

Most tests call ``main([...])`` in-process (fast); a few run ``python -m
fidlearn`` in a subprocess to prove the real entry point works. Every user
error must end with status 2 and exactly one line ``error: ...`` on stderr,
no traceback and no output file.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest
from helpers import assert_user_error
from helpers import run_cli as run

import fidlearn
from fidlearn import Camera, MarkerMap, _cv, data_dir, data_path, frames

SEED_BARE = {  # the seed's bare layout: no units, no size
    "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
    "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
    "2": {"translation": [0, 0.5, 0.75], "rotation": [0, 0, 0]},
}


def run_subprocess(*argv, cwd=None):
    proc = subprocess.run(
        [sys.executable, "-m", "fidlearn", *map(str, argv)], capture_output=True, text=True, cwd=cwd, timeout=120
    )
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture
def seed_bare(tmp_path):
    path = tmp_path / "seed_map.json"
    path.write_text(json.dumps(SEED_BARE))
    return path


@pytest.fixture(scope="module")
def ideal_camera(tmp_path_factory):
    path = tmp_path_factory.mktemp("cam") / "camera.json"
    Camera.from_fov(60, (640, 480)).save(path)
    return path


# -- help, doctor ------------------------------------------------------------------------
def test_help_lists_every_command_subprocess():
    code, out, err = run_subprocess("--help")
    assert code == 0
    assert err == ""
    for cmd in ("board", "calibrate", "markers", "corners", "locate", "render", "doctor"):
        assert f"    {cmd} " in out


def test_doctor_exit_0_subprocess():
    code, out, err = run_subprocess("doctor")
    assert code == 0, out + err
    assert out.strip().endswith("all good")
    assert "OpenCV" in out
    assert "cv2.aruco.ArucoDetector: yes" in out


def test_unknown_option_is_one_line(capsys):
    code, out, err = run(capsys, "markers", "--ids", "0-3", "--size-mm", "50", "-o", "m.pdf", "--colour", "red")
    assert_user_error(code, err, "unrecognized arguments: --colour", "--help")
    code, out, err = run(capsys, "markers", "--ids", "0-3")
    assert_user_error(code, err, "required: -o/--output")
    code, out, err = run(capsys, "markers", "--ids", "0-3", "-o", "m.pdf")
    assert_user_error(code, err, "give --ids and --size-mm (e.g. --ids 0-9 --size-mm 80), or --map MAP.json")


# -- corners -------------------------------------------------------------------------------
def test_corners_seed_map_in_feet(capsys, seed_bare, tmp_path):
    out_path = tmp_path / "corners.json"
    code, out, err = run(capsys, "corners", seed_bare, "--units", "ft", "--marker-size-mm", 80, "-o", out_path)
    assert code == 0, err
    corners = json.loads(out_path.read_text())
    # the seed's documented answer for marker 0 at [0, 0, 1] ft, 80 mm
    assert np.allclose(corners["0"], [[0, 0, 304.8], [0, 80, 304.8], [0, 80, 224.8], [0, 0, 224.8]])
    assert np.allclose(corners["2"][0], [0, 152.4, 228.6])
    assert "corners of 3 markers" in out
    assert "coplanar" in out


def test_corners_missing_units_is_an_error(capsys, seed_bare, tmp_path):
    out_path = tmp_path / "corners.json"
    code, out, err = run(capsys, "corners", seed_bare, "--marker-size-mm", 80, "-o", out_path)
    assert_user_error(code, err, "units", "--units")
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seed_map.json"]


# -- markers and board ---------------------------------------------------------------------------
def test_markers_subprocess_pdf(tmp_path):
    pdfium = pytest.importorskip("pypdfium2")
    code, out, err = run_subprocess(
        "markers", "--ids", "0-3,8", "--size-mm", 40, "--dictionary", "6X6_250", "-o", "m.pdf", cwd=tmp_path
    )
    assert code == 0, err
    assert "5 markers of 40 mm (6X6_250) on 1 a4 page" in out
    doc = pdfium.PdfDocument(str(tmp_path / "m.pdf"))
    gray = cv2.cvtColor(doc[0].render(scale=200 / 72).to_numpy()[:, :, :3].copy(), cv2.COLOR_RGB2GRAY)
    doc.close()
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    corners, ids, _ = det.detectMarkers(gray)
    assert sorted(np.asarray(ids).ravel().tolist()) == [0, 1, 2, 3, 8]
    side_mm = np.linalg.norm(np.diff(np.asarray(corners).reshape(-1, 4, 2)[:, :2], axis=1), axis=2) / (200 / 25.4)
    assert np.allclose(side_mm, 40, atol=0.5)


def test_markers_png_pages(capsys, tmp_path):
    code, out, err = run(
        capsys, "markers", "--ids", "0-2", "--size-mm", 80, "--paper", "letter", "--dpi", 50, "-o", tmp_path / "m.png"
    )
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m-1.png", "m-2.png"]
    img = cv2.imread(str(tmp_path / "m-1.png"))
    assert img.shape[:2] == (round(11 * 50), round(8.5 * 50))


def test_board_pdf(capsys, tmp_path):
    code, out, err = run(capsys, "board", "--pattern", "9x6", "--square-mm", 25, "-o", tmp_path / "board.pdf")
    assert code == 0, err
    assert "checkerboard 9x6 inner corners (10x7 squares), square 25 mm, a4, landscape" in out
    assert (tmp_path / "board.pdf").stat().st_size > 1000


def test_board_charuco_png(capsys, tmp_path):
    code, out, err = run(
        capsys,
        "board",
        "--squares",
        "5x7",
        "--square-mm",
        30,
        "--charuco",
        "--marker-mm",
        22,
        "--dpi",
        100,
        "-o",
        tmp_path / "ch.png",
    )
    assert code == 0, err
    assert "ChArUco 5x7 squares (4x6 inner corners), square 30 mm, marker 22 mm, 6X6_250" in out
    gray = cv2.imread(str(tmp_path / "ch.png"), cv2.IMREAD_GRAYSCALE)
    board = cv2.aruco.CharucoBoard((5, 7), 30.0, 22.0, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    ch_corners, ch_ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(gray)
    assert ch_ids is not None
    assert len(ch_ids) == 24


def test_board_too_big_says_largest(capsys, tmp_path):
    code, out, err = run(capsys, "board", "--pattern", "9x6", "--square-mm", 40, "-o", tmp_path / "b.pdf")
    assert_user_error(code, err, "does not fit on a4 paper", "largest square that fits is", "--square-mm")
    assert list(tmp_path.iterdir()) == []


# -- render --------------------------------------------------------------------------------
def test_render_pose_and_look_at_agree_with_truth(capsys, ideal_camera, tmp_path):
    wall = data_path("world_map.json")
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    code, out, err = run(
        capsys,
        "render",
        "--map",
        wall,
        "--camera",
        ideal_camera,
        "--pose",
        "1200,150,250,-90,0,90",
        "-o",
        a,
        "--truth",
        tmp_path / "truth.json",
    )
    assert code == 0, err
    assert "markers seen whole: 0, 1, 2" in out
    code, out, err = run(
        capsys,
        "render",
        "--map",
        wall,
        "--camera",
        ideal_camera,
        "--from",
        "1200,150,250",
        "--look-at",
        "0,150,250",
        "-o",
        b,
    )
    assert code == 0, err
    img_a, img_b = cv2.imread(str(a), cv2.IMREAD_GRAYSCALE), cv2.imread(str(b), cv2.IMREAD_GRAYSCALE)
    assert img_a.shape == (480, 640)
    assert np.abs(img_a.astype(int) - img_b).max() <= 1  # the two ways of giving the same pose
    truth = json.loads((tmp_path / "truth.json").read_text())
    T = np.array(truth["T_world_camera"])
    assert np.allclose(T, frames.make_transform(frames.rotation_from_rpy_deg(-90, 0, 90), [1200, 150, 250]))
    assert np.allclose(truth["rpy_deg"], [-90, 0, 90])
    assert truth["position_mm"] == [1200, 150, 250]
    # the truth is what the camera model projects, and what a detector finds in the image
    cam, m = Camera.load(ideal_camera), MarkerMap.load(wall)
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL))
    corners, ids, _ = det.detectMarkers(img_a)
    assert sorted(np.asarray(ids).ravel().tolist()) == [0, 1, 2]
    for c, i in zip(corners, np.asarray(ids).ravel()):
        expected = cam.project(m.marker_corners(int(i)), T)
        assert np.allclose(truth["markers_px"][str(i)], expected)
        assert np.abs(np.asarray(c).reshape(4, 2) - expected).max() < 1.0


def test_render_nothing_in_view_warns(capsys, ideal_camera, tmp_path):
    code, out, err = run(
        capsys,
        "render",
        "--map",
        data_path("world_map.json"),
        "--camera",
        ideal_camera,
        "--pose",
        "1200,150,250,-90,0,-90",
        "-o",
        tmp_path / "away.png",
    )
    assert code == 0
    assert "markers seen whole: none" in out
    assert err.startswith("warning: no marker of the map is in view")


# -- calibrate -------------------------------------------------------------------------------
def test_calibrate_reproduces_the_true_camera(capsys, tmp_path):
    out_path = tmp_path / "camera.json"
    code, out, err = run(
        capsys,
        "calibrate",
        data_path("calibration"),
        "--pattern",
        "9x6",
        "--square-mm",
        25,
        "-o",
        out_path,
        "--annotate",
        tmp_path / "ann",
    )
    assert code == 0, err
    # 20 well-spread views: no warning, just the counter line (stderr is not a terminal here)
    assert err == "calibrate: searched 20 images, board found in 20\n"
    truth, cam = Camera.load(data_path("calibration", "camera_true.json")), Camera.load(out_path)
    assert cam.image_size == truth.image_size == (640, 480)
    assert cam.fx == pytest.approx(truth.fx, rel=2e-3)
    assert cam.fy == pytest.approx(truth.fy, rel=2e-3)
    assert abs(cam.cx - truth.cx) < 1.5
    assert abs(cam.cy - truth.cy) < 1.5
    assert np.allclose(cam.dist[:2], truth.dist[:2], atol=0.03)
    # the printed intrinsics are the saved ones, with standard deviations
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("fx"))
    assert float(line.split()[1]) == pytest.approx(cam.fx, abs=0.006)
    assert "±" in line
    assert "from 20 of 20 views" in out
    assert "view_19.png" in out
    grid = [[int(v) for v in ln.split()] for ln in out.split("(3x3 grid):\n")[1].splitlines()[:3]]
    assert np.sum(grid) == 20 * 54
    assert np.min(grid) > 0
    assert sorted(p.name for p in (tmp_path / "ann").iterdir()) == [f"view_{i:02d}.png" for i in range(20)]
    # the file carries the calibration's covariance: its fx standard deviation is the printed one's or more
    assert "with its calibration's covariance" in out
    sd_fx = float(line.split("±")[1].split()[0])
    assert cam.intrinsics_covariance[0, 0] ** 0.5 >= 0.99 * sd_fx
    # and a pose located with it is the same, with a wider covariance than without it
    scene = data_path("trajectory", "frame_000.png")  # 640x480, as calibrated
    with_cov = fidlearn.locate(fidlearn.detection.load_image(scene), data_path("world_map.json"), cam)
    bare = Camera(cam.K, cam.dist, cam.image_size)
    without = fidlearn.locate(fidlearn.detection.load_image(scene), data_path("world_map.json"), bare)
    np.testing.assert_allclose(with_cov.position_mm, without.position_mm, atol=1e-9)
    assert np.trace(with_cov.covariance[3:, 3:]) > np.trace(without.covariance[3:, 3:])


def test_calibrate_real_charuco_matches_opencv_and_warns(capsys, tmp_path):
    images = sorted(data_path("real", "opencv_charuco").glob("img_0*.jpg"))
    out_path = tmp_path / "camera.yml"
    code, out, err = run(
        capsys,
        "calibrate",
        *images,
        "--charuco",
        "--squares",
        "5x7",
        "--square-mm",
        40,
        "--marker-mm",
        20,
        "--dictionary",
        "6X6_250",
        "-o",
        out_path,
    )
    assert code == 0, err
    cam = Camera.load(out_path)
    found = np.array([cam.fx, cam.fy, cam.cx, cam.cy])
    std = np.array(
        [float(ln.split("±")[1].split()[0]) for ln in out.splitlines() if ln.strip()[:2] in ("fx", "fy", "cx", "cy")]
    )
    # OpenCV's tutorial file (an older OpenCV, same four photos): within 3 of the printed standard deviations
    assert np.all(np.abs(found - [452.511, 456.767, 317.703, 277.752]) < 3 * std), (found, std)
    if cv2.__version__.startswith("5."):
        # published for OpenCV 5.0 (data/real/README): a plain cv2.calibrateCamera gives these
        assert np.allclose(found, [457.29, 461.32, 317.22, 275.61], atol=0.2)
    warns = [ln for ln in err.splitlines() if ln.startswith("warning: ")]
    assert any("only 4 views were used" in w for w in warns)
    assert any("views too similar" in w for w in warns)  # OpenCV's four tutorial photos are all near face-on
    assert any("no board corner in the" in w for w in warns)


def test_calibrate_duplicate_photo_warns(capsys, tmp_path):
    """A second photo of the board where it was (a burst; here a copy) adds weight, not geometry: warned. The
    same file given twice is refused (tests/test_hostile_cli.py)."""
    views = sorted(data_path("calibration").glob("view_*.png"))[:10]
    burst = shutil.copy(views[3], tmp_path / "burst.png")
    code, out, err = run(
        capsys,
        "calibrate",
        *views,
        burst,
        "--pattern",
        "9x6",
        "--square-mm",
        25,
        "-o",
        tmp_path / "c.json",
        "--annotate",
        tmp_path / "ann",
    )
    assert code == 0, err
    assert "1 pair(s) of nearly identical views (e.g. view_03.png and burst.png)" in err
    assert len(list((tmp_path / "ann").iterdir())) == 11


def test_progress_bar_on_a_terminal(capsys, monkeypatch):
    from fidlearn.cli._common import _Progress

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    bar = _Progress("calibrate")
    for i in range(1, 5):
        bar(i, 4, f"photos/view_{i}.png")
    bar.clear()
    bar.finish(4)  # nothing more on a terminal: the bar was the progress
    err = capsys.readouterr().err
    assert err.startswith("\rcalibrate [######------------------] 1/4 view_1.png")
    assert "\rcalibrate [########################] 4/4 view_4.png" in err
    assert err.endswith("\r\x1b[K")
    assert "\n" not in err


def test_coverage_grid_known_cells():
    from fidlearn.calibration import coverage_grid

    pts = np.array([[0, 0], [639, 479], [319.5, 239.5], [212, 10], [214, 10]])
    grid = coverage_grid([pts[:3], pts[3:]], (640, 480))
    # -0.5..212.83 is the first third of 640 px: u=212 is in column 0, u=214 in column 1
    assert grid.tolist() == [[2, 1, 0], [0, 1, 0], [0, 0, 1]]


def test_view_diversity_known_angles():
    from fidlearn.calibration import view_diversity

    face_on = frames.make_transform(np.eye(3), [0, 0, 1000])
    tilted = frames.make_transform(frames.rot_x(np.radians(30)), [0, 0, 1000])
    nudged = frames.make_transform(frames.rot_y(np.radians(1)), [5, 0, 1000])
    diversity = view_diversity({"a": face_on, "b": tilted, "c": nudged})
    assert diversity.spread_deg == pytest.approx(np.degrees(np.arccos(np.cos(np.radians(30)) * np.cos(np.radians(1)))))
    assert [(d.a, d.b) for d in diversity.duplicates] == [("a", "c")]


# -- locate ----------------------------------------------------------------------------------
def scenes_truth():
    """data/scenes/poses.json grouped by map: {map file: [(image path, T_world_camera)]}."""
    record = json.loads(data_path("scenes", "poses.json").read_text())
    groups: dict[str, list] = {}
    for im in record["images"]:
        groups.setdefault(im["map"], []).append((data_path("scenes", im["image"]), np.array(im["T_world_camera"])))
    return groups


def assert_pose_close(T_est, T_true, what):
    """Position within 1 % of the distance to the world origin region, orientation within 0.5 deg."""
    err_mm = np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])
    assert err_mm < 0.01 * np.linalg.norm(T_true[:3, 3]), (what, err_mm)
    assert frames.rotation_angle_deg(T_est[:3, :3], T_true[:3, :3]) < 0.5, what


@pytest.mark.parametrize("map_name", ["world_map.json", "two_walls_map.json"])
def test_locate_reproduces_known_poses(capsys, tmp_path, map_name):
    shots = scenes_truth()[map_name]
    jsonl, ann = tmp_path / "poses.jsonl", tmp_path / "ann"
    code, out, err = run(
        capsys,
        "locate",
        *[p for p, _ in shots],
        "--camera",
        data_path("scenes", "camera.json"),
        "--map",
        data_path(map_name),
        "--json",
        jsonl,
        "--annotate",
        ann,
    )
    assert code == 0, err
    assert err == ""
    records = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert [r["frame"] for r in records] == [p.name for p, _ in shots]
    for rec, (path, T_true) in zip(records, shots):
        assert rec["located"], rec
        assert not rec["ambiguous"], rec
        assert_pose_close(np.array(rec["T_world_camera"]), T_true, path.name)
        assert rec["reprojection_rms_px"] < 0.5
        # the printed line carries the same numbers
        line = next(ln for ln in out.splitlines() if ln.startswith(path.name))
        assert np.allclose([float(v) for v in line.split()[1:4]], rec["position_mm"], atol=0.051)
    assert f"{len(shots)} frames, {len(shots)} located (100 %), median rms" in out
    assert sorted(p.name for p in ann.iterdir()) == sorted(p.name for p, _ in shots)
    assert cv2.imread(str(ann / shots[0][0].name)).shape == (720, 1280, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ann", "poses.jsonl"]  # no staging folder left


def test_locate_bare_map_in_feet(capsys, tmp_path):
    """The seed's bare map with --units ft --marker-size-mm 80 gives the same poses as the full map."""
    full = json.loads(data_path("world_map.json").read_text())
    assert full["units"] == "ft"
    assert full["marker_size_mm"] == 80
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps(full["markers"]))
    shots = scenes_truth()["world_map.json"][:2]
    code, out, err = run(
        capsys,
        "locate",
        *[p for p, _ in shots],
        "--camera",
        data_path("scenes", "camera.json"),
        "--map",
        bare,
        "--units",
        "ft",
        "--marker-size-mm",
        80,
        "--json",
        tmp_path / "p.jsonl",
    )
    assert code == 0, err
    for line, (path, T_true) in zip((tmp_path / "p.jsonl").read_text().splitlines(), shots):
        assert_pose_close(np.array(json.loads(line)["T_world_camera"]), T_true, path.name)
    code, out, err = run(capsys, "locate", shots[0][0], "--camera", data_path("scenes", "camera.json"), "--map", bare)
    assert_user_error(code, err, "--units")


def test_locate_frame_without_markers_is_reported(capsys, tmp_path, ideal_camera):
    blank = tmp_path / "wall.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    code, out, err = run(
        capsys,
        "locate",
        blank,
        "--camera",
        ideal_camera,
        "--map",
        data_path("world_map.json"),
        "--json",
        tmp_path / "p.jsonl",
    )
    assert code == 0, err
    assert "wall.png" in out
    assert "no known marker" in out
    rec = json.loads((tmp_path / "p.jsonl").read_text())
    assert rec == {"frame": "wall.png", "located": False, "reason": "no known marker", "detected_ids": []}
    stranger = tmp_path / "stranger.png"  # a marker, but not one of the map's
    cv2.imwrite(
        str(stranger),
        np.pad(_cv.generate_marker("ARUCO_ORIGINAL", 7, 140), ((170, 170), (250, 250)), constant_values=255),
    )
    code, out, err = run(capsys, "locate", stranger, "--camera", ideal_camera, "--map", data_path("world_map.json"))
    assert code == 0, err
    assert "no known marker (saw ids 7, not in the map)" in out.splitlines()[1]


def test_locate_video_subprocess(tmp_path):
    """A video made of the robot's drive (data/trajectory) runs frame by frame through ``python -m fidlearn locate``."""
    record = json.loads(data_path("trajectory", "poses.json").read_text())
    shots = [(data_path("trajectory", f["image"]), np.array(f["T_world_camera"])) for f in record["frames"]]
    first = cv2.imread(str(shots[0][0]))
    video = tmp_path / "drive.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (first.shape[1], first.shape[0]))
    for path, _ in shots:
        writer.write(cv2.imread(str(path)))
    writer.release()
    code, out, err = run_subprocess(
        "locate",
        video,
        "--camera",
        data_path("trajectory", "camera.json"),
        "--map",
        data_path(record["map"]),
        "--json",
        tmp_path / "drive.jsonl",
    )
    assert code == 0, err
    records = [json.loads(line) for line in (tmp_path / "drive.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in records] == [f"drive.avi#{k}" for k in range(len(shots))]
    errors = []
    for rec, (_, T_true) in zip(records, shots):
        assert rec["located"], rec
        T_est = np.array(rec["T_world_camera"])
        err_mm = np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])
        # markers of 15 to 40 px through JPEG compression: judge each frame by its own reported uncertainty
        assert err_mm < 3 * np.linalg.norm(rec["position_std_mm"]), (rec["frame"], err_mm, rec["position_std_mm"])
        assert frames.rotation_angle_deg(T_est[:3, :3], T_true[:3, :3]) < 1.5, rec["frame"]
        errors.append(err_mm / np.linalg.norm(T_true[:3, 3]))
    assert np.median(errors) < 0.01
    assert f"{len(shots)} frames, {len(shots)} located (100 %), median rms" in out


def test_locate_error_midway_leaves_nothing(capsys, tmp_path):
    good = data_path("scenes", "scene_00.png")
    broken = tmp_path / "broken.png"
    broken.write_bytes(good.read_bytes()[:200])  # a truncated PNG after a good one
    code, out, err = run(
        capsys,
        "locate",
        good,
        broken,
        "--camera",
        data_path("scenes", "camera.json"),
        "--map",
        data_path("world_map.json"),
        "--json",
        tmp_path / "p.jsonl",
        "--annotate",
        tmp_path / "ann",
    )
    assert_user_error(code, err, "broken.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.png"]


# -- bad input: one error line, status 2, nothing written -----------------------------------------------
def _other_aspect_camera(tmp_path):
    path = tmp_path / "wide.json"
    Camera.from_fov(60, (1280, 720)).save(path)
    return path


BAD = {
    "missing map file": (
        ["corners", "{tmp}/nope.json", "--units", "ft", "-o", "{tmp}/out.json"],
        ["nope.json", "no such file"],
    ),
    "bad pattern": (["board", "--pattern", "9by6", "--square-mm", "25", "-o", "{tmp}/out.pdf"], ["'9by6'", "9x6"]),
    "negative size": (
        ["markers", "--ids", "0-3", "--size-mm", "-80", "-o", "{tmp}/out.pdf"],
        ["--size-mm", "positive"],
    ),
    "size not a number": (
        ["markers", "--ids", "0-3", "--size-mm", "big", "-o", "{tmp}/out.pdf"],
        ["--size-mm", "'big'"],
    ),
    "unknown dictionary": (
        ["markers", "--ids", "0-3", "--size-mm", "50", "--dictionary", "7X7_9", "-o", "{tmp}/out.pdf"],
        ["unknown ArUco dictionary '7X7_9'", "7X7_50"],
    ),
    "id not in dictionary": (
        ["markers", "--ids", "48-52", "--size-mm", "50", "--dictionary", "4X4_50", "-o", "{tmp}/out.pdf"],
        ["marker id 50", "0 to 49"],
    ),
    "bad ids": (["markers", "--ids", "0-", "--size-mm", "50", "-o", "{tmp}/out.pdf"], ["--ids", "0-9"]),
    "unknown output type": (["markers", "--ids", "0", "--size-mm", "50", "-o", "{tmp}/out.svg"], [".pdf or .png"]),
    "missing output folder": (
        ["markers", "--ids", "0", "--size-mm", "50", "-o", "{tmp}/no/out.pdf"],
        ["does not exist"],
    ),
    "charuco options without --charuco": (
        ["board", "--pattern", "9x6", "--square-mm", "20", "--marker-mm", "15", "-o", "{tmp}/out.pdf"],
        ["--charuco"],
    ),
    "camera of another aspect ratio": (
        [
            "render",
            "--map",
            "{data}/world_map.json",
            "--camera",
            "{wide}",
            "--pose",
            "1200,150,250,-90,0,90",
            "--size",
            "640x480",
            "-o",
            "{tmp}/out.png",
        ],
        ["aspect", "calibrate at the resolution"],
    ),
    "locate: missing image": (
        ["locate", "{tmp}/nope.png", "--camera", "{wide}", "--map", "{data}/world_map.json", "--json", "{tmp}/p.jsonl"],
        ["nope.png", "no such file"],
    ),
    "locate: empty folder": (
        ["locate", "{tmp}/empty", "--camera", "{wide}", "--map", "{data}/world_map.json", "--annotate", "{tmp}/ann"],
        ["empty", "no images"],
    ),
    "locate: camera of another aspect ratio": (
        [
            "locate",
            "{data}/scenes/scene_00.png",
            "--camera",
            "{four3}",
            "--map",
            "{data}/world_map.json",
            "--json",
            "{tmp}/p.jsonl",
            "--annotate",
            "{tmp}/ann",
        ],
        ["aspect", "calibrate at the resolution"],
    ),
    "locate: unreadable video": (
        ["locate", "{tmp}/bad.mp4", "--camera", "{wide}", "--map", "{data}/world_map.json", "--json", "{tmp}/p.jsonl"],
        ["bad.mp4", "cannot open this video"],
    ),
    "locate: nothing to read": (["locate", "--camera", "{wide}", "--map", "{data}/world_map.json"], ["--camera-index"]),
    "calibrate: empty folder": (
        ["calibrate", "{tmp}/empty", "--pattern", "9x6", "--square-mm", "25", "-o", "{tmp}/c.json"],
        ["empty", "no images"],
    ),
    "calibrate: bad pattern": (
        ["calibrate", "{data}/calibration", "--pattern", "9by6", "--square-mm", "25", "-o", "{tmp}/c.json"],
        ["'9by6'", "9x6"],
    ),
    "calibrate: squares counted as corners": (
        [
            "calibrate",
            "{data}/calibration/view_00.png",
            "{data}/calibration/view_01.png",
            "{data}/calibration/view_02.png",
            "--pattern",
            "10x7",
            "--square-mm",
            "25",
            "-o",
            "{tmp}/c.json",
            "--annotate",
            "{tmp}/ann",
        ],
        ["inner corners"],
    ),
    "calibrate: charuco without marker size": (
        ["calibrate", "{data}/calibration", "--charuco", "--squares", "5x7", "--square-mm", "40", "-o", "{tmp}/c.json"],
        ["--marker-mm"],
    ),
    "pose with 5 numbers": (
        [
            "render",
            "--map",
            "{data}/world_map.json",
            "--camera",
            "{wide}",
            "--pose",
            "1200,150,250,-90,0",
            "-o",
            "{tmp}/out.png",
        ],
        ["--pose", "6 numbers"],
    ),
}


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_input(capsys, tmp_path, case):
    argv, fragments = BAD[case]
    wide = _other_aspect_camera(tmp_path)
    four3 = tmp_path / "four3.json"
    Camera.from_fov(60, (640, 480)).save(four3)
    (tmp_path / "empty").mkdir()
    (tmp_path / "bad.mp4").write_text("not a video")
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = [a.format(tmp=tmp_path, wide=wide, four3=four3, data=data_dir()) for a in argv]
    code, out, err = run(capsys, *argv)
    assert_user_error(code, err, *fragments)
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no output, no temporary file


def test_bad_input_subprocess_no_traceback(tmp_path):
    code, out, err = run_subprocess("board", "--pattern", "9by6", "--square-mm", 25, "-o", tmp_path / "b.pdf")
    assert_user_error(code, err, "9by6")
    assert list(tmp_path.iterdir()) == []


def test_locate_video_annotated_frames_are_named_by_frame_number(capsys, tmp_path):
    # "drive.avi#0" was saved as drive.png, "#1" as drive-2.png, "#9" as drive-10.png: every file
    # name one off the frame it showed. Each file now carries its own zero-padded frame number.
    record = json.loads(data_path("trajectory", "poses.json").read_text())
    frames_used = record["frames"][:3]
    first = cv2.imread(str(data_path("trajectory", frames_used[0]["image"])))
    video = tmp_path / "drive.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (first.shape[1], first.shape[0]))
    # frame 1 is blank: its annotated picture must say "no known marker", and be drive_00001.png
    blank = np.full_like(first, 128)
    for img in (first, blank, cv2.imread(str(data_path("trajectory", frames_used[2]["image"])))):
        writer.write(img)
    writer.release()
    code, out, err = run(
        capsys,
        "locate",
        video,
        "--camera",
        data_path("trajectory", "camera.json"),
        "--map",
        data_path(record["map"]),
        "--annotate",
        tmp_path / "ann",
    )
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "ann").iterdir()) == [
        "drive_00000.png",
        "drive_00001.png",
        "drive_00002.png",
    ]
    assert "drive.avi#1" in out
    assert "no known marker" in out
    marked = cv2.imread(str(tmp_path / "ann" / "drive_00001.png"))
    red = (marked[:, :, 2] > 200) & (marked[:, :, 1] < 80) & (marked[:, :, 0] < 80)  # the red "no known marker"
    assert red.sum() > 50
    located = cv2.imread(str(tmp_path / "ann" / "drive_00000.png"))
    assert not ((located[:, :, 2] > 200) & (located[:, :, 1] < 80) & (located[:, :, 0] < 80))[:40, :300].sum() > 50


def test_locate_and_render_take_image_size_for_a_yaml_camera_without_one(capsys, tmp_path):
    # OpenCV's tutorial camera file has no image_width/image_height; the error said to use
    # "--image-size WxH", which the command line did not have.
    yml = data_path("real", "opencv_aruco_photo", "tutorial_camera_params.yml")
    photo = data_path("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg")
    desk = tmp_path / "desk.json"  # marker 23 alone, 50 mm, as in OpenCV's tutorial
    desk.write_text(
        json.dumps(
            {
                "units": "mm",
                "marker_size_mm": 50,
                "dictionary": "6X6_250",
                "markers": {"23": {"translation": [0, 0, 0], "rotation": [0, 0, 0]}},
            }
        )
    )
    code, out, err = run(capsys, "locate", photo, "--camera", yml, "--map", desk)
    assert_user_error(code, err, "no image_width/image_height", "--image-size WxH")
    code, out, err = run(capsys, "locate", photo, "--camera", yml, "--image-size", "640x480", "--map", desk)
    assert code == 0, err
    row = out.splitlines()[1].split()
    assert row[0] == "singlemarkersoriginal.jpg"
    assert row[7] == "23"
    # data/README.md: each marker is 0.7 to 0.9 m from the camera
    assert 700 <= np.linalg.norm([float(v) for v in row[1:4]]) <= 900
    code, out, err = run(
        capsys,
        "render",
        "--map",
        desk,
        "--camera",
        yml,
        "--image-size",
        "640x480",
        "--from",
        "600,0,0",
        "--look-at",
        "0,0,0",
        "-o",
        tmp_path / "r.png",
    )
    assert code == 0, err
    assert "640x480" in out
    code, out, err = run(capsys, "locate", photo, "--camera", yml, "--image-size", "640", "--map", desk)
    assert_user_error(code, err, "--image-size")


@pytest.mark.parametrize(
    "where", [["--from", "-1000,190,230", "--look-at", "0,-190,-230"], ["--pose", "-1000,-190,-230,-90,0,-90"]]
)
def test_render_takes_negative_coordinates(capsys, ideal_camera, tmp_path, where):
    # argparse read "--from -1000,190,230" as two options and said "expected one argument".
    code, out, err = run(
        capsys,
        "render",
        "--map",
        data_path("world_map.json"),
        "--camera",
        ideal_camera,
        *where,
        "-o",
        tmp_path / "r.png",
        "--truth",
        tmp_path / "t.json",
    )
    assert code == 0, err
    truth = json.loads((tmp_path / "t.json").read_text())
    assert truth["position_mm"] == [-1000, 190 if where[0] == "--from" else -190, 230 if where[0] == "--from" else -230]


def test_calibrate_warns_when_a_third_of_the_picture_is_nearly_empty(capsys, tmp_path):
    # OpenCV's right*.jpg photos leave the right third of the picture almost bare (1, 6 and 3 of
    # 648 corners): the "no board corner" warning never fired because no cell was exactly empty.
    code, out, err = run(
        capsys,
        "calibrate",
        data_path("real", "opencv_checkerboard_right"),
        "--pattern",
        "9x6",
        "--square-mm",
        25,
        "-o",
        tmp_path / "camera.json",
    )
    assert code == 0, err
    assert "warning: few board corners in the top-right, right, bottom-right of the picture (1, 6, 3," in err
    code, out, err = run(
        capsys,
        "calibrate",
        data_path("calibration"),
        "--pattern",
        "9x6",
        "--square-mm",
        25,
        "-o",
        tmp_path / "camera.json",
    )
    assert code == 0  # 20 views that visit every part of the picture
    assert "warning" not in err


def test_annotation_text_wraps_instead_of_being_cut():
    # A rejected view's reason was cut at 90 characters and ran off a 640 px picture, losing
    # "blurred, or a corner found in the wrong place?", the part that says what to do.
    from fidlearn.drawing import wrap_to_width

    text = (
        "outlier: reprojection RMS 1.20 px, above 0.72 px (max of 3 x the median 0.22 px and median + 0.5 px): "
        "blurred, or a corner found in the wrong place?"
    )
    lines = wrap_to_width(text, 624, 0.45)
    assert len(lines) == 2
    assert " ".join(lines) == text
    assert all(cv2.getTextSize(line, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] <= 624 for line in lines)


def test_corners_of_one_marker_is_singular(capsys, tmp_path):
    one = tmp_path / "one.json"
    one.write_text(json.dumps({"0": SEED_BARE["0"]}))
    code, out, err = run(capsys, "corners", one, "--units", "ft", "--marker-size-mm", 80, "-o", tmp_path / "c.json")
    assert code == 0, err
    assert "corners of 1 marker [0], 80 mm" in out


def test_swapped_camera_and_map_say_which_is_which(capsys, tmp_path):
    code, out, err = run(
        capsys,
        "locate",
        data_path("scenes", "scene_00.png"),
        "--camera",
        data_path("world_map.json"),
        "--map",
        data_path("scenes", "camera.json"),
    )
    assert_user_error(code, err, "this is a world map (marker placements), not a camera file", "--camera")
    code, out, err = run(capsys, "corners", data_path("scenes", "camera.json"), "-o", tmp_path / "c.json")
    assert_user_error(code, err, "this is a camera file", "not a world map")
    assert not (tmp_path / "c.json").exists()


def test_pose_record_is_strict_json_when_the_covariance_is_undetermined():
    # A pose without a covariance (singular J^T J) wrote "position_std_mm": [NaN, NaN, NaN],
    # which no strict JSON reader (fidlearn's read_json included) accepts.
    from fidlearn import Pose
    from fidlearn.cli.locate import _pose_record

    pose = Pose(
        T_world_camera=np.eye(4),
        marker_ids=(0,),
        residuals_px={0: np.zeros((4, 2))},
        reprojection_rms_px=0.0,
        covariance=None,
        corner_sigma_px=0.25,
    )
    rec = _pose_record("frame.png", pose)
    assert rec["position_std_mm"] is None
    json.dumps(rec, allow_nan=False)


def test_locate_names_the_picture_of_another_aspect_ratio(capsys, tmp_path):
    # In a folder of many, the error did not say which picture the camera did not fit.
    folder = tmp_path / "frames"
    folder.mkdir()
    for name in ("a.png", "b.png"):
        (folder / name).write_bytes(data_path("scenes", "scene_00.png").read_bytes())
    (folder / "c.png").write_bytes(data_path("trajectory", "frame_000.png").read_bytes())
    code, out, err = run(
        capsys,
        "locate",
        folder,
        "--camera",
        data_path("scenes", "camera.json"),
        "--map",
        data_path("world_map.json"),
        "--json",
        tmp_path / "p.jsonl",
    )
    assert_user_error(code, err, "c.png: camera calibrated at 1280x720", "cannot be used on 640x480")
    assert not (tmp_path / "p.jsonl").exists()


def test_locate_detects_each_picture_once_and_draws_those_detections(capsys, tmp_path, monkeypatch):
    """A picture with the map's markers is detected once (drawn from the same detections); one without
    them twice at most: the map's markers, then the whole dictionary to say which ids are in view; and
    once a run, the first such picture with each other family of dictionaries (6), to name one in view."""
    import fidlearn.detection as detection

    calls = []
    real = detection._detect

    def counting(image, *args, **kw):
        calls.append(image.shape)
        return real(image, *args, **kw)

    monkeypatch.setattr(detection, "_detect", counting)
    blank = np.full((720, 1280), 255, np.uint8)
    cv2.imwrite(str(tmp_path / "blank.png"), blank)
    scene = data_path("scenes", "scene_00.png")
    for picture, most in ((scene, 1), (tmp_path / "blank.png", 2 + 6)):
        calls.clear()
        ann = tmp_path / f"ann_{most}"
        code, out, err = run(
            capsys, "locate", picture, "--camera", data_path("scenes", "camera.json"),
            "--map", data_path("world_map.json"), "--annotate", ann,
        )  # fmt: skip
        assert code == 0, err
        assert 1 <= len(calls) <= most, (picture, len(calls))
        assert len(list(ann.iterdir())) == 1
    assert "no known marker" in out or "no marker" in out
