"""Rigid entries in the survey: a board or a bundle is one unknown placement, its markers' corners fixed in it.

An entry (:mod:`fidlearn.markermap_entries`) is placed like a marker: a rotation and a point (its top-left corner,
a bundle's origin). In the survey it takes one slot of the adjustment, with the corners of all its markers in
that placement frame (``Group.local``, 4 rows a marker, in the order of ``Group.members``); a detected marker of
the entry contributes its 4 corners to the entry's slot. So a board is surveyed as the rigid object it is: its
markers cannot drift apart, and its tape prior, its suspect test and its fixed placement are the entry's.

An entry's tape prior is a marker's: its point within ``map_sigma_mm`` per coordinate, its rotation within
``map_sigma_mm / marker_size_mm`` radians (the map's marker size, not the board's: looser than a tape laid along a
whole board, which the photos make up for: they fix a board's rotation far better than any tape).

The print scale, when the survey applies it, scales a board as a whole (a board is one printed sheet) and a
bundle's markers each about their own top-left corner (markers printed apart, mounted where the bundle says).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import frames
from ..errors import SurveyError
from ..markermap import MARKER_CORNERS_LOCAL, MarkerMap
from ..markermap_entries import BoardEntry, BundleEntry
from ._geometry import fit_motion, skew


@dataclass(frozen=True)
class Group:
    """An entry as one slot of the adjustment: its name, its markers (the map's keys) and their corners.

    ``local`` is (4 * len(members), 3), mm: the members' corners (TL, TR, BR, BL each) in the entry's placement
    frame (``entry_frame``).
    """

    name: str
    members: tuple
    local: np.ndarray


def entry_frame(entry: BoardEntry | BundleEntry) -> tuple[np.ndarray, np.ndarray]:
    """``(R_world_place (3, 3), point (3,), mm)``: the entry's placement, as a marker's (its rotation, its point)."""
    return frames.rotation_from_rpy_deg(*entry.rotation_deg), np.asarray(entry.translation_mm, float)


def scaled_entry(entry: BoardEntry | BundleEntry, scale: float) -> BoardEntry | BundleEntry:
    """The entry as printed at ``scale``: a board's lengths all scaled, a bundle's markers' own sides scaled."""
    if scale == 1.0:
        return entry
    if isinstance(entry, BoardEntry):
        return dataclasses.replace(
            entry,
            marker_size_mm=entry.marker_size_mm * scale,
            square_size_mm=None if entry.square_size_mm is None else entry.square_size_mm * scale,
            separation_mm=None if entry.separation_mm is None else entry.separation_mm * scale,
        )
    sized = tuple(p if p.size_mm is None else dataclasses.replace(p, size_mm=p.size_mm * scale) for p in entry.markers)
    return dataclasses.replace(entry, markers=sized)


def entry_groups(tape: MarkerMap, scale: float = 1.0) -> dict[str, Group]:
    """Every entry of the tape map as a :class:`Group`, its markers printed at ``scale``."""
    groups = {}
    for name, entry in tape.entries.items():
        members = tuple(k for k, owner in tape.owner.items() if owner == name)
        R, p = entry_frame(entry)
        world = np.concatenate([_corners(tape, k, scale, entry, p) for k in members])
        groups[name] = Group(name, members, (world - p) @ R)
    return groups


def _corners(tape: MarkerMap, key, scale: float, entry, point: np.ndarray) -> np.ndarray:
    """Marker ``key``'s world corners (4, 3) with its entry printed at ``scale``."""
    if isinstance(entry, BoardEntry):
        return point + scale * (tape.marker_corners(key) - point)
    pl = tape.placements[key]
    return (
        np.asarray(pl.translation_mm, float)
        + (MARKER_CORNERS_LOCAL * tape.marker_size(key) * scale) @ pl.R_world_marker.T
    )


def slot_of(key, owners: dict):
    """The adjustment's slot of a marker key: its entry's name (``owners``: ``MarkerMap.owner``), or the key itself
    for a single marker."""
    return owners.get(key, key)


def slot_order(key) -> tuple:
    """A sort key for slots: single markers by id (then dictionary), entries after them by name."""
    if isinstance(key, str):
        return (1, 0, "", key)
    return (0, int(key), getattr(key, "dictionary", ""), "")


def start_from_photos(group: Group, cams: list, placed: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """An entry's placement from its markers as the photos place them (a rigid fit of ``local`` onto them).

    Used when the tape's placement of the entry is gross: its markers are then left out of the map the photos are
    located with, so ``placed`` holds the photos' placements of them, one by one (``{key: (R_world_place,
    top_left)}``). One marker's four corners fix the entry; None when the photos place none of them.
    """
    src, dst = [], []
    for m, k in enumerate(group.members):
        if k in placed and any(k in ph.corners for ph in cams):
            R, p = placed[k]
            side = np.linalg.norm(group.local[4 * m + 1] - group.local[4 * m])
            src.append(group.local[4 * m : 4 * m + 4])
            dst.append(p + (MARKER_CORNERS_LOCAL * side) @ R.T)
    if not src:
        return None
    fit = fit_motion(np.concatenate(src), np.concatenate(dst))
    return None if fit is None else (fit[1], fit[2])


def member_covariance(C: np.ndarray, R: np.ndarray, group: Group, m: int) -> np.ndarray:
    """Member ``m``'s 6x6 covariance ``[rotation, top-left corner]`` from its entry's ``C`` at rotation ``R``.

    The member's top-left corner is ``p + R q`` (``q`` its corner in the entry's frame): a rotation ``phi``
    applied on the left moves it by ``-[R q]x phi`` and turns the member's frame by ``phi``.
    """
    a = R @ group.local[4 * m]
    G = np.eye(6)
    G[3:, :3] = -skew(a)
    return G @ C @ G.T


def surveyed_entry(entry, R: np.ndarray, p: np.ndarray, scale: float):
    """The entry placed at ``(R, p)``, printed at ``scale``: what the surveyed map holds."""
    roll, pitch, yaw = (float(v) for v in frames.rpy_deg_from_rotation(R))
    x, y, z = (float(v) for v in p)
    return dataclasses.replace(scaled_entry(entry, scale), translation_mm=(x, y, z), rotation_deg=(roll, pitch, yaw))


def adjustment_slots(cams: list, placed: dict, owners: dict, fixed) -> tuple[list, list]:
    """``(free, slots)``: the adjustment's slots the photos show (a marker, or an entry by name), the fixed last."""
    seen = {slot_of(i, owners) for ph in cams for i in ph.corners if slot_of(i, owners) in placed}
    held = {slot_of(i, owners) for i in fixed}
    free = sorted(seen - held, key=slot_order)
    return free, free + sorted(seen & held, key=slot_order)


def refuse_untied(cams: list, slots: list, n_free: int, owners: dict, fixed) -> None:
    """SurveyError for placements no chain of photos links to a fixed marker (``map_sigma_mm=inf``).

    With the tape left out only the fixed markers hold the map in the world: markers whose photos share no
    marker, in a chain, with a fixed marker's photos could sit anywhere, and their placements would be the
    starting values with made-up standard deviations.
    """
    if len(slots) == n_free:
        raise SurveyError(f"no photo shows a fixed marker ({list(fixed)}): take one that does, or give map_sigma_mm")
    index = {slot: k for k, slot in enumerate(slots)}
    group = list(range(len(slots)))

    def root(k: int) -> int:
        while group[k] != k:
            k = group[k]
        return k

    for ph in cams:
        ks = [index[slot_of(i, owners)] for i in ph.corners if slot_of(i, owners) in index]
        for k in ks[1:]:
            group[root(k)] = root(ks[0])
    held = {root(k) for k in range(n_free, len(slots))}
    loose = [str(slots[k]) for k in range(n_free) if root(k) not in held]
    if loose:
        raise SurveyError(
            f"with map_sigma_mm=inf only the fixed markers ({', '.join(map(str, fixed))}) hold the map, and no chain "
            f"of photos links {', '.join(loose)} to them (each photo linking markers it shows together): take photos "
            "that show those with markers the fixed ones reach, fix one of them too, or give map_sigma_mm"
        )
