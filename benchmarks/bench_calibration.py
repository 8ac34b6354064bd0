"""Measure fidlearn's calibration: focal-length error against views and tilt, corner finders, real photos.

Not a test: run it by hand and read the numbers.

    .venv/bin/python benchmarks/bench_calibration.py            # everything (about 2 minutes on one core)
    .venv/bin/python benchmarks/bench_calibration.py --quick    # one seed, fewer cells

1. Synthetic sets (``fidlearn.synthetic.render_calibration_views``, the true
   camera of ``data/calibration/camera_true.json``, 9x6 inner corners, 25 mm):
   error of fx, fy and the principal point against the number of views and
   the range of board tilts, mean over seeds, with the standard deviation
   ``calibrateCameraExtended`` claims beside the error it really made.
2. Corner finders on ``data/calibration`` (20 views, true corners in
   ``views.json``) and on a harder rendered set (k1 = -0.28, blur 1 px,
   tilts 30 to 55 degrees, small squares): corner error against the truth,
   fx error, time, for
   ``findChessboardCorners`` + capped ``cornerSubPix`` (fidlearn's default),
   the same with OpenCV's sample's fixed 11 px half-window, and
   ``findChessboardCornersSB`` with ``CALIB_CB_ACCURACY``.
3. Real photos: OpenCV's 13 checkerboard photos (with and without outlier
   rejection) and the 4 ChArUco tutorial photos: RMS, intrinsics with their
   standard deviations, against the published numbers.
4. Speed against plain OpenCV on the same images (in memory), interleaved call
   by call in this process, wall and CPU time, median of the per-pair ratios:
   ``calibrate_checkerboard`` against ``findChessboardCorners`` + ``cornerSubPix``
   (11 px) + ``calibrateCamera`` at 10, 20, 40 and 60 rendered views (also with
   ``std_intrinsics`` read), ``calibrate_charuco`` against
   ``CharucoDetector.detectBoard`` + ``matchImagePoints`` + ``calibrateCamera``,
   and what ``calibrateCameraExtended`` costs over ``calibrateCamera`` alone.
"""

from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from fidlearn import Board, Camera, data_path
from fidlearn.calibration import calibrate_charuco, calibrate_checkerboard, find_checkerboard_corners
from fidlearn.errors import BoardNotFoundError
from fidlearn.images import load_image
from fidlearn.synthetic import render_calibration_views

TUTORIAL = Board.charuco((5, 7), 40, 20)  # OpenCV's tutorial ChArUco board

PATTERN = (9, 6)
SQUARE_MM = 25.0


def synthetic_sweep(quick: bool) -> None:
    truth = Camera.load(data_path("calibration", "camera_true.json"))
    counts = (3, 5, 10, 20)
    tilts = ((0.0, 10.0), (10.0, 25.0), (10.0, 45.0), (35.0, 60.0))
    seeds = (1,) if quick else (1, 2, 3)
    if quick:
        tilts = tilts[::2]
    print(
        "1. Synthetic views: error against the true camera (mean over seeds "
        f"{', '.join(map(str, seeds))}; 'std' = calibrateCameraExtended's claimed fx standard deviation)"
    )
    print(f"   true camera: {truth!r}")
    print(
        f"   {'tilt deg':>9}  {'views':>5}  {'|fx err| %':>10}  {'|fy err| %':>10}  "
        f"{'pp err px':>9}  {'std fx %':>8}  {'rms px':>6}  used"
    )
    for lo, hi in tilts:
        sets = [render_calibration_views(truth, n_views=max(counts), seed=s, tilt_range_deg=(lo, hi)) for s in seeds]
        for n in counts:
            rows = []
            for views in sets:
                cal = calibrate_checkerboard(views.images[:n], PATTERN, SQUARE_MM)
                c = cal.camera
                rows.append(
                    (
                        abs(c.fx / truth.fx - 1) * 100,
                        abs(c.fy / truth.fy - 1) * 100,
                        float(np.hypot(c.cx - truth.cx, c.cy - truth.cy)),
                        cal.std_intrinsics["fx"] / c.fx * 100,
                        cal.rms_px,
                        len(cal.used),
                    )
                )
            r = np.array(rows)
            print(
                f"   {lo:4.0f}-{hi:<4.0f}  {n:5d}  {r[:, 0].mean():10.3f}  {r[:, 1].mean():10.3f}  "
                f"{r[:, 2].mean():9.2f}  "
                f"{r[:, 3].mean():8.3f}  {r[:, 4].mean():6.3f}  {r[:, 5].mean():.1f}/{n}"
            )


