"""Regenerate fidlearn's bundled data from seeds: ``make data`` or

    .venv/bin/python tools/make_data.py [--only calibration|scenes|trajectory|survey|real]

Folders it writes (see data/README.md for what each holds):

* ``data/calibration/``: 20 synthetic checkerboard views (9x6 inner corners,
  25 mm squares, 640x480), ``camera_true.json`` and ``views.json`` (true poses
  and corner pixels).
* ``data/scenes/``: the seed's room from 10 known poses (1280x720), on
  ``world_map.json`` and on ``two_walls_map.json`` (written here too), with
  ``camera.json`` and ``poses.json``.
* ``data/trajectory/``: a 40-frame drive of a robot's camera (640x480) with
  ``camera.json`` and ``poses.json``.
* ``data/survey/``: 24 photos (1280x720 JPEG) of a walk through a room with 12
  markers on three walls and the floor, ``camera.json``, ``true_map.json``,
  ``tape_map.json`` (tape errors of 20 mm, marker 7 moved 100 mm) and ``poses.json``.
* ``data/real/``: real photos from OpenCV's samples and a robot-held ChArUco board, kept in the repository
  with their provenance (data/README.md). They are not regenerated: ``make
  data`` only checks that they are all there. ``--import-real FOLDER`` copies
  them in again from a folder holding ``opencv_checkerboard_right``,
  ``opencv_charuco``, ``opencv_aruco_photo`` and ``robot_charuco`` (the only option that reads
  anything outside the repository, and only when given). The ChArUco board's
  marker map, ``real/opencv_charuco/board_map.json``, is written from OpenCV's
  board geometry.

Everything it reads is in the repository; ``--data-dir`` writes elsewhere than
``data/`` (the tests do, to check that nothing outside is read).

Everything synthetic is a pure function of the recipes below and their seeds:
running it twice gives the same pixels on the same OpenCV build. Each JSON
record holds every argument needed to re-render its picture in-process
(``tests/test_data.py`` does).
"""

from __future__ import annotations

import argparse
import platform
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np

import fidlearn
from fidlearn import Board, Camera, MarkerMap, frames
from fidlearn.data import repo_dir
from fidlearn.frames import look_at
from fidlearn.io import atomic_write, write_json_atomic
from fidlearn.synthetic import (
    render_calibration_views,
    render_scene,
    render_trajectory,
    survey_room,
    survey_walk,
    tape_measured,
    trajectory_poses,
)

DATA = repo_dir() / "data"
REAL_FOLDERS = ("opencv_checkerboard_right", "opencv_charuco", "opencv_aruco_photo", "robot_charuco")

# -- recipes: every number that decides a picture ------------------------------------------------

CALIBRATION = {
    "seed": 7,
    "n_views": 20,
    "pattern_size": [9, 6],
    "square_size_mm": 25.0,
    # a typical webcam at 640x480: slightly non-square pixels, off-centre principal point, barrel distortion
    "camera": {
        "camera_matrix": [[615.2, 0.0, 321.7], [0.0, 613.9, 243.4], [0.0, 0.0, 1.0]],
        "dist_coeffs": [-0.11, 0.09, 0.0006, -0.0004, -0.03],
        "image_size": [640, 480],
        "source": "synthetic: the true camera of data/calibration (tools/make_data.py)",
    },
    "render": {"blur_px": 0.4, "noise_std_gray": 1.5, "gradient": 0.15, "supersample": 4, "wall_texture_std_gray": 3.0},
}

