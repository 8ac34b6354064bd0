"""Corner accuracy and cost of every corner refinement, on synthetic scenes with known corners.

Run from the repository (about 1-2 minutes on one core)::

    python benchmarks/bench_corners.py            # accuracy table + timing table
    python benchmarks/bench_corners.py --quick    # fewer scenes, for a smoke test
    python benchmarks/bench_corners.py --robustness   # adds narrow quiet zones, heavy blur, inverted...

Accuracy: markers of a nominal side (15 to 150 px) on a wall, seen by a 640x480
camera from random oblique directions (up to 35 degrees) with a random roll, a
Gaussian blur of 0.5-1.0 px and noise of 1-2 gray levels
(:func:`fidlearn.synthetic.render_scene`, whose truth is ``cv2.projectPoints``
of the 3D corners). For each refinement: how many markers were found, the
corner RMS error, the 95th percentile, the mean radial offset (error along the
marker-centre-to-corner direction; negative means corners pulled inwards) and
the mean image-frame offset (dx, dy) which shows a constant shift.

Real photos: the ChArUco photos in data/real (no corner truth, but a known
geometry: a flat board's marker corners map by one homography).

Cost: :func:`fidlearn.detect_markers` per refinement, and ``fidlearn.pose.locate``
(detect with the default refinement + pose) when it exists, relative to a plain ``ArucoDetector.detectMarkers`` with
OpenCV's default parameters (no refinement) on the same gray image, at
640x480, 1280x720 and 1920x1080 (synthetic) and on the real 640x480 photo.
Twice: CPU time with OpenCV on one thread (the work each call does, which a
busy machine disturbs least) and wall-clock time with OpenCV's threads. Calls
are interleaved; the tables give the fastest of many repetitions and the
median ratio of neighbouring calls.

Not part of the test suite; the tables are copied into docs/corner_refinement.md.
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import cv2
import numpy as np

import fidlearn
from fidlearn import Camera, MarkerMap, MarkerPlacement, _cv, _cv_charuco
from fidlearn.detection import REFINE_METHODS, Detection, detect_markers, refine_corners_edges
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

MARKER_MM = 80.0  # printed marker side [mm]
SIDES_PX = (15, 20, 30, 45, 60, 90, 120, 150)  # nominal marker side in the image [px]


def grid_map(n_cols: int, n_rows: int, dictionary: str, first_id: int = 0) -> MarkerMap:
    """Markers on the north wall (x = 0 plane, facing +X), 1.75 marker sides apart."""
    pitch = 1.75 * MARKER_MM
    placements = {}
    for r in range(n_rows):
        for c in range(n_cols):
            mid = first_id + r * n_cols + c
            placements[mid] = MarkerPlacement(mid, (0.0, c * pitch, 1000.0 - r * pitch), (0.0, 0.0, 0.0))
    return MarkerMap(placements, MARKER_MM, dictionary)


def scene(side_px: float, seed: int, dictionary: str, image_size=(640, 480), blur=None, noise=None):
    """One rendered scene whose markers are about ``side_px`` pixels wide: (image, truth, map, camera)."""
    rng = np.random.default_rng(seed)
    cam = Camera.from_fov(60.0, image_size)
    w, h = image_size
    n_cols = max(1, min(3, int((w - 80) / (1.9 * side_px))))
    n_rows = max(1, min(2, int((h - 80) / (1.9 * side_px))))
    mm = grid_map(n_cols, n_rows, dictionary, first_id=int(rng.integers(0, 10)))
    centre = np.array(
        [
            0.0,
            (n_cols - 1) * 0.875 * MARKER_MM + MARKER_MM / 2,
            1000.0 - (n_rows - 1) * 0.875 * MARKER_MM - MARKER_MM / 2,
        ]
    )
    dist = cam.fx * MARKER_MM / side_px  # [mm] distance giving the nominal side when seen head-on
    az, el = math.radians(rng.uniform(-35, 35)), math.radians(rng.uniform(-25, 25))
    eye = centre + dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    T = look_at(eye, centre, roll_deg=float(rng.uniform(0, 360)))
    blur = float(rng.uniform(0.5, 1.0)) if blur is None else blur
    noise = float(rng.uniform(1.0, 2.0)) if noise is None else noise
    image, truth = render_scene(mm, cam, T, seed=seed, blur_px=blur, noise_std_gray=noise, gradient=0.2)
    return image, truth, mm, cam


GAMMA_COLUMN = "edges, gamma 2.2"


def accuracy(dictionary: str, n_scenes: int, methods) -> dict:
    """Per nominal side and refinement: statistics over every marker that refinement found.

    The extra column ``edges, gamma 2.2`` refines OpenCV's unrefined corners with
    ``refine_corners_edges(..., gamma=2.2)``: what that option does to a picture
    whose gray levels are proportional to light, as the renderer's are.
    """
    cells = _cv.dictionary_marker_bits(dictionary) + 2
    rows = {}
    for side in SIDES_PX:
        errs = {m: [] for m in methods + [GAMMA_COLUMN]}
        truths = {m: [] for m in errs}
        visible = 0
        for s in range(n_scenes):
            image, truth, _, _ = scene(side, 1000 * side + s, dictionary)
            visible += len(truth)
            per = {m: {d.id: d.corners_px for d in detect_markers(image, dictionary, refine=m)} for m in methods}
            if per["none"]:
                ids = sorted(per["none"])
                fine = refine_corners_edges(image, np.stack([per["none"][i] for i in ids]), cells, gamma=2.2)
                per[GAMMA_COLUMN] = dict(zip(ids, fine))
            else:
                per[GAMMA_COLUMN] = {}
            for m in errs:
                errs[m] += [per[m][i] - truth[i] for i in truth if i in per[m]]
                truths[m] += [truth[i] for i in truth if i in per[m]]
        rows[side] = {}
        for m in errs:
            e = np.array(errs[m]).reshape(-1, 4, 2)
            if e.size == 0:
                rows[side][m] = None
                continue
            T = np.array(truths[m]).reshape(-1, 4, 2)
            radial = T - T.mean(axis=1, keepdims=True)
            radial /= np.linalg.norm(radial, axis=2, keepdims=True)
            r = np.linalg.norm(e, axis=2)
            rows[side][m] = dict(
                found=len(e),
                visible=visible,
                rms=float(np.sqrt((r**2).mean())),
                p95=float(np.percentile(r, 95)),
                radial=float((e * radial).sum(2).mean()),
                dxdy=e.reshape(-1, 2).mean(axis=0),
            )
    return rows


def print_accuracy(rows, methods, dictionary):
    print(f"\nCorner error [px] vs truth, {dictionary}, 640x480, blur 0.5-1.0 px, noise 1-2 gray levels")
    print(
        "cell: RMS / 95th percentile / mean radial offset (- = inwards); found/visible; "
        "each method over the markers it found"
    )
    head = "| side px | " + " | ".join(methods) + " |"
    print(head)
    print("|" + "---|" * (len(methods) + 1))
    for side, per in rows.items():
        cells = []
        for m in methods:
            r = per[m]
            cells.append(
                "-"
                if r is None
                else f"{r['rms']:.3f} / {r['p95']:.2f} / {r['radial']:+.2f}; {r['found']}/{r['visible']}"
            )
        print(f"| {side} | " + " | ".join(cells) + " |")
    print("\nMean image-frame offset (dx, dy) [px] over all sides (a constant shift shows here):")
    for m in methods:
        d = np.concatenate([[per[m]["dxdy"]] for per in rows.values() if per[m] is not None]).mean(axis=0)
        print(f"  {m:9s} ({d[0]:+.3f}, {d[1]:+.3f})")


ROBUSTNESS_CASES = {  # label: (marker side px, dictionary, invert the picture, render_scene keywords)
    "baseline (45 px, blur 0.7, noise 1.5)": (45, "ARUCO_ORIGINAL", False, {}),
    "quiet zone 0.5 cell, wall 120": (45, "ARUCO_ORIGINAL", False, {"margin_cells": 0.5}),
    "quiet zone 0.5 cell, dark wall 40": (45, "ARUCO_ORIGINAL", False, {"margin_cells": 0.5, "wall_gray": 40}),
    "quiet zone 0.25 cell": (45, "ARUCO_ORIGINAL", False, {"margin_cells": 0.25}),
    "no quiet zone (marker on the wall)": (45, "ARUCO_ORIGINAL", False, {"margin_cells": 0.0}),
    "illumination gradient 60 %": (45, "ARUCO_ORIGINAL", False, {"gradient": 0.6}),
    "low contrast (ink 90, paper 170)": (45, "ARUCO_ORIGINAL", False, {"ink_gray": 90, "paper_gray": 170}),
    "blur 1.5 px, 30 px markers": (30, "ARUCO_ORIGINAL", False, {"blur_px": 1.5}),
    "blur 2 px, noise 5": (45, "ARUCO_ORIGINAL", False, {"blur_px": 2.0, "noise_std_gray": 5.0}),
    "inverted markers (detectInvertedMarker)": (45, "ARUCO_ORIGINAL", True, {}),
    "6X6_250, 30 px": (30, "6X6_250", False, {}),
    "4X4_50, 25 px": (25, "4X4_50", False, {}),
}


def robustness(methods, n_scenes: int = 4) -> dict:
    """Corner RMS / max error per refinement when the picture departs from the easy case."""
    rows = {}
    cam = Camera.from_fov(60.0, (640, 480))
    for label, (side, dic, invert, extra) in ROBUSTNESS_CASES.items():
        mm = grid_map(3, 2, dic)
        centre = np.array([0.0, 2 * 0.875 * MARKER_MM + MARKER_MM / 2, 1000.0 - 0.875 * MARKER_MM - MARKER_MM / 2])
        errs = {m: [] for m in methods}
        visible = 0
        for s in range(n_scenes):
            rng = np.random.default_rng(s)
            az, el = math.radians(rng.uniform(-35, 35)), math.radians(rng.uniform(-25, 25))
            eye = centre + cam.fx * MARKER_MM / side * np.array(
                [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
            )
            kw = {"blur_px": 0.7, "noise_std_gray": 1.5, **extra}
            image, truth = render_scene(
                mm, cam, look_at(eye, centre, roll_deg=float(rng.uniform(0, 360))), seed=s, **kw
            )
            if invert:
                image = 255 - image
            visible += len(truth)
            params = {"detectInvertedMarker": True} if invert else None
            for m in methods:
                errs[m] += [
                    d.corners_px - truth[d.id]
                    for d in detect_markers(image, dic, refine=m, detector_params=params)
                    if d.id in truth
                ]
        rows[label] = {m: (np.array(e), visible) for m, e in errs.items()}
    return rows


def print_robustness(rows, methods):
    print("\nRobustness: corner RMS / max error [px]; found/visible (640x480, 4 scenes each)")
    print("| case | " + " | ".join(methods) + " |")
    print("|" + "---|" * (len(methods) + 1))
    for label, per in rows.items():
        cells = []
        for m in methods:
            e, vis = per[m]
            r = np.linalg.norm(e.reshape(-1, 2), axis=1) if e.size else np.zeros(0)
            cells.append(f"{np.sqrt((r**2).mean()):.3f} / {r.max():.2f}; {len(e)}/{vis}" if r.size else f"- ; 0/{vis}")
        print(f"| {label} | " + " | ".join(cells) + " |")


SUBPIX_WINDOWS = {  # label: DetectorParameters overrides for refine="subpix"
    "default: min(5 px, 0.3 cell)": {},
    "fixed 5 px": {"relativeCornerRefinmentWinSize": 10.0},
    "fixed 10 px": {"relativeCornerRefinmentWinSize": 10.0, "cornerRefinementWinSize": 10},
    "0.5 cell": {"relativeCornerRefinmentWinSize": 0.5, "cornerRefinementWinSize": 50},
}


def print_subpix_windows(dictionary: str, n_scenes: int = 3) -> None:
    """cornerSubPix's window: fixed in pixels (OpenCV before 4.7) or relative to the cell."""
    print(f"\nsubpix window sizes: corner RMS / max error [px], {dictionary}, same scenes as the accuracy table")
    print("| side px | " + " | ".join(SUBPIX_WINDOWS) + " |")
    print("|" + "---|" * (len(SUBPIX_WINDOWS) + 1))
    for side in (30, 60, 150):
        cells = []
        for params in SUBPIX_WINDOWS.values():
            e = []
            for s in range(n_scenes):
                image, truth, _, _ = scene(side, 1000 * side + s, dictionary)
                e += [
                    d.corners_px - truth[d.id]
                    for d in detect_markers(image, dictionary, refine="subpix", detector_params=params)
                    if d.id in truth
                ]
            r = np.linalg.norm(np.array(e).reshape(-1, 2), axis=1)
            cells.append(f"{np.sqrt((r**2).mean()):.3f} / {r.max():.2f}")
        print(f"| {side} | " + " | ".join(cells) + " |")