def corner_finders(quick: bool) -> None:
    truth = Camera.load(data_path("calibration", "camera_true.json"))
    files = sorted(data_path("calibration").glob("view_*.png"))
    views = json.loads(data_path("calibration", "views.json").read_text())["views"]
    grays = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
    print("\n2. Corner finders against the true corners")
    _compare_finders("data/calibration (20 views)", grays, [np.array(v["corners_px"]) for v in views], truth)
    # a harder set: strong barrel distortion, more blur, small and steeply tilted squares
    hard = Camera([[540.0, 0, 328], [0, 540, 247], [0, 0, 1]], [-0.28, 0.10, 0, 0, -0.02], (640, 480))
    n = 10 if quick else 20
    views = render_calibration_views(
        hard, n_views=n, seed=5, tilt_range_deg=(30.0, 55.0), fill_range=(0.22, 0.4), blur_px=1.0
    )
    sizes = [float(np.linalg.norm(np.diff(p.reshape(6, 9, 2), axis=1), axis=2).min()) for p in views.image_points]
    print(f"   hard set: {hard!r}, squares {min(sizes):.0f} to {max(sizes):.0f} px at their narrowest, blur 1 px")
    _compare_finders(f"hard set ({n} views)", views.images, views.image_points, hard)


def _compare_finders(label: str, grays: list, true_points: list, truth: Camera) -> None:
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)

    def fixed11(gray):
        ok, c = cv2.findChessboardCorners(gray, PATTERN)
        return cv2.cornerSubPix(gray, c, (11, 11), (-1, -1), crit).reshape(-1, 2).astype(float) if ok else None

    def ours(finder):
        def find(gray):
            try:
                return find_checkerboard_corners(gray, PATTERN, finder)
            except BoardNotFoundError:
                return None

        return find

    finders = {
        "findChessboardCorners + capped cornerSubPix (default)": ours("classic"),
        "findChessboardCorners + cornerSubPix 11 (OpenCV sample)": fixed11,
        "findChessboardCornersSB, CALIB_CB_ACCURACY": ours("sb"),
    }
    objp = np.zeros((54, 3), np.float32)
    objp[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * SQUARE_MM
    print(
        f"   {label:<58}  found  {'corner rms px':>13}  {'max px':>6}  {'fx err %':>8}  {'fy err %':>8}  {'time s':>6}"
    )
    for name, find in finders.items():
        t0 = time.perf_counter()
        found = [find(g) for g in grays]
        dt = time.perf_counter() - t0
        errs, img = [], []
        for c, true in zip(found, true_points):
            if c is None:
                continue
            true = np.asarray(true, dtype=float)
            if np.linalg.norm(c[0] - true[0]) > np.linalg.norm(c[-1] - true[0]):
                c = c[::-1]  # a symmetric board: OpenCV may number it from the far corner
            errs.append(np.linalg.norm(c - true, axis=1))
            img.append(c.astype(np.float32))
        e = np.concatenate(errs)
        _rms, K, *_ = cv2.calibrateCamera([objp] * len(img), img, truth.image_size, None, None)
        print(
            f"   {'  ' + name:<58}  {len(img):2d}/{len(grays):<2d}  {np.sqrt(np.mean(e**2)):13.3f}  {e.max():6.3f}  "
            f"{(K[0, 0] / truth.fx - 1) * 100:8.3f}  {(K[1, 1] / truth.fy - 1) * 100:8.3f}  {dt:6.2f}"
        )


def real_photos() -> None:
    print("\n3. Real photos")
    files = sorted(data_path("real", "opencv_checkerboard_right").glob("right*.jpg"))
    charuco = [data_path("real", "opencv_charuco", f"img_0{i}.jpg") for i in range(4)]
    published = Camera.load(data_path("real", "opencv_charuco", "tutorial_camera_charuco.yml"), image_size=(640, 480))
    runs = [
        (
            "checkerboard right*.jpg, all views",
            lambda: calibrate_checkerboard(files, PATTERN, SQUARE_MM, reject_outliers=False),
        ),
        ("checkerboard right*.jpg, outliers out", lambda: calibrate_checkerboard(files, PATTERN, SQUARE_MM)),
        (
            "checkerboard right*.jpg, SB finder",
            lambda: calibrate_checkerboard(files, PATTERN, SQUARE_MM, corner_finder="sb", reject_outliers=False),
        ),
        ("ChArUco img_00..03", lambda: calibrate_charuco(charuco, TUTORIAL)),
    ]
    print(
        f"   {'set':<38}  views  {'rms px':>6}  {'fx +- std':>14}  {'fy +- std':>14}  "
        f"{'cx +- std':>13}  {'cy +- std':>13}  {'k1 +- std':>15}"
    )
    for name, run in runs:
        cal = run()
        c, s = cal.camera, cal.std_intrinsics
        print(
            f"   {name:<38}  {len(cal.used):2d}/{len(cal.views):<2d}  {cal.rms_px:6.3f}  "
            f"{c.fx:7.2f} +- {s['fx']:4.2f}  {c.fy:7.2f} +- {s['fy']:4.2f}  {c.cx:6.2f} +- {s['cx']:4.2f}  "
            f"{c.cy:6.2f} +- {s['cy']:4.2f}  {c.dist[0]:7.4f} +- {s['k1']:.4f}"
        )
        for n, reason in cal.rejected:
            print(f"      rejected {n.rsplit('/', 1)[-1]}: {reason}")
    print(
        f"   {'published tutorial_camera_charuco.yml':<38}  {'4/4':>5}  {0.182:6.3f}  {published.fx:7.2f}"
        f"{'':8}  {published.fy:7.2f}{'':8}  {published.cx:6.2f}{'':8}  "
        f"{published.cy:6.2f}{'':8}  {published.dist[0]:7.4f}"
    )


def _interleaved(f_ours, f_plain, pairs: int) -> tuple[float, float, float, float]:
    """Median ms of each (wall), and the medians of the per-pair wall and CPU ratios ours / plain."""
    f_ours(), f_plain()  # warm up
    rows = []
    for k in range(pairs):
        timed = {}
        order = [("ours", f_ours), ("plain", f_plain)][:: 1 if k % 2 == 0 else -1]
        for name, f in order:
            w0, c0 = time.perf_counter(), time.process_time()
            f()
            timed[name] = (time.perf_counter() - w0, time.process_time() - c0)
        rows.append((*timed["ours"], *timed["plain"]))
    r = np.array(rows)
    cpu_ratio = np.median(r[:, 1] / np.maximum(r[:, 3], 1e-9))
    return np.median(r[:, 0]) * 1e3, np.median(r[:, 2]) * 1e3, float(np.median(r[:, 0] / r[:, 2])), float(cpu_ratio)


def _plain_checkerboard(grays: list) -> tuple:
    """OpenCV's sample recipe: findChessboardCorners, cornerSubPix (11, 11), calibrateCamera."""
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
    objp = checkerboard_object()
    obj, img = [], []
    for g in grays:
        ok, c = cv2.findChessboardCorners(g, PATTERN)
        if ok:
            obj.append(objp)
            img.append(cv2.cornerSubPix(g, c, (11, 11), (-1, -1), crit))
    return cv2.calibrateCamera(obj, img, grays[0].shape[::-1], None, None)


def _plain_charuco(grays: list) -> tuple:
    """OpenCV's recipe: CharucoDetector.detectBoard, board.matchImagePoints, calibrateCamera."""
    board = cv2.aruco.CharucoBoard((5, 7), 40.0, 20.0, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250))
    detector = cv2.aruco.CharucoDetector(board)
    obj, img = [], []
    for g in grays:
        corners, ids, _mc, _mi = detector.detectBoard(g)
        if ids is not None and len(ids) >= 6:
            o, p = board.matchImagePoints(corners, ids)
            obj.append(o)
            img.append(p)
    return cv2.calibrateCamera(obj, img, grays[0].shape[::-1], None, None)


