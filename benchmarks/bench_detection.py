"""Detection: recall and speed of fidlearn's detection against a plain OpenCV detectMarkers, and the sweep of
OpenCV's detector parameters behind fidlearn's defaults.

    python benchmarks/bench_detection.py            # about 4 minutes on a loaded 2-core machine
    python benchmarks/bench_detection.py --quick    # fewer frames, rooms and repetitions

1. The sweep: OpenCV's detector with its defaults and with one or two parameters changed
   (``minMarkerDistanceRate``, ``adaptiveThreshWinSize*``, ``perspectiveRemovePixelPerCell``), and
   fidlearn's defaults (``fidlearn.detection.DEFAULT_DETECTOR_PARAMS``), on the tracking video of
   ``bench_speed.py`` (a camera walking toward 37 ARUCO_ORIGINAL markers, 1920x1080) and on rendered
   rooms (a wall of 1 to 12 markers of 80 or 150 mm seen from 0.5 to 4 m and up to 45 degrees off its
   axis, 640x480 to 1920x1080, blur 0.3-1 px) for ArUco dictionaries and AprilTag ones, walls of large
   markers, rooms in hard light and the bundled survey photos (``data/survey``, their rendered corners in
   ``poses.json``). Recall of the markers of 20 px or more (shortest side, whole with their white margin
   inside the frame), the false ids (not in the picture) and wrong corners (a true id more than 3 px off, or
   turned), and the CPU time against OpenCV's defaults (median of the per-frame ratios, the calls
   alternating). OpenCV's detector alone, and ``detect_markers(refine="none")``: the same parameters, then
   fidlearn's check that each quad is its marker's outline.
2. Speed: ``fidlearn.locate`` and ``detect_markers(ids=map's ids)`` (OpenCV's detection with fidlearn's
   defaults plus the ``edges`` refinement, what ``locate`` runs before ``estimate_pose``) against
   ``cv2.aruco.ArucoDetector(dictionary, DetectorParameters()).detectMarkers`` with the whole dictionary,
   for every dictionary family, 1 to 50 markers, 640x480 to 3840x2160, interleaved call by call, wall
   clock and CPU time of the same calls; the ratio is the median of the per-call ratios. The scaling is
   plotted in ``docs/img/detection_speed.png``.
3. Where ``locate``'s time goes with one marker at 640x480 (``locate_profile.py``): its stages beside a
   plain detection and OpenCV's own cheapest pose.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np
from bench_speed import countable, hall_map, walk_poses

import fidlearn
from fidlearn import Camera, MarkerMap, MarkerPlacement, _cv
from fidlearn.detection import (
    DEFAULT_DETECTOR_PARAMS,
    _detector,
    as_gray,
    detect_markers,
    load_image,
    refine_corners_edges,
)
from fidlearn.frames import look_at
from fidlearn.synthetic import render_scene

ROOT = Path(__file__).resolve().parents[1]
PLOT = ROOT / "docs" / "img" / "detection_speed.png"
ARUCO = ("ARUCO_ORIGINAL", "4X4_50", "5X5_100", "6X6_250", "7X7_1000")
APRILTAG = ("APRILTAG_16h5", "APRILTAG_25h9", "APRILTAG_36h10", "APRILTAG_36h11")
SIZES = ((640, 480), (1280, 720), (1920, 1080), (3840, 2160))

SETTINGS = {
    "OpenCV's defaults": {},
    "minMarkerDistanceRate 0.05": {"minMarkerDistanceRate": 0.05},
    "adaptiveThreshWinSize 3, 13 (max 13)": {"adaptiveThreshWinSizeMax": 13},
    "adaptiveThreshWinSize 3, 23 (step 20)": {"adaptiveThreshWinSizeStep": 20},
    "perspectiveRemovePixelPerCell 2": {"perspectiveRemovePixelPerCell": 2},
    "perspectiveRemovePixelPerCell 6": {"perspectiveRemovePixelPerCell": 6},
    "perspectiveRemovePixelPerCell 8": {"perspectiveRemovePixelPerCell": 8},
    "minMarkerDistanceRate 0.05, perspectiveRemovePixelPerCell 8": {
        "minMarkerDistanceRate": 0.05,
        "perspectiveRemovePixelPerCell": 8,
    },
    "the same, perspectiveRemovePixelPerCell 6, windows 3, 23": {
        "minMarkerDistanceRate": 0.05,
        "perspectiveRemovePixelPerCell": 6,
        "adaptiveThreshWinSizeStep": 20,
    },
    "the same, perspectiveRemovePixelPerCell 8, windows 3, 23, minMarkerDistanceRate 0.065": {
        "minMarkerDistanceRate": 0.065,
        "perspectiveRemovePixelPerCell": 8,
        "adaptiveThreshWinSizeStep": 20,
    },
    "the same, perspectiveRemovePixelPerCell 8, window 23 only": {
        "minMarkerDistanceRate": 0.05,
        "perspectiveRemovePixelPerCell": 8,
        "adaptiveThreshWinSizeMin": 23,
        "adaptiveThreshWinSizeMax": 23,
    },
}
#: Settings run through ``detect_markers(refine="none")``: OpenCV's detection, then fidlearn's check that each
#: quad is its marker's outline (its four edges fitted within half a cell), which drops the rest.
CHECKED = {
    "OpenCV's defaults + outline check": {},
    "perspectiveRemovePixelPerCell 8 + outline check": {"perspectiveRemovePixelPerCell": 8},
    "perspectiveRemovePixelPerCell 8, windows 3, 23, minMarkerDistanceRate 0.05 + outline check": {
        "minMarkerDistanceRate": 0.05,
        "perspectiveRemovePixelPerCell": 8,
        "adaptiveThreshWinSizeStep": 20,
    },
    "perspectiveRemovePixelPerCell 8, windows 3, 23, minMarkerDistanceRate 0.06 + outline check": {
        "minMarkerDistanceRate": 0.06,
        "perspectiveRemovePixelPerCell": 8,
        "adaptiveThreshWinSizeStep": 20,
    },
}


def detector(dictionary: str, overrides: dict):
    params = cv2.aruco.DetectorParameters()
    for k, v in overrides.items():
        setattr(params, k, v)
    return cv2.aruco.ArucoDetector(_cv.get_dictionary(dictionary), params)


def timed(f):
    """(result, wall s, CPU s) of one call."""
    w, c = time.perf_counter(), time.process_time()
    out = f()
    return out, time.perf_counter() - w, time.process_time() - c


# ------------------------------------------------------------------------------------------------
# Scenes: the tracking video and rendered rooms
# ------------------------------------------------------------------------------------------------


def video_frames(n: int) -> list:
    """(dictionary, gray, countable truth, size) of the tracking video's frames (every one of ``n``)."""
    m = hall_map()
    cam = Camera(
        [[1371.0, 0, 961.3], [0, 1371.0, 538.2], [0, 0, 1]], [-0.08, 0.05, 0.0003, -0.0002, -0.01], (1920, 1080)
    )
    cells = _cv.dictionary_marker_bits(m.dictionary) + 2
    out = []
    for i, T in enumerate(walk_poses(n)):
        scene = render_scene(m, cam, T, seed=i, blur_px=0.5, noise_std_gray=1.5, gradient=0.1, supersample=2)
        image, truth = scene.image, scene.truth
        out.append((m.dictionary, image, truth, countable(truth, cells, cam.image_size)))
    return out


