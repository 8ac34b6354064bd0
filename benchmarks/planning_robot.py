"""Predicted against measured camera-position error on the robot's ChArUco photos (``data/real/robot_charuco``).

    python benchmarks/planning_robot.py     # the table (a minute or two)

As ``planning_real.py`` does for OpenCV's tutorial photos: each photo's reference pose is OpenCV's
ChArUco-corner pose (``robot_charuco.charuco_pose``), the camera is a plain OpenCV calibration from
all the photos' ChArUco corners; for subsets of the board's markers the camera position
``fidlearn.estimate_pose`` finds from them alone is compared with the reference's, and its error
with ``fidlearn.predict_accuracy`` at the reference pose, with the noise that the *other* photos'
all-marker poses measured (``noise.noise_from_pose``). The reported figures are the tail's: the RMS
of measured over predicted RMS error and the share within the predicted 90th percentile.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

import fidlearn
from fidlearn import MarkerMap, predict_accuracy
from fidlearn.planning import noise
from fidlearn.pose import pose_jacobian

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks import planning_real  # noqa: E402
from benchmarks import robot_charuco as rc  # noqa: E402
from benchmarks.handeye import invert  # noqa: E402

GROUPS = ((1, 1), (2, 3), (4, 17))


def reference_variance(i: int, T: np.ndarray, camera) -> float:
    """The reference camera position's own variance (mm^2, trace): its ChArUco corners' residual noise
    through the least squares, as ``planning_real.reference_pose`` has it."""
    px, ids = rc.charuco_corners(i)
    P = rc.chess_corners_mm()[ids]
    r = camera.project(P, T) - px
    sigma2 = float(np.sum(r**2)) / (r.size - 6)
    J = pose_jacobian(P, T, camera)
    return sigma2 * float(np.trace(np.linalg.inv(J.T @ J)[3:, 3:]))


def measure(most: int = 20, seed: int = 2) -> dict:
    """``{group: {"measured", "rms", "p90"} arrays}`` over every photo with a reference and four markers."""
    camera = rc.opencv_calibration()[0]
    world = rc.board_map()
    photos = []
    for i in range(rc.N_PHOTOS):
        ref = rc.charuco_pose(i, camera)
        dets = {d.id: d for d in rc.markers(i) if d.id in world}
        if ref.T_camera_board is None or len(dets) < 4:
            continue
        T = invert(ref.T_camera_board)
        pose = fidlearn.estimate_pose(list(dets.values()), world, camera)
        photos.append((T, dets, noise.noise_from_pose(pose, world, camera), reference_variance(i, T, camera)))
    noises = [n for _, _, n, _ in photos]
    rng = np.random.default_rng(seed)
    out = {}
    for lo, hi in GROUPS:
        got: dict[str, list] = {"measured": [], "rms": [], "p90": []}
        for k, (T, dets, _, ref_var) in enumerate(photos):
            other = planning_real.others_noise(noises, k)
            for sub in planning_real.subsets(sorted(dets), lo, hi, rng, most):
                try:
                    pose = fidlearn.estimate_pose([dets[i] for i in sub], world, camera)
                except fidlearn.FidlearnError:
                    continue
                sub_map = MarkerMap({i: world.placements[i] for i in sub}, world.marker_size_mm)
                p = predict_accuracy(sub_map, camera, T, **other.kwargs())
                if not p.possible:
                    continue
                got["measured"].append(float(np.linalg.norm(pose.position_mm - T[:3, 3])))
                got["rms"].append(math.sqrt(p.position_rms_mm**2 + ref_var))
                got["p90"].append(p.position_p90_mm)
        out[(lo, hi)] = {key: np.array(v) for key, v in got.items()}
    return {"groups": out, "photos": len(photos), "noises": noises}


def report(most: int = 20) -> float:
    """Print the robot photos' tail and its target line; the RMS of measured over predicted."""
    r = measure(most)
    groups = r["groups"]
    q = np.concatenate([d["measured"] / d["rms"] for d in groups.values()])
    inside = np.concatenate([d["measured"] <= d["p90"] for d in groups.values()])
    rms = math.sqrt(float(np.mean(q**2)))
    sigma = np.median([n.corner_sigma_px for n in r["noises"]])
    print(
        f"\nOn the robot's ChArUco photos (`data/real/robot_charuco`, {r['photos']} photos with a ChArUco pose, "
        f"1600x1200, 18 mm markers; median corner noise measured {sigma:.2f} px): camera from a plain OpenCV "
        "calibration of all photos, reference pose from each photo's ChArUco corners (its own variance added "
        "to the predicted), predicted with the other photos' measured noise; "
        f"up to {most} subsets per photo and group.\n"
    )
    print("| markers | subsets | median measured (mm) | RMS measured / predicted | within predicted p90 |")
    print("|---|---|---|---|---|")
    for (lo, hi), d in groups.items():
        g = math.sqrt(float(np.mean((d["measured"] / d["rms"]) ** 2))) if len(d["measured"]) else math.nan
        within = 100 * float(np.mean(d["measured"] <= d["p90"])) if len(d["measured"]) else math.nan
        name = lo if lo == hi else f"{lo}-{hi}"
        print(f"| {name} | {len(d['measured'])} | {np.median(d['measured']):.2f} | {g:.2f} | {within:.0f} % |")
    print(
        f"\nAll {len(q)} subsets: RMS measured / predicted {rms:.2f}, {100 * inside.mean():.0f} % within the "
        "predicted 90th percentile."
    )
    print(
        "\n<!-- target: planning: RMS of measured / predicted position error within 0.8-1.25 on the robot's "
        f"ChArUco photos | {rms:.2f} | {'yes' if 0.8 <= rms <= 1.25 else 'no'} -->"
    )
    return rms


if __name__ == "__main__":
    report()
