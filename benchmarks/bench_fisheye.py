"""A 160-degree fisheye: pose accuracy against a pinhole of the same pixel count and against plain OpenCV's fisheye
pipeline, the cost of the fisheye path, and the real fisheye sets' calibrations against each other.

    python benchmarks/bench_fisheye.py            # 24 scenes (about 3 minutes on 2 shared cores)
    python benchmarks/bench_fisheye.py --quick    # 10 scenes

The scenes: 120 mm markers 300 mm apart on a wall 3 m x 1.8 m (world X = 0, facing +X); a camera 0.3-0.7 m from
it, looking at a random point of the wall, rolled up to 20 degrees, sees them from the centre of the picture to
80 degrees off the axis. Each pose is rendered (``fidlearn.render_scene``, blur 0.5 px, 2 gray levels of noise)
twice at 800 x 600: through an equidistant fisheye of 160 degrees across the width (fx = 286 px) and through a
pinhole of 100 degrees (fx = 336 px). Seeds 0 to n/2 - 1 were looked at while the fisheye path was written, the
others are held out and reported on their own. Errors are the camera position's against the truth.

* fidlearn: ``fidlearn.locate(image, map, camera)`` (its default corner refinement, ``"edges"``), and with
  ``refine="contour"``.
* vs the pinhole: both poses from the markers both pictures show (each camera's own detections,
  ``estimate_pose``; the fisheye's corners refined again as ``locate`` does, their sides fitted as the lens bends
  them), where both show at least one.
* plain OpenCV's fisheye pipeline: ``cv2.aruco.ArucoDetector`` (default parameters),
  ``cv2.fisheye.undistortPoints`` (to the pixels of K), ``cv2.solvePnP`` SQPNP on every detected map corner, then
  ``cv2.solvePnPRefineLM``.
* speed: ``locate`` of the fisheye picture with the fisheye camera against the pinhole path on the same picture,
  interleaved call by call, the median of the per-pair ratios: ``locate``'s detection, ``estimate_pose`` of the same
  corners undistorted with the pinhole camera of the same K (less the markers at the rim, past 89.8 degrees here,
  which the fisheye's pose too leaves out: ``RIM_PICTURE_PX``), and what ``locate`` does next with a pinhole camera
  (``missed_in_view`` with its pose, which it always runs, and the second look, ``read_again``, at the markers both
  poses predict in view and the detector missed: the same crops; the pose again when one is found there). Before
  2026-11-29 the pinhole path stopped at the first pose, which left out work ``locate`` does whatever the lens; that
  ratio is printed too. Markers only the fisheye's pose predicts (its wider view) are read again on its side alone.
  The target is read in CPU time (wall time too is printed; before 2026-11-29 the row was wall time): on 2 shared
  cores the waits of a loaded machine fall on both sides and pull a wall-time ratio towards 1 (1.21 at load 3,
  1.12 at load 7 in two runs of the same code).
* real sets: fidlearn's fisheye calibration of the corners of every photo of data/real/fisheye_checkerboard's three
  sets (``corners.json``) and of each set's even and odd photos, compared pair by pair with ``compare_calibrations``
  (the projection difference across the picture over the size both calibrations' uncertainty predicts). The halves
  of a set are one lens, ``mono`` and ``left`` most likely one (both named ``left-*``), ``left`` and ``right`` the
  stereo pair's two copies of the lens (data/README.md). ``model="auto"`` on the real sets' photos and on the
  bundled checkerboard views.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import fidlearn  # noqa: E402
from fidlearn import Board, Camera, MarkerMap, frames, render_scene  # noqa: E402
from fidlearn.calibration import Calibration, calibrate_checkerboard, compare_calibrations  # noqa: E402
from fidlearn.calibration.run import _calibrate_points  # noqa: E402
from fidlearn.errors import FidlearnError  # noqa: E402
from fidlearn.pose._inputs import _rim_markers  # noqa: E402
from fidlearn.pose._locate import _detect_map_markers, _straightened  # noqa: E402
from fidlearn.pose._second_look import missed_in_view, read_again  # noqa: E402

W, H = 800, 600
F_FE = (W / 2) / math.radians(80)
FISHEYE = Camera([[F_FE, 0, W / 2 - 0.5], [0, F_FE, H / 2 - 0.5], [0, 0, 1]], [0.0] * 4, (W, H), model="fisheye")
PINHOLE = Camera.from_fov(100, (W, H))
FISHEYE_AS_PINHOLE = Camera(FISHEYE.K, None, (W, H))
# the same camera for estimate_pose on undistorted corners: a 160-degree lens's ideal pixels reach far beyond its
# picture (which estimate_pose takes for corners of another picture size), so its picture is made large enough
# to hold them; K is the same, and nothing else of the pose depends on the picture's size
FISHEYE_AS_PINHOLE_POSE = Camera(FISHEYE.K, None, (64 * W, 64 * H))
WALL = MarkerMap.from_dict(
    {
        str(k): {"translation": [0, y, z], "rotation": [0, 0, 0]}
        for k, (y, z) in enumerate((y, z) for y in range(-1500, 1501, 300) for z in range(-900, 901, 300))
    },
    marker_size_mm=120,
    units="mm",
)


def pose_of(seed: int) -> np.ndarray:
    rng = np.random.default_rng(1000 + seed)
    eye = [rng.uniform(300, 700), rng.uniform(-400, 400), rng.uniform(-300, 300)]
    at = [0.0, rng.uniform(-600, 600), rng.uniform(-400, 400)]
    return frames.look_at(eye, at, roll_deg=rng.uniform(-20, 20))


def opencv_fisheye(image: np.ndarray, cam: Camera) -> np.ndarray | None:
    """Plain OpenCV: detect, cv2.fisheye.undistortPoints, SQPNP, RefineLM; the camera position (mm) or None."""
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_ORIGINAL))
    corners, ids, _ = det.detectMarkers(image)
    if ids is None:
        return None
    obj, img = [], []
    for c, i in zip(corners, ids.ravel()):
        if int(i) in WALL:
            obj.append(WALL.marker_corners(int(i)))
            img.append(c.reshape(4, 2))
    if not obj:
        return None
    pts = cv2.fisheye.undistortPoints(np.concatenate(img).reshape(-1, 1, 2), cam.K, cam.dist.reshape(4, 1), P=cam.K)
    obj_a = np.concatenate(obj).astype(np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj_a, pts, cam.K, None, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj_a, pts, cam.K, None, rvec, tvec)
    R, _ = cv2.Rodrigues(rvec)
    return (-R.T @ tvec).ravel()


def error_of(fn, truth: np.ndarray) -> float:
    try:
        p = fn()
    except FidlearnError:
        return math.inf
    if p is None:
        return math.inf
    pos = p.position_mm if hasattr(p, "position_mm") else p
    return float(np.linalg.norm(pos - truth))


def scene_row(seed: int) -> dict:
    T = pose_of(seed)
    truth = T[:3, 3]
    fe = render_scene(WALL, FISHEYE, T, seed=seed, blur_px=0.5, noise_std_gray=2.0).image
    ph = render_scene(WALL, PINHOLE, T, seed=seed, blur_px=0.5, noise_std_gray=2.0).image
    det_fe = [d for d in fidlearn.detect_markers(fe, WALL.dictionary) if d.id in WALL]
    det_fe = _straightened(fe, det_fe, FISHEYE, WALL.dictionary, None)  # as locate does on a fisheye
    det_ph = [d for d in fidlearn.detect_markers(ph, WALL.dictionary) if d.id in WALL]
    both = {d.id for d in det_fe} & {d.id for d in det_ph}
    row = {
        "seed": seed,
        "markers": len(det_fe),
        "both": len(both),
        "fidlearn": error_of(lambda: fidlearn.locate(fe, WALL, FISHEYE), truth),
        "contour": error_of(lambda: fidlearn.locate(fe, WALL, FISHEYE, refine="contour"), truth),
        "opencv": error_of(lambda: opencv_fisheye(fe, FISHEYE), truth),
        "image": fe,
    }
    if both:
        row["fe_both"] = error_of(
            lambda: fidlearn.estimate_pose([d for d in det_fe if d.id in both], WALL, FISHEYE), truth
        )
        row["ph_both"] = error_of(
            lambda: fidlearn.estimate_pose([d for d in det_ph if d.id in both], WALL, PINHOLE), truth
        )
    return row


def accuracy(rows: list[dict], title: str) -> tuple[float, float, int]:
    fl = np.array([r["fidlearn"] for r in rows])
    cv = np.array([r["opencv"] for r in rows])
    paired = [r for r in rows if "fe_both" in r and math.isfinite(r["fe_both"]) and math.isfinite(r["ph_both"])]
    fb = np.array([r["fe_both"] for r in paired])
    pb = np.array([r["ph_both"] for r in paired])
    ok_cv = np.isfinite(cv)
    ratio_cv = float(np.median(fl[ok_cv]) / np.median(cv[ok_cv])) if ok_cv.any() else math.nan
    ratio_ph = float(np.median(fb) / np.median(pb)) if paired else math.nan
    fails = int((~np.isfinite(fl)).sum() + (fl[np.isfinite(fl)] > 50).sum())
    co = np.array([r["contour"] for r in rows])
    print(
        f"| {title} | {len(rows)} | {np.median(fl[np.isfinite(fl)]):.2f} | {fails} | {np.median(co):.2f} | "
        f"{np.median(cv[ok_cv]):.2f} ({int((~ok_cv).sum())} failed) | {ratio_cv:.2f} | "
        f"{len(paired)} | {np.median(fb):.2f} | {np.median(pb):.2f} | {ratio_ph:.2f} |"
    )
    return ratio_cv, ratio_ph, fails


def resolution_note() -> str:
    """How much larger the pinhole draws what both see: its pixels per radian over the fisheye's, off the axis."""
    fp, ff = PINHOLE.fx, FISHEYE.fx
    parts = []
    for deg in (0, 30, 50):
        th = math.radians(deg)
        radial = fp / math.cos(th) ** 2 / ff
        across = fp / math.cos(th) / (ff * (th / math.sin(th) if th else 1.0))
        parts.append(f"{deg} degrees {radial:.1f} x along the radius and {across:.1f} x across it")
    return (
        "\nThe same pixel count spread over 160 degrees instead of 100: the pinhole draws the markers both see larger, "
        f"at {'; '.join(parts)} (fx {fp:.0f} px against {ff:.0f} px per radian), so its corners place them "
        "that much more finely."
    )


