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
import numbers
import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import _cv, frames
from ._files import did_you_mean
from ._io import read_json, write_json_atomic
from .errors import DictionaryError, MapError

__all__ = ["MarkerMap", "MarkerPlacement", "UNITS_TO_MM", "MARKER_CORNERS_LOCAL", "CORNER_NAMES"]

#: Millimetres per unit for the units a map file may declare.
UNITS_TO_MM: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "ft": 304.8}

#: Corner names in the winding order used everywhere (ArUco's): top-left, top-right, bottom-right, bottom-left.
CORNER_NAMES = ("TL", "TR", "BR", "BL")

#: Corners of a unit marker relative to its top-left corner, rotation [0, 0, 0]: TL, TR, BR, BL.
MARKER_CORNERS_LOCAL = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, -1.0], [0.0, 0.0, -1.0]])

_FULL_KEYS = {"units", "marker_size_mm", "dictionary", "markers", "name", "description"}


@dataclass(frozen=True)
class MarkerPlacement:
    """One marker's placement: top-left corner (mm, world) and roll-pitch-yaw (degrees)."""

    id: int
    translation_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]

    @property
    def R_world_marker(self) -> np.ndarray:
        """Rotation (3, 3) of the placement, ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
        return frames.rotation_from_rpy_deg(*self.rotation_deg)


def _units_name(units: Any, where: str) -> str:
    if not isinstance(units, str) or units.strip().lower() not in UNITS_TO_MM:
        raise MapError(
            f"{where}: unknown units {units!r}; use one of {', '.join(UNITS_TO_MM)} "
            "(millimetres, centimetres, metres, inches, feet)"
        )
    return units.strip().lower()


#: Largest marker side a map may declare (mm): 10 m, beyond any print.
MAX_MARKER_SIZE_MM = 10_000.0


def _marker_size(size: Any, where: str) -> float:
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, numbers.Real):
        raise MapError(f"{where}: marker_size_mm must be a number (the black square's side in mm), got {size!r}")
    try:
        size = float(size)
    except OverflowError:  # a whole number with hundreds of digits
        raise MapError(
            f"{where}: marker_size_mm is too large for a number; write the black square's side in mm"
        ) from None
    if not math.isfinite(size) or size <= 0:
        raise MapError(
            f"{where}: marker_size_mm is {size:g}; it must be positive: measure the black square's side "
            "in mm (the white margin not included)"
        )
    if size > MAX_MARKER_SIZE_MM:
        raise MapError(
            f"{where}: marker_size_mm is {size:g}, more than {MAX_MARKER_SIZE_MM:g} mm; measure the black square's "
            "side in millimetres"
        )
    if size < 1.0:  # no printer makes a marker under 1 mm: a size in metres, as OpenCV's tutorials write it
        raise MapError(
            f"{where}: marker_size_mm is {size:g}, under 1 mm; if that is metres, write it in mm ({size * 1000:g}): "
            "the black square's side in millimetres"
        )
    return size


def _vector3(value: Any, where: str, field: str, meaning: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)):
        raise MapError(f"{where}: {field} must be a list of 3 numbers {meaning}, got {value!r}")
    if len(value) != 3:
        raise MapError(f"{where}: {field} has {len(value)} values, expected 3 {meaning}")
    out = []
    for v in value:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
            raise MapError(f"{where}: {field} contains {v!r}, which is not a number; expected 3 numbers {meaning}")
        if isinstance(v, int) and abs(v) > 1e300:  # a whole number with hundreds of digits overflows float()
            raise MapError(f"{where}: {field} contains a number too large for a float; check the units {meaning}")
        if not math.isfinite(v):
            raise MapError(f"{where}: {field} contains {v}, expected finite numbers {meaning}")
        if abs(v) > 1e9:
            raise MapError(f"{where}: {field} contains {v:g}, far beyond any room; check the units {meaning}")
        out.append(float(v))
    return (out[0], out[1], out[2])


def _is_corner_list(value: Any) -> bool:
    """Whether ``value`` looks like one marker of a corner file: four lists of three numbers."""
    return (
        isinstance(value, list)
        and len(value) == 4
        and all(isinstance(c, list) and len(c) == 3 and all(isinstance(v, numbers.Real) for v in c) for c in value)
    )


def _marker_id(key: Any, where: str) -> int:
    text = str(key).strip()
    if isinstance(key, bool) or not re.fullmatch(r"-?[0-9]+", text):
        raise MapError(
            f"{where}: marker id {key!r} is not a whole number; ids are the integers printed under each marker"
        )
    mid = int(text)
    if mid < 0:
        raise MapError(f"{where}: marker id {mid} is negative; ids start at 0")
    return mid


def _check_layout(d: Any, source: str) -> tuple[bool, Mapping]:
    """``(full, markers)``: whether ``d`` is the full layout, and its id -> placement mapping.

    Refuses what is not a map (a camera file, a corner file) and unknown fields, with the fix.
    """
    if not isinstance(d, Mapping):
        raise MapError(f"{source}: expected a JSON object mapping marker ids to placements, got {type(d).__name__}")
    if "camera_matrix" in d:  # the two files of the command line swapped
        raise MapError(
            f"{source}: this is a camera file (it has camera_matrix), not a world map (the map does not say "
            "its units, marker size or placements); give the map of marker placements here (command line: "
            "--map) and the camera file as the camera (--camera)"
        )
    full = "markers" in d
    if not full and any(k in _FULL_KEYS for k in d):
        others = [k for k in d if k not in _FULL_KEYS]
        hint = f" (unknown field {others[0]!r}{did_you_mean(others[0], ['markers'])})" if others else ""
        raise MapError(
            f'{source}: the map has {", ".join(k for k in d if k in _FULL_KEYS)} but no "markers"{hint}; '
            'a full map puts the placements under "markers": {"0": {"translation": [...], ...}}'
        )
    if not full and d and all(_is_corner_list(v) for v in d.values()):
        raise MapError(
            f"{source}: this is a corner file (four [x, y, z] corners in mm per id, as 'fidlearn corners' "
            "writes it), not a world map; give the map of placements it was made from"
        )
    if not full:
        return False, d
    unknown = set(d) - _FULL_KEYS
    if unknown:
        field = sorted(unknown)[0]
        raise MapError(
            f"{source}: unknown field {field!r}{did_you_mean(field, _FULL_KEYS)}; a full map has "
            f"{', '.join(sorted(_FULL_KEYS))}"
        )
    markers = d["markers"]
    if not isinstance(markers, Mapping):
        raise MapError(f'{source}: "markers" must be an object mapping ids to placements')
    return True, markers


def _disagree(name: str, given: Any, in_file: Any, source: str) -> bool:
    """Whether a value given by the caller differs from the file's (units, marker size or dictionary)."""
    if name == "units":
        return str(given).lower() != str(in_file).lower()
    if name == "marker_size_mm":
        return not math.isclose(_marker_size(given, source), _marker_size(in_file, source))
    return name == "dictionary" and _cv.dictionary_name(given) != _cv.dictionary_name(in_file)


