"""Predicted against measured: pose error over rendered rooms, and the farthest a marker is found.

    python benchmarks/bench_planning.py            # the whole benchmark (a few minutes on 2 cores)
    python benchmarks/bench_planning.py --quick    # fewer scenes
    python benchmarks/bench_planning.py --noise    # re-measure the corner-noise table of fidlearn.planning.noise
    python benchmarks/bench_planning.py --fisheye  # the fisheye group alone (benchmarks/planning_fisheye.py)
    python benchmarks/bench_planning.py --noise --fisheye  # re-measure the fisheye's corner-noise table

Scenes are rendered by ``fidlearn.synthetic.render_scene`` with the bundled scenes' settings
(blur 0.5 px, noise 1.2 gray levels, gradient 0.2), the settings the noise model was measured
with. For each group of scenes the predicted distribution of the position error is the mixture
of each scene's predicted Gaussian (``predict_accuracy``, default noise model); its median is
compared with the median of the errors ``fidlearn.locate`` makes on the rendered pictures.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import cv2
import numpy as np

import fidlearn
from fidlearn import Camera, MarkerMap, look_at, predict_accuracy, render_scene
from fidlearn.errors import FidlearnError
from fidlearn.planning import noise

try:  # run as a script (benchmarks/ on the path) or imported as benchmarks.bench_planning
    import planning_fisheye
    import planning_real
    import planning_robot
    from planning_walls import RENDER, print_noise_table, wall_map
except ImportError:
    from benchmarks import planning_fisheye, planning_real, planning_robot
    from benchmarks.planning_walls import RENDER, print_noise_table, wall_map

SIZES = [(640, 480), (1280, 720), (1920, 1080)]


def scene(rng: np.random.Generator, world: MarkerMap, distance_mm: float):
    centre = np.mean([world.marker_corners(i).mean(axis=0) for i in world.ids], axis=0)
    az = math.radians(rng.uniform(-45, 45))
    eye = centre + distance_mm * np.array([math.cos(az), math.sin(az), rng.uniform(-0.2, 0.2)])
    return look_at(eye, centre + rng.normal(0, 60, 3))


def group_rows(n_scenes: int, n_seeds: int, seed: int = 7) -> list[dict]:
    """Per group: the median over (scene, noise seed) of measured error / the scene's predicted median."""
    rng = np.random.default_rng(seed)
    groups = [(size, counts) for size in SIZES for counts in ((1, 1), (2, 4), (5, 12))]
    rows = []
    for size, (lo, hi) in groups:
        camera = Camera.from_fov(60, size)
        ratios, predicted, measured, flips, t0, used, tries = [], [], [], 0, time.perf_counter(), 0, 0
        no_pose = 0.0  # pictures without a pose predicted: the sum of 1 - pose_probability
        squares, inside = [], []  # (measured / predicted RMS)^2, and measured <= predicted 90th percentile
        while used < n_scenes and tries < 5 * n_scenes:
            tries += 1
            world = wall_map(rng, int(rng.integers(lo, hi + 1)))
            T = scene(rng, world, rng.uniform(500, 4000))
            p = predict_accuracy(world, camera, T)
            if not p.possible:
                continue
            used += 1
            flips += p.flip_likely
            no_pose += n_seeds * (1.0 - p.pose_probability)
            for k in range(n_seeds):
                image = render_scene(world, camera, T, seed=1000 * tries + k, **RENDER).image
                try:
                    pose = fidlearn.locate(image, world, camera)
                    err = float(np.linalg.norm(pose.position_mm - T[:3, 3]))
                except FidlearnError:
                    err = math.inf  # no pose where one was predicted: counts as a large error
                ratios.append(err / p.position_error_mm)
                squares.append((err / p.position_rms_mm) ** 2)
                inside.append(err <= p.position_p90_mm)
                predicted.append(p.position_error_mm)
                measured.append(err)
        ratio = float(np.median(ratios)) if ratios else math.nan
        rows.append(
            {
                "size": size,
                "markers": (lo, hi),
                "n": used,
                "samples": len(ratios),
                "predicted": float(np.median(predicted)),
                "measured": float(np.median(measured)),
                "ratio": 1.0 / ratio if ratio else math.nan,
                "squares": squares,
                "inside": inside,
                "rms_ratio": math.sqrt(float(np.mean([q for q in squares if math.isfinite(q)] or [math.nan]))),
                "no_pose": (sum(not math.isfinite(q) for q in squares), no_pose),
                "p90_coverage": float(np.mean(inside)) if inside else math.nan,
                "flip_likely": flips,
                "seconds": time.perf_counter() - t0,
            }
        )
        print(
            f"  {size[0]}x{size[1]}, {lo}-{hi} markers: {used} scenes, predicted / measured {rows[-1]['ratio']:.2f}",
            file=sys.stderr,
            flush=True,
        )
    return rows