def speed(images: list[np.ndarray], reps: int) -> dict[tuple[str, str], float]:
    """``locate`` with the fisheye camera over the pinhole path on the same picture, the median of the per-pair
    ratios, twice: against ``locate``'s detection and the pose of the same (already undistorted) corners with the
    pinhole camera of the same K; and against that and the rest of what ``locate`` does with a pinhole camera:
    its look for map markers its pose puts in view that were not detected (``missed_in_view``, always) and the
    second look at those of them the fisheye's pose predicts too (the same crops of the same picture, and the
    pose again when one is found there). Markers only the fisheye's wider view predicts are read again on the
    fisheye's side alone. Each in CPU time (the process's, OpenCV's threads included: what the work costs, which
    a loaded machine's waits do not dilute) and in wall time; keyed ``(clock, "narrow" or "whole")``."""
    prepared = []
    for im in images:
        dets = _detect_map_markers(im, WALL, None, None, True)
        und = [dataclasses.replace(d, corners_px=FISHEYE.undistort_points(d.corners_px)) for d in dets]
        und = [d for d in und if np.isfinite(d.corners_px).all()]
        rim = _rim_markers({d.id: d.corners_px for d in und}, FISHEYE)  # left out of the fisheye's pose too
        und = [d for d in und if d.id not in rim]
        found = {WALL.key(d.id, d.dictionary) for d in dets}
        first = fidlearn.estimate_pose(_straightened(im, dets, FISHEYE, WALL.dictionary, None), WALL, FISHEYE)
        fe_missed = missed_in_view(WALL, FISHEYE, first.T_world_camera, found, None)
        pose = fidlearn.estimate_pose(und, WALL, FISHEYE_AS_PINHOLE_POSE)
        ph_missed = {k for k, _, _ in missed_in_view(WALL, FISHEYE_AS_PINHOLE, pose.T_world_camera, found, None)}
        shared = [m for m in fe_missed if m[0] in ph_missed]
        more = [
            dataclasses.replace(d, corners_px=FISHEYE.undistort_points(d.corners_px))
            for d in read_again(im, shared, None, None)
        ]
        prepared.append((und, found, shared, [d for d in more if np.isfinite(d.corners_px).all()]))
    ratios: dict[tuple[str, str], list[float]] = {(c, k): [] for c in ("cpu", "wall") for k in ("narrow", "whole")}
    for _ in range(reps):
        for im, (und, found, shared, more) in zip(images, prepared):
            t0 = _clocks()
            fidlearn.locate(im, WALL, FISHEYE)
            t1 = _clocks()
            _detect_map_markers(im, WALL, None, None, True)  # locate's detection
            pose = fidlearn.estimate_pose(und, WALL, FISHEYE_AS_PINHOLE_POSE)
            t2 = _clocks()
            missed_in_view(WALL, FISHEYE_AS_PINHOLE, pose.T_world_camera, found, None)
            if shared and read_again(im, shared, None, None) and more:
                fidlearn.estimate_pose(und + more, WALL, FISHEYE_AS_PINHOLE_POSE)
            t3 = _clocks()
            for k, clock in enumerate(("cpu", "wall")):
                ratios[clock, "narrow"].append((t1[k] - t0[k]) / (t2[k] - t1[k]))
                ratios[clock, "whole"].append((t1[k] - t0[k]) / (t3[k] - t1[k]))
    return {key: float(np.median(v)) for key, v in ratios.items()}


