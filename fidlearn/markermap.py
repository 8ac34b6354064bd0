"""The world map: where each printed marker is, and the 3D corners that follow.

A placement gives the world position of the marker's **top-left corner** and a
rotation ``[roll, pitch, yaw]`` in degrees about the fixed world X, Y, Z axes,
applied about that corner. With rotation ``[0, 0, 0]`` the marker lies in the
world YZ plane (the north wall of the seed room) facing +X::

    TL = translation
    TR = TL + s * Y
    BR = TL + s * Y - s * Z
    BL = TL - s * Z            (s = marker side)

Corners come out in mm, in the order TL, TR, BR, BL: the winding order ArUco
detection reports.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import _cv, frames
from ._io import read_json, write_json_atomic
from ._map_keys import _Keys
from ._map_parse import (
    UNITS_TO_MM,
    MarkerKey,
    MarkerPlacement,
    _check_layout,
    _entry,
    _keyed,
    _map_options,
    _marker_size,
    _placements,
    _units_name,
)
from ._wpilib import is_wpilib, map_from_wpilib, to_wpilib
from .errors import DictionaryError, FidlearnWarning, MapError
from .markermap_entries import BoardEntry, BundleEntry, _Entries, _merge_placements, _parse_entries

__all__ = [
    "MarkerMap",
    "MarkerPlacement",
    "MarkerKey",
    "BoardEntry",
    "BundleEntry",
    "UNITS_TO_MM",
    "MARKER_CORNERS_LOCAL",
    "CORNER_NAMES",
]


#: Corner names in the winding order used everywhere (ArUco's): top-left, top-right, bottom-right, bottom-left.
CORNER_NAMES = ("TL", "TR", "BR", "BL")

#: Corners of a unit marker relative to its top-left corner, rotation [0, 0, 0]: TL, TR, BR, BL.
MARKER_CORNERS_LOCAL = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, -1.0], [0.0, 0.0, -1.0]])


class MarkerMap(_Keys, _Entries):
    """Markers placed in the world: ids, placements, marker size and dictionary.

    Build one with :meth:`load` (a JSON file) or :meth:`from_dict`. Lengths are
    stored in millimetres, whatever unit the file used.

    Parameters
    ----------
    placements : mapping of int to MarkerPlacement
        Each marker's placement (mm, degrees), by id.
    marker_size_mm : float
        Side of each marker's black square (border included, white margin not), mm.
    dictionary : str
        ArUco dictionary name, e.g. ``"ARUCO_ORIGINAL"`` or ``"6X6_250"``.
    units : {"mm", "cm", "m", "in", "ft"}
        The units the map's file uses (kept to write it back the same way).
    source : str
        Where the map came from, named in error messages.
    entries : sequence of BoardEntry or BundleEntry
        Rigid entries (:mod:`fidlearn.markermap_entries`): their markers join ``placements``.

    Attributes
    ----------
    placements : dict of int to MarkerPlacement
        Sorted by id.
    marker_size_mm, dictionary, units, source
        As given (the dictionary's name normalized). ``field_m``: a WPILib layout's field (length, width), m, else None.
    entries : dict of str to BoardEntry or BundleEntry
        The rigid entries by name; ``owner`` maps each of their markers' keys to its entry's name.

    Raises
    ------
    MapError
        If there is no marker, the size is not a positive length in mm, the units or the dictionary are
        unknown, or an id does not exist in the dictionary.

    Examples
    --------
    The seed's example (DESIGN.md): 80 mm markers, units ft, marker 0 at [0, 0, 1].

    >>> m = MarkerMap.from_dict({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}},
    ...                         units="ft", marker_size_mm=80)
    >>> m.corners()[0].tolist()
    [[0.0, 0.0, 304.8], [0.0, 80.0, 304.8], [0.0, 80.0, 224.8], [0.0, 0.0, 224.8]]
    """

    def __init__(
        self,
        placements: Mapping[int, MarkerPlacement],
        marker_size_mm: float,
        *,
        dictionary: str = "ARUCO_ORIGINAL",
        units: str = "mm",
        source: str = "<map>",
        entries: Sequence[BoardEntry | BundleEntry] = (),
    ):
        self.source = source
        self.field_m: tuple[float, float] | None = None  # a WPILib layout's field (length, width), m
        self.marker_size_mm = _marker_size(marker_size_mm, source)
        try:
            self.dictionary = _cv.dictionary_name(dictionary)
        except DictionaryError as exc:
            raise MapError(f"{source}: {exc}") from None
        self.units = _units_name(units, source)
        singles = _keyed(placements, self.dictionary, source)
        merged, self.owner = _merge_placements(singles, list(entries), self.dictionary, source)
        self.entries = {e.name: e for e in entries}
        if len(self.entries) < len(entries):
            twice = next(e.name for k, e in enumerate(entries) if e.name in [f.name for f in entries[:k]])
            raise MapError(f"{source}: two boards or bundles are named {twice!r}; give each its own name")
        self.placements: dict[int, MarkerPlacement] = _keyed(dict(enumerate(merged)), self.dictionary, source)
        if not self.placements:
            raise MapError(f"{source}: the map has no markers; add at least one placement")

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_dict(
        cls,
        d: Mapping[str, Any],
        *,
        units: str | None = None,
        marker_size_mm: float | None = None,
        dictionary: str | None = None,
        source: str = "<map>",
    ) -> MarkerMap:
        """A map from the seed's bare layout, the full layout or a WPILib AprilTag field layout.

        Bare: ``{"0": {"translation": [...], "rotation": [...]}, ...}`` with
        ``units`` and ``marker_size_mm`` given here. Full: ``{"units": "ft",
        "marker_size_mm": 80, "dictionary": "ARUCO_ORIGINAL", "markers": {...}}``.
        A value given both here and in the file must agree. The full layout may place boards and tag bundles
        as rigid entries too (``"boards"``, ``"bundles"``: :mod:`fidlearn.markermap_entries`).
        WPILib's ``{"tags": [...], "field": {...}}`` (metres, each tag's centre; docs/conventions.md) with
        ``dictionary`` and ``marker_size_mm`` given here.

        Parameters
        ----------
        d : mapping
            The parsed JSON, either layout. ``translation`` is the top-left corner in ``units``;
            ``rotation`` is ``[roll, pitch, yaw]`` in degrees (default ``[0, 0, 0]``).
        units : {"mm", "cm", "m", "in", "ft"}, optional
            Required when ``d`` does not say its units: fidlearn never guesses.
        marker_size_mm : float, optional
            Required when ``d`` does not say it: the black square's side, mm.
        dictionary : str, optional
            ArUco dictionary; ``"ARUCO_ORIGINAL"`` when neither ``d`` nor the caller says.
        source : str
            Where ``d`` came from, named in error messages.

        Returns
        -------
        MarkerMap
            Translations converted to mm.

        Raises
        ------
        MapError
            With the field and the fix: not a map (a camera or a corner file), unknown fields (with a
            guess), no units or size, a value that disagrees with the file, a malformed placement.

        Examples
        --------
        >>> seed = {"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}}
        >>> m = MarkerMap.from_dict(seed, units="ft", marker_size_mm=80)
        >>> m.corners()[0].tolist()   # TL, TR, BR, BL, mm
        [[0.0, 0.0, 304.8], [0.0, 80.0, 304.8], [0.0, 80.0, 224.8], [0.0, 0.0, 224.8]]
        """
        if is_wpilib(d):
            return map_from_wpilib(cls, d, units, marker_size_mm, dictionary, source)
        full, markers = _check_layout(d, source)
        units, size, dictionary = _map_options(d, full, units, marker_size_mm, dictionary, source)
        try:
            dictionary = _cv.dictionary_name(dictionary)
        except DictionaryError as exc:
            raise MapError(f"{source}: {exc}") from None
        placements = {
            key: MarkerPlacement(mid, t, r, s, name)  # type: ignore[arg-type]
            for key, (mid, t, r, s, name) in _placements(markers, units, source, dictionary).items()
        }
        if not (full and "surveyed" in d):  # a survey writes each measured tilt, however small
            _warn_radians({key: p.rotation_deg for key, p in placements.items()}, source)
        entries = _parse_entries(d, units, source, dictionary) if full else []
        return cls(
            placements, _marker_size(size, source), dictionary=dictionary, units=units, source=source, entries=entries
        )

    @classmethod
    def load(
        cls,
        path: str | os.PathLike,
        units: str | None = None,
        marker_size_mm: float | None = None,
        dictionary: str | None = None,
    ) -> MarkerMap:
        """Read a map file (bare or full layout); see :meth:`from_dict`.

        Parameters
        ----------
        path : path-like
            The JSON map file.
        units, marker_size_mm, dictionary : optional
            As for :meth:`from_dict`: needed when the file does not say them, and must agree when it does.

        Returns
        -------
        MarkerMap
            Its ``source`` is the file's path.

        Raises
        ------
        MapError
            If the file is missing or not JSON, or as :meth:`from_dict`.
        """
        d = read_json(path, MapError, "world map")
        return cls.from_dict(d, units=units, marker_size_mm=marker_size_mm, dictionary=dictionary, source=str(path))

    # -- the map's content -------------------------------------------------------------
    @property
    def ids(self) -> list[int]:
        """Marker ids, sorted."""
        return list(self.placements)

    def __len__(self) -> int:
        return len(self.placements)

    def __contains__(self, marker_id: object) -> bool:
        return marker_id in self.placements

    def __iter__(self) -> Iterator[int]:
        return iter(self.placements)

    def __repr__(self) -> str:
        plane = "coplanar" if self.is_coplanar() else "not coplanar"
        sizes = sorted({self.marker_size(k) for k in self.placements})
        size = " and ".join(f"{v:g}" for v in sizes) + " mm"
        return (
            f"MarkerMap({len(self)} markers {self.ids}, {size}, {' and '.join(self.dictionaries)}, "
            f"file units {self.units}, {plane})"
        )

    def marker_corners(self, marker_id: int) -> np.ndarray:
        """One marker's corners in the world.

        Parameters
        ----------
        marker_id : int
            A marker of the map.

        Returns
        -------
        ndarray, shape (4, 3)
            World corners, mm, in TL, TR, BR, BL order (:data:`CORNER_NAMES`).

        Raises
        ------
        MapError
            If the map has no such marker.
        """
        p = self._placement(marker_id)
        local = MARKER_CORNERS_LOCAL * (p.size_mm or self.marker_size_mm)
        corners = local @ p.R_world_marker.T + np.asarray(p.translation_mm)
        return np.round(corners, 9) + 0.0  # drop -0.0 and 1e-14 noise from exact right angles

    def corners(self) -> dict[int, np.ndarray]:
        """Every marker's corners in the world.

        Returns
        -------
        dict of int to ndarray, shape (4, 3)
            ``{id: corners}``, mm, TL, TR, BR, BL.

        Examples
        --------
        >>> m = MarkerMap.from_dict({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}},
        ...                         units="ft", marker_size_mm=80)
        >>> {i: c.shape for i, c in m.corners().items()}
        {0: (4, 3)}
        """
        return {mid: self.marker_corners(mid) for mid in self.placements}

    def T_world_marker(self, marker_id: int) -> np.ndarray:
        """Pose of a marker's own frame in the world.

        The marker frame is OpenCV's: origin at the marker's centre, x from TL
        to TR, y from BL to TL (up the marker), z out of the printed face.

        Parameters
        ----------
        marker_id : int
            A marker of the map.

        Returns
        -------
        ndarray, shape (4, 4)
            ``T_world_marker``, mm.
        """
        c = self.marker_corners(marker_id)
        s = self.marker_size(marker_id)
        x = (c[1] - c[0]) / s
        y = (c[0] - c[3]) / s
        z = np.cross(x, y)
        return frames.make_transform(np.column_stack([x, y, z]), c.mean(axis=0))

    def normal(self, marker_id: int) -> np.ndarray:
        """Unit normal of a marker's printed face, pointing towards where it can be seen from.

        Parameters
        ----------
        marker_id : int
            A marker of the map.

        Returns
        -------
        ndarray, shape (3,)
            In the world frame.
        """
        return self.T_world_marker(marker_id)[:3, 2].copy()

    # -- output ------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The full layout, in the map's own units.

        Returns
        -------
        dict
            ``units``, ``marker_size_mm``, ``dictionary`` and ``markers`` (translation in ``units``,
            rotation in degrees), as :meth:`from_dict` reads it.
        """
        scale = UNITS_TO_MM[self.units]
        return {
            "units": self.units,
            "marker_size_mm": self.marker_size_mm,
            "dictionary": self.dictionary,
            "markers": {str(key): _entry(p, scale) for key, p in self.placements.items() if key not in self.owner},
            **self.entries_dict(scale),
        }

    def save(
        self,
        path: str | os.PathLike,
        format: str = "fidlearn",  # noqa: A002 - the file's format
        *,
        field_m: tuple[float, float] | None = None,
    ) -> Path:
        """Write the map as JSON (atomically): the full layout, or a WPILib AprilTag field layout.

        Parameters
        ----------
        path : path-like
            The file to write.
        format : {"fidlearn", "wpilib"}
            ``"wpilib"``: ``{"tags": [...], "field": {...}}``, metres, each tag's centre and quaternion; the map's
            markers must share one dictionary and size.
        field_m : (float, float), optional
            ``"wpilib"`` only: the field's length and width, m. Default: the field of the layout the map was read
            from; a map with none needs it (a layout carries it, and a pose outside it is refused).

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        MapError
            An unknown format; for ``"wpilib"``, markers of several dictionaries or sizes, or no field's size.
        """
        if format not in ("fidlearn", "wpilib"):
            raise MapError(f"unknown map format {format!r}; use 'fidlearn' (the full layout) or 'wpilib'")
        if format == "fidlearn":
            if field_m is not None:
                raise MapError("field_m is a WPILib layout's field; the full layout holds none: drop it")
            return write_json_atomic(path, self.to_dict())
        return write_json_atomic(path, to_wpilib(self, self.field_m if field_m is None else field_m))

    def corners_dict(self) -> dict[str, list[list[float]]]:
        """The seed's corner-file layout.

        Returns
        -------
        dict of str to list
            ``{"0": [[x, y, z], ...4]}``, mm, TL, TR, BR, BL.
        """
        return {str(mid): [[float(v) for v in row] for row in c] for mid, c in self.corners().items()}

    def save_corners(self, path: str | os.PathLike) -> Path:
        """Write :meth:`corners_dict` as JSON (atomically).

        Parameters
        ----------
        path : path-like
            The file to write.

        Returns
        -------
        Path
            The file written.
        """
        return write_json_atomic(path, self.corners_dict())