def detected_fraction(camera: Camera, side_mm: float, distance_mm: float, trials: int) -> float:
    world = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": side_mm,
            "markers": {"0": {"translation": [0, -side_mm / 2, 1000 + side_mm / 2], "rotation": [0, 0, 0]}},
        }
    )
    found = 0
    for k in range(trials):
        T = look_at([distance_mm, 0, 1000], [0, 0, 1000], roll_deg=7.0 * k)
        rendered = render_scene(world, camera, T, seed=k, **RENDER)
        image, truth = rendered.image, rendered.truth
        found += bool(fidlearn.detect_markers(image, ids=[0])) if 0 in truth else 0
    return found / trials


def max_distance_rows(trials: int) -> list[dict]:
    rows = []
    for size in SIZES:
        camera = Camera.from_fov(60, size)
        for side_mm in (80.0, 150.0):
            predicted = 4 * camera.fx * side_mm / noise.min_perimeter_px(size)
            lo, hi = 0.5 * predicted, 1.5 * predicted  # bisection on the 50 % detection distance
            for _ in range(7):
                mid = (lo + hi) / 2
                if detected_fraction(camera, side_mm, mid, trials) >= 0.5:
                    lo = mid
                else:
                    hi = mid
            measured = (lo + hi) / 2
            rows.append(
                {
                    "size": size,
                    "side_mm": side_mm,
                    "predicted": predicted,
                    "measured": measured,
                    "ratio": predicted / measured,
                }
            )
            print(
                f"  {size[0]}x{size[1]}, {side_mm:g} mm: predicted {predicted:.0f} mm, measured {measured:.0f} mm",
                file=sys.stderr,
                flush=True,
            )
    return rows


def measure_noise_table(n_scenes: int = 150, seed: int = 11) -> None:
    """The table of ``fidlearn.planning.noise``: RMS corner error against the apparent marker side.

    Measured on rooms like those of the accuracy groups (other seeds): walls of 1 to 12 markers
    seen from 0.5 to 4 m at the three image sizes, every detected marker's corners against the truth.
    """
    rng = np.random.default_rng(seed)
    sides, errs = [], []
    for k in range(n_scenes):
        camera = Camera.from_fov(60, SIZES[k % len(SIZES)])
        world = wall_map(rng, int(rng.integers(1, 13)))
        T = scene(rng, world, rng.uniform(500, 4000))
        rendered = render_scene(world, camera, T, seed=k, **RENDER)
        image, truth = rendered.image, rendered.truth
        for d in fidlearn.detect_markers(image, ids=world.ids):
            if d.id in truth:
                t = truth[d.id]
                sides.append(float(np.mean(np.linalg.norm(t - np.roll(t, 1, axis=0), axis=1))))
                errs.append((d.corners_px - t).ravel())
    print_noise_table(sides, errs)


