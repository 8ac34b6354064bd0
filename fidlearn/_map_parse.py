"""Reading a world map's JSON: the layout, the units, the marker size and each placement, every error with its fix."""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _cv, frames
from ._files import did_you_mean
from .errors import DictionaryError, MapError

#: Millimetres per unit for the units a map file may declare.
UNITS_TO_MM: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "ft": 304.8}


_FULL_KEYS = {
    "units",
    "marker_size_mm",
    "dictionary",
    "markers",
    "boards",
    "bundles",
    "name",
    "description",
    "surveyed",
}


def _units_name(units: Any, where: str) -> str:
    if not isinstance(units, str) or units.strip().lower() not in UNITS_TO_MM:
        raise MapError(
            f"{where}: unknown units {units!r}; use one of {', '.join(UNITS_TO_MM)} "
            "(millimetres, centimetres, metres, inches, feet)"
        )
    return units.strip().lower()


#: Largest marker side a map may declare (mm): 10 m, beyond any print.
MAX_MARKER_SIZE_MM = 10_000.0


def _marker_size(size: Any, where: str, field: str = "marker_size_mm") -> float:
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, numbers.Real):
        raise MapError(f"{where}: {field} must be a number (the black square's side in mm), got {size!r}")
    try:
        size = float(size)
    except OverflowError:  # a whole number with hundreds of digits
        raise MapError(f"{where}: {field} is too large for a number; write the black square's side in mm") from None
    if not math.isfinite(size) or size <= 0:
        raise MapError(
            f"{where}: {field} is {size:g}; it must be positive: measure the black square's side "
            "in mm (the white margin not included)"
        )
    if size > MAX_MARKER_SIZE_MM:
        raise MapError(
            f"{where}: {field} is {size:g}, more than {MAX_MARKER_SIZE_MM:g} mm; measure the black square's "
            "side in millimetres"
        )
    if size < 1.0:  # no printer makes a marker under 1 mm: a size in metres, as OpenCV's tutorials write it
        raise MapError(
            f"{where}: {field} is {size:g}, under 1 mm; if that is metres, write it in mm ({size * 1000:g}): "
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
    full = any(k in d for k in ("markers", "boards", "bundles"))
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
    markers = d.get("markers", {})
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
            if (dictionary is not None or (full and d.get("dictionary") is not None))
            else "ARUCO_ORIGINAL"
        )
    except DictionaryError as exc:
        raise MapError(f"{source}: {exc}") from None
    return units, size, dictionary


class MarkerKey(int):
    """A marker of a map drawn from another dictionary than the map's own: its id, and that dictionary.

    A map's markers are identified by (dictionary, id): the same id may be printed from two dictionaries
    (a 4X4_50 marker 3 and an ARUCO_ORIGINAL marker 3 are different markers). Markers of the map's own
    dictionary keep their plain ``int`` ids as keys; a marker of another dictionary is keyed by a
    ``MarkerKey``, an ``int`` (its id, for arithmetic and formatting with ``:d``) that equals only a
    ``MarkerKey`` of the same id and dictionary, never a plain id. Its text is ``"4X4_50:3"``, as the map
    file writes the key.

    Parameters
    ----------
    marker_id : int
        The id in ``dictionary``.
    dictionary : str
        The dictionary's name (normalized, e.g. ``"4X4_50"``).

    Attributes
    ----------
    id : int
        The plain id.
    dictionary : str
        The dictionary's name.

    Examples
    --------
    >>> k = MarkerKey(3, "4X4_50")
    >>> k == 3, k == MarkerKey(3, "4X4_50"), str(k), k.id
    (False, True, '4X4_50:3', 3)
    """

    dictionary: str

    def __new__(cls, marker_id: int, dictionary: str) -> MarkerKey:
        obj = super().__new__(cls, int(marker_id))
        obj.dictionary = str(dictionary)
        return obj

    @property
    def id(self) -> int:
        """The plain id in :attr:`dictionary`."""
        return int(self)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MarkerKey) and int(self) == int(other) and self.dictionary == other.dictionary

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    def __hash__(self) -> int:
        return hash((int(self), self.dictionary))

    def __repr__(self) -> str:
        return f"{self.dictionary}:{int(self)}"

    __str__ = __repr__

    def __reduce__(self):
        return (MarkerKey, (int(self), self.dictionary))


_KEY = re.compile(r"\s*(?:(?P<dictionary>[A-Za-z0-9_]+)\s*:\s*)?(?P<id>-?[0-9]+)\s*")