SCENES = {
    "camera": {
        # an HD webcam: about 67 degrees horizontal field of view, mild barrel distortion
        "camera_matrix": [[962.5, 0.0, 641.3], [0.0, 961.8, 357.9], [0.0, 0.0, 1.0]],
        "dist_coeffs": [-0.06, 0.045, 0.0003, -0.0002, -0.01],
        "image_size": [1280, 720],
        "source": "synthetic: the true camera of data/scenes (tools/make_data.py)",
    },
    "render": {"blur_px": 0.5, "noise_std_gray": 1.2, "gradient": 0.2, "supersample": 4, "wall_texture_std_gray": 3.0},
    # (map, eye mm, target mm, roll deg): 1 to 3 m from the markers, from the front, the sides, above and below
    "views": [
        ("world_map.json", [1000, 190, 230], [0, 190, 230], 0.0),
        ("world_map.json", [1500, -600, 420], [0, 190, 240], 4.0),
        ("world_map.json", [1300, 1000, 150], [0, 200, 240], -6.0),
        ("world_map.json", [2100, 300, 900], [0, 180, 230], 2.0),
        ("world_map.json", [2900, -300, 260], [0, 190, 230], -12.0),
        ("world_map.json", [1700, 700, 240], [0, 120, 300], 25.0),
        ("two_walls_map.json", [2200, 300, 400], [300, -300, 260], 0.0),
        ("two_walls_map.json", [2500, 900, 300], [200, -500, 270], -3.0),
        ("two_walls_map.json", [2000, -200, 350], [500, 900, 270], 5.0),
        ("two_walls_map.json", [2600, 100, 600], [300, 100, 250], 0.0),
    ],
}

# the seed's three markers on the north wall (x = 0), plus two on the west wall (y = -900 mm,
# facing east: yaw 90) and one on the east wall (y = 1300 mm, facing west: yaw -90)
TWO_WALLS_MAP = {
    "units": "mm",
    "marker_size_mm": 80,
    "dictionary": "ARUCO_ORIGINAL",
    "markers": {
        "0": {"translation": [0, 0, 304.8], "rotation": [0, 0, 0]},
        "1": {"translation": [0, 304.8, 304.8], "rotation": [0, 0, 0]},
        "2": {"translation": [0, 152.4, 228.6], "rotation": [0, 0, 0]},
        "3": {"translation": [600, -900, 300], "rotation": [0, 0, 90]},
        "4": {"translation": [1100, -900, 250], "rotation": [0, 0, 90]},
        "5": {"translation": [800, 1300, 280], "rotation": [0, 0, -90]},
    },
}

TRAJECTORY = {
    "seed": 11,
    "n_frames": 40,
    "map": "world_map.json",
    "camera": {
        "camera_matrix": [[540.0, 0.0, 318.9], [0.0, 540.0, 241.2], [0.0, 0.0, 1.0]],
        "dist_coeffs": [-0.08, 0.02, 0.0, 0.0, 0.0],
        "image_size": [640, 480],
        "source": "synthetic: the true camera of data/trajectory (tools/make_data.py)",
    },
    "render": {"blur_px": 0.5, "noise_std_gray": 1.0, "gradient": 0.1, "supersample": 4, "wall_texture_std_gray": 3.0},
}


SURVEY = {
    "seed": 23,
    "n_photos": 24,
    "marker_size_mm": 160.0,
    "camera": {
        "camera_matrix": [[962.5, 0.0, 641.2], [0.0, 961.8, 358.9], [0.0, 0.0, 1.0]],
        "dist_coeffs": [-0.09, 0.03, 0.0004, -0.0003, 0.0],
        "image_size": [1280, 720],
        "source": "synthetic: the true camera of data/survey (tools/make_data.py)",
    },
    "render": {"blur_px": 0.5, "noise_std_gray": 1.2, "gradient": 0.2, "supersample": 4, "wall_texture_std_gray": 3.0},
    "jpeg_quality": 90,
    # the tape: every top-left corner off by 20 mm (sd, per coordinate), every rotation by 1 degree;
    # marker 7 was moved 100 mm along its wall after it was measured
    "tape": {"sigma_mm": 20.0, "sigma_deg": 1.0, "moved": {"7": [100.0, 0.0, 0.0]}, "seed": 24, "units": "cm"},
}


# -- helpers -----------------------------------------------------------------------------------------


def provenance() -> dict:
    """What made the files: the versions that decide their exact pixels."""
    return {
        "generator": "tools/make_data.py",
        "fidlearn": fidlearn.__version__,
        "opencv": cv2.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }


def write_png(path: Path, image: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise RuntimeError(f"cannot encode {path}")
    atomic_write(path, lambda tmp: tmp.write_bytes(buf.tobytes()))
    path.chmod(0o644)


def plain(value: float, digits: int) -> float:
    """``value`` rounded to ``digits``, with -0.0 written as 0.0.

    Rounding a tiny negative number (a rotation's -1e-17) gives -0.0, which JSON keeps as
    ``-0.0``: the files would change sign with the last bit of a processor's arithmetic.
    """
    return round(float(value), digits) + 0.0  # -0.0 + 0.0 == +0.0


def positive_zeros(obj):
    """``obj`` with every float -0.0 (in nested dicts and lists) made 0.0."""
    if isinstance(obj, dict):
        return {k: positive_zeros(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [positive_zeros(v) for v in obj]
    if isinstance(obj, float):
        return obj + 0.0
    return obj


def write_json(path: Path, obj) -> None:
    write_json_atomic(path, positive_zeros(obj))
    path.chmod(0o644)


def fresh_folder(folder: Path, pattern: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob(pattern):
        old.unlink()


def matrix(T: np.ndarray) -> list:
    return [[plain(v, 12) for v in row] for row in np.asarray(T)]


def corners_json(truth: dict) -> dict:
    return {str(i): [[plain(v, 6) for v in p] for p in c] for i, c in sorted(truth.items())}


# -- the folders ------------------------------------------------------------------------------------


def make_calibration() -> None:
    folder = DATA / "calibration"
    fresh_folder(folder, "view_*.png")
    camera = Camera.from_dict(CALIBRATION["camera"])
    camera.save(folder / "camera_true.json")
    (folder / "camera_true.json").chmod(0o644)
    views = render_calibration_views(
        camera,
        n_views=CALIBRATION["n_views"],
        board=Board.checkerboard(CALIBRATION["pattern_size"], CALIBRATION["square_size_mm"]),
        seed=CALIBRATION["seed"],
        **CALIBRATION["render"],
    )
    records = []
    for i, (image, T, px) in enumerate(zip(views.images, views.T_world_camera, views.image_points)):
        name = f"view_{i:02d}.png"
        write_png(folder / name, image)
        T_camera_board = frames.invert_transform(T)
        tilt = frames.rotation_angle_deg(T_camera_board[:3, :3], np.eye(3))
        records.append(
            {
                "image": name,
                "T_world_camera": matrix(T),
                "T_camera_board": matrix(T_camera_board),
                "distance_mm": plain(np.linalg.norm(T_camera_board[:3, 3]), 3),
                "board_rotation_deg": plain(tilt, 3),
                "corners_px": [[plain(v, 6) for v in p] for p in px],
            }
        )
    write_json(
        folder / "views.json",
        {
            "what": "synthetic checkerboard views; the world frame is the board's (OpenCV object points: "
            "inner corner (i, j) at (i * square, j * square, 0) mm)",
            "camera": "camera_true.json",
            "function": "fidlearn.synthetic.render_calibration_views",
            "arguments": {k: v for k, v in CALIBRATION.items() if k not in ("camera", "render")}
            | CALIBRATION["render"],
            "object_points_mm": [[float(v) for v in p] for p in views.object_points],
            "views": records,
            "provenance": provenance(),
        },
    )
    print(f"calibration: {len(records)} views in {folder}")


def make_scenes() -> None:
    folder = DATA / "scenes"
    fresh_folder(folder, "scene_*.png")
    MarkerMap.from_dict(TWO_WALLS_MAP, source="two_walls_map.json").save(DATA / "two_walls_map.json")
    (DATA / "two_walls_map.json").chmod(0o644)
    camera = Camera.from_dict(SCENES["camera"])
    camera.save(folder / "camera.json")
    (folder / "camera.json").chmod(0o644)
    records = []
    for i, (map_name, eye, target, roll) in enumerate(SCENES["views"]):
        marker_map = MarkerMap.load(DATA / map_name)
        T = look_at(eye, target, roll_deg=roll)
        seed = 100 + i
        scene = render_scene(marker_map, camera, T, seed=seed, **SCENES["render"])
        image, truth = scene.image, scene.truth
        name = f"scene_{i:02d}.png"
        write_png(folder / name, image)
        records.append(
            {
                "image": name,
                "map": map_name,
                "T_world_camera": matrix(T),
                "look_at": {"eye_mm": eye, "target_mm": target, "roll_deg": roll},
                "seed": seed,
                "visible_ids": sorted(int(k) for k in truth),
                "corners_px": corners_json(truth),
            }
        )
    write_json(
        folder / "poses.json",
        {
            "what": "the seed's room seen from known poses; maps are in data/, T_world_camera in mm",
            "camera": "camera.json",
            "function": "fidlearn.synthetic.render_scene",
            "render": SCENES["render"],
            "images": records,
            "provenance": provenance(),
        },
    )
    print(f"scenes: {len(records)} images in {folder}, and {DATA / 'two_walls_map.json'}")


def make_trajectory() -> None:
    folder = DATA / "trajectory"
    fresh_folder(folder, "frame_*.png")
    camera = Camera.from_dict(TRAJECTORY["camera"])
    camera.save(folder / "camera.json")
    (folder / "camera.json").chmod(0o644)
    marker_map = MarkerMap.load(DATA / TRAJECTORY["map"])
    poses = trajectory_poses(marker_map, TRAJECTORY["n_frames"], TRAJECTORY["seed"])
    drive = render_trajectory(marker_map, camera, seed=TRAJECTORY["seed"], poses=poses, **TRAJECTORY["render"])
    records = []
    for i, (image, T, truth) in enumerate(zip(drive.images, drive.T_world_camera, drive.truth)):
        name = f"frame_{i:03d}.png"
        write_png(folder / name, image)
        records.append(
            {
                "image": name,
                "T_world_camera": matrix(T),
                "visible_ids": sorted(int(k) for k in truth),
                "corners_px": corners_json(truth),
            }
        )
    write_json(
        folder / "poses.json",
        {
            "what": "a camera on a robot driving toward the north wall; frame i is rendered with seed "
            "seed * 1000 + i; T_world_camera in mm",
            "camera": "camera.json",
            "map": TRAJECTORY["map"],
            "function": "fidlearn.synthetic.render_trajectory (poses from fidlearn.synthetic.trajectory_poses)",
            "seed": TRAJECTORY["seed"],
            "n_frames": TRAJECTORY["n_frames"],
            "render": TRAJECTORY["render"],
            "frames": records,
            "provenance": provenance(),
        },
    )
    print(f"trajectory: {len(records)} frames in {folder}")


def make_survey() -> None:
    folder = DATA / "survey"
    fresh_folder(folder, "photo_*.jpg")
    camera = Camera.from_dict(SURVEY["camera"])
    camera.save(folder / "camera.json")
    (folder / "camera.json").chmod(0o644)
    truth = survey_room(SURVEY["marker_size_mm"])
    write_json(folder / "true_map.json", truth.to_dict())
    tape = SURVEY["tape"]
    moved = {int(k): tuple(v) for k, v in tape["moved"].items()}
    taped = tape_measured(
        truth,
        sigma_mm=tape["sigma_mm"],
        sigma_deg=tape["sigma_deg"],
        moved=moved,
        seed=tape["seed"],
        units=tape["units"],
    )
    write_json(folder / "tape_map.json", taped.to_dict())
    records = []
    for i, T in enumerate(survey_walk(truth, camera, n_photos=SURVEY["n_photos"], seed=SURVEY["seed"])):
        name = f"photo_{i:02d}.jpg"
        scene = render_scene(truth, camera, T, seed=SURVEY["seed"] * 1000 + i, **SURVEY["render"])
        image, seen = scene.image, scene.truth
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, SURVEY["jpeg_quality"]])
        if not ok:
            raise RuntimeError(f"cannot encode {name}")
        atomic_write(folder / name, lambda tmp, b=buf: tmp.write_bytes(b.tobytes()))
        (folder / name).chmod(0o644)
        records.append(
            {
                "image": name,
                "T_world_camera": matrix(T),
                "seed": SURVEY["seed"] * 1000 + i,
                "visible_ids": sorted(int(k) for k in seen),
                "corners_px": corners_json(seen),
            }
        )
    write_json(
        folder / "poses.json",
        {
            "what": "a walk through a 5 m x 4 m room with 12 markers on three walls and the floor; "
            "photo i is rendered with seed seed * 1000 + i; T_world_camera in mm",
            "camera": "camera.json",
            "true_map": "true_map.json",
            "tape_map": "tape_map.json",
            "function": "fidlearn.synthetic.render_scene (room: survey_room, poses: survey_walk, tape: tape_measured)",
            **{k: SURVEY[k] for k in ("seed", "n_photos", "marker_size_mm", "render", "jpeg_quality", "tape")},
            "photos": records,
            "provenance": provenance(),
        },
    )
    print(f"survey: {len(records)} photos in {folder}")


def check_real() -> None:
    """The real photos are part of the repository: say so if one of their folders is missing."""
    missing = [name for name in REAL_FOLDERS if not (repo_dir() / "data" / "real" / name).is_dir()]
    if missing:
        raise SystemExit(
            f"error: data/real/{missing[0]} is missing from the checkout; restore it with git "
            "(git checkout -- data/real) or bring it in with --import-real FOLDER"
        )
    print(f"real: {', '.join(REAL_FOLDERS)} present in data/real (kept, not regenerated)")


def make_charuco_map() -> None:
    """``real/opencv_charuco/board_map.json``: the ChArUco board's 17 markers at their nominal places, a map
    in the board's frame (the one ``benchmarks/planning_real.py`` measures the photos against)."""
    sys.path.insert(0, str(repo_dir()))
    from benchmarks.planning_real import board_map

    path = DATA / "real" / "opencv_charuco" / "board_map.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    board_map().save(path)
    path.chmod(0o644)
    print(f"real: the ChArUco board's map in {path}")


#: Real sets stored grey: their colour is not used (detection, corners and calibration read grey, the
#: same pixels as cv2.cvtColor of the colour photo) and grey takes a third of the space.
GREY_REAL = ("robot_charuco",)
#: Files of a real set left out: the robot set's camera_intr.yaml is empty as published.
SKIPPED_REAL = ("camera_intr.yaml",)


def _write_grey_png(src: Path, dst: Path) -> None:
    """A colour photo stored as the grey picture OpenCV makes of it, losslessly."""
    image = cv2.imread(str(src), cv2.IMREAD_COLOR)
    if image is None:
        raise SystemExit(f"error: {src} is not a picture OpenCV can read")
    if not cv2.imwrite(str(dst), cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise SystemExit(f"error: could not write {dst}")


def import_real(source: Path) -> None:
    """Copy the real photos in from ``source`` (a folder holding the three sample folders)."""
    missing = [name for name in REAL_FOLDERS if not (source / name).is_dir()]
    if missing:
        raise SystemExit(
            f"error: {source / missing[0]} does not exist; --import-real needs a folder holding "
            f"{', '.join(REAL_FOLDERS)}"
        )
    folder = DATA / "real"
    folder.mkdir(parents=True, exist_ok=True)
    for name in REAL_FOLDERS:
        dst = folder / name
        dst.mkdir(exist_ok=True)
        for f in sorted((source / name).iterdir()):
            if not f.is_file() or f.name in SKIPPED_REAL:
                continue
            if name in GREY_REAL and f.suffix == ".png":
                _write_grey_png(f, dst / f.name)
            else:
                shutil.copyfile(f, dst / f.name)
            (dst / f.name).chmod(0o644)
    print(f"real: {', '.join(REAL_FOLDERS)} copied from {source} to {folder}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Regenerate fidlearn's data/ folder from seeds.")
    parser.add_argument(
        "--only",
        choices=["calibration", "scenes", "trajectory", "survey", "real"],
        action="append",
        help="regenerate only this part (repeatable); default: all",
    )
    parser.add_argument("--data-dir", type=Path, default=None, help="write here instead of the repository's data/")
    parser.add_argument(
        "--import-real",
        type=Path,
        metavar="FOLDER",
        help="copy the real photos in from FOLDER (the one step that reads outside the repository)",
    )
    args = parser.parse_args(argv)
    global DATA
    if args.data_dir is not None:
        DATA = args.data_dir.resolve()
        DATA.mkdir(parents=True, exist_ok=True)
        # the hand-written seed map is an input of the scenes and the drive
        shutil.copyfile(repo_dir() / "data" / "world_map.json", DATA / "world_map.json")
    parts = args.only or ["calibration", "scenes", "trajectory", "survey", "real"]
    # check what must already be there before anything is rewritten
    if "real" in parts and args.import_real is None:
        check_real()
    if "calibration" in parts:
        make_calibration()
    if "scenes" in parts:
        make_scenes()
    if "trajectory" in parts:
        make_trajectory()
    if "survey" in parts:
        make_survey()
    if args.import_real is not None:
        import_real(args.import_real)
    if "real" in parts:
        make_charuco_map()
    return 0


if __name__ == "__main__":
    sys.exit(main())