def _pick(d: Mapping, full: bool, name: str, given: Any, meaning: str, source: str) -> Any:
    """The file's value of ``name`` or the caller's; both given must agree; neither: :class:`MapError` (``meaning``)."""
    in_file = d.get(name) if full else None
    if in_file is not None and given is not None and _disagree(name, given, in_file, source):
        raise MapError(f"{source}: the file says {name} = {in_file!r} but {given!r} was given; drop one of them")
    value = in_file if in_file is not None else given
    if value is None:
        raise MapError(f"{source}: {meaning}")
    return value


def _map_options(
    d: Mapping, full: bool, units: Any, marker_size_mm: Any, dictionary: Any, source: str
) -> tuple[str, Any, str]:
    """``(units, marker size, dictionary)`` from the file and the caller: units and size are required."""
    units = _pick(
        d,
        full,
        "units",
        units,
        'no units: the map does not say its units; add "units": "ft" (or mm, cm, m, in) to the file, '
        "or pass units= (command line: --units); fidlearn never guesses",
        source,
    )
    units = _units_name(units, source)
    size = _pick(
        d,
        full,
        "marker_size_mm",
        marker_size_mm,
        'no marker size: add "marker_size_mm": 80 (the black square\'s side) to the file, '
        "or pass marker_size_mm= (command line: --marker-size-mm)",
        source,
    )
    try:
        dictionary = (
            _pick(d, full, "dictionary", dictionary, "", source)
            if (dictionary or (full and d.get("dictionary")))
            else "ARUCO_ORIGINAL"
        )
    except DictionaryError as exc:
        raise MapError(f"{source}: {exc}") from None
    return units, size, dictionary