def key_json(key: int) -> int | str:
    """A marker's key as a JSON file writes it: its id, or ``"4X4_50:3"`` for a marker of another dictionary than
    its map's (JSON would write a :class:`MarkerKey`, an ``int``, as its bare number: the map's own marker of that
    id)."""
    return str(key) if isinstance(key, MarkerKey) else int(key)


def key_from_json(value: Any) -> int | None:
    """The key :func:`key_json` wrote: a whole number >= 0, or ``"DICT:ID"`` (a :class:`MarkerKey`); None for
    anything else (the caller says what it expected)."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return value if value >= 0 else None
    m = _KEY.fullmatch(value) if isinstance(value, str) else None
    if m is None or m["dictionary"] is None or int(m["id"]) < 0:
        return None
    try:
        return MarkerKey(int(m["id"]), _cv.dictionary_name(m["dictionary"]))
    except DictionaryError:
        return None


_MARKER_FIELDS = ("translation", "rotation", "size_mm", "dictionary")


def _entry_dictionary(key: Any, value: Mapping, source: str) -> str | None:
    """The dictionary a marker entry names, by its key (``"4X4_50:3"``) or its ``"dictionary"`` field (both: must
    agree); None when it names none."""
    m = _KEY.fullmatch(str(key)) if not isinstance(key, bool) else None
    names = []
    for given in (m and m["dictionary"], value.get("dictionary")):
        if given is None:
            continue
        try:
            names.append(_cv.dictionary_name(given))
        except (DictionaryError, TypeError, AttributeError) as exc:
            raise MapError(f"{source}: marker {key!r}: {exc}") from None
    if len(set(names)) > 1:
        raise MapError(
            f"{source}: marker {key!r} names dictionary {names[0]} in its key but {names[1]} in its "
            '"dictionary" field; drop one of them'
        )
    return names[0] if names else None


def _placements(markers: Mapping, units: str, source: str, dictionary: str = "ARUCO_ORIGINAL") -> dict[int, tuple]:
    """``{key: (id, translation_mm, rotation_deg, size_mm or None, dictionary or None)}`` of each marker, converted
    from ``units`` to mm. The key is the id for a marker of the map's ``dictionary`` (its dictionary then None), a
    :class:`MarkerKey` for a marker of another."""
    scale = UNITS_TO_MM[units]
    placements: dict[int, tuple] = {}
    for key, value in markers.items():
        m = _KEY.fullmatch(str(key)) if not isinstance(key, bool) else None
        mid = _marker_id(m["id"] if m else key, source)
        if not isinstance(value, Mapping):
            raise MapError(f'{source}: marker {key} must be an object with "translation" and "rotation"')
        name = _entry_dictionary(key, value, source)
        name = None if name == dictionary else name
        mkey = mid if name is None else MarkerKey(mid, name)
        where = f"{source}: marker {mkey}"
        if mkey in placements:
            raise MapError(f"{where} appears twice (as {key!r}); each marker (dictionary, id) must be unique")
        extra = set(value) - set(_MARKER_FIELDS)
        if extra:
            field = sorted(extra)[0]
            raise MapError(
                f"{where} has unknown field {field!r}{did_you_mean(field, _MARKER_FIELDS)}; "
                "a placement has translation and rotation, and may have size_mm and dictionary"
            )
        if "translation" not in value:
            raise MapError(f'{where} has no "translation" (the world position of its top-left corner, in {units})')
        t = _vector3(value["translation"], where, "translation", f"[x, y, z] in {units}")
        r = _vector3(value.get("rotation", [0, 0, 0]), where, "rotation", "[roll, pitch, yaw] in degrees")
        size = value.get("size_mm")
        if size is not None:
            size = _marker_size(size, where, "size_mm")
        placements[mkey] = (mid, tuple(v * scale for v in t), r, size, name)
    return placements


@dataclass(frozen=True)
class MarkerPlacement:
    """One marker's placement: its top-left corner in the world and its roll-pitch-yaw.

    Attributes
    ----------
    id : int
        The marker id printed under the marker.
    translation_mm : (float, float, float)
        World position of the marker's top-left corner, mm.
    rotation_deg : (float, float, float)
        ``[roll, pitch, yaw]`` in degrees about the fixed world X, Y, Z axes, applied about the
        top-left corner (``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``).
    size_mm : float or None
        This marker's black square side, mm; None: the map's ``marker_size_mm``.
    dictionary : str or None
        This marker's dictionary; None: the map's ``dictionary``.
    """

    id: int
    translation_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]
    size_mm: float | None = None
    dictionary: str | None = None

    @property
    def R_world_marker(self) -> np.ndarray:
        """Rotation (3, 3) of the placement, ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
        return frames.rotation_from_rpy_deg(*self.rotation_deg)


