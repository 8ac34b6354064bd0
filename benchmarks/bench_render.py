"""How long the synthetic renderer takes per frame (fidlearn.synthetic).

Run from the repository (well under a minute)::

    python benchmarks/bench_render.py            # the table
    python benchmarks/bench_render.py --quick    # fewer repetitions

Cases: the seed's three 80 mm markers seen by an HD webcam (1280x720, mild
barrel distortion) from 1.2 m and from 0.4 m, the same at 640x480, a sheet
that crosses the camera's plane (every pixel must be tested: the worst case),
one 640x480 checkerboard calibration view, and a 640x480 frame of the
robot's drive. All at ``supersample=4`` with blur, gradient and noise on.

"first" is the first frame of a new camera, which also builds the camera's
ray map (undistortion of every pixel, cached per camera); "per frame" is the
fastest and the median of the following frames. The fastest is what the code
costs on an idle machine; the median shows the load of a shared one.
"""

from __future__ import annotations

import argparse
import platform
import time

import cv2
import numpy as np

from fidlearn import Camera, MarkerMap, data_path
from fidlearn.frames import look_at
from fidlearn.synthetic import render_calibration_views, render_scene, trajectory_poses
from fidlearn.synthetic._rays import _normalized_map_cached

RENDER = dict(blur_px=0.5, noise_std_gray=1.5, gradient=0.2, supersample=4)


def webcam(size) -> Camera:
    """About 67 degrees wide, mild barrel distortion (the camera of data/scenes at 1280x720)."""
    w, h = size
    f = 962.5 * w / 1280
    return Camera(
        [[f, 0, (w - 1) / 2 + 1.3], [0, f, (h - 1) / 2 - 1.6], [0, 0, 1]], [-0.06, 0.045, 0.0003, -0.0002, -0.01], size
    )


def timed(fn, repeats: int) -> tuple[float, float, float]:
    """Seconds of the first call (cold ray map), and the fastest and median of ``repeats`` more."""
    _normalized_map_cached.cache_clear()
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return first, min(times), float(np.median(times))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 repetitions instead of 5")
    args = parser.parse_args(argv)
    repeats = 2 if args.quick else 5
    wall = MarkerMap.load(data_path("world_map.json"))
    hd, vga = webcam((1280, 720)), webcam((640, 480))
    drive_pose = trajectory_poses(wall, 40, seed=11)[20]
    chessboard_cam = Camera(
        [[615.2, 0, 321.7], [0, 613.9, 243.4], [0, 0, 1]], [-0.11, 0.09, 0.0006, -0.0004, -0.03], (640, 480)
    )
    cases = [
        (
            "1280x720, 3 markers at 1.2 m",
            lambda: render_scene(wall, hd, look_at([1200, -200, 300], [0, 190, 240], roll_deg=5), **RENDER),
        ),
        (
            "1280x720, 3 markers at 0.4 m (close-up)",
            lambda: render_scene(wall, hd, look_at([400, 190, 260], [0, 190, 240]), **RENDER),
        ),
        (
            "1280x720, sheets crossing the camera plane",
            lambda: render_scene(wall, hd, look_at([20, 40, 260], [60, 2000, 250]), **RENDER),
        ),
        (
            "640x480, 3 markers at 1.2 m",
            lambda: render_scene(wall, vga, look_at([1200, -200, 300], [0, 190, 240], roll_deg=5), **RENDER),
        ),
        ("640x480, robot's drive frame 20", lambda: render_scene(wall, vga, drive_pose, **RENDER)),
    ]
    per_view = [
        (
            "640x480, checkerboard set of 20 views, per view",
            lambda: render_calibration_views(chessboard_cam, n_views=20, seed=7),
            20,
        )
    ]
    print(
        f"fidlearn.synthetic render time per frame, supersample 4 (OpenCV {cv2.__version__}, "
        f"NumPy {np.__version__}, Python {platform.python_version()}, {platform.machine()})"
    )
    print(f"{'case':46s} {'first':>9s} {'fastest':>9s} {'median':>9s}")
    for name, fn in cases:
        first, fastest, median = timed(fn, repeats)
        print(f"{name:46s} {first * 1000:7.0f} ms {fastest * 1000:7.0f} ms {median * 1000:7.0f} ms")
    for name, fn, n in per_view:
        first, fastest, median = timed(fn, max(1, repeats // 5))
        print(f"{name:46s} {first * 1000 / n:7.0f} ms {fastest * 1000 / n:7.0f} ms {median * 1000 / n:7.0f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