def real_photos(methods) -> dict:
    """Consistency of each refinement with a known geometry on the real ChArUco photos.

    The board is flat, so after undistortion (the tutorial's calibration) its
    marker corners map from the board by one homography. Reported: the RMS
    residual of that fit; the RMS when the markers may also shrink or grow
    about their centres by one common factor (what ink spread, exposure or
    gamma do to a printed marker), and that factor; and the mean image-frame
    offset from the ``edges`` corners (a constant shift the homography absorbs).
    """
    from fidlearn.data import data_path
    from fidlearn.detection import load_image

    cam = Camera.load(data_path("real", "opencv_charuco", "tutorial_camera_charuco.yml"))
    board = _cv_charuco.charuco_board((5, 7), 40.0, 20.0, "6X6_250")
    obj = {
        int(i): np.asarray(o, float).reshape(4, 3)[:, :2]
        for i, o in zip(np.ravel(board.getIds()), board.getObjPoints())
    }

    def fit(P, Q):
        H, _ = cv2.findHomography(P.reshape(-1, 2), Q, 0)
        return Q - cv2.perspectiveTransform(P.reshape(-1, 1, 2), H).reshape(-1, 2)

    out = {m: {"h": [], "hs": [], "s": [], "d": []} for m in methods + ["edges, gamma 2.2"]}
    names = ("img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg", "chocclusion_original.jpg")
    for name in names:
        image = load_image(data_path("real", "opencv_charuco", name))
        ref = {d.id: d.corners_px for d in detect_markers(image, "6X6_250", refine="edges")}
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        for m in methods + ["edges, gamma 2.2"]:
            if m == "edges, gamma 2.2":  # the edge at half the light, for a camera with an sRGB-like curve
                dets = [d for d in detect_markers(image, "6X6_250", refine="none") if d.id in obj]
                fine = refine_corners_edges(gray, np.stack([d.corners_px for d in dets]), 8, gamma=2.2)
                dets = [Detection(d.id, c) for d, c in zip(dets, fine)]
            else:
                dets = [d for d in detect_markers(image, "6X6_250", refine=m) if d.id in obj]
            P = np.stack([obj[d.id] for d in dets])
            Q = cv2.undistortPoints(
                np.concatenate([d.corners_px for d in dets]).reshape(-1, 1, 2), cam.K, cam.dist, P=cam.K
            ).reshape(-1, 2)
            out[m]["h"].append(fit(P, Q))
            centre = P.mean(axis=1, keepdims=True)
            best = min((float((fit(centre + s * (P - centre), Q) ** 2).sum()), s) for s in np.linspace(0.95, 1.05, 201))
            out[m]["hs"].append(fit(centre + best[1] * (P - centre), Q))
            out[m]["s"].append(best[1])
            out[m]["d"] += [d.corners_px - ref[d.id] for d in dets if d.id in ref]
    return {
        m: dict(
            h=float(np.sqrt((np.concatenate(v["h"]) ** 2).sum(1).mean())),
            hs=float(np.sqrt((np.concatenate(v["hs"]) ** 2).sum(1).mean())),
            s=float(np.mean(v["s"])),
            d=np.concatenate(v["d"]).reshape(-1, 2).mean(axis=0),
            n=sum(len(x) for x in v["h"]) // 4,
        )
        for m, v in out.items()
    }


