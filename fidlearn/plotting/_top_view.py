"""The room seen from above: markers as their top edges, cameras as dots with their headings."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from ..errors import PlotError
from ..markermap import MarkerMap
from ._room import _pose_matrix


def plot_top_view(
    marker_map: MarkerMap | None = None,
    poses: Sequence = (),
    *,
    truth: Sequence | None = None,
    ax: Axes | None = None,
    arrow_mm: float = 150.0,
    title: str | None = None,
) -> Axes:
    """The room seen from above (world X right, Y up the page): markers, camera positions and headings.

    Each marker is drawn as its top edge seen from above (a short segment, its
    id beside it); each pose as a dot with an arrow along its optical axis
    projected on the floor.

    Parameters
    ----------
    marker_map : MarkerMap, optional
    poses : sequence
        (4, 4) ``T_world_camera`` arrays (mm) or objects with ``T_world_camera`` (a ``Pose``).
    truth : sequence, optional
        True poses in the same order, drawn in grey with lines joining each estimate to its truth.
    ax : Axes, optional
        A 2D Axes; by default a new figure's.
    arrow_mm : float
        Length of the heading arrows, mm.
    title : str, optional

    Returns
    -------
    Axes
        Equal-aspect, in mm. ``ax.lines[-1]`` is the estimated path (positions in order).

    Raises
    ------
    PlotError
        If ``truth`` does not have one pose per pose.
    TransformError
        If a pose is not a rigid transform.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6.5, 6.0))
    if marker_map is not None:
        for mid, c in marker_map.corners().items():
            ax.plot(c[[0, 1], 0], c[[0, 1], 1], color="k", linewidth=3)
            n = marker_map.normal(mid)
            u, v = c[:2, :2].mean(axis=0) + 0.6 * marker_map.marker_size_mm * n[:2]
            ax.annotate(str(mid), (u, v), ha="center", va="center", fontsize=9)

    def positions_and_headings(ps):
        Ts = [_pose_matrix(p) for p in ps]
        return np.array([T[:3, 3] for T in Ts]).reshape(-1, 3), np.array([T[:3, 2] for T in Ts]).reshape(-1, 3)

    if truth is not None:
        tp, th = positions_and_headings(truth)
        if len(tp) != len(poses):
            raise PlotError(f"plot_top_view: {len(tp)} true poses for {len(poses)} poses")
        ax.plot(tp[:, 0], tp[:, 1], "o-", color="0.6", markersize=3, linewidth=1, label="truth")
    p, h = positions_and_headings(poses)
    if len(p):
        if truth is not None:
            for a, b in zip(p, tp):
                ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:red", linewidth=0.8)
        flat = h[:, :2] / np.maximum(np.linalg.norm(h[:, :2], axis=1, keepdims=True), 1e-9)
        ax.quiver(
            p[:, 0],
            p[:, 1],
            flat[:, 0] * arrow_mm,
            flat[:, 1] * arrow_mm,
            angles="xy",
            scale_units="xy",
            scale=1,
            color="tab:orange",
            width=0.004,
        )
        ax.plot(p[:, 0], p[:, 1], "o-", color="tab:orange", markersize=3, linewidth=1, label="camera")
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    if title:
        ax.set_title(title)
    return ax