def _print_tails(groups: list[dict]) -> None:
    """The tail over all pictures: RMS of measured over predicted, and the 90th-percentile coverage."""
    squares = np.concatenate([r["squares"] for r in groups])
    inside = np.concatenate([r["inside"] for r in groups])
    finite = np.isfinite(squares)
    rms = math.sqrt(float(np.mean(squares[finite])))
    print(
        "\n'RMS measured / predicted': each picture's error over its scene's predicted RMS error "
        "(`Prediction.position_rms_mm`), root mean square over the pictures (1 when the tail is right); "
        "'within predicted p90': pictures whose error is at most the predicted 90th percentile "
        f"(`Prediction.position_p90_mm`; 90 % when right). Over all {len(squares)} pictures "
        f"({int((~finite).sum())} without a pose, left out of the RMS, counted outside the 90th percentile): "
        f"RMS measured / predicted {rms:.2f}, {100 * inside.mean():.0f} % within the predicted 90th percentile. "
        "The prediction mixes the subsets of markers the detector may find (`Prediction.found_probability`, "
        "`fidlearn.planning.finding`, measured on other rooms); 'no pose': pictures where no marker was found, "
        "against the sum of the scenes' predicted chances (`1 - Prediction.pose_probability`)."
    )
    print(
        f"\n<!-- target: planning: RMS of measured / predicted position error within 0.8-1.25 over rendered scenes | "
        f"{rms:.2f} | {'yes' if 0.8 <= rms <= 1.25 else 'no'} -->"
    )
    print(
        f"\n<!-- target: planning: predicted 90th-percentile position error covers 85-95 % of rendered pictures | "
        f"{100 * inside.mean():.0f} % | {'yes' if 0.85 <= inside.mean() <= 0.95 else 'no'} -->"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--noise", action="store_true", help="re-measure the corner-noise table instead")
    ap.add_argument("--fisheye", action="store_true", help="the fisheye group alone (with --noise: its table)")
    args = ap.parse_args(argv)
    if args.noise:
        if args.fisheye:
            planning_fisheye.measure_noise_table()
        else:
            measure_noise_table()
        return 0
    if args.fisheye:
        planning_fisheye.report(*((10, 1) if args.quick else (40, 1)))
        return 0
    t0 = time.perf_counter()
    groups = group_rows(8, 2) if args.quick else group_rows(25, 4)
    print(
        "Predicted against measured camera-position error, per group of rendered scenes (60 deg camera, "
        "one wall of 80 mm markers, distance 0.5-4 m, up to 45 deg off the wall's axis, several noise seeds "
        "per scene). Each picture's error is divided by its scene's predicted median error; "
        "'predicted / measured' is 1 over the median of those quotients (1 when the prediction is right):\n"
    )
    print(
        "| image | markers | scenes | pictures | median predicted (mm) | "
        "median measured (mm) | predicted / measured | RMS measured / predicted | within predicted p90 | flip likely | "
        "no pose: measured, predicted |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in groups:
        print(
            f"| {r['size'][0]}x{r['size'][1]} | {r['markers'][0]}-{r['markers'][1]} | {r['n']} | {r['samples']} | "
            f"{r['predicted']:.2f} | {r['measured']:.2f} | {r['ratio']:.2f} | {r['rms_ratio']:.2f} | "
            f"{100 * r['p90_coverage']:.0f} % | {r['flip_likely']} | {r['no_pose'][0]}, {r['no_pose'][1]:.1f} |"
        )
    _print_tails(groups)
    ratios = [r["ratio"] for r in groups if math.isfinite(r["ratio"])]
    within = [0.75 <= q <= 1.25 for q in ratios]
    print(
        f"\n<!-- target: planning: predicted median position error within +/-25 % of measured, per group of rendered "
        f"scenes | {sum(within)} of {len(within)} groups (ratios {min(ratios):.2f} to {max(ratios):.2f}) | "
        f"{'yes' if all(within) else 'no'} -->"
    )
    planning_fisheye.report(*((10, 1) if args.quick else (40, 1)))  # through a 160-degree fisheye
    planning_real.report(most=15 if args.quick else 40)  # the same target on real photos with a known pose
    planning_robot.report(most=8 if args.quick else 20)  # and on the robot's photos
    dist = max_distance_rows(3 if args.quick else 6)
    print(
        "\nFarthest a face-on marker is found (half of the trials), predicted from "
        "`fidlearn.planning.noise.min_perimeter_px` against measured by bisection:\n"
    )
    print("| image | marker | predicted (mm) | measured (mm) | predicted / measured |\n|---|---|---|---|---|")
    for r in dist:
        print(
            f"| {r['size'][0]}x{r['size'][1]} | {r['side_mm']:g} mm | "
            f"{r['predicted']:.0f} | {r['measured']:.0f} | {r['ratio']:.2f} |"
        )
    worst = max(abs(r["ratio"] - 1) for r in dist)
    print(
        f"\n<!-- target: planning: predicted maximum detection distance within 15 % of measured | "
        f"{100 * worst:.0f} % at worst over {len(dist)} cases | {'yes' if worst <= 0.15 else 'no'} -->"
    )
    n_seeds = 4 if args.quick else 12
    coached = coach_rows(n_seeds)
    print(
        "\nThe calibration coach (`fidlearn.planning.coach`): views until fx is within 0.1 % of the truth and the "
        "reprojection uncertainty is under 0.3 px over 90 % of the picture, starting from 4 random views; then "
        "either the coach's next view or another random one (board anywhere in the picture, tilted 0 to 40 deg, "
        "400 to 800 mm away); every view shows the whole printed board, its outer row of squares too, as a "
        f"detector needs; corners with 0.1 px noise; the camera of data/calibration; {n_seeds} seeds, "
        "at most 40 views:\n"
    )
    print("| strategy | views needed (median) | per seed |\n|---|---|---|")
    med = {k: float(np.median(v)) for k, v in coached.items()}
    for k, v in coached.items():
        print(f"| {k} | {med[k]:.1f} | {', '.join(map(str, v))} |")
    saving = 1 - med["coach"] / med["random"]
    print(
        "\n<!-- target: coach: its next views reach fx within 0.1 % and < 0.3 px over 90 % of the picture "
        "with >= 30 % "
        f"fewer views than random ones | {100 * saving:.0f} % fewer ({med['coach']:.1f} against {med['random']:.1f}) | "
        f"{'yes' if saving >= 0.3 else 'no'} -->"
    )
    flags = flag_rows(n_seeds)
    print("\nSeeded calibration sets (20 views unless said, 0.1 px noise) and how often the coach flags them:\n")
    print("| set | flagged |\n|---|---|")
    for name, n, total in flags:
        print(f"| {name} | {n} of {total} |")
    bad_ok = all(n == total for name, n, total in flags if name != "good")
    good_ok = all(n == 0 for name, n, total in flags if name == "good")
    print(
        f"\n<!-- target: coach: every seeded bad calibration set flagged, no good set flagged | "
        f"{'all bad sets flagged' if bad_ok else 'a bad set missed'}, "
        f"{'no good set flagged' if good_ok else 'a good set flagged'} | "
        f"{'yes' if bad_ok and good_ok else 'no'} -->"
    )
    print(f"\n{time.perf_counter() - t0:.0f} s")
    return 0


# ------------------------------------------------------------------------------------------------
# The calibration coach: its next views against random views of the same kind
# ------------------------------------------------------------------------------------------------
def _board(pattern=(9, 6), square_mm=25.0) -> np.ndarray:
    cols, rows = pattern
    return np.array([[i * square_mm, j * square_mm, 0.0] for j in range(rows) for i in range(cols)])


def random_board_pose(
    rng: np.random.Generator, camera: Camera, board: np.ndarray, tilt_max_deg: float = 40.0, region: int | None = None
):
    """A board pose whose every point is in the picture: somewhere in the picture (in one of its 3x3
    ``region`` s when given, 0 the top left), tilted up to ``tilt_max_deg``."""
    from fidlearn import frames
    from fidlearn.planning.coach import _board_in_picture

    centre = board.mean(axis=0)
    for _ in range(1000):
        if region is None:
            u, v = rng.uniform(0.1, 0.9) * camera.width, rng.uniform(0.1, 0.9) * camera.height
        else:
            u = (region % 3 + rng.uniform(0, 1)) / 3 * camera.width
            v = (region // 3 + rng.uniform(0, 1)) / 3 * camera.height
        ray = cv2.undistortPoints(np.array([[[u, v]]]), camera.K, camera.dist).reshape(2)
        C = np.array([ray[0], ray[1], 1.0]) * rng.uniform(400, 800)
        axis = rng.normal(size=2)
        axis = np.array([*(axis / np.linalg.norm(axis)), 0.0])
        R = cv2.Rodrigues(axis * math.radians(rng.uniform(0, tilt_max_deg)))[0]
        T = frames.make_transform(R, C - R @ centre)
        if _board_in_picture(camera, board, T):
            return T
    raise RuntimeError("no board pose fits the picture")


def _observe(rng, camera, board, T, sigma):
    from fidlearn import frames

    rvec, tvec = frames.rvec_tvec_from_transform(T)
    px = cv2.projectPoints(board.reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist)[0].reshape(-1, 2)
    return px + rng.normal(0, sigma, px.shape)


def _calibrate(camera_true: Camera, board: np.ndarray, observed: list, other_sizes: int = 0):
    from fidlearn import frames
    from fidlearn.planning.coach import coach

    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [board.astype(np.float32)] * len(observed),
        [o.astype(np.float32) for o in observed],
        camera_true.image_size,
        None,
        None,
    )
    cam = Camera(K, dist.ravel(), camera_true.image_size)
    names = [f"v{i}" for i in range(len(observed))]
    T = {n: frames.transform_from_rvec_tvec(r, t) for n, r, t in zip(names, rvecs, tvecs)}
    c = coach(
        cam,
        {n: board for n in names},
        dict(zip(names, observed)),
        T,
        corner_sigma_px=max(rms / math.sqrt(2), 1e-3),
        other_sizes=other_sizes,
    )
    return cam, c


def views_needed(
    strategy: str, seed: int, camera_true: Camera, sigma: float = 0.1, start: int = 4, most: int = 40
) -> int:
    """Views until fx is within 0.1 % and the coach's map is under 0.3 px over 90 % of the picture."""
    from fidlearn import frames

    rng = np.random.default_rng(seed)
    board = _board()
    observed = [
        _observe(rng, camera_true, board, random_board_pose(rng, camera_true, board), sigma) for _ in range(start)
    ]
    while len(observed) < most:
        cam, c = _calibrate(camera_true, board, observed)
        if abs(cam.fx / camera_true.fx - 1) < 1e-3 and c.good_fraction >= 0.9:
            return len(observed)
        if strategy == "coach" and c.next_view is not None:
            T_est = c.next_view.T_camera_board
            T = frames.make_transform(T_est[:3, :3], T_est[:3, 3])
        else:
            T = random_board_pose(rng, camera_true, board)
        observed.append(_observe(rng, camera_true, board, T, sigma))
    return most


def coach_rows(seeds: int) -> dict:
    camera_true = Camera.load(fidlearn.data_path("calibration/camera_true.json"))
    out = {"coach": [], "random": []}
    for s in range(seeds):
        for strategy in out:
            out[strategy].append(views_needed(strategy, s, camera_true))
        print(f"  seed {s}: coach {out['coach'][-1]}, random {out['random'][-1]} views", file=sys.stderr, flush=True)
    return out


def seeded_sets(rng: np.random.Generator, camera: Camera) -> dict:
    """Calibration sets with a known fault, and a good one: ``{name: (observed, poses, other_sizes)}``."""
    from fidlearn import frames

    board = _board()

    def views(n, pose=None, bend_view=None):
        # a careful user's set: the board reaching each ninth of the picture in turn
        Ts = [pose() if pose else random_board_pose(rng, camera, board, region=k % 9) for k in range(n)]
        obs = []
        for k, T in enumerate(Ts):
            pts = board.copy()
            if k == bend_view:  # the print lifted off: 4 mm of bow across the board
                x = (pts[:, 0] - pts[:, 0].mean()) / np.ptp(pts[:, 0])
                pts[:, 2] = 16.0 * x**2
            obs.append(_observe(rng, camera, pts, T, 0.1))
        return obs

    def face_on():
        while True:
            T = random_board_pose(rng, camera, board, tilt_max_deg=5.0)
            return T

    def left_only():
        while True:
            T = random_board_pose(rng, camera, board)
            rvec, tvec = frames.rvec_tvec_from_transform(T)
            px = cv2.projectPoints(board.reshape(-1, 1, 3), rvec, tvec, camera.K, camera.dist)[0].reshape(-1, 2)
            if px[:, 0].max() < 0.6 * camera.width:
                return T

    return {
        "good": (views(20), 0),
        "face-on": (views(20, face_on), 0),
        "left part only": (views(20, left_only), 0),
        "too few": (views(6), 0),
        "mixed resolutions": (views(20), 3),
        "bent board": (views(20, bend_view=7), 0),
    }


def flag_rows(seeds: int) -> list[tuple[str, int, int]]:
    camera_true = Camera.load(fidlearn.data_path("calibration/camera_true.json"))
    board = _board()
    counts: dict[str, int] = {}
    for s in range(seeds):
        rng = np.random.default_rng(100 + s)
        for name, (observed, other_sizes) in seeded_sets(rng, camera_true).items():
            _, c = _calibrate(camera_true, board, observed, other_sizes)
            counts[name] = counts.get(name, 0) + bool(c.flags)
    return [(name, n, seeds) for name, n in counts.items()]


if __name__ == "__main__":
    sys.exit(main())
