"""A room for surveys: markers on three walls and the floor, a walk-through of photos, and a taped map."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..camera import Camera
from ..frames import look_at, rotation_from_rpy_deg, rpy_deg_from_rotation
from ..markermap import MarkerMap, MarkerPlacement
from ._checks import _check_seed
from ._scenes import visible_markers

__all__ = ["survey_room", "mixed_survey_room", "board_survey_room", "mixed_wall", "survey_walk", "tape_measured"]

#: Room size (x into the room from the north wall, y along it, z up), mm.
ROOM_MM = (5000.0, 4000.0, 2500.0)


def _wall_slots() -> list[tuple[str, int, int]]:
    north = [("north", y, z) for y, z in ((700, 1700), (1600, 1300), (2500, 1800), (3300, 1400))]
    west = [("west", x, z) for x, z in ((900, 1500), (2000, 1900), (3100, 1300))]
    east = [("east", x, z) for x, z in ((1000, 1800), (2200, 1350), (3300, 1700))]
    floor = [("floor", x, y) for x, y in ((1200, 1300), (1500, 2800))]
    return north + west + east + floor


def _placement(i: int, wall: str, a: float, b: float) -> MarkerPlacement:
    X, Y, _ = ROOM_MM
    if wall == "north":
        return MarkerPlacement(i, (0.0, a, b), (0.0, 0.0, 0.0))
    if wall == "west":  # y = 0, facing +Y
        return MarkerPlacement(i, (a, 0.0, b), (0.0, 0.0, 90.0))
    if wall == "east":  # y = Y, facing -Y
        return MarkerPlacement(i, (a, Y, b), (0.0, 0.0, -90.0))
    return MarkerPlacement(i, (a, b, 0.0), (0.0, -90.0, 0.0))  # floor, facing up


def survey_room(marker_size_mm: float = 160.0, dictionary: str = "ARUCO_ORIGINAL") -> MarkerMap:
    """The true map of a 5 m x 4 m room: 12 markers, 4 on the north wall, 3 on each side wall, 2 on the floor.

    Parameters
    ----------
    marker_size_mm : float
        Side of each marker, mm.
    dictionary : str
        ArUco dictionary of the markers (ids 0-11).

    Returns
    -------
    MarkerMap
        In mm: the north wall is the world YZ plane (markers facing +X), the west wall y = 0
        (facing +Y, yaw 90), the east wall y = 4000 (facing -Y, yaw -90), the floor z = 0
        (facing up, pitch -90).

    Examples
    --------
    >>> m = survey_room()
    >>> len(m), m.is_coplanar()
    (12, False)
    """
    pl = {i: _placement(i, *slot) for i, slot in enumerate(_wall_slots())}
    return MarkerMap(pl, marker_size_mm, dictionary=dictionary, units="mm", source="survey room")


def mixed_survey_room() -> MarkerMap:
    """The room of :func:`survey_room` printed as people print: markers of 80, 150 and 200 mm, two dictionaries.

    Returns
    -------
    MarkerMap
        The 12 places of :func:`survey_room`, in turn 200, 80 and 150 mm; the first 8 are ARUCO_ORIGINAL
        markers 0-7 (the map's dictionary and size, 80 mm, for those without their own ``size_mm``), the last
        4 (east wall and floor) 4X4_50 markers 0-3, the same ids as four of the others.

    Examples
    --------
    >>> m = mixed_survey_room()
    >>> sorted({m.marker_size(k) for k in m.ids}), m.dictionaries
    ([80.0, 150.0, 200.0], ['ARUCO_ORIGINAL', '4X4_50'])
    """
    pl = {}
    for k, slot in enumerate(_wall_slots()):
        p = _placement(k % 8, *slot)
        size = (200.0, None, 150.0)[k % 3]
        pl[k] = MarkerPlacement(p.id, p.translation_mm, p.rotation_deg, size, "4X4_50" if k >= 8 else None)
    return MarkerMap(pl, 80.0, dictionary="ARUCO_ORIGINAL", units="mm", source="mixed survey room")


def board_survey_room() -> MarkerMap:
    """The room of :func:`survey_room` with a ChArUco board on the north wall and a robot's dock as a bundle.

    Returns
    -------
    MarkerMap
        The 160 mm markers of :func:`survey_room` but 1 and 8; where marker 1 was, the rigid entry ``"wall
        board"``: a ChArUco board of 5 x 7 squares of 100 mm (75 mm markers 20-36, its top-left corner at
        y 1400, z 1700); where marker 8 was, the bundle ``"dock"``: markers 40 and 41 (160 mm) on one plate
        on the east wall, 350 mm apart along it and 50 mm apart in height.

    Examples
    --------
    >>> m = board_survey_room()
    >>> sorted(m.entries), len(m), m.owner[20], m.owner[41]
    (['dock', 'wall board'], 29, 'wall board', 'dock')
    """
    from ..markermap_entries import BoardEntry, BundleEntry

    room = survey_room()
    singles = {i: p for i, p in room.placements.items() if i not in (1, 8)}
    board = BoardEntry(
        "wall board", "charuco", (0.0, 1400.0, 1700.0), (0.0, 0.0, 0.0), (5, 7), 75.0, "ARUCO_ORIGINAL", 100.0,
        first_id=20,
    )  # fmt: skip
    plate = (
        MarkerPlacement(40, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        MarkerPlacement(41, (0.0, 350.0, -50.0), (0.0, 0.0, 0.0)),
    )
    dock = BundleEntry("dock", (2100.0, ROOM_MM[1], 1350.0), (0.0, 0.0, -90.0), plate)
    return MarkerMap(singles, 160.0, units="mm", source="board survey room", entries=[board, dock])


#: A wall of four 80 mm ARUCO_ORIGINAL markers and two 200 mm 4X4_50 markers whose ids (0, 1) two small ones use too.
MIXED_WALL: dict[str, Any] = {
    "units": "mm",
    "marker_size_mm": 80,
    "dictionary": "ARUCO_ORIGINAL",
    "markers": {
        "0": {"translation": [0, 0, 1400]},
        "1": {"translation": [0, 300, 1400]},
        "2": {"translation": [0, 0, 1100]},
        "3": {"translation": [0, 300, 1100]},
        "4X4_50:0": {"translation": [0, 800, 1500], "size_mm": 200},
        # named by its key and by its "dictionary" field, which agree
        "4X4_50:1": {"translation": [0, 800, 1100], "size_mm": 200, "dictionary": "DICT_4X4_50"},
    },
}


def mixed_wall(without=()) -> MarkerMap:
    """A wall of markers of two sizes and two dictionaries (:data:`MIXED_WALL`), in the world YZ plane facing +X.

    Parameters
    ----------
    without : sequence of str
        Keys of :data:`MIXED_WALL` left out (e.g. ``["4X4_50:0"]``: the wall printed without that marker).

    Returns
    -------
    MarkerMap
        Four 80 mm ARUCO_ORIGINAL markers 0-3 and 200 mm 4X4_50 markers 0 and 1, mm.

    Examples
    --------
    >>> m = mixed_wall()
    >>> [m.marker_size(k) for k in m.ids]
    [80.0, 200.0, 80.0, 200.0, 80.0, 80.0]
    """
    markers = {k: v for k, v in MIXED_WALL["markers"].items() if k not in without}
    return MarkerMap.from_dict({**MIXED_WALL, "markers": markers}, source="mixed wall")


def survey_walk(
    marker_map: MarkerMap, camera: Camera, *, n_photos: int = 20, seed: int = 0, min_markers: int = 3
) -> list[np.ndarray]:
    """Camera poses of a walk through the room, each photo showing several markers whole.

    Parameters
    ----------
    marker_map : MarkerMap
        The room (e.g. :func:`survey_room`).
    camera : Camera
        Intrinsics and image size.
    n_photos : int
        How many poses.
    seed : int
        Seed of ``numpy.random.default_rng``.
    min_markers : int
        Markers each photo must show whole.

    Returns
    -------
    list of ndarray, shape (4, 4)
        ``T_world_camera`` (mm) of each photo: standing 1.2-1.8 m high, 1.2-4.5 m from the north
        wall, looking midway between the marker seen least so far and another one (so that every
        marker is photographed several times), turned up to 10 degrees about the optical axis.

    Raises
    ------
    ValueError
        If ``n_photos`` is not a positive whole number, or poses that see enough markers cannot be found.
    """
    if not isinstance(n_photos, (int, np.integer)) or n_photos < 1:
        raise ValueError(f"n_photos must be a positive whole number, got {n_photos!r}")
    rng = np.random.default_rng(_check_seed(seed))
    centres = np.array([c.mean(axis=0) for c in marker_map.corners().values()])
    X, Y, _ = ROOM_MM
    poses: list[np.ndarray] = []
    seen = np.zeros(len(centres))
    for attempt in range(200 * n_photos):
        # aim at the marker seen least so far (as a careful surveyor does), with one other
        least = int(np.argmin(seen + rng.uniform(0, 0.5, len(seen))))
        other = rng.choice([k for k in range(len(centres)) if k != least])
        eye = [rng.uniform(1200, X - 500), rng.uniform(500, Y - 500), rng.uniform(1200, 1800)]
        T = look_at(eye, (centres[least] + centres[other]) / 2, roll_deg=float(rng.uniform(-10, 10)))
        visible = [marker_map.ids.index(i) for i in visible_markers(marker_map, camera, T, margin_px=10.0)]
        if len(visible) >= min_markers and (least in visible or attempt % 50 == 49):
            poses.append(T)
            seen[visible] += 1
            if len(poses) == n_photos:
                return poses
    raise ValueError(f"found only {len(poses)} poses that see {min_markers} markers; use a wider camera")


def tape_measured(
    true_map: MarkerMap,
    *,
    sigma_mm: float = 20.0,
    sigma_deg: float = 1.0,
    moved: dict[int, tuple[float, float, float]] | None = None,
    seed: int = 0,
    units: str = "mm",
) -> MarkerMap:
    """The map a tape measure gives: each placement off by Gaussian errors, some markers moved.

    Parameters
    ----------
    true_map : MarkerMap
        The truth.
    sigma_mm : float
        Standard deviation of each coordinate of each top-left corner, mm.
    sigma_deg : float
        Standard deviation of each rotation error, degrees (about world X, Y, Z, on the left).
    moved : dict of int to (float, float, float), optional
        Markers moved after taping (by the map's keys; a rigid entry by its name): the tape's placement is
        the truth minus this displacement (mm).
    seed : int
        Seed of ``numpy.random.default_rng``.
    units : {"mm", "cm", "m", "in", "ft"}
        The units the map says it uses when saved.

    Returns
    -------
    MarkerMap
        Same markers, sizes and dictionaries; each rigid entry (a board, a bundle) taped as one object, its pose
        off by the same errors as a marker's.
    """
    rng = np.random.default_rng(_check_seed(seed))
    moved = moved or {}

    def taped(key, R_true: np.ndarray, t_true) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        dt = rng.normal(0.0, sigma_mm, 3) - np.asarray(moved.get(key, (0.0, 0.0, 0.0)), float)
        droll, dpitch, dyaw = rng.normal(0.0, sigma_deg, 3)
        roll, pitch, yaw = (
            float(a) for a in rpy_deg_from_rotation(rotation_from_rpy_deg(droll, dpitch, dyaw) @ R_true)
        )
        x, y, z = (float(v) for v in np.asarray(t_true, float) + dt)
        return (x, y, z), (roll, pitch, yaw)

    pl = {}
    for i, p in true_map.placements.items():
        if i not in true_map.owner:  # an entry's markers move with it
            pl[i] = MarkerPlacement(p.id, *taped(i, p.R_world_marker, p.translation_mm), p.size_mm, p.dictionary)
    entries = []
    for name, e in true_map.entries.items():
        t, r = taped(name, rotation_from_rpy_deg(*e.rotation_deg), e.translation_mm)
        entries.append(dataclasses.replace(e, translation_mm=t, rotation_deg=r))
    return MarkerMap(
        pl,
        true_map.marker_size_mm,
        dictionary=true_map.dictionary,
        units=units,
        source="tape-measured map",
        entries=entries,
    )
