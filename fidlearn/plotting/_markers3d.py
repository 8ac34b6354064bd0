"""Markers drawn in a 3D room: filled squares at their world corners, labelled by id (a board or bundle once)."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from mpl_toolkits.mplot3d import Axes3D
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from .._map_parse import id_ranges
from ..errors import PlotError
from ..markermap import CORNER_NAMES, MarkerKey, MarkerMap


def draw_markers(
    ax: Axes3D,
    marker_map: MarkerMap,
    *,
    ids: Iterable[int] | None = None,
    color: str = "0.2",
    show_ids: bool = True,
    show_corners: bool = False,
    alpha: float = 0.9,
) -> Poly3DCollection:
    """Draw markers as filled squares at their world corners, with their ids.

    The top-left corner of each marker gets a red dot, so a wrong rotation in a
    map shows at a glance; the id is written just above the marker's top edge. The
    markers of a board or a bundle of the map get one label instead, above the
    entry: its name and its markers' ids (``wall board (20-36)``).

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        A 3D Axes in mm (:func:`new_axes_3d`).
    marker_map : MarkerMap
    ids : iterable of int, optional
        The markers to draw (the map's keys: a marker of another dictionary than the map's is its
        ``MarkerKey``); all by default.
    color : str
    show_ids : bool
    show_corners : bool
        Label TL, TR, BR, BL too.
    alpha : float

    Returns
    -------
    Poly3DCollection
        One polygon per marker, vertices TL, TR, BR, BL (mm, world).

    Raises
    ------
    PlotError
        If one of ``ids`` is not a marker of the map.
    """
    corners = marker_map.corners()
    ids = list(corners) if ids is None else list(ids)
    missing = [i for i in ids if i not in corners]
    if missing:
        known = ", ".join(str(k) for k in corners)
        raise PlotError(f"draw_markers: markers {missing} are not in the map {marker_map.source} (it has {known})")
    quads = [corners[i] for i in ids]
    coll = Poly3DCollection(quads, facecolors=color, edgecolors="k", linewidths=1.0, alpha=alpha)
    ax.add_collection3d(coll)
    owner = marker_map.owner
    for mid, c in zip(ids, quads):
        ax.scatter(*c[0], color="tab:red", s=12, depthshade=False)
        if show_ids and mid not in owner:  # just above the top edge, clear of the dark face
            ax.text(*((c[0] + c[1]) / 2 + 0.45 * (c[0] - c[3])), str(mid), **_ID_STYLE)
        if show_corners:
            for name, p in zip(CORNER_NAMES, c):
                ax.text(*p, name, fontsize=7, color="tab:red")
    if show_ids:
        _label_entries(ax, marker_map, {i: c for i, c in zip(ids, quads) if i in owner})
    return coll


_ID_STYLE = {"color": "k", "fontsize": 10, "ha": "center", "va": "center", "fontweight": "bold"}


def _label_entries(ax: Axes3D, marker_map: MarkerMap, quads: dict) -> None:
    """One label per board or bundle drawn: its name and its markers' ids, above its highest corner."""
    by_entry: dict[str, list] = {}
    for key, c in quads.items():
        by_entry.setdefault(marker_map.owner[key], []).append((key, c))
    for name, members in by_entry.items():
        pts = np.concatenate([c for _, c in members])
        first = members[0][1]
        at = pts.mean(axis=0)
        at[2] = pts[:, 2].max() + 0.45 * np.linalg.norm(first[1] - first[0])  # above it, whichever way it faces
        keys = [k for k, _ in members]
        dictionary = f"{keys[0].dictionary}:" if isinstance(keys[0], MarkerKey) else ""  # one dictionary an entry
        ax.text(*at, f"{name} ({dictionary}{id_ranges(sorted(int(k) for k in keys))})", **_ID_STYLE)
