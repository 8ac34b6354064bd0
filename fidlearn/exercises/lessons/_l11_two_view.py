"""Lesson 11, q6: the scale of a map made from two photos and no map (how monocular SLAM starts).

Kept apart from :mod:`.l11_mapping` (which lists ``_q6`` in its ``build``) for that module's length.
"""

from __future__ import annotations

import cv2
import numpy as np

from ...camera import Camera
from ...frames import invert_transform, look_at
from ...markermap import MarkerMap, MarkerPlacement
from .._engine import Detector, Question, QuestionText
from .._parsers import _close, _cmp_scalar, _scalar
from .._scenery import ROOM_MM, _rng, _sees_all

#: q6's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q6: QuestionText = {
    "title": "The scale of a map from two photos",
    "task": """
        Two photos and no map. `rays_1` and `rays_2` (n, 4, 2) are n markers' corners (TL, TR, BR,
        BL) in photo 1 and in photo 2, marker by marker in the same order, as normalized image
        coordinates (x/z, y/z: the lens's distortion already undone). `R` (3, 3) and `t` (3,) are the
        motion between the photos, as `cv2.recoverPose` gives it: a point at X in camera 1's frame is
        at R X + t in camera 2's, and t has length 1. Every marker is `marker_size_mm` wide.
        Write code that computes how far apart the two cameras stood, in mm.
        """,
    "hint": [
        "Two photos alone cannot tell a room from a model of it ten times smaller: the map they make has the "
        "baseline (the distance between the cameras) as its unit. A length you know gives that unit in mm.",
        (
            "Triangulate the corners with the projection matrices [I | 0] and [R | t] "
            "(cv2.triangulatePoints, then divide by the fourth row); a marker's side (TL to TR, TR to BR, ...) "
            "then comes out as a fraction of the baseline. Take the median of every side of every marker: one "
            "side carries its two corners' noise."
        ),
    ],
    "solution": """
        x1 = np.asarray(q6.inputs.rays_1, dtype=float).reshape(-1, 2)
        x2 = np.asarray(q6.inputs.rays_2, dtype=float).reshape(-1, 2)
        P2 = np.hstack([q6.inputs.R, np.reshape(q6.inputs.t, (3, 1))])
        X = cv2.triangulatePoints(np.eye(3, 4), P2, x1.T, x2.T)
        corners = (X[:3] / X[3]).T.reshape(-1, 4, 3)  # in baselines, camera 1's frame
        sides = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2)
        q6.answer = q6.inputs.marker_size_mm / np.median(sides)
        """,
    "level": "medium",
    "look": (
        "import matplotlib.pyplot as plt\n"
        "fig, axes = plt.subplots(1, 2, figsize=(9, 3.2), sharex=True, sharey=True)\n"
        "for ax, rays, name in zip(axes, (q6.inputs.rays_1, q6.inputs.rays_2), ('photo 1', 'photo 2')):\n"
        "    for k, quad in enumerate(np.asarray(rays)):\n"
        "        ax.fill(quad[:, 0], quad[:, 1], alpha=0.5)\n"
        "        ax.annotate(str(k), quad[0], fontsize=8)\n"
        "    ax.set_title(f'{name}: the corners as rays (x/z, y/z)')\n"
        "    ax.set_aspect('equal')\n"
        "axes[0].invert_yaxis()  # y down, as in the pictures\n"
        "plt.show()"
    ),
}

#: The grading tolerance, relative: the median or the mean of all sides lands within a third of it (the variant
#: is drawn so).
_RTOL = 0.015
#: How far the reference answer (and the mean of the sides instead of their median) may be from the truth.
_FAIR = 0.005
_WEST_Y = float(ROOM_MM[0][1])


def _q6_map(rng: np.random.Generator) -> MarkerMap:
    """Two to four markers on the north wall and two to four on the west wall, near the room's corner."""
    size = float(rng.choice([120.0, 150.0, 200.0]))
    n_north, n_west = int(rng.integers(2, 5)), int(rng.integers(2, 5))
    ids = np.sort(rng.choice(50, size=n_north + n_west, replace=False)).astype(int)
    placements: dict[int, MarkerPlacement] = {}
    while len(placements) < len(ids):
        z = float(np.round(rng.uniform(700, 1800), -1))
        if len(placements) < n_north:  # facing +X
            tl, rot = (0.0, float(np.round(rng.uniform(_WEST_Y + 300, _WEST_Y + 1600), -1)), z), (0.0, 0.0, 0.0)
        else:  # facing +Y
            tl, rot = (float(np.round(rng.uniform(300, 1600), -1)), _WEST_Y, z), (0.0, 0.0, 90.0)
        if all(np.linalg.norm(np.subtract(p.translation_mm, tl)) >= 2 * size for p in placements.values()):
            mid = int(ids[len(placements)])
            placements[mid] = MarkerPlacement(mid, tl, rot)
    return MarkerMap(placements, size, dictionary="ARUCO_ORIGINAL", units="mm")


