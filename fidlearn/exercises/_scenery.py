"""Seeded scenery the lessons share: the generator of a learner's numbers, cameras, walls and markers."""

from __future__ import annotations

import contextvars
import hashlib

import numpy as np

from ..camera import Camera
from ..detection import Detection
from ..markermap import MarkerMap, MarkerPlacement

#: The seed of graded variants while :func:`build_questions` builds them (see fidlearn.grading).
_SEED: contextvars.ContextVar = contextvars.ContextVar("fidlearn_exercise_seed", default=None)


def _rng(lesson_id: str, learner: str, question: str) -> np.random.Generator:
    """A generator seeded from SHA-256 of the lesson, the learner's id and the question.

    While :func:`build_questions` runs with a ``seed`` function (graded mode), that function
    seeds it instead: HMAC of the class secret, which nobody without the secret can repeat.
    """
    seed_fn = _SEED.get()
    if seed_fn is not None:
        return np.random.default_rng(seed_fn(question))
    digest = hashlib.sha256(f"fidlearn-exercises/{lesson_id}/{learner}/{question}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


_SIZES = [(640, 480), (800, 600), (1280, 720), (1920, 1080)]


_WALL_YAW = {"north": 0, "south": 180, "west": 90, "east": -90}


_ROOM_FT = {
    "north": 0.0,
    "south": 16.0,
    "west": -6.0,
    "east": 6.0,
}  # wall positions: x for north/south, y for west/east


#: The room every lesson's scenery stands in, mm: (x_min, y_min, z_min), (x_max, y_max, z_max).
ROOM_MM = (
    np.array([_ROOM_FT["north"] * 304.8, _ROOM_FT["west"] * 304.8, 0.0]),
    np.array([_ROOM_FT["south"] * 304.8, _ROOM_FT["east"] * 304.8, 2700.0]),
)


def _wall_translation(
    rng: np.random.Generator, wall: str, step: float, span: tuple, height: tuple, per_ft: float
) -> list:
    """A top-left corner on a wall of the room: along the wall within ``span``, at a height in ``height``.

    ``step`` rounds the values; ``per_ft`` is the unit of the result per foot
    (1 for feet, 304.8 for mm), the room's walls being given in feet. ``span`` is measured from
    the middle of the wall, so on the west and east walls (which run along x, from the north wall
    at x = 0 to the south wall) it is centred on the middle of the room, never behind a wall.
    """
    along = float(np.round(rng.uniform(*span) / step) * step)
    z = float(np.round(rng.uniform(*height) / step) * step)
    if wall in ("north", "south"):
        return [_ROOM_FT[wall] * per_ft, along, z]
    middle = (_ROOM_FT["north"] + _ROOM_FT["south"]) / 2 * per_ft
    return [float(np.round((middle + along) / step) * step), _ROOM_FT[wall] * per_ft, z]


def _wall_map(
    rng: np.random.Generator, n: int, size_mm: float, first_id: int = 0, spread_mm: float = 900.0
) -> MarkerMap:
    """n markers on the north wall (x = 0, facing +X), top-left corners on a loose grid, mm."""
    ids = first_id + np.sort(rng.choice(40, size=n, replace=False))
    placements: dict[int, MarkerPlacement] = {}
    k = 0
    while len(placements) < n:
        y = float(np.round(rng.uniform(-spread_mm, spread_mm), -1))
        z = float(np.round(rng.uniform(700, 1700), -1))
        tl = np.array([0.0, y, z])
        if all(np.abs(np.asarray(p.translation_mm) - tl)[1:].max() > 2 * size_mm for p in placements.values()):
            mid = int(ids[k])
            placements[mid] = MarkerPlacement(mid, (0.0, y, z), (0.0, 0.0, 0.0))
            k += 1
    return MarkerMap(placements, size_mm, dictionary="ARUCO_ORIGINAL", units="mm")


def _noisy_detections(
    rng: np.random.Generator, marker_map: MarkerMap, camera: Camera, T_world_camera: np.ndarray, noise_px: float
) -> list:
    dets = []
    for mid in marker_map.ids:
        px = camera.project(marker_map.marker_corners(mid), T_world_camera)
        dets.append(Detection(mid, np.round(px + rng.normal(0, noise_px, px.shape), 3)))
    return dets


def _sees_all(camera: Camera, marker_map: MarkerMap, T_world_camera: np.ndarray, margin_px: float = 10.0) -> bool:
    """Whether every marker of the map is in front of the camera, faces it, and lies inside its image."""
    corners = np.concatenate([marker_map.marker_corners(i) for i in marker_map.ids])
    if not np.all(camera.points_in_front(corners, T_world_camera)):
        return False
    eye = T_world_camera[:3, 3]
    if any(marker_map.normal(i) @ (eye - marker_map.marker_corners(i).mean(axis=0)) <= 0 for i in marker_map.ids):
        return False
    px = camera.project(corners, T_world_camera)
    return bool(np.all((px >= margin_px) & (px <= np.array(camera.image_size) - 1 - margin_px)))


def _pose_seeing_all(
    rng: np.random.Generator, camera: Camera, marker_map: MarkerMap, draw, tries: int = 200
) -> np.ndarray:
    """A camera pose T_world_camera from ``draw(rng)``, drawn again until the camera sees every marker whole.

    The first draw is kept when it is good, so a variant that was possible stays as it was.
    """
    for _ in range(tries):
        T = draw(rng)
        if _sees_all(camera, marker_map, T):
            return T
    raise RuntimeError("no camera pose in the drawn range sees every marker; widen the range")  # a lesson bug
