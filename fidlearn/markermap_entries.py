"""Rigid entries of a world map: a ChArUco board, an ArUco grid board or a tag bundle placed by one pose.

An entry is placed like a marker: ``translation`` is the world position of its top-left corner (a board's
outer corner, a bundle's origin) and ``rotation`` its ``[roll, pitch, yaw]`` in degrees about that point. With
rotation ``[0, 0, 0]`` a board lies in the world YZ plane facing +X, as a marker does: the board's x axis (along
its first row, OpenCV's board frame) is world +Y and its y axis (down the board) is world -Z. A bundle's own
frame is a small world: its markers are placed in it exactly as markers are placed in a map, and the bundle's
pose carries them into the world.

Every marker of an entry becomes a :class:`~fidlearn.markermap.MarkerPlacement` of the map (so everything that
reads marker corners reads the entry's too); a board's markers' corners are OpenCV's board geometry
(``getObjPoints()``, ``getIds()``), and a ChArUco board's chess corners (``getChessboardCorners()``) are kept
apart, by the board's name (:meth:`~fidlearn.MarkerMap.chess_corners`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _cv, frames
from ._files import did_you_mean
from ._map_parse import (  # id_ranges: how the survey's report and the plot write an entry's ids
    UNITS_TO_MM,
    MarkerKey,
    MarkerPlacement,
    _entry,
    _marker_size,
    _placements,
    _vector3,
    id_ranges,
)
from .errors import FidlearnError, MapError

__all__ = ["BoardEntry", "BundleEntry", "BOARD_TO_WORLD", "id_ranges"]

#: The board frame's axes in the world at rotation [0, 0, 0] (columns): x -> +Y, y -> -Z, z (into the board) -> -X.
BOARD_TO_WORLD = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

_BOARD_FIELDS = {
    "charuco": ("type", "translation", "rotation", "squares", "square_mm", "marker_mm", "dictionary", "first_id",
                "legacy"),
    "grid": ("type", "translation", "rotation", "markers", "marker_mm", "separation_mm", "dictionary", "first_id"),
}  # fmt: skip
_BUNDLE_FIELDS = ("translation", "rotation", "markers", "dictionary")


@dataclass(frozen=True)
class BoardEntry:
    """A ChArUco board or an ArUco grid board placed in the world as one rigid entry.

    Attributes
    ----------
    name : str
        The entry's name in the map file.
    kind : {"charuco", "grid"}
    translation_mm : (float, float, float)
        World position of the board's top-left outer corner, mm.
    rotation_deg : (float, float, float)
        ``[roll, pitch, yaw]`` about that corner, degrees (as a marker's).
    counts : (int, int)
        ChArUco: squares (x, y); grid: markers (x, y), as OpenCV's board constructors count them.
    marker_size_mm : float
        Side of each marker's black square, mm.
    dictionary : str
        The markers' dictionary.
    square_size_mm : float or None
        ChArUco: side of a chess square, mm.
    separation_mm : float or None
        Grid: the gap between two neighbouring markers, mm.
    first_id : int
        The id of the board's first marker; the others follow in OpenCV's order.
    legacy : bool
        ChArUco: the marker layout of boards made before OpenCV 4.6 (differs with an even number of rows).
    """

    name: str
    kind: str
    translation_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]
    counts: tuple[int, int]
    marker_size_mm: float
    dictionary: str
    square_size_mm: float | None = None
    separation_mm: float | None = None
    first_id: int = 0
    legacy: bool = False

    @property
    def n_markers(self) -> int:
        """How many markers the board carries."""
        x, y = self.counts
        return (x * y) // 2 if self.kind == "charuco" else x * y

    def cv_board(self):
        """OpenCV's board (``cv2.aruco.CharucoBoard`` or ``cv2.aruco.GridBoard``), lengths in mm.

        Returns
        -------
        cv2.aruco.CharucoBoard or cv2.aruco.GridBoard
        """
        _cv.require_aruco()
        ids = np.arange(self.first_id, self.first_id + self.n_markers, dtype=np.int32)
        dictionary = _cv.get_dictionary(self.dictionary)
        if self.kind == "grid":
            assert self.separation_mm is not None
            return _cv._ARUCO.GridBoard(self.counts, self.marker_size_mm, self.separation_mm, dictionary, ids)
        assert self.square_size_mm is not None
        board = _cv._ARUCO.CharucoBoard(self.counts, self.square_size_mm, self.marker_size_mm, dictionary, ids)
        if self.legacy:
            board.setLegacyPattern(True)
        return board

    @property
    def R_world_board(self) -> np.ndarray:
        """Rotation (3, 3) of the board frame (OpenCV's: x along a row, y down, z into the board) in the world."""
        return frames.rotation_from_rpy_deg(*self.rotation_deg) @ BOARD_TO_WORLD

    def to_world(self, points_board: np.ndarray) -> np.ndarray:
        """Points (N, 3) of the board frame, mm, in the world, mm.

        Parameters
        ----------
        points_board : ndarray, shape (N, 3)
            In OpenCV's board frame, mm.

        Returns
        -------
        ndarray, shape (N, 3)
        """
        world = np.asarray(points_board, dtype=float).reshape(-1, 3) @ self.R_world_board.T + self.translation_mm
        return np.round(world, 9) + 0.0

    def chess_corners_board(self) -> np.ndarray:
        """A ChArUco board's chess corners in its own frame (``getChessboardCorners()``).

        Returns
        -------
        ndarray, shape (N, 3)
            mm, in corner-id order; (0, 3) for a grid board.
        """
        if self.kind != "charuco":
            return np.zeros((0, 3))
        return np.asarray(self.cv_board().getChessboardCorners(), dtype=float).reshape(-1, 3)

    def placements(self) -> list[MarkerPlacement]:
        """The board's markers as placements of the map.

        Returns
        -------
        list of MarkerPlacement
            In the world, in OpenCV's marker order; their dictionary as the entry names it.
        """
        b = self.cv_board()
        corners = np.asarray(b.getObjPoints(), dtype=float).reshape(-1, 4, 3)
        ids = np.asarray(b.getIds()).ravel()
        tl = self.to_world(corners[:, 0])
        return [
            MarkerPlacement(
                int(i), (float(t[0]), float(t[1]), float(t[2])), self.rotation_deg, self.marker_size_mm, self.dictionary
            )
            for i, t in zip(ids, tl)
        ]

    def to_dict(self, scale: float) -> dict:
        """The entry as the map file writes it.

        Parameters
        ----------
        scale : float
            mm per unit of the map file.

        Returns
        -------
        dict
        """
        out: dict[str, Any] = {
            "type": self.kind,
            "translation": [round(v / scale, 9) for v in self.translation_mm],
            "rotation": list(self.rotation_deg),
        }
        if self.kind == "charuco":
            out.update(squares=list(self.counts), square_mm=self.square_size_mm, marker_mm=self.marker_size_mm)
            if self.legacy:
                out["legacy"] = True
        else:
            out.update(markers=list(self.counts), marker_mm=self.marker_size_mm, separation_mm=self.separation_mm)
        out.update(dictionary=self.dictionary, first_id=self.first_id)
        return out


@dataclass(frozen=True)
class BundleEntry:
    """Markers fixed on one rigid object (a robot's dock), given in the object's frame and placed by one pose.

    Attributes
    ----------
    name : str
        The entry's name in the map file.
    translation_mm : (float, float, float)
        World position of the bundle frame's origin, mm.
    rotation_deg : (float, float, float)
        ``[roll, pitch, yaw]`` of the bundle frame in the world, degrees.
    markers : tuple of MarkerPlacement
        Each marker in the bundle's frame (mm, degrees), placed there as a marker is placed in a map.
    """

    name: str
    translation_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]
    markers: tuple[MarkerPlacement, ...]

    def placements(self) -> list[MarkerPlacement]:
        """The bundle's markers placed in the world.

        Returns
        -------
        list of MarkerPlacement
            Each marker's top-left corner and rotation in the world.
        """
        R = frames.rotation_from_rpy_deg(*self.rotation_deg)
        out = []
        for p in self.markers:
            t = np.round(R @ np.asarray(p.translation_mm) + self.translation_mm, 9) + 0.0
            rpy = tuple(float(v) for v in frames.rpy_deg_from_rotation(R @ p.R_world_marker))
            out.append(MarkerPlacement(p.id, tuple(float(v) for v in t), rpy, p.size_mm, p.dictionary))  # type: ignore[arg-type]
        return out

    def to_dict(self, scale: float) -> dict:
        """The entry as the map file writes it.

        Parameters
        ----------
        scale : float
            mm per unit of the map file.

        Returns
        -------
        dict
        """
        return {
            "translation": [round(v / scale, 9) for v in self.translation_mm],
            "rotation": list(self.rotation_deg),
            "markers": {_key_text(p): _entry(p, scale) for p in self.markers},
        }


def _key_text(p: MarkerPlacement) -> str:
    return str(p.id) if p.dictionary is None else f"{p.dictionary}:{p.id}"


def _count_pair(value: Any, where: str, field: str, least: int, example: str) -> tuple[int, int]:
    ok = isinstance(value, (list, tuple)) and len(value) == 2
    ok = ok and all(isinstance(v, numbers.Integral) and not isinstance(v, bool) for v in value)
    if not ok or min(value) < least:
        raise MapError(
            f"{where}: {field} must be two whole numbers (x, y), each at least {least}, got {value!r:.60}; "
            f'e.g. "{field}": {example}'
        )
    return int(value[0]), int(value[1])


def _length(value: Any, where: str, field: str) -> float:
    try:
        ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(float(value))
    except OverflowError:  # an int beyond any float
        ok = False
    if not ok or value <= 0:
        raise MapError(f"{where}: {field} must be a positive length in mm, got {value!r:.40}")
    return _marker_size(value, where, field)


def _first_id(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise MapError(f"{where}: first_id must be a whole number >= 0 (the id of the board's first marker)")
    return int(value)


def _dictionary(value: Any, where: str, default: str) -> str:
    try:
        return _cv.dictionary_name(default if value is None else value)
    except FidlearnError as exc:
        raise MapError(f"{where}: {exc}") from None


def _check_fields(value: Any, where: str, known: tuple[str, ...]) -> None:
    if not isinstance(value, Mapping):
        raise MapError(f'{where} must be an object with "translation", "rotation" and the entry\'s description')
    extra = sorted(set(value) - set(known))
    if extra:
        raise MapError(
            f"{where} has unknown field {extra[0]!r}{did_you_mean(extra[0], known)}; it has {', '.join(known)}"
        )
    if "translation" not in value:
        raise MapError(f'{where} has no "translation" (the world position of its top-left corner)')


def _pose(value: Mapping, where: str, units: str) -> tuple[tuple[float, ...], tuple[float, float, float]]:
    t = _vector3(value["translation"], where, "translation", f"[x, y, z] in {units}")
    r = _vector3(value.get("rotation", [0, 0, 0]), where, "rotation", "[roll, pitch, yaw] in degrees")
    return tuple(v * UNITS_TO_MM[units] for v in t), r


def _board(name: str, value: Any, units: str, source: str, dictionary: str) -> BoardEntry:
    """One ``"boards"`` entry, every field checked, with the fix."""
    where = f"{source}: board {name!r}"
    kind = value.get("type") if isinstance(value, Mapping) else None
    if not isinstance(kind, str) or kind not in _BOARD_FIELDS:
        raise MapError(f'{where}: "type" must be "charuco" or "grid", got {kind!r}')
    _check_fields(value, where, _BOARD_FIELDS[kind])
    t, r = _pose(value, where, units)
    name_dict = _dictionary(value.get("dictionary"), where, dictionary)
    legacy = value.get("legacy", False)
    if not isinstance(legacy, bool):
        raise MapError(f"{where}: legacy must be true or false (true: a board made before OpenCV 4.6)")
    marker = _length(value.get("marker_mm"), where, "marker_mm")
    if kind == "charuco":
        counts = _count_pair(value.get("squares"), where, "squares", 3, "[5, 7]")
        square = _length(value.get("square_mm"), where, "square_mm")
        if marker >= square:
            raise MapError(f"{where}: marker_mm ({marker:g}) must be smaller than square_mm ({square:g})")
        entry = BoardEntry(name, kind, t, r, counts, marker, name_dict, square, None, 0, legacy)  # type: ignore[arg-type]
    else:
        counts = _count_pair(value.get("markers"), where, "markers", 1, "[4, 3]")
        separation = _length(value.get("separation_mm"), where, "separation_mm")
        entry = BoardEntry(name, kind, t, r, counts, marker, name_dict, None, separation)  # type: ignore[arg-type]
    first = _first_id(value.get("first_id", 0), where)
    size = _cv.dictionary_size(name_dict)
    if first + entry.n_markers > size:
        raise MapError(
            f"{where}: its {entry.n_markers} markers from id {first} run past {name_dict}'s last id {size - 1}; "
            "lower first_id, use fewer squares or a bigger dictionary"
        )
    return BoardEntry(**{**entry.__dict__, "first_id": first})


def _bundle(name: str, value: Any, units: str, source: str, dictionary: str) -> BundleEntry:
    """One ``"bundles"`` entry: its pose and its markers in its own frame."""
    where = f"{source}: bundle {name!r}"
    _check_fields(value, where, _BUNDLE_FIELDS)
    t, r = _pose(value, where, units)
    own = _dictionary(value.get("dictionary"), where, dictionary)
    markers = value.get("markers")
    if not isinstance(markers, Mapping) or not markers:
        raise MapError(f'{where}: "markers" must be an object of its markers in its own frame, e.g. {{"7": {{...}}}}')
    placed = _placements(markers, units, where, own)
    entries = [
        MarkerPlacement(mid, tt, rr, s, n if n is not None else (None if own == dictionary else own))
        for mid, tt, rr, s, n in placed.values()
    ]
    return BundleEntry(name, t, r, tuple(entries))  # type: ignore[arg-type]


def _parse_entries(d: Mapping, units: str, source: str, dictionary: str) -> list[BoardEntry | BundleEntry]:
    """The ``"boards"`` and ``"bundles"`` of a full map, in file order (boards first).

    Parameters
    ----------
    d : mapping
        The full layout.
    units : str
        The map's units.
    source : str
        Named in error messages.
    dictionary : str
        The map's dictionary (an entry's default).

    Returns
    -------
    list of BoardEntry or BundleEntry

    Raises
    ------
    MapError
        A malformed entry, with its fix.
    """
    out: list[BoardEntry | BundleEntry] = []
    for field, parse in (("boards", _board), ("bundles", _bundle)):
        group = d.get(field, {})
        if not isinstance(group, Mapping):
            raise MapError(f'{source}: "{field}" must be an object mapping names to entries')
        out += [parse(str(name), value, units, source, dictionary) for name, value in group.items()]  # type: ignore[operator]
    names = [e.name for e in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise MapError(f"{source}: the entry name {twice[0]!r} is used twice; give each board and bundle its own name")
    return out


def _merge_placements(
    singles: Mapping[int, MarkerPlacement], entries: list, dictionary: str, source: str
) -> tuple[list[MarkerPlacement], dict[int, str]]:
    """Every placement of the map (single markers and entries' markers) and which entry owns each marker.

    Raises :class:`MapError` for a marker that two entries, or an entry and a single marker, both hold.
    """

    def key(p: MarkerPlacement) -> int:
        name = _cv.dictionary_name(p.dictionary) if p.dictionary is not None else dictionary
        return int(p.id) if name == dictionary else MarkerKey(int(p.id), name)

    seen = {key(p): None for p in singles.values()}
    owner: dict[int, str] = {}
    out = list(singles.values())
    for e in entries:
        if isinstance(e, BoardEntry):  # one made in Python is checked as a file's is
            try:
                as_written = e.to_dict(1.0)
            except (TypeError, ValueError):
                as_written = None
            _board(str(e.name), as_written, "mm", source, dictionary)
        for p in e.placements():
            k = key(p)
            if k in seen:
                other = "a single marker" if seen[k] is None else f"entry {seen[k]!r}"
                raise MapError(
                    f"{source}: marker {k} of entry {e.name!r} is also {other} of the map; a marker (dictionary, id) "
                    "is in one place only: remove it there, or give the entry another first_id or dictionary"
                )
            seen[k] = owner[k] = e.name
            out.append(p)
    return out, owner


class _Entries:
    """What a map with rigid entries adds: its entries, each board's chess corners, and the map's shape."""

    entries: dict[str, BoardEntry | BundleEntry]
    owner: dict[int, str]

    def corners(self) -> dict[int, np.ndarray]:  # pragma: no cover - MarkerMap's
        raise NotImplementedError

    def chess_corners(self) -> dict[str, np.ndarray]:
        """Each ChArUco board entry's chess corners in the world, in OpenCV's corner-id order.

        Returns
        -------
        dict of str to ndarray, shape (N, 3)
            ``{board name: corners}``, mm; empty when the map holds no ChArUco board.
        """
        return {
            n: e.to_world(e.chess_corners_board())
            for n, e in self.entries.items()
            if isinstance(e, BoardEntry) and e.kind == "charuco"
        }

    def planarity_mm(self) -> float:
        """How far the map is from flat.

        Returns
        -------
        float
            Largest distance (mm) of any corner from the plane that fits all corners best.
        """
        pts = np.concatenate(list(self.corners().values()))
        centred = pts - pts.mean(axis=0)
        _, s, vt = np.linalg.svd(centred, full_matrices=False)
        return float(np.abs(centred @ vt[2]).max())

    def is_coplanar(self, tol_mm: float = 1.0) -> bool:
        """Whether every corner lies within ``tol_mm`` of one plane.

        Coplanar maps suit IPPE (and have a two-fold ambiguity when seen from
        afar); maps on several walls need a general solver.

        Parameters
        ----------
        tol_mm : float
            Largest distance from the plane, mm.

        Returns
        -------
        bool
        """
        return self.planarity_mm() <= tol_mm

    def entries_dict(self, scale: float) -> dict:
        """The map's entries as the map file writes them.

        Parameters
        ----------
        scale : float
            mm per unit of the map file.

        Returns
        -------
        dict
            ``{"boards": {...}, "bundles": {...}}``, only those the map has.
        """
        out: dict[str, dict] = {}
        for name, e in self.entries.items():
            out.setdefault("boards" if isinstance(e, BoardEntry) else "bundles", {})[name] = e.to_dict(scale)
        return out
