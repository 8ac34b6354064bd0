"""Where the time of ``locate`` goes with one marker in a small picture: the stages side by side with a
plain ``detectMarkers`` and with OpenCV's own cheapest pose, CPU time, interleaved call by call.

    python benchmarks/locate_profile.py        # (also printed by bench_detection.py, section 3)

``locate`` = fidlearn's detection (map-only dictionary, fidlearn's detector parameters and checks) +
the ``edges`` refinement + ``estimate_pose``. The last two cost a fixed few tenths of a millisecond
whatever the picture, which is more than 10 % of a plain detection of one marker at 640x480.
"""

from __future__ import annotations

import time

import cv2
import numpy as np
from bench_detection import detector, wall_scene

import fidlearn
from fidlearn import _cv
from fidlearn.detection import _detector, as_gray, detect_markers, refine_corners_edges


def stages(dictionary: str, size=(640, 480), repeats: int = 200) -> dict:
    """Median CPU ms of each stage for a wall of one 180 mm marker (``bench_detection.wall_scene``)."""
    m, cam, image, _ = wall_scene(dictionary, 1, size)
    cam = cam.for_image(image)
    plain = detector(dictionary, {})
    gray = as_gray(image)
    ids = m.ids
    det, cells, _ = _detector(_cv.dictionary_name(dictionary), "edges", None, tuple(sorted(ids)))
    raw, _, _ = _cv.detect(det, gray)
    stacked = np.stack(raw)
    dets = detect_markers(image, dictionary, ids=ids)
    s = m.marker_size_mm
    obj = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0], [-s / 2, -s / 2, 0]])
    px = np.asarray(plain.detectMarkers(image)[0][0], float).reshape(4, 2)

    def opencv_pose():
        _, rvec, tvec = cv2.solvePnP(obj, px, cam.K, cam.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        return cv2.solvePnPRefineLM(obj, px, cam.K, cam.dist, rvec, tvec)

    calls = {
        "plain detectMarkers (whole dictionary, OpenCV's defaults)": lambda: plain.detectMarkers(image),
        "fidlearn's detection without refinement (map's ids, its defaults and checks)": lambda: detect_markers(
            image, dictionary, ids=ids, refine="none"
        ),
        "edges refinement of the marker": lambda: refine_corners_edges(gray, stacked, cells),
        "estimate_pose (both planar solutions by LM, flip test, covariance)": lambda: fidlearn.estimate_pose(
            dets, m, cam
        ),
        "locate (all of it)": lambda: fidlearn.locate(image, m, cam),
        "OpenCV's own pose: solvePnP IPPE_SQUARE + solvePnPRefineLM": opencv_pose,
    }
    for f in calls.values():
        f()
    cpu = {k: [] for k in calls}
    for _ in range(repeats):
        for k, f in calls.items():
            t0 = time.process_time()
            f()
            cpu[k].append(time.process_time() - t0)
    return {k: 1e3 * float(np.median(v)) for k, v in cpu.items()}


def report(dictionaries=("ARUCO_ORIGINAL", "4X4_50", "APRILTAG_36h11"), repeats: int = 200) -> None:
    """Print the stages' table, one column per dictionary (ms, and / plain in brackets)."""
    cols = {d: stages(d, repeats=repeats) for d in dictionaries}
    names = list(next(iter(cols.values())))
    print("| stage, 1 marker, 640x480, CPU time | " + " | ".join(dictionaries) + " |")
    print("|---" * (len(dictionaries) + 1) + "|")
    for name in names:
        cells = []
        for d in dictionaries:
            c = cols[d]
            base = c[names[0]]
            cells.append(f"{c[name]:.3f} ms ({c[name] / base:.2f} x)")
        print(f"| {name} | " + " | ".join(cells) + " |")
    fixed = [cols[d][names[2]] + cols[d][names[3]] for d in dictionaries]
    plain = [cols[d][names[0]] for d in dictionaries]
    print(
        f"\nThe refinement and the pose cost {min(fixed):.2f}-{max(fixed):.2f} ms whatever the picture; a plain "
        f"detection of one marker at 640x480 takes {min(plain):.2f}-{max(plain):.2f} ms, so `locate` is within "
        f"1.10 x only where the plain detection takes about ten times their cost (from 1280x720 up, or with "
        f"many candidates to compare).\n"
    )


if __name__ == "__main__":
    report()
