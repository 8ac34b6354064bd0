"""Pictures with points on them: images (OpenCV's BGR), detected and projected markers, reprojection errors.

Pixel centres sit at integer coordinates (OpenCV's convention), which is also where ``imshow`` puts them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..camera import Camera
from ..errors import PlotError
from ..markermap import CORNER_NAMES, MarkerMap


def _rgb(image: np.ndarray) -> tuple[np.ndarray, dict]:
    image = np.asarray(image)
    if image.ndim == 2:
        kw: dict[str, Any] = {"cmap": "gray"}
        if image.dtype == np.uint8:
            kw.update(vmin=0, vmax=255)
        return image, kw
    if image.ndim == 3 and image.shape[2] == 3:
        return image[:, :, ::-1], {}  # OpenCV's BGR to matplotlib's RGB
    if image.ndim == 3 and image.shape[2] == 4:
        return image[:, :, [2, 1, 0, 3]], {}
    raise PlotError(f"show_image: shape {image.shape} is not an image; expected (H, W) gray or (H, W, 3) BGR")


def show_image(
    ax: Axes | None,
    image: np.ndarray,
    *,
    points: np.ndarray | None = None,
    labels: Sequence | None = None,
    color: str = "tab:red",
    title: str | None = None,
    marker: str = "+",
    markersize: float = 80.0,
) -> Axes:
    """Show an OpenCV image (gray, or BGR as OpenCV loads it) with optional points and labels.

    Pixel centres sit at integer coordinates, as in OpenCV, so a point (u, v)
    from OpenCV lands on the right pixel. Axes are in pixels, y down.

    Parameters
    ----------
    ax : Axes or None
        Where to draw (None: a new figure).
    image : ndarray, shape (H, W) or (H, W, 3) BGR
        The picture (uint8 gray is shown 0..255).
    points : array_like, shape (N, 2), optional
        Pixel points (u, v) to mark.
    labels : sequence, optional
        One label per point, written beside it.
    color, marker, markersize :
        The points' style.
    title : str, optional

    Returns
    -------
    Axes
        The Axes drawn on.

    Raises
    ------
    PlotError
        If ``image`` is not (H, W), (H, W, 3) or (H, W, 4), or the labels do not match the points.
    """
    if ax is None:
        h, w = _image_size(image, "show_image")
        _, ax = plt.subplots(figsize=(6.4, 6.4 * h / max(w, 1)))
    shown, kw = _rgb(image)
    ax.imshow(shown, interpolation="nearest", **kw)
    if points is not None:
        draw_points(ax, points, labels=labels, color=color, marker=marker, markersize=markersize)
    if title:
        ax.set_title(title)
    return ax


def _image_size(image, where: str) -> tuple[int, int]:
    """``(height, width)`` of a picture array, or PlotError saying what a picture is."""
    a = np.asarray(image) if isinstance(image, np.ndarray) else None
    if a is None or a.ndim not in (2, 3) or a.size == 0:
        shape = getattr(a, "shape", type(image).__name__)
        raise PlotError(f"{where}: an image is an array (H, W), (H, W, 3) or (H, W, 4), got {shape}")
    return int(a.shape[0]), int(a.shape[1])


def show_images(
    images: Sequence[np.ndarray], titles: Sequence[str] | None = None, ncols: int = 4, width_in: float = 10.0
) -> Figure:
    """A grid of images (gray or BGR) with optional titles; ticks hidden, each image framed.

    Parameters
    ----------
    images : sequence of ndarray, shape (H, W) or (H, W, 3)
        The pictures, all shown at the first one's aspect.
    titles : sequence of str, optional
        One per image.
    ncols : int
        Columns of the grid.
    width_in : float
        Figure width, inches.

    Returns
    -------
    Figure
        One Axes per grid slot (unused slots hidden).

    Raises
    ------
    PlotError
        If there is no image or one is not an image.
    """
    n = len(images)
    if n == 0:
        raise PlotError("show_images: no images")
    if titles is not None and len(titles) != n:
        raise PlotError(f"show_images: {n} images and {len(titles)} titles; give one title per image, or none")
    ncols = max(1, min(ncols, n))
    nrows = -(-n // ncols)
    h, w = _image_size(images[0], "show_images")
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(width_in, width_in / ncols * h / w * nrows + 0.4 * nrows), squeeze=False
    )
    for k, ax in enumerate(axes.flat):
        if k < n:  # ticks hidden, the frame kept: a white margin stays visible on a white page
            show_image(ax, images[k], title=titles[k] if titles is not None else None)
            ax.set_xticks([])
            ax.set_yticks([])
        else:
            ax.axis("off")
    fig.tight_layout()
    return fig


def draw_points(
    ax: Axes,
    points: np.ndarray,
    *,
    labels: Sequence | None = None,
    color: str = "tab:red",
    marker: str = "+",
    markersize: float = 80.0,
):
    """Mark pixel points on an image Axes, with optional labels.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    points : array_like, shape (N, 2)
        Pixel points (u, v).
    labels : sequence, optional
        One label per point.
    color, marker, markersize :
        The points' style.

    Returns
    -------
    matplotlib.collections.PathCollection
        The scatter artist.

    Raises
    ------
    PlotError
        If the labels do not match the points.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    art = ax.scatter(pts[:, 0], pts[:, 1], c=color, marker=marker, s=markersize, linewidths=1.5)
    if labels is not None:
        if len(labels) != len(pts):
            raise PlotError(f"draw_points: {len(labels)} labels for {len(pts)} points")
        for (u, v), text in zip(pts, labels):
            ax.annotate(str(text), (u, v), xytext=(4, -4), textcoords="offset points", color=color, fontsize=8)
    return art