def speed(quick: bool) -> None:
    truth = Camera.load(data_path("calibration", "camera_true.json"))
    views = list(render_calibration_views(truth, n_views=60, seed=1).images)
    charuco_views = list(render_calibration_views(truth, n_views=10, board=TUTORIAL, seed=2).images)
    photos = [load_image(data_path("real", "opencv_charuco", f"img_0{i}.jpg")) for i in range(4)]
    photos = [cv2.cvtColor(p, cv2.COLOR_BGR2GRAY) if p.ndim == 3 else p for p in photos]
    print(
        "\n4. Speed against plain OpenCV: the same gray images in memory, the two calls interleaved "
        f"(median of the per-pair ratios; OpenCV threads {cv2.getNumThreads()})"
    )
    print(
        "   plain checkerboard = findChessboardCorners + cornerSubPix (11, 11) + calibrateCamera; plain ChArUco = "
        "CharucoDetector.detectBoard + matchImagePoints + calibrateCamera"
    )
    print(f"   {'set':<22}  views  {'fidlearn ms':>11}  {'plain ms':>8}  {'wall ratio':>10}  {'CPU ratio':>9}")
    # a row's ratio scatters by a few per cent on a shared machine: enough pairs for the median to hold still
    pairs = {10: 21, 20: 15, 40: 11, 60: 9} if not quick else {10: 5, 20: 5, 40: 3, 60: 3}
    rows = []
    for n, k in pairs.items():
        rows.append(("checkerboard", n, lambda n=n: calibrate_checkerboard(views[:n], PATTERN, SQUARE_MM), k))
    for n, k in pairs.items():

        def with_std(n=n):
            return calibrate_checkerboard(views[:n], PATTERN, SQUARE_MM).std_intrinsics

        rows.append(("checkerboard+std", n, with_std, k))
    for label, ims, k in (("charuco-rendered", charuco_views, 15), ("charuco-photos", photos, 15)):
        rows.append((label, len(ims), lambda ims=ims: calibrate_charuco(ims, TUTORIAL), k if not quick else 3))
    for label, n, f, k in rows:
        plain = (lambda n=n: _plain_checkerboard(views[:n])) if label.startswith("checker") else None
        if plain is None:
            ims = charuco_views if label == "charuco-rendered" else photos
            plain = lambda ims=ims: _plain_charuco(ims)  # noqa: E731
        ours_ms, plain_ms, wall, cpu = _interleaved(f, plain, k)
        print(f"   {label:<22}  {n:5d}  {ours_ms:11.1f}  {plain_ms:8.1f}  {wall:10.3f}  {cpu:9.3f}")
    _extended_cost(views, pairs)


