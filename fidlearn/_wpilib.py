"""WPILib's AprilTag field layout (``AprilTagFieldLayout`` JSON): read into a map's placements, written from a map.

The file: ``{"tags": [{"ID": 1, "pose": {"translation": {"x", "y", "z"}, "rotation": {"quaternion": {"W", "X",
"Y", "Z"}}}}, ...], "field": {"length", "width"}}``, metres. Each pose is the tag's **centre** in the field
frame (right-handed, Z up, as fidlearn's world) and the tag's frame: x out of the printed face (towards
whoever can see it), y to that viewer's right, z up the tag. That is fidlearn's placement frame at rotation
``[0, 0, 0]`` (the marker in the YZ plane facing +X, TL -> TR along +Y), moved from the top-left corner to the
centre: ``TL = centre + R @ (0, -s/2, +s/2)`` (s the black square's side). The file holds neither the tag family
nor the size: the caller gives both (FRC: ``dictionary="apriltag_36h11"``, ``marker_size_mm=165.1``).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import frames
from ._files import did_you_mean
from .errors import MapError

#: The tag's top-left corner from its centre, in units of the side, tag frame (x out, y right, z up).
TL_FROM_CENTRE = np.array([0.0, -0.5, 0.5])


def is_wpilib(d: Any) -> bool:
    """Whether parsed JSON is a WPILib AprilTag field layout (it has a ``"tags"`` list)."""
    return isinstance(d, Mapping) and "tags" in d


#: The farthest a layout's number may reach (m): beyond any field, and what a full map file allows (1e9 mm).
_FARTHEST_M = 1e6


def _number(value: Any, where: str, field: str) -> float:
    try:
        out = float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else math.nan
    except OverflowError:  # an int too large for a float
        out = math.inf
    if not abs(out) <= _FARTHEST_M:
        raise MapError(
            f"{where}: {field} must be a finite number of metres (at most {_FARTHEST_M:g}), got {value!r:.40}"
        )
    return out


def _get(d: Any, key: str, where: str, what: str) -> Any:
    if not isinstance(d, Mapping) or key not in d:
        known = list(d) if isinstance(d, Mapping) else []
        hint = did_you_mean(key, known) if known else ""
        raise MapError(f'{where}: no "{key}"{hint}; a WPILib tag is {what}')
    return d[key]


_TAG = (
    '{"ID": 1, "pose": {"translation": {"x": .., "y": .., "z": ..}, "rotation": {"quaternion": {"W", "X", "Y", "Z"}}}}'
)


def placements_from_wpilib(d: Mapping, marker_size_mm: float, source: str) -> list[tuple[int, tuple, tuple]]:
    """``[(id, top-left corner (mm), rotation [roll, pitch, yaw] (deg))]`` of each tag of a WPILib layout.

    Raises :class:`MapError` naming the tag and the field for anything malformed, a quaternion far from unit
    length or an id twice.
    """
    tags = d["tags"]
    if not isinstance(tags, list) or not tags:
        raise MapError(f'{source}: "tags" must be a non-empty list of tags, each {_TAG}')
    out: list[tuple[int, tuple, tuple]] = []
    seen: set[int] = set()
    for k, tag in enumerate(tags):
        where = f"{source}: tags[{k}]"
        tid = _get(tag, "ID", where, _TAG)
        if isinstance(tid, bool) or not isinstance(tid, int) or tid < 0:
            raise MapError(f"{where}: ID must be a whole number >= 0, got {tid!r:.40}")
        if tid in seen:
            raise MapError(f"{where}: tag ID {tid} appears twice; each tag's ID must be unique")
        seen.add(tid)
        where = f"{source}: tag {tid}"
        pose = _get(tag, "pose", where, _TAG)
        t = _get(pose, "translation", where, _TAG)
        q = _get(_get(pose, "rotation", where, _TAG), "quaternion", where, _TAG)
        centre = np.array([_number(_get(t, a, where, _TAG), where, f"translation {a}") for a in "xyz"]) * 1000.0
        wxyz = np.array([_number(_get(q, a, where, _TAG), where, f"quaternion {a}") for a in "WXYZ"])
        norm = float(np.linalg.norm(wxyz))
        if abs(norm - 1.0) > 1e-3:
            raise MapError(f"{where}: the quaternion has length {norm:.4g}; a rotation's quaternion has length 1")
        R = frames.matrix_from_quaternion(np.r_[wxyz[1:], wxyz[0]] / norm)
        top_left = centre + marker_size_mm * (R @ TL_FROM_CENTRE)
        rpy = frames.rpy_deg_from_rotation(R)
        out.append((tid, tuple(float(v) for v in top_left), tuple(float(v) for v in rpy)))
    return out


def field_size_m(d: Mapping, source: str) -> tuple[float, float] | None:
    """``(length, width)`` of the layout's ``"field"``, m, or None when it has none."""
    field = d.get("field")
    if field is None:
        return None
    where = f"{source}: field"
    length, width = (_number(_get(field, a, where, '{"length": m, "width": m}'), where, a) for a in ("length", "width"))
    if length <= 0 or width <= 0:
        raise MapError(
            f"{where}: length {length:g} and width {width:g} must both be above 0 (m): the field's size, which every "
            "camera is on (FRC 2024: 16.541 x 8.211)"
        )
    return length, width


