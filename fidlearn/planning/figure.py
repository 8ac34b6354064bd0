"""The room plan as a picture: seen from above, coloured by the predicted position error."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter

from ..markermap import MarkerMap
from .room import RoomPlan


def _draw_markers(ax, marker_map: MarkerMap) -> None:
    """Each marker's outline seen from above (a bar on a wall, a square on the floor or the ceiling), with an
    arrow along its normal where the normal is not vertical."""
    for mid in marker_map.ids:
        c = marker_map.marker_corners(mid)
        n = marker_map.normal(mid)
        upright = np.hypot(n[0], n[1]) > 0.3
        ax.fill(c[:, 0], c[:, 1], facecolor="none", edgecolor="black", lw=3 if upright else 1.5, joinstyle="miter")
        centre = c.mean(axis=0)
        if upright:
            tip = centre + 150.0 * n
            arrow = {"arrowstyle": "->", "color": "black", "lw": 0.8}
            ax.annotate("", xy=tip[:2], xytext=centre[:2], arrowprops=arrow)
        ax.text(centre[0], centre[1], f" {mid}", fontsize=8, ha="left", va="bottom")


def _panel(ax, plan: RoomPlan, grid: np.ndarray, title: str, norm, target_mm: float | None):
    extent = [
        plan.x_mm[0] - (plan.x_mm[1] - plan.x_mm[0] if len(plan.x_mm) > 1 else 1) / 2,
        plan.x_mm[-1] + (plan.x_mm[1] - plan.x_mm[0] if len(plan.x_mm) > 1 else 1) / 2,
        plan.y_mm[0] - (plan.y_mm[1] - plan.y_mm[0] if len(plan.y_mm) > 1 else 1) / 2,
        plan.y_mm[-1] + (plan.y_mm[1] - plan.y_mm[0] if len(plan.y_mm) > 1 else 1) / 2,
    ]
    ax.set_facecolor("0.85")  # no pose possible: grey
    shown = np.ma.masked_invalid(np.where(np.isfinite(grid), grid, np.nan))
    im = ax.imshow(shown, origin="lower", extent=extent, cmap="viridis", norm=norm, interpolation="nearest")
    if target_mm is not None and np.isfinite(grid).sum() > 3 and len(plan.x_mm) > 1 and len(plan.y_mm) > 1:
        ax.contour(
            plan.x_mm,
            plan.y_mm,
            np.ma.masked_invalid(np.where(np.isfinite(grid), grid, np.nan)),
            levels=[target_mm],
            colors="white",
            linewidths=1.5,
        )
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("world X (mm)")
    ax.set_aspect("equal")
    return im


def plan_figure(plan: RoomPlan, marker_map: MarkerMap, target_mm: float | None = None) -> Figure:
    """A figure of ``plan`` seen from above: error looking at the markers, and the worst level heading.

    Grey where no pose is possible; a white line at ``target_mm`` when given; each marker as its
    outline seen from above (a black bar with an arrow along its normal on a wall, a black square on
    the floor or the ceiling).

    Parameters
    ----------
    plan : RoomPlan
        The result of :func:`fidlearn.plan_room`.
    marker_map : MarkerMap
        The map it was computed for.
    target_mm : float, optional
        Draw the contour of this predicted position error (mm).

    Returns
    -------
    matplotlib.figure.Figure
        One panel, or two when some level heading sees a marker.
    """
    panels = [(plan.toward_mm, "looking toward the markers")]
    if np.isfinite(plan.worst_mm).any():
        panels.append((plan.worst_mm, "worst level heading that sees a marker"))
    fig = Figure(figsize=(5.5 * len(panels), 5.0), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    finite = np.concatenate([g[np.isfinite(g)] for g, _ in panels])
    lo = max(float(finite.min()) if finite.size else 0.1, 0.05)
    hi = max(float(finite.max()) if finite.size else 1.0, lo * 1.01)
    norm = LogNorm(vmin=lo, vmax=hi)
    im = None
    for ax, (grid, title) in zip(axes, panels):
        im = _panel(ax, plan, grid, title, norm, target_mm)
        _draw_markers(ax, marker_map)
    axes[0].set_ylabel("world Y (mm)")
    assert im is not None  # one panel at least
    bar = fig.colorbar(im, ax=list(axes), label="predicted median position error (mm); grey: no pose", shrink=0.85)
    plain = FuncFormatter(lambda v, _: f"{v:g}")  # 0.9, 1, 20: not 9x10^-1
    bar.ax.yaxis.set_major_formatter(plain)
    if hi / lo < 10:  # less than a decade: label the minor ticks too, in plain numbers
        bar.ax.yaxis.set_minor_formatter(plain)
    fig.suptitle(
        f"Camera {abs(plan.height_mm):.0f} mm {'above' if plan.height_mm >= 0 else 'below'} the floor"
        + (f", white line: {target_mm:g} mm" if target_mm is not None else ""),
        fontsize=11,
    )
    return fig


def coach_figure(coach, camera) -> Figure:
    """The calibration coach's picture: reprojection uncertainty over the image, the line where it crosses
    :data:`~fidlearn.planning.coach.GOOD_UNCERTAINTY_PX` (named in a legend, when the picture has both sides of
    it), and the next view in the title.

    Parameters
    ----------
    coach : CalibrationCoach
        The coach's verdict on a calibration.
    camera : Camera
        The calibrated camera (its image size sets the axes).

    Returns
    -------
    matplotlib.figure.Figure
        The uncertainty map (px) over the picture.
    """
    from .coach import GOOD_UNCERTAINTY_PX

    fig = Figure(figsize=(7.0, 7.0 * camera.height / camera.width + 1.0), layout="constrained")
    ax = fig.subplots()
    u = np.ma.masked_invalid(coach.uncertainty_px)  # a fisheye's corners beyond its model's reach: grey
    top = float(u.max()) if u.count() else 0.0
    im = ax.imshow(
        u,
        extent=(-0.5, camera.width - 0.5, camera.height - 0.5, -0.5),
        cmap=colormaps["magma_r"].with_extremes(bad="0.85"),
        vmin=0.0,
        vmax=max(top, 2 * GOOD_UNCERTAINTY_PX),
        interpolation="bicubic",
    )
    rows, cols = u.shape
    xs = (np.arange(cols) + 0.5) * camera.width / cols - 0.5
    ys = (np.arange(rows) + 0.5) * camera.height / rows - 0.5
    if u.count() and u.min() < GOOD_UNCERTAINTY_PX < top:  # the line and its legend entry only where it is drawn
        ax.contour(xs, ys, u, levels=[GOOD_UNCERTAINTY_PX], colors="deepskyblue", linewidths=1.5)
        line = Line2D([], [], color="deepskyblue", linewidth=1.5, label=f"{GOOD_UNCERTAINTY_PX} px")
        ax.legend(handles=[line], loc="lower right", fontsize=8, title="uncertainty", title_fontsize=8)
    if coach.next_view is not None:
        ax.set_title(f"next photo: {coach.next_view.where}, {coach.next_view.tilt}", fontsize=9)
    ax.set_xlim(-0.5, camera.width - 0.5)
    ax.set_ylim(camera.height - 0.5, -0.5)
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    fig.colorbar(im, ax=ax, shrink=0.8, label="reprojection uncertainty (px)")
    fig.suptitle(
        f"Calibration uncertainty: under {GOOD_UNCERTAINTY_PX} px over {100 * coach.good_fraction:.0f} % "
        "of the picture",
        fontsize=11,
    )
    return fig