def _q6_layout(rng: np.random.Generator) -> tuple[MarkerMap, Camera, np.ndarray, np.ndarray]:
    """The map, the camera and the two photos' poses T_world_camera (both see every marker whole)."""
    m = _q6_map(rng)
    cam = Camera.from_fov(float(np.round(rng.uniform(65, 80))), (1280, 720))
    centre = np.mean([m.marker_corners(i).mean(axis=0) for i in m.ids], axis=0)
    lo, hi = ROOM_MM
    for _ in range(1000):
        eye_1 = np.array([rng.uniform(1800, 3000), rng.uniform(1500, 2800) + _WEST_Y, rng.uniform(1000, 1700)])
        step = rng.normal(size=3) * [1.0, 1.0, 0.2]
        eye_2 = eye_1 + step / np.linalg.norm(step) * rng.uniform(800, 1600)
        T_1 = look_at(eye_1, centre + rng.uniform(-150, 150, 3))
        T_2 = look_at(eye_2, centre + rng.uniform(-150, 150, 3))
        inside = bool(np.all(eye_2 > lo + 300) and np.all(eye_2 < hi - 300))
        if inside and _sees_all(cam, m, T_1) and _sees_all(cam, m, T_2):
            return m, cam, T_1, T_2
    raise RuntimeError("no two camera poses in the drawn range see every marker; widen the range")  # a lesson bug


def _rays(rng: np.random.Generator, m: MarkerMap, cam: Camera, T_world_camera: np.ndarray) -> np.ndarray:
    """Every marker's corners seen from T_world_camera with 0.2 px of noise, as normalized coordinates (n, 4, 2)."""
    corners = np.concatenate([m.marker_corners(i) for i in m.ids])
    px = cam.project(corners, T_world_camera) + rng.normal(0, 0.2, (len(corners), 2))
    return np.round((px - [cam.cx, cam.cy]) / [cam.fx, cam.fy], 7).reshape(-1, 4, 2)


def _triangulated(rays_1: np.ndarray, rays_2: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    P_2 = np.hstack([R, t.reshape(3, 1)])
    X = cv2.triangulatePoints(np.eye(3, 4), P_2, rays_1.reshape(-1, 2).T, rays_2.reshape(-1, 2).T)
    return (X[:3] / X[3]).T.reshape(-1, 4, 3)


def _q6_data(rng: np.random.Generator):
    """rays_1, rays_2, R, t, the marker size, the true baseline, the corners triangulated (in baselines) and the
    scene (the map, the camera and the two poses T_world_camera)."""
    while True:
        m, cam, T_1, T_2 = _q6_layout(rng)
        rays_1, rays_2 = _rays(rng, m, cam, T_1), _rays(rng, m, cam, T_2)
        T_21 = invert_transform(T_2) @ T_1  # camera 1's frame to camera 2's
        baseline = float(np.linalg.norm(T_21[:3, 3]))
        R, t = np.round(T_21[:3, :3], 9), np.round(T_21[:3, 3] / baseline, 9)
        corners = _triangulated(rays_1, rays_2, R, t)
        sides = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2)
        answers = m.marker_size_mm / np.array([np.median(sides), np.mean(sides)])
        # a right method lands well inside the tolerance; the baseline in metres is not 1 (t's length)
        if np.all(np.abs(answers / baseline - 1) < _FAIR) and abs(baseline - 1000) > 50:
            return rays_1, rays_2, R, t, m.marker_size_mm, baseline, corners, (m, cam, T_1, T_2)


def _q6_mistakes(size: float, baseline: float, corners: np.ndarray) -> list[tuple[Detector, str]]:
    """The mistakes q6 names, each a detector of the answer it gives and the message."""
    diagonals = np.linalg.norm(corners - np.roll(corners, -2, axis=1), axis=2)[:, :2]
    pairs = [np.linalg.norm(corners[:, a] - corners[:, b], axis=1) for a in range(4) for b in range(a + 1, 4)]
    sides = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2)
    one_marker = np.concatenate([sides.ravel(), np.mean(sides, axis=1), np.median(sides, axis=1)])
    return [
        (
            lambda a: bool(np.any(np.abs(a * one_marker / size - 1) < 1e-4)),
            "that is the scale of one side (or one marker): each carries its corners' noise; take the median of "
            "every side of every marker",
        ),
        (
            lambda a: abs(a - 1.0) < 1e-4,
            "that is the length of t: cv2.recoverPose gives only the direction of the motion (length 1), "
            "whatever the distance; the markers' known size gives the scale",
        ),
        (
            lambda a: _close(a, size / np.median(diagonals), rtol=_RTOL),
            "that takes a marker's diagonal (TL to BR) for its side: a side joins neighbouring corners",
        ),
        (
            lambda a: _close(a, size / np.mean(pairs), rtol=_RTOL),
            "that averages every pair of corners, diagonals included: a side joins neighbouring corners only",
        ),
        (
            lambda a: _close(a, np.median(sides) / size, rtol=_RTOL) or _close(a, 1.0 / baseline, rtol=0.05),
            "that is the side over the size: the baseline in mm is the marker's size over its side in baselines",
        ),
        (
            lambda a: _close(a, baseline / 1000, rtol=0.05) or _close(a, baseline / 10, rtol=0.05),
            "that is in metres or centimetres: give the distance in mm, as marker_size_mm is",
        ),
    ]


def _q6(learner: str) -> Question:
    """q6: The scale of a map from two photos."""
    rng = _rng("11", learner, "q6")
    rays_1, rays_2, R, t, size, baseline, corners, _ = _q6_data(rng)
    return Question(
        "q6",
        inputs={"rays_1": rays_1, "rays_2": rays_2, "R": R, "t": t, "marker_size_mm": size},
        expected=baseline,
        parse=_scalar("the distance between the cameras, mm"),
        compare=_cmp_scalar(0.0, " mm", rtol=_RTOL),
        wrong=_q6_mistakes(size, baseline, corners),
        **_Q6,
    )
