"""Speed of fidlearn.locate and of the video tracker against a plain OpenCV detectMarkers on the same frames.

    python benchmarks/bench_speed.py            # about 3 minutes on a loaded 2-core machine
    python benchmarks/bench_speed.py --quick    # fewer repetitions and frames

1. ``fidlearn.locate(image, map, camera)`` against
   ``cv2.aruco.ArucoDetector(dictionary, DetectorParameters()).detectMarkers(gray)`` on the same
   rendered frame at 640x480, 1280x720 and 1920x1080, two scenes: the course's three 80 mm
   markers from 1.2 m (35 to 100 px), twelve 150 mm markers on a wall from 2.7 m (27 to 83 px).
   The calls alternate (plain, locate, plain, locate, ...) and the ratio
   is the median of the per-pair ratios, in wall-clock time and in CPU time
   (``time.process_time``, all threads). Then where locate's time goes: each step of it timed
   the same way (gray conversion, the camera check, OpenCV's detection inside
   ``detect_markers``, the edge refinement, ``estimate_pose``).
2. ``MarkerTracker.locate`` on a 1920x1080 video: a camera walking 2.5 m toward a hall with 43
   markers of 80 mm (a back wall and two rows of stands), 40 frames rendered once
   (``render_scene``, supersample 2, blur 0.5 px, noise 1.5), markers 17 to 180 px. Against
   plain ``detectMarkers`` frame by frame (interleaved, three passes, each with a fresh
   tracker so its full-frame detections count); the recall of markers of 20 px or more
   (shortest side, whole with their white margin inside the frame) for plain detectMarkers,
   ``detect_markers``, the tracker and OpenCV's ArUco3 mode (``useAruco3Detection``) at two
   settings; corner and pose errors against the truth.
"""

from __future__ import annotations

import argparse
import inspect
import math
import platform
import time

import cv2
import numpy as np

import fidlearn
from fidlearn import Camera, MarkerMap, MarkerPlacement, MarkerTracker, _cv
from fidlearn.detection import DEFAULT_DETECTOR_PARAMS, _detector, as_gray, detect_markers, refine_corners_edges
from fidlearn.errors import NoMarkersError, PoseError
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

DICT = "ARUCO_ORIGINAL"


def plain_detector(**overrides):
    params = cv2.aruco.DetectorParameters()
    for k, v in overrides.items():
        setattr(params, k, v)
    return cv2.aruco.ArucoDetector(_cv.get_dictionary(DICT), params)


def interleaved(calls: dict, repeats: int, clock) -> dict:
    """Times (s) of each call, the calls alternating within every repetition."""
    for f in calls.values():
        f()  # warm caches
    out = {k: [] for k in calls}
    for _ in range(repeats):
        for k, f in calls.items():
            t0 = clock()
            f()
            out[k].append(clock() - t0)
    return {k: np.array(v) for k, v in out.items()}


# ------------------------------------------------------------------------------------------------
# 1. locate vs plain detectMarkers
# ------------------------------------------------------------------------------------------------


def wall_map() -> MarkerMap:
    p = {}
    for r in range(3):
        for c in range(4):
            i = 4 * r + c
            p[i] = MarkerPlacement(i, (0.0, c * 400.0, 1800.0 - r * 400.0), (0.0, 0.0, 0.0))
    return MarkerMap(p, 150.0, DICT, "mm", source="speed benchmark wall")


def webcam(size) -> Camera:
    w, h = size
    f = 1371.0 * w / 1920
    return Camera(
        [[f, 0, (w - 1) / 2 + 1.3], [0, f, (h - 1) / 2 - 1.1], [0, 0, 1]], [-0.08, 0.05, 0.0003, -0.0002, -0.01], size
    )


def scenes() -> list:
    """(label, map, T_world_camera): the course's three 80 mm markers from 1.2 m, and twelve 150 mm markers
    from 2.7 m."""
    seed = MarkerMap.load(fidlearn.data_path("world_map.json"))
    return [
        ("3 markers (seed map), 1.2 m", seed, look_at([1200, -200, 300], [0, 190, 240], roll_deg=5)),
        ("12 markers, 2.7 m", wall_map(), look_at([2500, 700, 1300], [0, 600, 1400], roll_deg=5)),
    ]