def to_wpilib(marker_map: Any, field_m: tuple[float, float] | None = None) -> dict:
    """A map as a WPILib AprilTag field layout (metres, each tag's centre and quaternion).

    Raises :class:`MapError` when the map's markers are not all of one dictionary and one size (the file
    holds neither), a marker id would repeat, or the field's size is not known (``field_m`` None): WPILib's
    layouts carry it, and fidlearn refuses a pose outside it, so a size made up from the tags would refuse
    cameras that stand where the map's own photos were taken.
    """
    sizes = {marker_map.marker_size(k) for k in marker_map.ids}
    used = sorted({marker_map.marker_dictionary(k) for k in marker_map.ids})
    if len(used) > 1 or len(sizes) > 1:
        raise MapError(
            f"{marker_map.source}: a WPILib field layout holds tags of one family and one size, but this map has "
            f"{' and '.join(used)}, {' and '.join(f'{s:g}' for s in sorted(sizes))} mm; save "
            "each family and size to a layout of its own"
        )
    if field_m is None:
        raise MapError(
            f"{marker_map.source}: a WPILib field layout says the field's length and width (m), which this map does "
            "not hold (it was not read from a field layout): give them, save(path, format='wpilib', "
            "field_m=(16.541, 8.211)), the field that every tag and camera is on"
        )
    try:
        length, width = field_m
    except (TypeError, ValueError):
        raise MapError(f"field_m must be the field's (length, width) in metres, got {field_m!r:.40}") from None
    length, width = field_size_m({"field": {"length": length, "width": width}}, "field_m") or (0.0, 0.0)
    tags = []
    for key in marker_map.ids:
        T = marker_map.T_world_marker(key)  # OpenCV's marker frame: x TL->TR, y up, z out of the face
        R = T[:3, :3] @ np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # to x out, y right, z up
        x, y, z, w = frames.quaternion_from_matrix(R)
        c = T[:3, 3] / 1000.0
        tags.append(
            {
                "ID": int(key),
                "pose": {
                    "translation": {"x": float(c[0]), "y": float(c[1]), "z": float(c[2])},
                    "rotation": {"quaternion": {"W": float(w), "X": float(x), "Y": float(y), "Z": float(z)}},
                },
            }
        )
    return {"tags": tags, "field": {"length": length, "width": width}}


def map_from_wpilib(cls: Any, d: Mapping, units: Any, marker_size_mm: Any, dictionary: Any, source: str) -> Any:
    """The :class:`~fidlearn.MarkerMap` (``cls``) of a WPILib layout: the family and the size from the caller."""
    from ._map_parse import MarkerPlacement, _marker_size

    missing = [n for n, v in (("dictionary", dictionary), ("marker_size_mm", marker_size_mm)) if v is None]
    if missing:
        raise MapError(
            f"{source}: a WPILib AprilTag field layout does not say its tags' {' or '.join(missing)}; give them, e.g. "
            'MarkerMap.load(path, dictionary="apriltag_36h11", marker_size_mm=165.1) (FRC\'s 6.5 in tags; command '
            "line: --dictionary, --marker-size-mm)"
        )
    if units is not None and str(units).strip().lower() != "m":
        raise MapError(f"{source}: a WPILib field layout is in metres, but units={units!r} was given; drop it")
    unknown = sorted(set(d) - {"tags", "field"})
    if unknown:
        raise MapError(f"{source}: unknown field {unknown[0]!r} in a WPILib field layout, which has tags and field")
    size = _marker_size(marker_size_mm, source)
    placements = {
        tid: MarkerPlacement(tid, t, r)  # type: ignore[arg-type]
        for tid, t, r in placements_from_wpilib(d, size, source)
    }
    out = cls(placements, size, dictionary=dictionary, units="m", source=source)
    out.field_m = field_size_m(d, source)
    out.layout_format = "wpilib"  # what a map made from it (a survey's) is saved as by default
    return out


def layout_format(marker_map: Any) -> str:
    """``"wpilib"`` for a map read from a WPILib field layout, else ``"fidlearn"`` (the format to save it back in)."""
    return "wpilib" if getattr(marker_map, "layout_format", None) == "wpilib" else "fidlearn"


#: How far outside a WPILib layout's field (m) a camera may be before its pose is refused: a robot's camera
#: overhangs the field's edge by less, and a pose behind a wall of tags is further out.
FIELD_MARGIN_M = 0.25


def outside_field(marker_map: Any, position_mm: np.ndarray, keys: Any) -> str | None:
    """Why a camera at ``position_mm`` cannot be on the field of a WPILib layout (None: it can, or no field).

    A field layout's tags face into the field; a map whose tags' corners are mirrored (TL and TR swapped, the
    tags turned to face the wall) fits the same pictures with a low residual from behind the wall, outside the
    field. That pose is refused with the fix, never returned.
    """
    field = getattr(marker_map, "field_m", None)
    if field is None:
        return None
    x, y = np.asarray(position_mm, float)[:2] / 1000.0
    out = max(-x, x - field[0], -y, y - field[1])
    if out <= FIELD_MARGIN_M:
        return None
    return (
        f"the camera's pose from tags {[int(k) for k in keys]} is at x = {x:.2f} m, y = {y:.2f} m, {out:.2f} m "
        f"outside the {field[0]:g} x {field[1]:g} m field of {marker_map.source}: a pose behind the tags' wall, "
        "which mirrored corners give (TL and TR swapped: a tag frame with y to the viewer's left, or a quaternion "
        "read as W last); check the layout's tag frame (x out of the tag, y to the viewer's right, z up) and the "
        "corner order TL, TR, BR, BL"
    )