def draw_corner_labels(
    ax: Axes,
    corners_px: np.ndarray,
    *,
    names: Sequence[str] = CORNER_NAMES,
    color: str = "tab:red",
    fontsize: float = 8,
) -> list:
    """Write TL, TR, BR, BL beside a quad's four corners, each pushed away from the centre.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    corners_px : array_like, shape (4, 2)
        The quad's corners, pixels, in ``names`` order.
    names : sequence of str
        The corner names, :data:`~fidlearn.markermap.CORNER_NAMES` by default.
    color : str
    fontsize : float

    Returns
    -------
    list of matplotlib.text.Annotation
        The four labels, in corner order.

    Raises
    ------
    PlotError
        If there are not as many corners as names.
    """
    c = np.asarray(corners_px, dtype=float).reshape(-1, 2)
    if len(c) != len(names):
        raise PlotError(f"draw_corner_labels: {len(c)} corners for {len(names)} names")
    centre = c.mean(axis=0)
    texts = []
    for name, p in zip(names, c):
        d = p - centre
        d = d / (np.linalg.norm(d) + 1e-12)
        texts.append(
            ax.annotate(
                name,
                tuple(p),
                xytext=tuple(8 * d * [1, -1]),
                textcoords="offset points",
                color=color,
                fontsize=fontsize,
                ha="center",
                va="center",
            )
        )
    return texts


def draw_quads(
    ax: Axes,
    quads_px: Sequence[np.ndarray],
    *,
    ids: Sequence | None = None,
    color: str = "lime",
    corner_labels: bool = False,
    linewidth: float = 1.5,
) -> list:
    """Outline quads on an image Axes, a dot on the first corner (TL), ids at centres.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    quads_px : sequence of array_like, shape (4, 2)
        Corners, pixels, TL, TR, BR, BL.
    ids : sequence, optional
        One id per quad, written at its centre.
    color : str
    corner_labels : bool
        Write TL, TR, BR, BL beside the corners.
    linewidth : float

    Returns
    -------
    list of matplotlib.lines.Line2D
        The outlines, one per quad, closed (5 vertices).
    """
    lines = []
    if ids is not None and len(ids) != len(quads_px):
        raise PlotError(f"draw_quads: {len(quads_px)} quads and {len(ids)} ids; give one id per quad, or none")
    for k, q in enumerate(quads_px):
        q = np.asarray(q, dtype=float).reshape(4, 2)
        closed = np.vstack([q, q[:1]])
        (line,) = ax.plot(closed[:, 0], closed[:, 1], color=color, linewidth=linewidth)
        lines.append(line)
        ax.plot(q[0, 0], q[0, 1], "o", color="tab:red", markersize=4)
        if ids is not None:
            u, v = q.mean(axis=0)
            ax.text(u, v, str(ids[k]), color=color, fontsize=10, ha="center", va="center", fontweight="bold")
        if corner_labels:
            draw_corner_labels(ax, q)
    return lines


def plot_detections(ax: Axes, detections: Sequence, color: str = "lime", corner_labels: bool = True) -> list:
    """Outline detected markers on an image Axes, with their ids and corner names (matplotlib).

    :func:`fidlearn.draw_detections` draws them into the image itself (OpenCV).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    detections : sequence of Detection
        Objects with ``.id`` and ``.corners_px`` (4, 2) pixels, TL, TR, BR, BL.
    color : str
    corner_labels : bool
        Write TL, TR, BR, BL beside the corners.

    Returns
    -------
    list of matplotlib.lines.Line2D
        The outlines, one per detection.
    """
    return draw_quads(
        ax, [d.corners_px for d in detections], ids=[d.id for d in detections], color=color, corner_labels=corner_labels
    )