def _clocks() -> tuple[float, float]:
    """The process's CPU time and the wall clock, s."""
    return time.process_time(), time.perf_counter()


def _calibrate_corners(views: dict, model: str, board: Board, size: tuple[int, int]) -> Calibration:
    """fidlearn's calibration (``_calibrate_points``, as ``calibrate_checkerboard`` runs it) of found corners."""
    names = list(views)
    obj = [board.object_points()] * len(names)
    img = [np.asarray(views[n], np.float64) for n in names]
    rms, K, dist, rotations, tvecs, _std, per_view = _calibrate_points(obj, img, size, 0, None, model)
    T = {}
    for n, R, t in zip(names, rotations, tvecs):
        T[n] = np.eye(4)
        T[n][:3, :3], T[n][:3, 3] = R, np.ravel(t)
    return Calibration(
        camera=Camera(K, np.ravel(dist), size, model=model),
        rms_px=float(rms),
        per_view_rms_px=dict(zip(names, per_view)),
        used=names,
        std_intrinsics=None,
        rejected=[],
        T_camera_board=T,
        image_points_px=dict(zip(names, img)),
        board_points_mm={n: board.object_points() for n in names},
    )


# Which pairs are one physical lens (data/README.md): the halves of a set always; mono and left most likely (both
# sets' files are named left-*, the source does not say it outright); left and right are the stereo pair's two
# copies of the lens, so a difference beyond noise is the expected answer there.
REAL_PAIRS = [
    ("mono even", "mono odd", "same lens (halves)"),
    ("left even", "left odd", "same lens (halves)"),
    ("right even", "right odd", "same lens (halves)"),
    ("mono", "left", "same lens most likely (not documented)"),
    ("left", "right", "two copies of the lens"),
    ("mono", "right", "two copies of the lens"),
]