def print_real(rows):
    n = next(iter(rows.values()))["n"]
    print(f"\nReal photos: ChArUco board (5 photos, {n} marker detections), homography fit of the undistorted corners")
    print(
        "| refinement | RMS [px] | RMS with a common marker scale [px] | that scale | "
        "mean offset from edges (dx, dy) [px] |"
    )
    print("|---|---|---|---|---|")
    for m, r in rows.items():
        print(f"| {m} | {r['h']:.3f} | {r['hs']:.3f} | {r['s']:.3f} | ({r['d'][0]:+.2f}, {r['d'][1]:+.2f}) |")


def timing(dictionary: str, methods, repeats: int, cpu: bool = False) -> dict:
    """Time every call; ``cpu=True``: CPU time of this process with OpenCV on one thread (the work done)."""
    from fidlearn.data import data_path
    from fidlearn.detection import load_image

    try:
        from fidlearn.pose import locate
    except ImportError:  # the pose module is not there yet
        locate = None
    cases = []
    for size in ((640, 480), (1280, 720), (1920, 1080)):
        image, truth, mm, cam = scene(60.0 * size[0] / 640, 7, dictionary, image_size=size, blur=0.7, noise=1.5)
        cases.append((f"{size[0]}x{size[1]} synthetic, {len(truth)} markers", image, dictionary, mm, cam))
    photo = load_image(data_path("real", "opencv_aruco_photo", "singlemarkersoriginal.jpg"))
    cases.append(("640x480 photo, 6 markers", cv2.cvtColor(photo, cv2.COLOR_BGR2GRAY), "6X6_250", None, None))
    out = {}
    threads = cv2.getNumThreads()
    clock = time.process_time if cpu else time.perf_counter
    if cpu:
        cv2.setNumThreads(1)
    for label, image, dic, mm, cam in cases:
        plain = cv2.aruco.ArucoDetector(_cv.get_dictionary(dic), cv2.aruco.DetectorParameters())
        calls = {"plain detectMarkers": lambda plain=plain, image=image: plain.detectMarkers(image)}
        for m in methods:
            calls[f"detect_markers {m}"] = lambda m=m, image=image, dic=dic: detect_markers(image, dic, refine=m)
        if locate is not None and mm is not None:
            calls["locate (default)"] = lambda image=image, mm=mm, cam=cam: locate(image, mm, cam)
        for f in calls.values():  # warm the caches
            f()
        samples = {k: [] for k in calls}
        for rep in range(repeats):
            for k, f in calls.items():
                if k.endswith("apriltag") and rep >= 3:  # tens of times slower: a few calls tell
                    continue
                t0 = clock()
                f()
                samples[k].append(clock() - t0)
        base = np.array(samples["plain detectMarkers"])
        out[label] = {
            k: (float(np.min(v)) * 1e3, float(np.min(v) / base.min()), float(np.median(np.array(v) / base[: len(v)])))
            for k, v in samples.items()
        }
    cv2.setNumThreads(threads)
    return out