def _extended_cost(views: list, pairs: dict) -> None:
    """What the standard deviations cost when OpenCV computes them: calibrateCameraExtended / calibrateCamera."""
    corners = [find_checkerboard_corners(g, PATTERN) for g in views]
    obj = [checkerboard_object()] * len(corners)
    img = [c.astype(np.float32).reshape(-1, 1, 2) for c in corners]
    parts = []
    for n, k in pairs.items():
        _a, _b, wall, cpu = _interleaved(
            lambda n=n: cv2.calibrateCameraExtended(obj[:n], img[:n], (640, 480), None, None),
            lambda n=n: cv2.calibrateCamera(obj[:n], img[:n], (640, 480), None, None),
            k,
        )
        parts.append(f"{n} views {wall:.2f} (CPU {cpu:.2f})")
    print("   calibrateCameraExtended / calibrateCamera alone, the cost fidlearn no longer pays: " + ", ".join(parts))


def checkerboard_object() -> np.ndarray:
    """The 9x6 board's corners (mm), z = 0, in OpenCV's order."""
    objp = np.zeros((54, 3), np.float32)
    objp[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * SQUARE_MM
    return objp


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed and two tilt ranges, fewer timed pairs")
    parser.add_argument("--speed", action="store_true", help="only section 4, the speed against plain OpenCV")
    args = parser.parse_args()
    if args.speed:
        print(f"OpenCV {cv2.__version__}")
        speed(args.quick)
        return
    t0 = time.perf_counter()
    print(f"OpenCV {cv2.__version__}")
    synthetic_sweep(args.quick)
    corner_finders(args.quick)
    real_photos()
    speed(args.quick)
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
