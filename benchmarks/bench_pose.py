"""Measure fidlearn's pose estimation: accuracy on rendered scenes, optimality, covariance, speed.

Not a test: run it by hand and read the numbers.

    .venv/bin/python benchmarks/bench_pose.py            # everything (a few minutes on one core)
    .venv/bin/python benchmarks/bench_pose.py --quick    # fewer scenes and trials

1. Rendered scenes (fidlearn.synthetic.render_scene: blur, sensor noise, lens
   distortion) on three maps: the seed's three 80 mm markers, six markers on
   one wall, six markers on two walls. Camera-position error of
   * the seed pipeline: ``ArucoDetector`` with default parameters (no corner
     refinement), then ``cv2.solvePnP(..., SOLVEPNP_IPPE)`` over all corners,
     no LM (it fails outright on markers on two walls: counted as failures);
   * ``fidlearn.locate`` with its defaults.
2. Optimality: noisy true corners (Gaussian sigma); NEES of the camera centre
   against the Cramer-Rao bound ``sigma^2 (J^T J)^-1`` at the true pose,
   for ``estimate_pose`` and for Levenberg-Marquardt started at the true pose.
3. Coverage: how often the true position falls inside the 95 % ellipsoid of
   ``Pose.covariance`` (given sigma and estimated sigma).
4. Speed: ``locate`` against a plain ``detectMarkers`` on the same 640x480 images.
5. A misplaced marker: how often it is rejected, how often a good one is.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings

import cv2
import numpy as np

import fidlearn
from fidlearn import _cv, frames
from fidlearn import pose as pose_mod
from fidlearn.camera import Camera
from fidlearn.detection import Detection
from fidlearn.frames import look_at
from fidlearn.markermap import MarkerMap, MarkerPlacement
from fidlearn.pose._refine import _lm
from fidlearn.synthetic import render_scene

CAMERA = Camera(
    [[600.0, 0, 321.0], [0, 600.0, 238.0], [0, 0, 1]],
    [-0.15, 0.09, 0.0005, -0.0004, 0.0],
    (640, 480),
    source="benchmark camera, 56 deg horizontal FOV, barrel distortion",
)
CHI2_3_95 = 7.815


def seed_map() -> MarkerMap:
    return MarkerMap.load(fidlearn.data_path("world_map.json"))


def wall_map() -> MarkerMap:
    p = {}
    for k, (y, z) in enumerate([(0, 1500), (450, 1500), (900, 1500), (150, 1050), (600, 1050), (1050, 1100)]):
        p[k] = MarkerPlacement(k, (0.0, float(y), float(z)), (0.0, 0.0, 0.0))
    return MarkerMap(p, 120.0, dictionary="ARUCO_ORIGINAL", units="mm")


def two_wall_map() -> MarkerMap:
    p = {
        0: MarkerPlacement(0, (0.0, 300.0, 1400.0), (0.0, 0.0, 0.0)),
        1: MarkerPlacement(1, (0.0, 900.0, 1300.0), (0.0, 0.0, 0.0)),
        2: MarkerPlacement(2, (0.0, 600.0, 900.0), (0.0, 0.0, 0.0)),
        3: MarkerPlacement(3, (900.0, 0.0, 1400.0), (0.0, 0.0, 90.0)),
        4: MarkerPlacement(4, (400.0, 0.0, 1200.0), (0.0, 0.0, 90.0)),
        5: MarkerPlacement(5, (700.0, 0.0, 800.0), (0.0, 0.0, 90.0)),
    }
    return MarkerMap(p, 150.0, dictionary="ARUCO_ORIGINAL", units="mm")


def random_view(marker_map: MarkerMap, rng, dist_range=(0.6, 2.5)) -> np.ndarray:
    """A camera pose that sees the markers: in front of their mean normal, looking at their centre."""
    centres = np.array([marker_map.T_world_marker(i)[:3, 3] for i in marker_map.ids])
    normal = np.mean([marker_map.normal(i) for i in marker_map.ids], axis=0)
    normal /= np.linalg.norm(normal)
    extent = float(np.ptp(centres, axis=0).max()) + marker_map.marker_size_mm
    d = rng.uniform(*dist_range) * max(1.0, extent / 600.0)  # metres
    # random direction within 45 degrees of the normal
    while True:
        v = normal + rng.normal(0, 0.45, 3)
        v /= np.linalg.norm(v)
        if v @ normal > math.cos(math.radians(50)):
            break
    target = centres.mean(axis=0) + rng.normal(0, 0.08 * extent, 3)
    return look_at(target + d * 1000.0 * v, target, roll_deg=rng.uniform(-20, 20))


def all_visible(marker_map, T, camera=CAMERA) -> bool:
    for c in marker_map.corners().values():
        if not camera.points_in_front(c, T).all():
            return False
        px = camera.project(c, T)
        if np.any(px < 8) or np.any(px > np.array(camera.image_size) - 9):
            return False
    return True


def seed_pipeline(image, marker_map, camera):
    """Detect with default parameters (no refinement), IPPE over all corners, no LM. None on failure."""
    det = _cv.make_detector(marker_map.dictionary)
    corners, ids, _ = _cv.detect(det, image)
    obj, img = [], []
    for c, i in zip(corners, ids):
        if int(i) in marker_map:
            obj.append(marker_map.marker_corners(int(i)))
            img.append(c)
    if not obj:
        return None
    try:
        ok, rvec, tvec = cv2.solvePnP(
            np.concatenate(obj), np.concatenate(img), camera.K, camera.dist, flags=_cv.solvepnp_flag("IPPE")
        )
    except cv2.error:
        return None
    if not ok:
        return None
    return frames.invert_transform(frames.transform_from_rvec_tvec(rvec, tvec))[:3, 3]


def bench_rendered(n_per_map: int, rng) -> None:
    print("\n== 1. rendered scenes: camera-position error (mm) ==")
    print("seed = default ArucoDetector, no corner refinement, solvePnP IPPE over all corners, no LM")
    print("locate[x] = fidlearn.locate(image, map, camera, refine=x); cover = true position inside the 95 % ellipsoid")
    refines = [None, "none", "subpix"]
    head = f"{'map':<11}{'n':>4}{'seed med':>10}{'fail':>5}"
    for r in refines:
        head += f"{'[' + str(r or 'default') + '] med':>17}{'p90':>7}{'max':>8}{'fail':>5}{'cover':>7}"
    print(head)
    totals = {"seed": []} | {r: [] for r in refines}
    for name, m in [("seed", seed_map()), ("one wall", wall_map()), ("two walls", two_wall_map())]:
        errs = {"seed": []} | {r: [] for r in refines}
        fails = {k: 0 for k in errs}
        cover = {r: 0 for r in refines}
        n_rejected = n_rejected_bad_detection = 0
        n = 0
        while n < n_per_map:
            T = random_view(m, rng)
            if not all_visible(m, T):
                continue
            n += 1
            scene = render_scene(
                m,
                CAMERA,
                T,
                seed=int(rng.integers(1 << 30)),
                blur_px=rng.uniform(0.3, 1.0),
                noise_std_gray=rng.uniform(1.0, 4.0),
                gradient=rng.uniform(0, 0.3),
            )
            image, truth = scene.image, scene.truth
            C = T[:3, 3]
            s = seed_pipeline(image, m, CAMERA)
            if s is None:
                fails["seed"] += 1
            else:
                errs["seed"].append(np.linalg.norm(s - C))
            for r in refines:
                try:
                    p = fidlearn.locate(image, m, CAMERA, refine=r)
                except fidlearn.FidlearnError:
                    fails[r] += 1
                    continue
                errs[r].append(np.linalg.norm(p.position_mm - C))
                cover[r] += p.position_ellipsoid_contains(C, 0.95)
                if r is None:
                    from fidlearn.detection import detect_markers

                    found = {d.id: d.corners_px for d in detect_markers(image, m.dictionary)}
                    for i in p.rejected_ids:  # the map is right: was the detection wrong?
                        bad = i not in truth or np.abs(found[i] - truth[i]).max() > 0.5
                        n_rejected_bad_detection += bad
                        n_rejected += not bad
        line = f"{name:<11}{n:>4}{np.median(errs['seed']) if errs['seed'] else float('nan'):>10.2f}{fails['seed']:>5}"
        for r in refines:
            e = np.array(errs[r])
            line += (
                f"{np.median(e):>17.2f}{np.percentile(e, 90):>7.1f}{e.max():>8.1f}{fails[r]:>5}"
                f"{100 * cover[r] / max(len(e), 1):>6.0f}%"
            )
        print(
            line
            + f"   (rejected: {n_rejected} well-detected markers, {n_rejected_bad_detection} detected > 0.5 px off)"
        )
        for k in totals:
            totals[k] += errs[k]
    line = f"{'all':<11}{len(totals[None]):>4}{np.median(totals['seed']):>10.2f}{'':>5}"
    for r in refines:
        line += f"{np.median(totals[r]):>17.2f}{np.percentile(totals[r], 90):>7.1f}{np.max(totals[r]):>8.1f}{'':>12}"
    print(line)
    print(
        f"median locate[default] / median seed (where the seed succeeds) = "
        f"{np.median(totals[None]) / np.median(totals['seed']):.3f} (target <= 0.5)"
    )


def nees_trial(m, T, sigma, rng, camera=CAMERA):
    """(NEES of estimate_pose, NEES of LM from the truth, ambiguous) for one noisy observation."""
    obj = np.concatenate(list(m.corners().values()))
    img = camera.project(obj, T) + rng.normal(0, sigma, (len(obj), 2))
    dets = [Detection(i, img[4 * k : 4 * k + 4]) for k, i in enumerate(m.ids)]
    J = pose_mod.pose_jacobian(obj, T, camera)
    P = sigma**2 * np.linalg.inv(J.T @ J)[3:, 3:]
    pose = fidlearn.estimate_pose(dets, m, camera, corner_sigma_px=sigma)
    _, C_lm, _, _, _ = _lm(obj, img, camera.K, camera.dist, T[:3, :3].copy(), T[:3, 3].copy(), tol_sigma2=0.0)
    e1 = pose.position_mm - T[:3, 3]
    e2 = C_lm - T[:3, 3]
    return float(e1 @ np.linalg.solve(P, e1)), float(e2 @ np.linalg.solve(P, e2)), pose.ambiguous


def single_marker_map() -> MarkerMap:
    return MarkerMap(
        {3: MarkerPlacement(3, (0.0, 0.0, 1000.0), (0.0, 0.0, 0.0))}, 100.0, dictionary="ARUCO_ORIGINAL", units="mm"
    )


def bench_nees(n_trials: int, rng) -> None:
    print("\n== 2. optimality: NEES of the camera centre w.r.t. the Cramer-Rao bound at the true pose ==")
    print("(expected median for an efficient estimator: 2.37; 'gross' = NEES > 25 / > 100)")
    print(
        f"{'scene':<26}{'sigma':>6}{'median ours':>12}{'median LM@truth':>16}{'ratio':>7}"
        f"{'gross ours':>11}{'gross truth':>12}{'gross100':>14}{'ambig %':>8}"
    )
    scenes = [
        ("seed map", seed_map(), (0.5, 1.5)),
        ("one wall, 6 markers", wall_map(), (0.8, 2.5)),
        ("two walls, 6 markers", two_wall_map(), (0.8, 2.5)),
        ("one marker 100 mm", single_marker_map(), (0.3, 2.0)),
    ]
    for name, m, dr in scenes:
        for sigma in (0.3, 1.0):
            ours, truth, amb = [], [], 0
            while len(ours) < n_trials:
                T = random_view(m, rng, dr)
                if not all_visible(m, T):
                    continue
                a, b, c = nees_trial(m, T, sigma, rng)
                ours.append(a)
                truth.append(b)
                amb += c
            ours, truth = np.array(ours), np.array(truth)
            print(
                f"{name:<26}{sigma:>6.1f}{np.median(ours):>12.2f}{np.median(truth):>16.2f}"
                f"{np.median(ours) / np.median(truth):>7.2f}{100 * np.mean(ours > 25):>10.1f}%"
                f"{100 * np.mean(truth > 25):>11.1f}%"
                f"{100 * np.mean(ours > 100):>6.1f}/{100 * np.mean(truth > 100):>5.1f}%{100 * amb / len(ours):>7.0f}%"
            )


def bench_nees_bundled(n_per_scene: int, rng) -> None:
    print("\n== 2b. the same on the bundled scenes' geometry (data/scenes: 1280x720, seed map and two walls, 1-3 m) ==")
    print(
        "'extra gross' = gross for estimate_pose but not for LM@truth; 'flagged' = of those, ambiguous=True;"
        " 'alt ok' = of those, Pose.alternative is not gross"
    )
    import json

    from fidlearn.detection import Detection as Det

    record = json.loads(fidlearn.data_path("scenes", "poses.json").read_text())
    camera = Camera.load(fidlearn.data_path("scenes", "camera.json"))
    for sigma in (0.3, 1.0, 2.0):
        ours, truth = [], []
        extra = flagged = alt_ok = 0
        for entry in record["images"]:
            m = MarkerMap.load(fidlearn.data_path(entry["map"]))
            T = np.array(entry["T_world_camera"])
            ids = entry["visible_ids"]
            obj = np.concatenate([m.marker_corners(i) for i in ids])
            J = pose_mod.pose_jacobian(obj, T, camera)
            P = sigma**2 * np.linalg.inv(J.T @ J)[3:, 3:]

            def nees(x):
                e = x - T[:3, 3]
                return float(e @ np.linalg.solve(P, e))

            for _ in range(n_per_scene):
                img = camera.project(obj, T) + rng.normal(0, sigma, (len(obj), 2))
                p = fidlearn.estimate_pose([Det(i, img[4 * j : 4 * j + 4]) for j, i in enumerate(ids)], m, camera)
                _, C, _, _, _ = _lm(obj, img, camera.K, camera.dist, T[:3, :3].copy(), T[:3, 3].copy(), tol_sigma2=0.0)
                a, b = nees(p.position_mm), nees(C)
                ours.append(a)
                truth.append(b)
                if a > 25 and b <= 25:
                    extra += 1
                    flagged += p.ambiguous
                    alt_ok += p.alternative is not None and nees(p.alternative.position_mm) <= 25
        ours, truth = np.array(ours), np.array(truth)
        print(
            f"sigma {sigma:.1f} px: median NEES {np.median(ours):.2f} vs LM@truth {np.median(truth):.2f} "
            f"(ratio {np.median(ours) / np.median(truth):.3f}); gross {100 * np.mean(ours > 25):.1f} % vs "
            f"{100 * np.mean(truth > 25):.1f} %; extra gross {extra}, flagged {flagged}, alt ok {alt_ok}"
        )


def _rotation_error_deg(T: np.ndarray, T_true: np.ndarray) -> float:
    R = T[:3, :3] @ T_true[:3, :3].T
    return math.degrees(math.acos(float(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def bench_coverage(n_trials: int, rng) -> None:
    print("\n== 3. coverage of the 95 % position ellipsoid (target 90-98 %) ==")
    print(
        "NEES = squared Mahalanobis distance of the true position under covariance[3:, 3:] (95 % inside when below"
        f" {CHI2_3_95}; its median is 2.37 for a covariance that is exactly right, lower for one widened for an"
        " estimated noise); a miss is 'wrong branch' when Pose.alternative is nearer the truth in rotation"
        " (the planar flip), 'flagged' when Pose.ambiguous, 'alt holds' when the truth is inside the"
        " alternative's own 95 % ellipsoid; 'with a flagged alternative's' also counts the truth inside an"
        " ambiguous pose's alternative's ellipsoid (the first column, the target's, counts this pose's alone)"
    )
    for name, m in [
        ("seed map", seed_map()),
        ("one wall", wall_map()),
        ("two walls", two_wall_map()),
        ("1 marker", single_marker_map()),
    ]:
        for sigma in (0.3, 1.0):
            for given in (True, False):
                nees = []
                flip = flagged = alt_holds = either = 0
                n = 0
                while n < n_trials:
                    T = random_view(m, rng, (0.6, 1.5))
                    if not all_visible(m, T):
                        continue
                    n += 1
                    obj = np.concatenate(list(m.corners().values()))
                    img = CAMERA.project(obj, T) + rng.normal(0, sigma, (len(obj), 2))
                    dets = [Detection(i, img[4 * k : 4 * k + 4]) for k, i in enumerate(m.ids)]
                    p = fidlearn.estimate_pose(dets, m, CAMERA, corner_sigma_px=sigma if given else None)
                    e = p.position_mm - T[:3, 3]
                    nees.append(float(e @ np.linalg.solve(p.covariance[3:, 3:], e)))
                    if p.position_ellipsoid_contains(T[:3, 3], 0.95) != (nees[-1] <= CHI2_3_95):
                        raise AssertionError("position_ellipsoid_contains disagrees with the NEES")
                    alt = p.alternative
                    either += nees[-1] <= CHI2_3_95 or (
                        p.ambiguous and alt is not None and alt.position_ellipsoid_contains(T[:3, 3], 0.95)
                    )
                    if (
                        nees[-1] > CHI2_3_95
                        and alt is not None
                        and _rotation_error_deg(alt.T_world_camera, T) < _rotation_error_deg(p.T_world_camera, T)
                    ):
                        flip += 1
                        flagged += p.ambiguous
                        alt_holds += alt.position_ellipsoid_contains(T[:3, 3], 0.95)
                nees_a = np.array(nees)
                capped = float(np.mean(np.minimum(nees_a, 100)))
                misses = int(np.sum(nees_a > CHI2_3_95))
                print(
                    f"{name:<10} sigma {sigma:.1f} px, "
                    f"{'given    ' if given else 'estimated'}: {100 * np.mean(nees_a <= CHI2_3_95):5.1f} % of {n};"
                    f" NEES median {np.median(nees_a):5.2f}, mean (each capped at 100) {capped:5.2f};"
                    f" misses {misses:3d}: wrong branch {flip:3d} (flagged {flagged:3d}, alt holds {alt_holds:3d}),"
                    f" right branch {misses - flip:3d}; with a flagged alternative's {100 * either / n:5.1f} %"
                )


def bench_speed(n_images: int, rng) -> None:
    print("\n== 4. speed: locate vs a plain detectMarkers (640x480, six 120 mm markers) ==")
    m = wall_map()
    images = []
    while len(images) < n_images:
        T = random_view(m, rng)
        if all_visible(m, T):
            images.append(render_scene(m, CAMERA, T, seed=len(images), blur_px=0.6, noise_std_gray=2.0).image)
    det = _cv.make_detector(m.dictionary)
    from fidlearn.detection import detect_markers

    dets = [detect_markers(im, m.dictionary) for im in images]

    jobs = {
        "plain detectMarkers": lambda k: det.detectMarkers(images[k]),
        "detect_markers[default]": lambda k: detect_markers(images[k], m.dictionary),
        "estimate_pose": lambda k: fidlearn.estimate_pose(dets[k], m, CAMERA),
        "locate[default]": lambda k: fidlearn.locate(images[k], m, CAMERA),
        "locate[subpix]": lambda k: fidlearn.locate(images[k], m, CAMERA, refine="subpix"),
        "locate[none]": lambda k: fidlearn.locate(images[k], m, CAMERA, refine="none"),
    }
    times = {name: [[] for _ in images] for name in jobs}
    # Interleaved call by call, many times over: the machine's load (shared cores) hits every
    # job alike, and the least disturbed call of each (job, image) is kept.
    for _ in range(15):
        for k in range(len(images)):
            for name, f in jobs.items():
                t = time.perf_counter()
                f(k)
                times[name][k].append(time.perf_counter() - t)
    best = {name: 1e3 * float(np.mean([min(v) for v in per_image])) for name, per_image in times.items()}
    base = best["plain detectMarkers"]
    for name, v in best.items():
        print(f"{name:<26}{v:8.2f} ms  {v / base:5.2f} x plain")
    print(f"cv2 threads: {cv2.getNumThreads()}; locate limit 1.25 x plain, goal 1.10 x")


def bench_misplaced(n_trials: int, rng) -> None:
    print("\n== 5. a misplaced marker (map wrong by `shift` mm along the wall), rendered scenes ==")
    for label, m, shift in [
        ("6 markers", wall_map(), 10.0),
        ("6 markers", wall_map(), 25.0),
        ("6 markers", wall_map(), 60.0),
        ("seed map, 3", seed_map(), 10.0),
        ("seed map, 3", seed_map(), 25.0),
    ]:
        caught = wrong = 0
        err_on, err_off = [], []
        n = 0
        while n < n_trials:
            T = random_view(m, rng, (0.6, 1.6))
            if not all_visible(m, T):
                continue
            image = render_scene(m, CAMERA, T, seed=int(rng.integers(1 << 30)), blur_px=0.6, noise_std_gray=2.0).image
            bad = int(rng.integers(len(m.ids)))
            pl = dict(m.placements)
            p0 = pl[bad]
            direction = rng.normal(0, 1, 2)
            direction = shift * direction / np.linalg.norm(direction)
            pl[bad] = MarkerPlacement(
                bad,
                (p0.translation_mm[0], p0.translation_mm[1] + direction[0], p0.translation_mm[2] + direction[1]),
                p0.rotation_deg,
            )
            wrong_map = MarkerMap(pl, m.marker_size_mm, dictionary=m.dictionary, units="mm")
            try:
                p_on = fidlearn.locate(image, wrong_map, CAMERA)
                p_off = fidlearn.locate(image, wrong_map, CAMERA, reject_outliers=False)
            except fidlearn.FidlearnError:
                continue
            if bad not in p_on.marker_ids + p_on.rejected_ids:
                continue  # not detected
            n += 1
            caught += bad in p_on.rejected_ids
            wrong += any(i != bad for i in p_on.rejected_ids)
            err_on.append(np.linalg.norm(p_on.position_mm - T[:3, 3]))
            err_off.append(np.linalg.norm(p_off.position_mm - T[:3, 3]))
        print(
            f"{label:<12} shift {shift:4.0f} mm: rejected {100 * caught / n:5.1f} % of {n}, a good marker rejected in "
            f"{100 * wrong / n:4.1f} %; median position error {np.median(err_on):6.2f} mm with rejection, "
            f"{np.median(err_off):6.2f} mm without"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer scenes and trials")
    ap.add_argument(
        "--threads", type=int, default=None, help="cv2.setNumThreads (1 gives steadier timings on a busy machine)"
    )
    ap.add_argument("--only", choices=["rendered", "nees", "coverage", "speed", "misplaced"], help="run one part")
    args = ap.parse_args(argv)
    warnings.simplefilter("error")
    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    rng = np.random.default_rng(20261121)
    n = 0.25 if args.quick else 1.0
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}")
    if args.only in (None, "rendered"):
        bench_rendered(int(40 * n), rng)
    if args.only in (None, "nees"):
        bench_nees(int(400 * n), rng)
    if args.only in (None, "nees"):
        bench_nees_bundled(int(100 * n), rng)
    if args.only in (None, "coverage"):
        bench_coverage(int(400 * n), rng)
    if args.only in (None, "misplaced"):
        bench_misplaced(int(100 * n), rng)
    if args.only in (None, "speed"):
        bench_speed(int(40 * n), rng)
    return 0


if __name__ == "__main__":
    sys.exit(main())