def real_sets() -> None:
    real = fidlearn.data_path("real", "fisheye_checkerboard")
    board = Board.checkerboard((6, 8), 25.0)
    sets = json.loads((real / "corners.json").read_text())["sets"]
    size = (800, 503)
    cals = {}
    for name, views in sets.items():
        cals[name] = _calibrate_corners(views, "fisheye", board, size)
        for k, half in ((0, "even"), (1, "odd")):
            cals[f"{name} {half}"] = _calibrate_corners(dict(list(views.items())[k::2]), "fisheye", board, size)
    print("\n| set | photos | fx | fy | cx | cy | RMS (px) |")
    print("|---|---|---|---|---|---|---|")
    for name in sets:
        c = cals[name].camera
        print(
            f"| {name} | {len(sets[name])} | {c.fx:.2f} | {c.fy:.2f} | {c.cx:.1f} | {c.cy:.1f} | "
            f"{cals[name].rms_px:.3f} |"
        )
    print("\n| pair | what | projection difference over its expected size (ratio) | verdict |")
    print("|---|---|---|---|")
    same, other = [], []
    for a, b, what in REAL_PAIRS:
        c = compare_calibrations(cals[a], cals[b])
        (same if what.startswith("same") else other).append((a, b, c.ratio))
        print(f"| {a} - {b} | {what} | {c.ratio:.2f} | {c.verdict} |")
    worst = max(r for *_, r in same)
    print(
        "\nEvery set's whole corners (`corners.json`, 24/46/46 photos) and its even and odd photos, each calibrated "
        "with the fisheye model; `compare_calibrations` (the projection difference across the picture against "
        "the size both calibrations' uncertainty predicts, as mrcal cross-validates)."
    )
    print(
        f"<!-- target: fisheye: fidlearn's fisheye calibrations of one lens (halves of each set; mono and left) agree "
        f"within 2x the difference their stated uncertainties predict | largest ratio {worst:.2f} "
        f"({', '.join(f'{a}/{b} {r:.2f}' for a, b, r in same)}) | {'yes' if worst <= 2 else '**no**'} -->"
    )
    lr = next(r for a, b, r in other if (a, b) == ("left", "right"))
    print(
        "\nTwo copies of the lens are not bound to agree: `left` and `right` (the stereo pair) differ beyond noise, as "
        "expected; `mono` against `right` is "
        + ", ".join(f"{r:.2f}" for a, b, r in other if a == "mono")
        + " times its expected size: the 24 photos of `mono` leave the difference within noise (cannot tell)."
    )
    print(
        f"<!-- target: fisheye: the stereo pair's two copies of the lens (left, right) found different | "
        f"{lr:.2f} x the expected difference | {'yes' if lr > 2 else '**no**'} -->"
    )


