"""Corner accuracy and cost of every corner refinement, on synthetic scenes with known corners.

Run from the repository (about 1-2 minutes on one core)::

    python benchmarks/bench_corners.py            # accuracy table + timing table
    python benchmarks/bench_corners.py --quick    # fewer scenes, for a smoke test

Accuracy: markers of a nominal side (15 to 150 px) on a wall, seen by a 640x480
camera from random oblique directions (up to 35 degrees) with a random roll, a
Gaussian blur of 0.5-1.0 px and noise of 1-2 gray levels
(:func:`fidlearn.synthetic.render_scene`, whose truth is ``cv2.projectPoints``
of the 3D corners). For each refinement: how many markers were found, the
corner RMS error, the 95th percentile, the mean radial offset (error along the
marker-centre-to-corner direction; negative means corners pulled inwards) and
the mean image-frame offset (dx, dy) which shows a constant shift.

Cost: :func:`fidlearn.detect_markers` per refinement, and ``fidlearn.pose.locate``
(detect with the default refinement + pose) when it exists, relative to a plain ``ArucoDetector.detectMarkers`` with
OpenCV's default parameters (no refinement) on the same gray image, at
640x480, 1280x720 and 1920x1080. Calls are interleaved; the table gives the
fastest of many repetitions (what the code costs when the machine is not busy)
and the median ratio of neighbouring calls.

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
from fidlearn import Camera, MarkerMap, MarkerPlacement, _cv
from fidlearn.detection import REFINE_METHODS, detect_markers
from fidlearn.synthetic import look_at, render_scene

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
    """One rendered scene whose markers are about ``side_px`` pixels wide; returns (image, truth)."""
    rng = np.random.default_rng(seed)
    cam = Camera.from_fov(60.0, image_size)
    w, h = image_size
    n_cols = max(1, min(3, int((w - 80) / (1.9 * side_px))))
    n_rows = max(1, min(2, int((h - 80) / (1.9 * side_px))))
    mm = grid_map(n_cols, n_rows, dictionary, first_id=int(rng.integers(0, 10)))
    centre = np.array([0.0, (n_cols - 1) * 0.875 * MARKER_MM + MARKER_MM / 2, 1000.0 - (n_rows - 1) * 0.875 * MARKER_MM - MARKER_MM / 2])
    dist = cam.fx * MARKER_MM / side_px  # [mm] distance giving the nominal side when seen head-on
    az, el = math.radians(rng.uniform(-35, 35)), math.radians(rng.uniform(-25, 25))
    eye = centre + dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    T = look_at(eye, centre, roll_deg=float(rng.uniform(0, 360)))
    blur = float(rng.uniform(0.5, 1.0)) if blur is None else blur
    noise = float(rng.uniform(1.0, 2.0)) if noise is None else noise
    return render_scene(cam, mm, T, seed=seed, blur_px=blur, noise_std=noise, gradient=0.2)


def accuracy(dictionary: str, n_scenes: int, methods) -> dict:
    rows = {}
    for side in SIDES_PX:
        errs = {m: [] for m in methods}
        found = {m: 0 for m in methods}
        truths = []
        visible = 0
        for s in range(n_scenes):
            image, truth = scene(side, 1000 * side + s, dictionary)
            visible += len(truth)
            per = {m: {d.id: d.corners for d in detect_markers(image, dictionary, refine=m)} for m in methods}
            common = [i for i in truth if all(i in per[m] for m in methods)]  # same markers for every method
            for m in methods:
                found[m] += sum(i in per[m] for i in truth)
                errs[m] += [per[m][i] - truth[i] for i in common]
            truths += [truth[i] for i in common]
        T = np.array(truths).reshape(-1, 4, 2)
        radial = T - T.mean(axis=1, keepdims=True)
        radial /= np.linalg.norm(radial, axis=2, keepdims=True)
        rows[side] = {}
        for m in methods:
            e = np.array(errs[m]).reshape(-1, 4, 2)
            if e.size == 0:
                rows[side][m] = None
                continue
            r = np.linalg.norm(e, axis=2)
            rows[side][m] = dict(
                found=found[m], visible=visible, n=len(e), rms=float(np.sqrt((r ** 2).mean())),
                p95=float(np.percentile(r, 95)), radial=float((e * radial).sum(2).mean()),
                dxdy=e.reshape(-1, 2).mean(axis=0),
            )
    return rows


def print_accuracy(rows, methods, dictionary):
    print(f"\nCorner error [px] vs truth, {dictionary}, 640x480, blur 0.5-1.0 px, noise 1-2 gray levels")
    print("cell: RMS / 95th percentile / mean radial offset (- = inwards); found/visible")
    head = f"| side px | " + " | ".join(methods) + " |"
    print(head)
    print("|" + "---|" * (len(methods) + 1))
    for side, per in rows.items():
        cells = []
        for m in methods:
            r = per[m]
            cells.append("-" if r is None else f"{r['rms']:.3f} / {r['p95']:.2f} / {r['radial']:+.2f}; {r['found']}/{r['visible']}")
        print(f"| {side} | " + " | ".join(cells) + " |")
    print("\nMean image-frame offset (dx, dy) [px] over all sides (a constant shift shows here):")
    for m in methods:
        d = np.concatenate([[per[m]["dxdy"]] for per in rows.values() if per[m] is not None]).mean(axis=0)
        print(f"  {m:9s} ({d[0]:+.3f}, {d[1]:+.3f})")


def timing(dictionary: str, methods, repeats: int) -> dict:
    out = {}
    try:
        from fidlearn.pose import locate
    except ImportError:  # the pose module is not there yet
        locate = None
    for size in ((640, 480), (1280, 720), (1920, 1080)):
        side = 60.0 * size[0] / 640
        image, truth = scene(side, 7, dictionary, image_size=size, blur=0.7, noise=1.5)
        plain = cv2.aruco.ArucoDetector(_cv.get_dictionary(dictionary), cv2.aruco.DetectorParameters())
        calls = {"plain detectMarkers": lambda: plain.detectMarkers(image)}
        for m in methods:
            calls[m] = (lambda m=m: detect_markers(image, dictionary, refine=m))
        if locate is not None:
            cam = Camera.from_fov(60.0, size)
            mm = grid_map(3, 2, dictionary)
            calls["locate (default)"] = lambda: locate(image, mm, cam)
        for f in calls.values():  # warm the caches
            f()
        samples = {k: [] for k in calls}
        for rep in range(repeats):
            for k, f in calls.items():
                if k == "apriltag" and rep >= 5:  # tens of times slower: a few calls tell
                    continue
                t0 = time.perf_counter()
                f()
                samples[k].append(time.perf_counter() - t0)
        base = np.array(samples["plain detectMarkers"])
        out[size] = {
            k: (float(np.min(v)) * 1e3, float(np.min(v) / base.min()), float(np.median(np.array(v) / base[: len(v)])))
            for k, v in samples.items()
        }
        out[size]["markers"] = len(truth)
    return out


def print_timing(t):
    print("\nCost: fastest time [ms], its ratio to the fastest plain detectMarkers (default parameters,")
    print("no refinement) and [the median of the ratios of interleaved calls]")
    sizes = list(t)
    keys = [k for k in t[sizes[0]] if k != "markers"]
    print("| call | " + " | ".join(f"{w}x{h} ({t[(w, h)]['markers']} markers)" for w, h in sizes) + " |")
    print("|" + "---|" * (len(sizes) + 1))
    for k in keys:
        print(f"| {k} | " + " | ".join(f"{t[s][k][0]:.2f} ms {t[s][k][1]:.2f}x [{t[s][k][2]:.2f}x]" for s in sizes) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dictionary", default="ARUCO_ORIGINAL")
    ap.add_argument("--scenes", type=int, default=6, help="scenes per marker side")
    ap.add_argument("--repeats", type=int, default=40, help="timing repetitions per call")
    ap.add_argument("--quick", action="store_true", help="2 scenes per side, 10 timing repetitions")
    args = ap.parse_args(argv)
    if args.quick:
        args.scenes, args.repeats = 2, 10
    methods = list(REFINE_METHODS)
    print(f"fidlearn {fidlearn.__version__}, OpenCV {cv2.__version__}, numpy {np.__version__}, "
          f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    t0 = time.perf_counter()
    print_accuracy(accuracy(args.dictionary, args.scenes, methods), methods, args.dictionary)
    print_timing(timing(args.dictionary, methods, args.repeats))
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