def room(rng: np.random.Generator, dictionary: str, k: int, hard: bool = False):
    """One rendered room: (dictionary, gray, truth, countable truth); ``hard``: more blur, noise and uneven light."""
    n = int(rng.integers(1, 13))
    side = float(rng.choice([80.0, 150.0]))
    cols = int(math.ceil(math.sqrt(n)))
    ids = rng.choice(_cv.dictionary_size(dictionary), size=n, replace=False)
    pitch = 2.5 * side
    places = {
        int(i): MarkerPlacement(int(i), (0.0, (j % cols) * pitch, 1500.0 - (j // cols) * pitch), (0.0, 0.0, 0.0))
        for j, i in enumerate(ids)
    }
    m = MarkerMap(places, side, dictionary=dictionary, units="mm", source="detection benchmark room")
    size = SIZES[k % 3]
    cam = Camera.from_fov(60, size)
    centre = np.array([0.0, (cols - 1) * pitch / 2, 1500.0 - ((n - 1) // cols) * pitch / 2])
    dist = rng.uniform(500.0, 4000.0) * (side / 150.0) ** 0.5
    yaw, pitch_deg = math.radians(rng.uniform(-45, 45)), math.radians(rng.uniform(-20, 20))
    eye = centre + dist * np.array([math.cos(yaw) * math.cos(pitch_deg), math.sin(yaw), math.sin(pitch_deg)])
    T = look_at(eye, centre + rng.normal(0, 0.1 * side, 3), roll_deg=rng.uniform(-10, 10))
    blur = rng.uniform(0.5, 1.8) if hard else rng.uniform(0.3, 1.0)
    light = dict(noise_std_gray=3.0, gradient=0.35) if hard else dict(noise_std_gray=1.5, gradient=0.1)
    scene = render_scene(m, cam, T, seed=k, blur_px=blur, supersample=2, **light)
    image, truth = scene.image, scene.truth
    cells = _cv.dictionary_marker_bits(dictionary) + 2
    return dictionary, image, truth, countable(truth, cells, size)


def big_walls() -> list:
    """Walls of 3 to 50 markers of 100 to 300 px (the speed section's scenes at 1920x1080 and 3840x2160)."""
    out = []
    for d in ("ARUCO_ORIGINAL", "4X4_50", "6X6_250", "APRILTAG_36h11"):
        for n, size in ((3, SIZES[2]), (12, SIZES[3]), (50, SIZES[3])):
            _, _, image, truth = wall_scene(d, n, size)
            out.append((d, image, truth, countable(truth, _cv.dictionary_marker_bits(d) + 2, size)))
    return out


def survey_photos() -> list:
    """The bundled survey photos (``data/survey``, 1280x720 JPEG, ARUCO_ORIGINAL) with their rendered corners."""
    folder = fidlearn.data_path("survey")
    record = json.loads((folder / "poses.json").read_text())
    out = []
    for ph in record["photos"]:
        image = as_gray(load_image(folder / ph["image"]))
        truth = {int(i): np.asarray(c, dtype=np.float64) for i, c in ph["corners_px"].items()}
        size = (image.shape[1], image.shape[0])
        out.append(
            ("ARUCO_ORIGINAL", image, truth, countable(truth, _cv.dictionary_marker_bits("ARUCO_ORIGINAL") + 2, size))
        )
    return out


def rooms(n_per_dict: int, dictionaries, seed: int, hard: bool = False) -> list:
    rng = np.random.default_rng(seed)
    return [room(rng, d, k, hard) for d in dictionaries for k in range(n_per_dict)]


# ------------------------------------------------------------------------------------------------
# 1. The sweep
# ------------------------------------------------------------------------------------------------


def score(corners, ids, truth: dict, counted: dict) -> tuple[int, int, int]:
    """(true markers found among ``counted``, ids not in the picture, true ids with corners more than 3 px off:
    out of place or turned)."""
    found, false, wrong = 0, 0, 0
    for c, i in zip(corners, np.asarray(ids).tolist()):
        t = truth.get(int(i))
        if t is None:
            false += 1
        elif np.abs(c - t).max() > 3.0:
            wrong += 1
        elif int(i) in counted:
            found += 1
    return found, false, wrong


def checked(dictionary: str, overrides: dict):
    """fidlearn's detection without refinement (OpenCV's corners, the outline check) as ``(corners, ids)``, with
    OpenCV's defaults changed by ``overrides``; None: fidlearn's defaults."""
    params = None
    if overrides is not None:  # over OpenCV's defaults, not fidlearn's: a whole DetectorParameters object
        params = cv2.aruco.DetectorParameters()
        for k, v in overrides.items():
            setattr(params, k, v)

    def run(gray):
        dets = detect_markers(gray, dictionary, refine="none", detector_params=params)
        return [d.corners_px for d in dets], np.array([d.id for d in dets], dtype=np.int64)

    return run


def sweep(groups: dict) -> dict:
    """Per setting and group: found, counted, false detections, CPU ratios against OpenCV's defaults.

    On each frame OpenCV's defaults run first and last, every setting once between them; a setting's
    ratio is its time over the mean of the two default runs on the same frame."""
    settings = {**SETTINGS, **CHECKED, "fidlearn's defaults": None}
    res = {s: {g: [0, 0, 0, 0, []] for g in groups} for s in settings}
    for g, frames in groups.items():
        for k, (dictionary, image, truth, counted) in enumerate(frames):
            gray = as_gray(image)
            base = detector(dictionary, {})
            dets = {s: detector(dictionary, over).detectMarkers for s, over in SETTINGS.items()}
            dets.update({s: checked(dictionary, over) for s, over in CHECKED.items()})
            dets["fidlearn's defaults"] = checked(dictionary, None)
            order = list(settings) if k % 2 else list(settings)[::-1]
            _, _, t0 = timed(lambda: base.detectMarkers(gray))  # noqa: B023
            out = {s: timed(lambda: dets[s](gray)) for s in order}  # noqa: B023
            _, _, t1 = timed(lambda: base.detectMarkers(gray))  # noqa: B023
            for s, (found_, _, t) in out.items():
                corners, ids = found_[0], found_[1]
                corners = [np.asarray(c, dtype=np.float64).reshape(4, 2) for c in corners]
                ids = np.asarray(ids if ids is not None else [], dtype=np.int64).ravel()
                r = res[s][g]
                for j, v in enumerate(score(corners, ids, truth, counted)):
                    r[j if j == 0 else j + 1] += v
                r[1] += len(counted)
                r[4].append(t / max(0.5 * (t0 + t1), 1e-6))
    return res


def print_sweep(res: dict, groups: dict) -> dict:
    head = " | ".join(f"recall, {g}" for g in groups)
    print(f"| detector parameters | {head} | false ids | wrong corners | CPU time / OpenCV's defaults |")
    print("|---|" + "---|" * len(groups) + "---|---|---|")
    summary = {}
    for s, per in res.items():
        cells = [f"{100 * r[0] / max(r[1], 1):.2f} % of {r[1]}" for r in per.values()]
        ratio = float(np.median(np.concatenate([r[4] for r in per.values()])))
        false, wrong = sum(r[2] for r in per.values()), sum(r[3] for r in per.values())
        name = f"**{s}**" if s == "fidlearn's defaults" else s
        print(f"| {name} | " + " | ".join(cells) + f" | {false} | {wrong} | {ratio:.2f} x |")
        summary[s] = ({g: r[0] / max(r[1], 1) for g, r in per.items()}, false + wrong, ratio)
    return summary


# ------------------------------------------------------------------------------------------------
# 2. Speed: every family, 1 to 50 markers, 640x480 to 3840x2160
# ------------------------------------------------------------------------------------------------


def wall_scene(dictionary: str, n: int, size):
    """(map, camera, image, true corners): ``n`` markers of 180 mm, 300 mm apart, in a grid of 16:9, seen from
    the front."""
    n = min(n, _cv.dictionary_size(dictionary))
    cols = int(math.ceil(math.sqrt(n * 16 / 9)))
    rows = int(math.ceil(n / cols))
    step = max(1, _cv.dictionary_size(dictionary) // n)
    places = {}
    for j in range(n):
        i = j * step
        places[i] = MarkerPlacement(i, (0.0, (j % cols) * 300.0, 2000.0 - (j // cols) * 300.0), (0.0, 0.0, 0.0))
    m = MarkerMap(places, 180.0, dictionary=dictionary, units="mm", source="detection benchmark wall")
    w, h = size
    f = 1371.0 * w / 1920  # about 70 degrees wide
    cam = Camera([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]], [-0.08, 0.05, 0.0, 0.0, 0.0], size)
    centre = np.array([0.0, (cols - 1) * 150.0, 2000.0 - (rows - 1) * 150.0])
    dist = max(1500.0, cols * 300.0 / 0.95)
    T = look_at(centre + [dist, 0.15 * dist, 0.08 * dist], centre, roll_deg=5)
    scene = render_scene(m, cam, T, seed=n, blur_px=0.6, noise_std_gray=1.5, gradient=0.1, supersample=1)
    image, truth = scene.image, scene.truth
    return m, cam, image, truth


def speed_case(dictionary: str, n: int, size, repeats: int) -> dict:
    m, cam, image, _ = wall_scene(dictionary, n, size)
    plain = detector(dictionary, {})
    ids = m.ids
    dets = detect_markers(image, dictionary, ids=ids)
    gray = as_gray(image)
    det, cells, _ = _detector(_cv.dictionary_name(dictionary), "edges", None, tuple(sorted(ids)))
    raw, _, _ = _cv.detect(det, gray)
    stacked = np.stack(raw) if raw else np.zeros((0, 4, 2))
    calls = {
        "plain": lambda: plain.detectMarkers(image),
        "detect": lambda: detect_markers(image, dictionary, ids=ids),
        "locate": lambda: fidlearn.locate(image, m, cam),
        "refine": lambda: refine_corners_edges(gray, stacked, cells),
    }
    for f in calls.values():
        f()
    wall = {k: [] for k in calls}
    cpu = {k: [] for k in calls}
    for _ in range(repeats):
        for k, f in calls.items():
            _, w, c = timed(f)
            wall[k].append(w)
            cpu[k].append(c)
    wall = {k: np.array(v) for k, v in wall.items()}
    cpu = {k: np.maximum(np.array(v), 1e-6) for k, v in cpu.items()}
    return dict(
        dictionary=dictionary,
        n=len(m),
        size=size,
        plain_ms=1e3 * float(np.median(wall["plain"])),
        plain_cpu_ms=1e3 * float(np.median(cpu["plain"])),
        locate_cpu_ms=1e3 * float(np.median(cpu["locate"])),
        detect_cpu_ms=1e3 * float(np.median(cpu["detect"])),
        refine_ms=1e3 * float(np.median(wall["refine"])),
        **{f"{k}_wall": float(np.median(wall[k] / wall["plain"])) for k in ("detect", "locate")},
        **{f"{k}_cpu": float(np.median(cpu[k] / cpu["plain"])) for k in ("detect", "locate")},
        found=(len(_cv.detect(plain, gray)[1]), len(dets)),
    )


def speed_cases(quick: bool) -> list:
    cases = []
    for d in ("ARUCO_ORIGINAL", "APRILTAG_36h11"):
        cases += [(d, n, s) for n in (1, 3, 12, 50) for s in SIZES]
    for d in ARUCO[1:] + APRILTAG[:-1]:
        cases += [(d, n, s) for n in (1, 50) for s in (SIZES[0], SIZES[-1])]
    out = []
    for d, n, s in cases:
        repeats = (3 if quick else 6) if s[0] > 2000 else (6 if quick else 14)
        out.append(speed_case(d, n, s, repeats))
    return out


def print_speed(rows: list) -> None:
    print(
        "| dictionary | markers | image | plain detectMarkers | detect_markers / plain, wall (CPU) | "
        "**locate / plain**, wall (CPU) | edges refinement alone | found by plain / fidlearn |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        w, h = r["size"]
        print(
            f"| {r['dictionary']} | {r['n']} | {w}x{h} | {r['plain_ms']:.1f} ms | "
            f"{r['detect_wall']:.2f} x ({r['detect_cpu']:.2f} x) | "
            f"**{r['locate_wall']:.2f} x** ({r['locate_cpu']:.2f} x) | "
            f"{r['refine_ms']:.2f} ms | {r['found'][0]} / {r['found'][1]} |"
        )


def exponents(rows: list) -> None:
    """How the CPU time grows with the pixels: the slope of log time against log pixels, 640x480 to 3840x2160."""
    print("\nCPU time against the number of pixels, fitted as time ~ pixels^k over the four image sizes:\n")
    print("| dictionary | markers | k, plain detectMarkers | k, detect_markers | k, locate |")
    print("|---|---|---|---|---|")
    for d in ("ARUCO_ORIGINAL", "APRILTAG_36h11"):
        for n in sorted({r["n"] for r in rows if r["dictionary"] == d}):
            sel = sorted((r for r in rows if r["dictionary"] == d and r["n"] == n), key=lambda r: r["size"][0])
            px = np.log([r["size"][0] * r["size"][1] for r in sel])
            k = [np.polyfit(px, np.log([r[f"{c}_cpu_ms"] for r in sel]), 1)[0] for c in ("plain", "detect", "locate")]
            print(f"| {d} | {n} | {k[0]:.2f} | {k[1]:.2f} | {k[2]:.2f} |")


def plot(rows: list) -> None:
    import matplotlib  # noqa: PLC0415 (only the plot needs it)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    import matplotlib.ticker  # noqa: PLC0415

    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    styles = {"plain": ("plain detectMarkers", "-"), "detect": ("detect_markers", ":"), "locate": ("locate", "--")}
    for ax, d in zip(axes[:2], ("ARUCO_ORIGINAL", "APRILTAG_36h11")):
        for n, colour in zip((1, 3, 12, 50), ("C0", "C1", "C2", "C3")):
            sel = sorted((r for r in rows if r["dictionary"] == d and r["n"] == n), key=lambda r: r["size"][0])
            mp = [r["size"][0] * r["size"][1] / 1e6 for r in sel]
            for key, (label, ls) in styles.items():
                ax.plot(
                    mp, [r[f"{key}_cpu_ms"] for r in sel], ls, color=colour, marker="o", ms=3, label=f"{label}, {n}"
                )
        ax.set(xscale="log", yscale="log", xlabel="image size", ylabel="CPU time per frame (ms)", title=d)
        ax.set_xticks([w * h / 1e6 for w, h in SIZES], [f"{w}x{h}" for w, h in SIZES], fontsize=7)
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=6, ncol=2)
    for d, colour in zip(("ARUCO_ORIGINAL", "APRILTAG_36h11"), ("C0", "C3")):
        sel = sorted((r for r in rows if r["dictionary"] == d and r["size"] == (1920, 1080)), key=lambda r: r["n"])
        for key, (label, ls) in styles.items():
            axes[2].plot(
                [r["n"] for r in sel],
                [r[f"{key}_cpu_ms"] for r in sel],
                ls,
                color=colour,
                marker="o",
                label=f"{d}, {label}",
            )
    axes[2].set(xscale="log", xlabel="markers in view", ylabel="CPU time per frame (ms)", title="1920x1080")
    axes[2].grid(True, which="both", alpha=0.3)
    axes[2].legend(fontsize=6)
    fig.tight_layout()
    PLOT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(PLOT, dpi=110)
    print(f"\n![locate and plain detection against image size and marker count](img/{PLOT.name})\n")


# ------------------------------------------------------------------------------------------------
# Main
# ------------------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer frames, rooms and repetitions")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(
        f"OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(f"fidlearn's detector parameters: {dict(DEFAULT_DETECTOR_PARAMS)} over OpenCV's defaults.\n")
    n_video, n_rooms = (12, 4) if args.quick else (24, 8)
    groups = {
        "video (ARUCO_ORIGINAL)": video_frames(n_video),
        "rooms, ArUco": rooms(n_rooms, ARUCO, 5),
        "rooms, AprilTag": rooms(n_rooms, APRILTAG, 6),
        "walls, large markers": big_walls(),
        "rooms, hard light": rooms(max(2, n_rooms // 2), ("ARUCO_ORIGINAL", "6X6_250", "APRILTAG_36h11"), 7, hard=True),
        "survey photos": survey_photos(),
    }
    print("### 1. Detector parameters: recall, false detections and time\n")
    print(
        f"Markers of 20 px or more: the tracking video ({n_video} frames, 1920x1080), rendered rooms "
        f"({n_rooms} per dictionary: {', '.join(ARUCO)}; {', '.join(APRILTAG)}), whole dictionaries. "
        "Large markers: the walls of section 2 at 1920x1080 (3 markers) and 3840x2160 (12 and 50), ARUCO_ORIGINAL, "
        "4X4_50, 6X6_250, APRILTAG_36h11. Hard light: blur 0.5-1.8 px, noise 3 gray levels, a 35 % light "
        "gradient (ARUCO_ORIGINAL, 6X6_250, "
        "APRILTAG_36h11). Survey photos: the 24 bundled JPEG photos of `data/survey` (1280x720, ARUCO_ORIGINAL), "
        "their rendered corners from `poses.json`. False ids: an id not in the picture; wrong corners: a true id "
        "whose corners are more than 3 px off (out of place, or turned: corners are compared in order), on every "
        'set. The rows marked + outline check run `detect_markers(refine="none")`: OpenCV\'s detection with those '
        "parameters, then fidlearn's check that each quad is its marker's outline (the four outer edges fitted, "
        "a dark border inside a light surround, no farther from the quad than the profiles reach: "
        "max(3 px, half a cell, sqrt(2) (their half-length + 0.5 px))), which drops the rest; "
        "their time includes the check. "
        "Time: CPU time of the whole-dictionary detection over OpenCV's defaults on the same frame (run "
        "before and after every setting), median over all frames.\n"
    )
    summary = print_sweep(sweep(groups), groups)
    print(f"\n({time.perf_counter() - t0:.0f} s so far)\n")
    print("### 2. Speed: `locate` and `detect_markers` against a plain `detectMarkers`\n")
    print(
        "A wall of markers of 180 mm seen from the front (70 degree camera, blur 0.6 px, noise 1.5); "
        "plain: `ArucoDetector(dictionary, DetectorParameters()).detectMarkers(image)` with the whole "
        "dictionary; `detect_markers(image, dictionary, ids=map's ids)` with fidlearn's defaults and the "
        "edges refinement (what `locate` runs before `estimate_pose`); `locate(image, map, camera)`. "
        "The four calls alternate; ratio = median over the repetitions of (fidlearn / plain), "
        "wall clock and, in brackets, CPU time of the same calls.\n"
    )
    rows = speed_cases(args.quick)
    print_speed(rows)
    exponents(rows)
    plot(rows)
    print(f"({time.perf_counter() - t0:.0f} s so far)\n")
    print("### 3. Where `locate`'s time goes with one marker at 640x480\n")
    print(
        "The stages of `locate` for the one-marker wall of section 2 at 640x480, and OpenCV's own cheapest pose "
        "(`solvePnP` IPPE_SQUARE + `solvePnPRefineLM` on the plain detection's corners), CPU time, the calls "
        "interleaved, median over the repetitions (`benchmarks/locate_profile.py`).\n"
    )
    import locate_profile  # (it builds on this module's scenes)

    locate_profile.report(repeats=60 if args.quick else 200)
    print(f"({time.perf_counter() - t0:.0f} s)\n")
    targets(summary, rows)
    return 0


def targets(summary: dict, rows: list) -> None:
    recall, false, ratio = summary["fidlearn's defaults"]
    low = min(v for g, v in recall.items() if g.startswith(("video", "rooms, ArUco", "rooms, AprilTag")))
    base = summary["OpenCV's defaults"][0]
    print(
        "<!-- target: detection: recall >= 99.5 % of markers >= 20 px on the video and rooms (ArUco, AprilTag), "
        "at least OpenCV's everywhere (large markers, hard light, survey photos too), no false id or wrong corners, "
        "at <= 1.10 x | "
        + ", ".join(f"{g} {100 * v:.2f} % (OpenCV's defaults {100 * base[g]:.2f} %)" for g, v in recall.items())
        + f"; {false} false ids or wrong corners; {ratio:.2f} x CPU | "
        + (
            "yes"
            if low >= 0.995 and ratio <= 1.10 and not false and all(v >= base[g] for g, v in recall.items())
            else "**no**"
        )
        + " -->"
    )
    for key, what in (("locate", "`locate`"), ("detect", "`detect_markers(ids=...)` (detection + edges refinement)")):
        worst = max(rows, key=lambda r: r[f"{key}_wall"])
        within = sum(r[f"{key}_wall"] <= 1.10 for r in rows)
        w, h = worst["size"]
        print(
            f"<!-- target: detection: {what} <= 1.10 x plain detectMarkers, every family, 1-50 markers, "
            f"640x480-3840x2160 | {within} of {len(rows)} cases; worst {worst[f'{key}_wall']:.2f} x "
            f"({worst[f'{key}_cpu']:.2f} x CPU), {worst['dictionary']}, {worst['n']} markers, {w}x{h} | "
            f"{'yes' if within == len(rows) else '**no**'} -->"
        )


if __name__ == "__main__":
    raise SystemExit(main())