def _entry(p: MarkerPlacement, scale: float) -> dict:
    """A placement as the full layout writes it, in units of ``scale`` mm."""
    out: dict[str, Any] = {
        "translation": [round(v / scale, 9) for v in p.translation_mm],
        "rotation": list(p.rotation_deg),
    }
    if p.size_mm is not None:
        out["size_mm"] = p.size_mm
    if p.dictionary is not None:
        out["dictionary"] = p.dictionary
    return out


def _keyed(placements: Mapping[int, MarkerPlacement], dictionary: str, source: str) -> dict[int, MarkerPlacement]:
    """The placements keyed as the map keys them (:meth:`MarkerMap.key`), each size checked and each dictionary
    named as the map names it (None for the map's own), sorted by id; raises :class:`MapError` for a marker twice
    or an id its dictionary does not have."""
    out: dict[int, MarkerPlacement] = {}
    for p in placements.values():
        name = p.dictionary
        if name is not None:
            try:
                name = _cv.dictionary_name(name)
            except DictionaryError as exc:
                raise MapError(f"{source}: marker {p.id}: {exc}") from None
        name = None if name == dictionary else name
        size = None if p.size_mm is None else _marker_size(p.size_mm, f"{source}: marker {p.id}", "size_mm")
        key = int(p.id) if name is None else MarkerKey(int(p.id), name)
        if key in out:
            raise MapError(f"{source}: marker {key} appears twice; each marker (dictionary, id) must be unique")
        count = _cv.dictionary_size(name or dictionary)
        if not 0 <= int(p.id) < count:
            raise MapError(
                f"{source}: marker id {p.id} does not exist in dictionary {name or dictionary}, "
                f"which has ids 0 to {count - 1}; check the id or the dictionary"
            )
        out[key] = MarkerPlacement(int(p.id), p.translation_mm, p.rotation_deg, size, name)
    _refuse_same_patterns(out, dictionary, source)
    order = {n: k for k, n in enumerate([dictionary, *sorted({p.dictionary or "" for p in out.values()})])}
    return dict(sorted(out.items(), key=lambda kv: (int(kv[0]), order[kv[1].dictionary or dictionary])))


def _refuse_same_patterns(out: Mapping[int, MarkerPlacement], dictionary: str, source: str) -> None:
    """Raise :class:`MapError` for two markers of different dictionaries that print the same pattern (in any of
    its four turns): OpenCV's 4X4_50 is the first 50 markers of 4X4_100, 4X4_250 and 4X4_1000, so ``"3"`` of one
    and ``"4X4_250:3"`` are one printed marker, found by both detectors and matched to both placements."""
    if len({p.dictionary or dictionary for p in out.values()}) < 2:
        return
    seen: dict[tuple[int, bytes], tuple[int, str]] = {}
    for key, p in out.items():
        name = p.dictionary or dictionary
        d = _cv.get_dictionary(name)
        turns = np.asarray(d.bytesList)[int(p.id)]  # (bytes, 4 turns)
        for turn in range(turns.shape[-1]):
            other = seen.get((d.markerSize, turns[:, turn].tobytes()))
            if other is not None and other[1] != name:
                raise MapError(
                    f"{source}: markers {other[0]} and {key} are one printed pattern ({other[1]} and {name} share "
                    "it): a detector cannot tell them apart; keep one of them, or give the other a different id"
                )
        seen[(d.markerSize, turns[:, 0].tobytes())] = (key, name)


def id_ranges(ids: list[int]) -> str:
    """Sorted marker ids as people write them, runs of consecutive ids joined by a dash.

    Parameters
    ----------
    ids : list of int
        Marker ids, sorted.

    Returns
    -------
    str
        The ids, comma-separated, each run of consecutive ids as ``first-last``.

    Examples
    --------
    >>> id_ranges([20, 21, 22, 25, 27, 28])
    '20-22, 25, 27-28'
    """
    parts, start = [], None
    for k, i in enumerate(ids):
        start = i if start is None else start
        if k + 1 == len(ids) or ids[k + 1] != i + 1:
            parts.append(str(i) if i == start else f"{start}-{i}")
            start = None
    return ", ".join(parts)