def _placements(markers: Mapping, units: str, source: str) -> dict[int, MarkerPlacement]:
    """Each marker's placement, its translation converted from ``units`` to mm; :class:`MapError` with the fix."""
    scale = UNITS_TO_MM[units]
    placements: dict[int, MarkerPlacement] = {}
    for key, value in markers.items():
        mid = _marker_id(key, source)
        where = f"{source}: marker {mid}"
        if mid in placements:
            raise MapError(f"{where} appears twice (as {key!r}); each marker id must be unique")
        if not isinstance(value, Mapping):
            raise MapError(f'{where} must be an object with "translation" and "rotation"')
        extra = set(value) - {"translation", "rotation"}
        if extra:
            field = sorted(extra)[0]
            raise MapError(
                f"{where} has unknown field {field!r}{did_you_mean(field, ('translation', 'rotation'))}; "
                "a placement has translation and rotation"
            )
        if "translation" not in value:
            raise MapError(f'{where} has no "translation" (the world position of its top-left corner, in {units})')
        t = _vector3(value["translation"], where, "translation", f"[x, y, z] in {units}")
        r = _vector3(value.get("rotation", [0, 0, 0]), where, "rotation", "[roll, pitch, yaw] in degrees")
        placements[mid] = MarkerPlacement(mid, tuple(v * scale for v in t), r)  # type: ignore[arg-type]
    return placements