def _radian_like(value: float) -> bool:
    """Whether an angle is a multiple of 15 degrees written in radians (1.57 for 90, 3.14 for 180)."""
    steps = value / (math.pi / 12)
    near = round(steps) != 0 and abs(steps - round(steps)) * math.pi / 12 < 0.005
    return near and value != round(value) and abs(value) <= 2 * math.pi + 0.01


def _warn_radians(rotations: Mapping[Any, tuple[float, float, float]], source: str) -> None:
    """Warn (:class:`~fidlearn.errors.FidlearnWarning`) once when rotations look like radians.

    A rotation is taken for radians when each of its angles is 0 or, not a whole number, within 0.005 of a
    multiple of pi/12 (15 degrees) up to 2 pi: ``[0, 0, 1.57]`` is a quarter turn written in radians, where a
    map's rotation is degrees.

    Parameters
    ----------
    rotations : mapping of marker key to (roll, pitch, yaw)
        Each marker's rotation as the file writes it.
    source : str
        The map's name, for the message.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _warn_radians({0: (0.0, 0.0, 1.57), 1: (0.0, 0.0, 90.0)}, "map.json")
    >>> "[0, 0, 90]" in str(caught[0].message)
    True
    """
    odd = [
        (key, r) for key, r in rotations.items() if any(v != 0 for v in r) and all(v == 0 or _radian_like(v) for v in r)
    ]
    if not odd:
        return
    key, r = odd[0]
    others = f" and {len(odd) - 1} more" if len(odd) > 1 else ""
    degrees = ", ".join(f"{math.degrees(v):.0f}" for v in r)
    warnings.warn(
        f"{source}: marker {key}'s rotation [{', '.join(f'{v:g}' for v in r)}]{others} looks like radians; a map's "
        f"rotation is [roll, pitch, yaw] in degrees: if radians were meant, write [{degrees}]",
        FidlearnWarning,
        stacklevel=3,
    )