def auto_choice() -> None:
    real = fidlearn.data_path("real", "fisheye_checkerboard")
    board = Board.checkerboard((6, 8), 25.0)
    got = {
        n: calibrate_checkerboard(sorted((real / n).glob("*.png")), board=board, model="auto").camera.model
        for n in ("mono", "left", "right")
    }
    views = sorted(fidlearn.data_path("calibration").glob("view_*.png"))
    got["checkerboard views"] = calibrate_checkerboard(
        views, board=Board.checkerboard((9, 6), 25.0), model="auto"
    ).camera.model
    ok = (
        all(m == "fisheye" for n, m in got.items() if n != "checkerboard views")
        and got["checkerboard views"] == "pinhole"
    )
    print(
        f"<!-- target: fisheye: `model='auto'` picks fisheye for the real fisheye sets, pinhole for the bundled "
        f"checkerboard views | {', '.join(f'{n} {m}' for n, m in got.items())} | {'yes' if ok else '**no**'} -->"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 scenes instead of 24, fewer timing repetitions")
    args = parser.parse_args(argv)
    n = 10 if args.quick else 24
    t0 = time.perf_counter()
    print(f"Load average when it started: {', '.join(f'{v:.1f}' for v in os.getloadavg())} (2 cores, shared).\n")
    rows = [scene_row(seed) for seed in range(n)]
    print(
        "| scenes | n | fidlearn median (mm) | fidlearn failures | refine='contour' median (mm) | "
        "OpenCV fisheye median (mm) | ratio to OpenCV | "
        "scenes both see | fisheye, shared markers (mm) | pinhole, shared markers (mm) | ratio to pinhole |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    accuracy(rows[: n // 2], f"seeds 0-{n // 2 - 1} (looked at)")
    held = accuracy(rows[n // 2 :], f"seeds {n // 2}-{n - 1} (held out)")
    ratio_cv, ratio_ph, fails = accuracy(rows, "all")
    print(resolution_note())
    print(
        f"\nMarkers detected per fisheye scene: {min(r['markers'] for r in rows)} to {max(r['markers'] for r in rows)}."
    )
    sp = speed([r["image"] for r in rows[:4]], 3 if args.quick else 8)
    ratio_t = sp["cpu", "whole"]
    print(
        f"\nSpeed: `locate` with the fisheye camera over the pinhole path on the same picture (`locate`'s detection, "
        "`estimate_pose` of the already undistorted corners with the pinhole camera of the same K, and what "
        "`locate` does after it with a pinhole camera: the look for map markers its pose puts in view undetected, "
        "the second look at those the fisheye's pose predicts too, the same crops, and the pose again with any "
        f"found there): median ratio {ratio_t:.2f} in CPU time ({sp['wall', 'whole']:.2f} in wall time); against "
        f"the detection and first pose alone (the comparison before 2026-11-29) {sp['cpu', 'narrow']:.2f} in CPU "
        f"time ({sp['wall', 'narrow']:.2f} in wall time) (load average now "
        f"{', '.join(f'{v:.1f}' for v in os.getloadavg())})."
    )
    real_sets()
    auto_choice()
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    print(
        f"<!-- target: fisheye: pose median error <= 1.5 x a pinhole's of the same pixel count (shared markers) | "
        f"{ratio_ph:.2f} x (held out {held[1]:.2f} x) | {'yes' if ratio_ph <= 1.5 else '**no**'} -->"
    )
    print(
        f"<!-- target: fisheye: pose median error <= 0.3 x plain OpenCV's fisheye pipeline | {ratio_cv:.2f} x "
        f"(held out {held[0]:.2f} x) | {'yes' if ratio_cv <= 0.3 else '**no**'} -->"
    )
    print(
        f"<!-- target: fisheye: no failure on the rendered fisheye scenes | {fails} of {len(rows)} | "
        f"{'yes' if fails == 0 else '**no**'} -->"
    )
    print(
        f"<!-- target: fisheye: `locate` on a fisheye camera <= 1.2 x the pinhole path on the same picture | "
        f"{ratio_t:.2f} x | {'yes' if ratio_t <= 1.2 else '**no**'} -->"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