class MarkerMap:
    """Markers placed in the world: ids, placements, marker size and dictionary.

    Build one with :meth:`load` (a JSON file) or :meth:`from_dict`. Lengths are
    stored in millimetres, whatever unit the file used.

    Examples
    --------
    >>> m = MarkerMap.from_dict({"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}},
    ...                         units="ft", marker_size_mm=80)
    >>> m.corners()[0].tolist()
    [[0.0, 0.0, 304.8], [0.0, 80.0, 304.8], [0.0, 80.0, 224.8], [0.0, 0.0, 224.8]]
    """

    def __init__(
        self,
        placements: Mapping[int, MarkerPlacement],
        marker_size_mm: float,
        dictionary: str = "ARUCO_ORIGINAL",
        units: str = "mm",
        source: str = "<map>",
    ):
        self.source = source
        self.marker_size_mm = _marker_size(marker_size_mm, source)
        try:
            self.dictionary = _cv.dictionary_name(dictionary)
        except DictionaryError as exc:
            raise MapError(f"{source}: {exc}") from None
        self.units = _units_name(units, source)
        self.placements: dict[int, MarkerPlacement] = dict(sorted(placements.items()))
        if not self.placements:
            raise MapError(f"{source}: the map has no markers; add at least one placement")
        size = _cv.dictionary_size(self.dictionary)
        too_big = [i for i in self.placements if i >= size]
        if too_big:
            raise MapError(
                f"{source}: marker id {too_big[0]} does not exist in dictionary {self.dictionary}, "
                f"which has ids 0 to {size - 1}; check the id or the dictionary"
            )

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_dict(
        cls,
        d: Mapping[str, Any],
        units: str | None = None,
        marker_size_mm: float | None = None,
        dictionary: str | None = None,
        source: str = "<map>",
    ) -> MarkerMap:
        """A map from the seed's bare layout or the full layout.

        Bare: ``{"0": {"translation": [...], "rotation": [...]}, ...}`` with
        ``units`` and ``marker_size_mm`` given here. Full: ``{"units": "ft",
        "marker_size_mm": 80, "dictionary": "ARUCO_ORIGINAL", "markers": {...}}``.
        A value given both here and in the file must agree.
        """
        full, markers = _check_layout(d, source)
        units, size, dictionary = _map_options(d, full, units, marker_size_mm, dictionary, source)
        placements = _placements(markers, units, source)
        return cls(placements, _marker_size(size, source), dictionary, units, source)

    @classmethod
    def load(
        cls,
        path: str | os.PathLike,
        units: str | None = None,
        marker_size_mm: float | None = None,
        dictionary: str | None = None,
    ) -> MarkerMap:
        """Read a map file (bare or full layout); see :meth:`from_dict`."""
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
        return (
            f"MarkerMap({len(self)} markers {self.ids}, {self.marker_size_mm:g} mm, {self.dictionary}, "
            f"file units {self.units}, {plane})"
        )

    def marker_corners(self, marker_id: int) -> np.ndarray:
        """World corners (4, 3), mm, of one marker in TL, TR, BR, BL order."""
        if marker_id not in self.placements:
            raise MapError(f"{self.source}: no marker {marker_id} in the map; it has {self.ids}")
        p = self.placements[marker_id]
        local = MARKER_CORNERS_LOCAL * self.marker_size_mm
        corners = local @ p.R_world_marker.T + np.asarray(p.translation_mm)
        return np.round(corners, 9) + 0.0  # drop -0.0 and 1e-14 noise from exact right angles

    def corners(self) -> dict[int, np.ndarray]:
        """World corners of every marker: ``{id: (4, 3) array}``, mm, TL, TR, BR, BL."""
        return {mid: self.marker_corners(mid) for mid in self.placements}

    def T_world_marker(self, marker_id: int) -> np.ndarray:
        """Pose (4, 4) of a marker's own frame in the world.

        The marker frame is OpenCV's: origin at the marker's centre, x from TL
        to TR, y from BL to TL (up the marker), z out of the printed face.
        """
        c = self.marker_corners(marker_id)
        x = (c[1] - c[0]) / self.marker_size_mm
        y = (c[0] - c[3]) / self.marker_size_mm
        z = np.cross(x, y)
        return frames.make_transform(np.column_stack([x, y, z]), c.mean(axis=0))

    def normal(self, marker_id: int) -> np.ndarray:
        """Unit normal (3,) of a marker's printed face, pointing towards where it can be seen from."""
        return self.T_world_marker(marker_id)[:3, 2].copy()

    def planarity_mm(self) -> float:
        """Largest distance (mm) of any corner from the plane that fits all corners best."""
        pts = np.concatenate(list(self.corners().values()))
        centred = pts - pts.mean(axis=0)
        _, s, vt = np.linalg.svd(centred, full_matrices=False)
        return float(np.abs(centred @ vt[2]).max())

    def is_coplanar(self, tol_mm: float = 1.0) -> bool:
        """Whether every corner lies within ``tol_mm`` of one plane.

        Coplanar maps suit IPPE (and have a two-fold ambiguity when seen from
        afar); maps on several walls need a general solver.
        """
        return self.planarity_mm() <= tol_mm

    # -- output ------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The full layout, in the map's own units."""
        scale = UNITS_TO_MM[self.units]
        return {
            "units": self.units,
            "marker_size_mm": self.marker_size_mm,
            "dictionary": self.dictionary,
            "markers": {
                str(mid): {
                    "translation": [round(v / scale, 9) for v in p.translation_mm],
                    "rotation": list(p.rotation_deg),
                }
                for mid, p in self.placements.items()
            },
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write the full layout to ``path`` (atomically)."""
        return write_json_atomic(path, self.to_dict())

    def corners_dict(self) -> dict[str, list[list[float]]]:
        """The seed's corner-file layout: ``{"0": [[x, y, z] x 4]}``, mm, TL, TR, BR, BL."""
        return {str(mid): [[float(v) for v in row] for row in c] for mid, c in self.corners().items()}

    def save_corners(self, path: str | os.PathLike) -> Path:
        """Write :meth:`corners_dict` to ``path`` as JSON (atomically)."""
        return write_json_atomic(path, self.corners_dict())