def draw_reprojection(
    ax: Axes, observed_px: np.ndarray, projected_px: np.ndarray, *, scale: float = 1.0, color: str = "tab:red"
):
    """Observed points (green dots) and the model's projections (red crosses), joined by error lines.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    observed_px : array_like, shape (N, 2)
        Measured pixels.
    projected_px : array_like, shape (N, 2)
        The model's pixels for the same points.
    scale : float
        Magnifies the error lines (10 shows a 0.3 px error as 3 px).
    color : str

    Returns
    -------
    ndarray, shape (N,)
        The per-point error, pixels.

    Raises
    ------
    PlotError
        If the two sets have different lengths.
    """
    obs = np.asarray(observed_px, dtype=float).reshape(-1, 2)
    proj = np.asarray(projected_px, dtype=float).reshape(-1, 2)
    if obs.shape != proj.shape:
        raise PlotError(f"draw_reprojection: {len(obs)} observed points but {len(proj)} projected")
    ax.scatter(obs[:, 0], obs[:, 1], s=14, color="tab:green", label="observed")
    ax.scatter(proj[:, 0], proj[:, 1], s=30, marker="x", color=color, label="projected")
    tips = obs + scale * (proj - obs)
    for a, b in zip(obs, tips):
        ax.plot([a[0], b[0]], [a[1], b[1]], color=color, linewidth=1)
    return np.linalg.norm(proj - obs, axis=1)


def _check_map_camera(marker_map, camera, call: str) -> None:
    """Raise :class:`PlotError` unless the map is a MarkerMap and the camera a Camera (the map comes first)."""
    if isinstance(marker_map, Camera) and isinstance(camera, MarkerMap):
        raise PlotError(f"{call}: the map comes first, then the camera; the arguments are swapped")
    if not isinstance(marker_map, MarkerMap):
        raise PlotError(f"{call}: marker_map must be a fidlearn.MarkerMap, got {type(marker_map).__name__}")
    if not isinstance(camera, Camera):
        raise PlotError(f"{call}: camera must be a fidlearn.Camera, got {type(camera).__name__}")


def draw_projected_markers(
    ax: Axes,
    marker_map: MarkerMap,
    camera: Camera,
    T_world_camera: np.ndarray,
    *,
    corner_labels: bool = True,
    color: str = "tab:blue",
) -> dict[int, np.ndarray]:
    """What the camera sees of the map: each marker's corners projected, labelled TL, TR, BR, BL.

    The Axes shows the whole image (pixels, y down). Markers behind the camera
    are left out.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        An image Axes (pixels, y down).
    marker_map : MarkerMap
        The markers (mm, world). The map comes first, then the camera.
    camera : Camera
    T_world_camera : array_like, shape (4, 4)
        The camera's pose in the world, mm.
    corner_labels : bool
        Write TL, TR, BR, BL beside the corners.
    color : str

    Returns
    -------
    dict of int to ndarray, shape (4, 2)
        ``{id: corners_px}`` of the markers drawn.

    Raises
    ------
    PlotError
        If the map or the camera is not one (a swapped call says the map comes first).
    """
    _check_map_camera(marker_map, camera, "draw_projected_markers(ax, marker_map, camera, T_world_camera)")
    w, h = camera.image_size
    out: dict[int, np.ndarray] = {}
    T_cw = np.linalg.inv(np.asarray(T_world_camera, dtype=float))
    slack = 0.5 * max(w, h)
    for mid, c in marker_map.corners().items():
        if not np.all(camera.points_in_front(c, T_world_camera)):
            continue
        pc = c @ T_cw[:3, :3].T + T_cw[:3, 3]  # far outside the view a lens's polynomial folds back: the pinhole first
        ideal = pc[:, :2] / pc[:, 2:3] * [camera.fx, camera.fy] + [camera.cx, camera.cy]
        if camera.model == "pinhole" and (np.any(ideal < -slack) or np.any(ideal > [w + slack, h + slack])):
            continue
        out[mid] = camera.project(c, T_world_camera)
    draw_quads(ax, list(out.values()), ids=list(out), color=color, corner_labels=corner_labels)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.add_patch(plt.Rectangle((-0.5, -0.5), w, h, fill=False, edgecolor="k", linewidth=1))
    return out