def bench_locate(repeats: int) -> list:
    print("### 1. `fidlearn.locate` against a plain `detectMarkers` on the same frame\n")
    print(
        f"Two scenes ({DICT}, camera about 70 degrees wide, blur 0.6 px, noise 1.5): the course's three 80 mm "
        "markers from 1.2 m, and twelve 150 mm markers on a wall from 2.7 m. "
        f"{repeats} interleaved pairs per frame, in wall-clock time and again in CPU time. "
        "Ratio = median over the pairs of (locate time / plain time); the plain column is its median time.\n"
    )
    print(
        "| frame | scene | markers, side px | plain detectMarkers | "
        "locate / plain, wall clock | locate / plain, CPU time | found by plain / locate |"
    )
    print("|---|---|---|---|---|---|---|")
    results = []
    profiles = []
    for size in ((640, 480), (1280, 720), (1920, 1080)):
        cam = webcam(size)
        for label, m, T in scenes():
            image, truth = render_scene(m, cam, T, seed=1, blur_px=0.6, noise_std_gray=1.5, gradient=0.1)
            sides = [float(np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1).min()) for c in truth.values()]
            plain = plain_detector()
            calls = {"plain": lambda: plain.detectMarkers(image), "locate": lambda: fidlearn.locate(image, m, cam)}
            wall = interleaved(calls, repeats, time.perf_counter)
            cpu = interleaved(calls, repeats, time.process_time)
            r_wall = float(np.median(wall["locate"] / wall["plain"]))
            r_cpu = float(np.median(cpu["locate"] / np.maximum(cpu["plain"], 1e-6)))
            n_plain = len(_cv.detect(plain, image)[1])
            n_locate = len(fidlearn.locate(image, m, cam).marker_ids)
            print(
                f"| {size[0]}x{size[1]} | {label} | {len(truth)}, {min(sides):.0f}-{max(sides):.0f} | "
                f"{np.median(wall['plain']) * 1e3:.1f} ms | "
                f"{r_wall:.2f} x | {r_cpu:.2f} x | {n_plain} / {n_locate} |"
            )
            results.append((size, label, r_wall, r_cpu))
            profiles.append((size, label, image, cam, m))

    print(
        "\nWhere `locate`'s time goes: each step alone, CPU time (less disturbed by the load than wall clock), "
        "median over interleaved repetitions, and as % of the plain call:\n"
    )
    print("| step | " + " | ".join(f"{s[0]}x{s[1]}, {label.split(',')[0]}" for s, label, _, _, _ in profiles) + " |")
    print("|---|" + "---|" * len(profiles))
    rows: dict[str, list[str]] = {}
    for _size, _label, image, cam, m in profiles:
        gray = as_gray(image)
        detector, cells, _ = _detector(DICT, "edges", None)
        corners, ids, _ = _cv.detect(detector, gray)
        stacked = np.stack(corners)
        dets = detect_markers(image, DICT)
        plain = plain_detector()
        full_dict = _cv.get_dictionary(DICT)
        only_map = cv2.aruco.ArucoDetector(
            cv2.aruco.Dictionary(
                full_dict.bytesList[m.ids], int(full_dict.markerSize), int(full_dict.maxCorrectionBits)
            ),
            cv2.aruco.DetectorParameters(),
        )
        calls = {
            "plain detectMarkers (reference)": lambda: plain.detectMarkers(image),
            "detectMarkers with a dictionary of the map's markers only": lambda: only_map.detectMarkers(image),
            "as_gray": lambda: as_gray(image),
            "camera.for_image": lambda: cam.for_image(image),
            "OpenCV detection inside detect_markers": lambda: _cv.detect(detector, gray),
            "edge refinement (refine_corners_edges)": lambda: refine_corners_edges(gray, stacked, cells),
            "whole detect_markers": lambda: detect_markers(image, DICT),
            "estimate_pose": lambda: fidlearn.estimate_pose(dets, m, cam),
            "whole locate": lambda: fidlearn.locate(image, m, cam),
        }
        if "ids" in inspect.signature(detect_markers).parameters:  # detection that looks for the map's markers only
            calls["detect_markers(ids=map's ids) + estimate_pose"] = lambda: fidlearn.estimate_pose(
                detect_markers(image, DICT, ids=m.ids), m, cam
            )
        t = interleaved(calls, max(5, repeats // 2), time.process_time)
        base = t["plain detectMarkers (reference)"]
        for k, v in t.items():
            rows.setdefault(k, []).append(f"{np.median(v) * 1e3:.2f} ms ({100 * np.median(v / base):.1f} %)")
    for k, cells in rows.items():
        print(f"| {k} | " + " | ".join(cells) + " |")
    print(
        "\nOpenCV compares every candidate quad that is not a marker with all 1024 markers of ARUCO_ORIGINAL; with a "
        "dictionary of the map's markers only (what `MarkerTracker` uses) the same detection costs much less."
    )
    return results


# ------------------------------------------------------------------------------------------------
# 2. The tracker on a 1920x1080 video
# ------------------------------------------------------------------------------------------------


def hall_map() -> MarkerMap:
    """27 markers on the back wall (x = 0), 4 on a stand at x = 1.5 m, 6 on one at x = 2.5 m; 80 mm, facing +X.

    Heights keep the stands' markers out of the way of those behind them for the camera's path.
    """
    p = {}
    k = 0
    for r in range(3):
        for c in range(9):
            p[k] = MarkerPlacement(k, (0.0, c * 450.0 - 200.0, 2300.0 - r * 250.0), (0.0, 0.0, 0.0))
            k += 1
    for y in (300, 1300, 2300, 3300):
        p[k] = MarkerPlacement(k, (1500.0, float(y), 1250.0), (0.0, 0.0, 0.0))
        k += 1
    for y in (800, 1800, 2800):
        for z in (1000, 800):
            p[k] = MarkerPlacement(k, (2500.0, float(y), float(z)), (0.0, 0.0, 0.0))
            k += 1
    return MarkerMap(p, 80.0, DICT, "mm", source="tracking benchmark hall")


def walk_poses(n: int) -> list:
    """A camera walking 2.5 m toward the hall (62 mm per frame for 40 frames), panning, with a little roll."""
    out = []
    for s in np.linspace(0.0, 1.0, n):
        eye = [5600 - 2500 * s, 700 + 1300 * s + 150 * math.sin(3 * s), 1300 + 10 * math.sin(7 * s)]
        target = [0.0, 1300 + 400 * math.sin(2.5 * s), 1250 - 250 * s]
        out.append(look_at(eye, target, roll_deg=3 * math.sin(5 * s)))
    return out


def countable(truth: dict, cells: int, size) -> dict:
    """The true markers of 20 px or more (shortest side) whose white margin (one cell) is inside the frame too."""
    w, h = size
    out = {}
    for i, c in truth.items():
        side = float(np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1).min())
        margin = side / cells + 2.0
        if side >= 20 and c.min() >= margin and (c[:, 0] <= w - 1 - margin).all() and (c[:, 1] <= h - 1 - margin).all():
            out[i] = c
    return out


def _tracked(tracker: MarkerTracker, image: np.ndarray):
    """The tracker's pose for the frame, None when the frame has none (MarkerTracker.locate raises then)."""
    try:
        return tracker.locate(image)
    except (NoMarkersError, PoseError):
        return None


def bench_tracker(n_frames: int, passes: int) -> tuple:
    m = hall_map()
    cam = Camera(
        [[1371.0, 0, 961.3], [0, 1371.0, 538.2], [0, 0, 1]], [-0.08, 0.05, 0.0003, -0.0002, -0.01], (1920, 1080)
    )
    poses = walk_poses(n_frames)
    t0 = time.perf_counter()
    frames = [
        render_scene(m, cam, T, seed=i, blur_px=0.5, noise_std_gray=1.5, gradient=0.1, supersample=2)
        for i, T in enumerate(poses)
    ]
    render_s = time.perf_counter() - t0
    cells = _cv.dictionary_marker_bits(DICT) + 2
    truths = [countable(t, cells, cam.image_size) for _, t in frames]
    all_sides = [float(np.linalg.norm(c - np.roll(c, -1, axis=0), axis=1).min()) for _, t in frames for c in t.values()]
    n_true = sum(len(t) for t in truths)

    print("\n### 2. `MarkerTracker` on a 1920x1080 video against a plain `detectMarkers` per frame\n")
    print(
        f"{n_frames} frames of a camera walking 2.5 m toward {len(m)} markers of 80 mm (rendered in {render_s:.0f} s); "
        f"markers in view {min(all_sides):.0f} to {max(all_sides):.0f} px; {n_true} sightings of 20 px or more, "
        "whole with their margin inside the frame, count for the recall.\n"
    )

    plain = plain_detector()
    a3_settings = {
        "ArUco3, canonical 16 px, min 1 % of the frame": dict(
            useAruco3Detection=True, minSideLengthCanonicalImg=16, minMarkerLengthRatioOriginalImg=0.01
        ),
        "ArUco3, OpenCV's defaults (canonical 32 px)": dict(useAruco3Detection=True),
    }
    # speed: interleaved per frame, passes with a fresh tracker each
    wall = {"plain": [], "tracker": [], "locate": []}
    cpu = {"plain": [], "tracker": [], "locate": []}
    full = []
    for p in range(passes):
        tracker = MarkerTracker(m, cam)
        clock = time.process_time if p % 2 else time.perf_counter
        store = cpu if p % 2 else wall
        for image, _ in frames:
            t = clock()
            plain.detectMarkers(image)
            store["plain"].append(clock() - t)
            t = clock()
            _tracked(tracker, image)
            store["tracker"].append(clock() - t)
            t = clock()
            fidlearn.locate(image, m, cam)
            store["locate"].append(clock() - t)
        full.append(tracker.full_detections)
    over_locate = float(np.median(np.array(wall["locate"]) / np.array(wall["tracker"])))
    ratio_wall = float(np.median(np.array(wall["plain"]) / np.array(wall["tracker"])))
    ratio_wall_total = float(np.sum(wall["plain"]) / np.sum(wall["tracker"]))
    ratio_cpu = (
        float(np.median(np.array(cpu["plain"]) / np.maximum(np.array(cpu["tracker"]), 1e-6)))
        if cpu["plain"]
        else float("nan")
    )
    ratio_cpu_total = float(np.sum(cpu["plain"]) / np.sum(cpu["tracker"])) if cpu["plain"] else float("nan")

    # recall and accuracy (one more pass, untimed)
    tracker = MarkerTracker(m, cam)
    # the other way round: OpenCV's detector with fidlearn's defaults, the tracker with OpenCV's
    tracker_close = MarkerTracker(m, cam, detector_params=cv2.aruco.DetectorParameters())
    plain_close = plain_detector(**DEFAULT_DETECTOR_PARAMS)
    found_close = {"plain": 0, "tracker": 0}
    a3 = {k: plain_detector(**v) for k, v in a3_settings.items()}
    found = {"plain detectMarkers": 0, "detect_markers (fidlearn default)": 0, "MarkerTracker": 0} | {k: 0 for k in a3}
    of_plain = 0  # markers plain detectMarkers finds that the tracker finds too
    a3_time = {k: [] for k in a3}
    a3_plain = {k: [] for k in a3}
    corner_err, pose_err_tracker, pose_err_locate = [], [], []
    n_pose = 0
    for (image, _), truth, T in zip(frames, truths, poses):
        ids_plain = set(_cv.detect(plain, image)[1].tolist())
        full_dets = {d.id: d.corners_px for d in detect_markers(image, DICT)}
        pose = _tracked(tracker, image)
        ours = {d.id: d.corners_px for d in tracker.last_detections}
        found["plain detectMarkers"] += len(set(truth) & ids_plain)
        found["detect_markers (fidlearn default)"] += len(set(truth) & set(full_dets))
        found["MarkerTracker"] += len(set(truth) & set(ours))
        of_plain += len(set(truth) & ids_plain & set(ours))
        found_close["plain"] += len(set(truth) & set(_cv.detect(plain_close, image)[1].tolist()))
        _tracked(tracker_close, image)
        found_close["tracker"] += len(set(truth) & {d.id for d in tracker_close.last_detections})
        for k, det in a3.items():
            t = time.perf_counter()
            plain.detectMarkers(image)
            a3_plain[k].append(time.perf_counter() - t)
            t = time.perf_counter()
            _, ids, _ = _cv.detect(det, image)
            a3_time[k].append(time.perf_counter() - t)
            found[k] += len(set(truth) & set(ids.tolist()))
        corner_err += [np.linalg.norm(ours[i] - c, axis=1) for i, c in truth.items() if i in ours]
        if pose is not None:
            n_pose += 1
            pose_err_tracker.append(np.linalg.norm(pose.position_mm - T[:3, 3]))
            pose_err_locate.append(np.linalg.norm(fidlearn.locate(image, m, cam).position_mm - T[:3, 3]))
    rms = float(np.sqrt(np.mean(np.concatenate(corner_err) ** 2)))

    print("| detection | recall of markers >= 20 px | speed-up over plain detectMarkers |")
    print("|---|---|---|")
    print(f"| plain detectMarkers | {100 * found['plain detectMarkers'] / n_true:.2f} % | 1 |")
    print(
        "| detect_markers (fidlearn default, edges) | "
        f"{100 * found['detect_markers (fidlearn default)'] / n_true:.2f} % | - |"
    )
    print(
        f"| `fidlearn.locate` per frame (detection + pose) | as detect_markers | "
        f"{float(np.median(np.array(wall['plain']) / np.array(wall['locate']))):.2f} x wall clock; "
        f"the tracker is {over_locate:.2f} x faster than it |"
    )
    print(
        f"| **MarkerTracker.locate** (detection + pose) | {100 * found['MarkerTracker'] / n_true:.2f} % | "
        f"**{ratio_wall:.2f} x** wall clock (median per frame; {ratio_wall_total:.2f} x in total), "
        f"{ratio_cpu:.2f} x CPU time ({ratio_cpu_total:.2f} x in total) |"
    )
    print(
        "| plain detectMarkers with fidlearn's detector parameters (`DEFAULT_DETECTOR_PARAMS`) | "
        f"{100 * found_close['plain'] / n_true:.2f} % | - |"
    )
    print(
        "| MarkerTracker with OpenCV's parameters (`detector_params=cv2.aruco.DetectorParameters()`) | "
        f"{100 * found_close['tracker'] / n_true:.2f} % | - |"
    )
    for k in a3:
        r = float(np.median(np.array(a3_plain[k]) / np.array(a3_time[k])))
        print(f"| {k} (detection only) | {100 * found[k] / n_true:.2f} % | {r:.2f} x wall clock |")
    print(
        "\nOf the markers plain detectMarkers finds, the tracker finds "
        f"{100 * of_plain / max(found['plain detectMarkers'], 1):.2f} %. "
        "The markers that plain detectMarkers misses are whole and sharp, some well inside the frame: OpenCV's "
        "filter of candidates closer than `minMarkerDistanceRate` (0.125 of the perimeter) keeps another quad "
        "instead of the marker's outline (with a white margin of one cell the paper's edge is 0.05 of the perimeter "
        "away; opencv/opencv_contrib#2913), or a small marker's cells are misread at 4 pixels per cell; OpenCV 4.14 "
        "does the same. fidlearn's detector parameters ("
        + ", ".join(f"`{k}` {v}" for k, v in DEFAULT_DETECTOR_PARAMS.items())
        + ": the sweep of `bench_detection.py`), with its check that every decoded quad is its marker's outline, "
        "find them (rows above)."
    )
    print(
        f"\nThe tracker ran a full-frame detection on {', '.join(map(str, full))} of {n_frames} frames "
        "in the timed passes "
        f"(frame 0, every 30th, and where most markers went missing from their windows)."
    )
    print(
        f"Tracker corners against the truth: RMS {rms:.3f} px over {len(corner_err)} markers. Camera position error: "
        f"median {np.median(pose_err_tracker):.2f} mm with the tracker, "
        f"{np.median(pose_err_locate):.2f} mm with `fidlearn.locate` "
        f"on the same frames; a pose in {n_pose} of {n_frames} frames."
    )
    recall = found["MarkerTracker"] / n_true
    return (
        ratio_wall,
        ratio_cpu,
        recall,
        of_plain / max(found["plain detectMarkers"], 1),
        found["plain detectMarkers"] / n_true,
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions and frames")
    args = ap.parse_args(argv)
    repeats, n_frames, passes = (8, 16, 2) if args.quick else (30, 40, 3)
    t0 = time.perf_counter()
    print(
        f"OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), NumPy {np.__version__}, "
        f"Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n"
    )
    results = bench_locate(repeats)
    ratio_wall, ratio_cpu, recall, recall_of_plain, recall_plain = bench_tracker(n_frames, passes)
    print(f"\n({time.perf_counter() - t0:.0f} s)\n")
    for size in sorted({r[0] for r in results}):
        rows = [r for r in results if r[0] == size]
        worst = max(r[2] for r in rows)
        met = "yes" if worst <= 1.10 else ("within the 1.25 x limit" if worst <= 1.25 else "**no**")
        print(
            f"<!-- target: speed: `locate` <= 1.10 x plain detectMarkers at {size[0]}x{size[1]} (limit 1.25 x) | "
            + ", ".join(
                f"{label.split(',')[0]}: {r_wall:.2f} x ({r_cpu:.2f} x CPU)" for _, label, r_wall, r_cpu in rows
            )
            + f" | {met} -->"
        )
    print(
        f"<!-- target: video: MarkerTracker >= 2.5 x faster than plain detectMarkers at 1920x1080 | "
        f"{ratio_wall:.2f} x wall clock, {ratio_cpu:.2f} x CPU | {'yes' if ratio_wall >= 2.5 else '**no**'} -->"
    )
    met = "yes" if recall >= 0.995 else ("no, as plain detectMarkers" if recall >= recall_plain else "**no**")
    print(
        "<!-- target: video: MarkerTracker finds >= 99.5 % of markers of 20 px or more | "
        f"{100 * recall:.2f} % of the true markers "
        f"(plain detectMarkers {100 * recall_plain:.2f} %), "
        f"{100 * recall_of_plain:.2f} % of those plain detectMarkers finds | {met} -->"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