def print_timing(t, cpu: bool):
    what = "CPU time, OpenCV on 1 thread" if cpu else f"wall-clock time, OpenCV on {cv2.getNumThreads()} threads"
    print(f"\nCost ({what}): fastest [ms], its ratio to the fastest plain detectMarkers (default")
    print("parameters, no refinement) and [the median of the ratios of interleaved calls]")
    labels = list(t)
    keys = list(dict.fromkeys(k for lab in labels for k in t[lab]))
    print("| call | " + " | ".join(labels) + " |")
    print("|" + "---|" * (len(labels) + 1))
    for k in keys:
        cells = [
            f"{t[lab][k][0]:.2f} ms {t[lab][k][1]:.2f}x [{t[lab][k][2]:.2f}x]" if k in t[lab] else "-" for lab in labels
        ]
        print(f"| {k} | " + " | ".join(cells) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dictionary", default="ARUCO_ORIGINAL")
    ap.add_argument("--scenes", type=int, default=6, help="scenes per marker side")
    ap.add_argument("--repeats", type=int, default=40, help="timing repetitions per call")
    ap.add_argument("--quick", action="store_true", help="2 scenes per side, 10 timing repetitions")
    ap.add_argument("--robustness", action="store_true", help="also the robustness table (about 30 s more)")
    args = ap.parse_args(argv)
    if args.quick:
        args.scenes, args.repeats = 2, 10
    methods = list(REFINE_METHODS)
    print(
        f"fidlearn {fidlearn.__version__}, OpenCV {cv2.__version__}, numpy {np.__version__}, "
        f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    t0 = time.perf_counter()
    print_accuracy(accuracy(args.dictionary, args.scenes, methods), methods + [GAMMA_COLUMN], args.dictionary)
    print_real(real_photos(methods))
    if args.robustness:
        print_robustness(robustness([m for m in methods if m != "apriltag"]), [m for m in methods if m != "apriltag"])
        print_subpix_windows(args.dictionary)
    print_timing(timing(args.dictionary, methods, args.repeats, cpu=True), cpu=True)
    print_timing(timing(args.dictionary, methods, args.repeats), cpu=False)
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
