"""The room in 3D (world axes, markers, cameras, paths) and seen from above.

World right-handed, Z up, mm; ``T_world_camera`` is the camera's pose; the camera frame is
OpenCV's (x right, y down, z forward). World axes are drawn X red, Y green, Z blue.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D  # also registers the 3d projection

from .. import frames
from ..camera import Camera
from ..errors import PlotError
from ..markermap import MarkerMap
from ._markers3d import draw_markers

#: Colours of the X, Y and Z axes of every frame drawn.
AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")


def new_axes_3d(
    ax: Axes3D | None = None, figsize: tuple[float, float] = (7.0, 6.0), elev: float = 20.0, azim: float = -35.0
) -> Axes3D:
    """A 3D Axes labelled in mm (a new figure unless ``ax`` is given).

    Parameters
    ----------
    ax : Axes, optional
        A 3D Axes to set up; by default a new figure's.
    figsize : (float, float)
        Size of the new figure, inches.
    elev, azim : float
        The view's elevation and azimuth, degrees.

    Returns
    -------
    Axes
        The 3D Axes, labelled X, Y, Z (mm).

    Raises
    ------
    PlotError
        If ``ax`` is a 2D Axes.
    """
    if ax is None:
        fig = plt.figure(figsize=figsize)
        ax = fig.add_subplot(projection="3d")
    if getattr(ax, "name", "") != "3d":
        raise PlotError("ax must be a 3D Axes: fig.add_subplot(projection='3d')")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_zlabel("Z (mm)")
    ax.view_init(elev=elev, azim=azim)
    return ax


@dataclass(frozen=True, eq=False)
class AxesCube:
    """The cube a 3D Axes shows after :func:`set_axes_equal`.

    Attributes
    ----------
    centre : ndarray, shape (3,)
        Centre of the cube shown, mm.
    half_range : float
        Half the side of that cube, mm (the same on every axis).
    """

    centre: np.ndarray
    half_range: float


def set_axes_equal(ax: Axes3D, points: np.ndarray | None = None, margin: float = 0.05) -> AxesCube:
    """Give a 3D Axes equal scales on X, Y and Z, so squares look square and right angles look right.

    Parameters
    ----------
    ax : 3D Axes
    points : array_like, shape (N, 3), optional
        Points (mm) that must be visible; by default the Axes' current limits.
    margin : float
        Extra room around the points, as a fraction of the largest extent.

    Returns
    -------
    AxesCube
        The ``centre`` (3,) and ``half_range`` of the cube shown, mm.
    """
    if points is None:
        lims = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])
        lo, hi = lims[:, 0], lims[:, 1]
    else:
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(pts) == 0 or not np.isfinite(pts).all():
            raise PlotError(f"set_axes_equal: points must be finite (N, 3) with N >= 1, got {len(pts)} of them")
        lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    half = float(max((hi - lo).max() / 2.0, 1e-9)) * (1.0 + margin)
    ax.set_xlim3d(centre[0] - half, centre[0] + half)
    ax.set_ylim3d(centre[1] - half, centre[1] + half)
    ax.set_zlim3d(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    return AxesCube(centre, half)


def draw_frame(
    ax: Axes3D,
    T_world_frame: np.ndarray,
    *,
    length_mm: float = 100.0,
    label: str | None = None,
    linewidth: float = 2.0,
    axis_names: Sequence[str] | None = None,
) -> list:
    """Draw a frame's X, Y, Z axes (red, green, blue) at its pose.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        A 3D Axes in mm (:func:`new_axes_3d`).
    T_world_frame : array_like, shape (4, 4)
        The frame's pose in the world, mm.
    length_mm : float
        Length of each axis drawn, mm.
    label : str, optional
        Written at the frame's origin.
    linewidth : float
    axis_names : sequence of 3 str, optional
        Written at the tips of X, Y and Z.

    Returns
    -------
    list of Line3D
        Three, X first; each runs from the origin to origin + ``length_mm`` along its axis.

    Raises
    ------
    TransformError
        If ``T_world_frame`` is not a rigid transform.
    """
    T = frames.check_transform(T_world_frame, name="T_world_frame")
    origin = T[:3, 3]
    lines = []
    for k in range(3):
        tip = origin + length_mm * T[:3, k]
        (line,) = ax.plot(*np.column_stack([origin, tip]), color=AXIS_COLORS[k], linewidth=linewidth)
        lines.append(line)
        if axis_names:
            ax.text(*(origin + 1.08 * length_mm * T[:3, k]), axis_names[k], color=AXIS_COLORS[k], fontsize=9)
    if label:
        ax.text(*origin, f" {label}", fontsize=9, color="k")
    return lines


def draw_world_axes(ax: Axes3D, length_mm: float = 300.0, label: str | None = "world") -> list:
    """The world frame at the origin, axes labelled X, Y, Z.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        A 3D Axes in mm (:func:`new_axes_3d`).
    length_mm : float
        Length of each axis, mm.
    label : str, optional

    Returns
    -------
    list of Line3D
        X, Y, Z.
    """
    return draw_frame(ax, np.eye(4), length_mm=length_mm, label=label, linewidth=2.5, axis_names=("X", "Y", "Z"))


def draw_box(
    ax: Axes3D, min_mm: Sequence[float], max_mm: Sequence[float], *, color: str = "0.6", linewidth: float = 0.8
) -> list:
    """Outline an axis-aligned box (a room) between two opposite corners.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        A 3D Axes in mm (:func:`new_axes_3d`).
    min_mm, max_mm : array_like, shape (3,)
        Opposite corners, world frame, mm.
    color : str
    linewidth : float

    Returns
    -------
    list of Line3D
        The 12 edges.
    """
    lo, hi = np.asarray(min_mm, dtype=float), np.asarray(max_mm, dtype=float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    lines = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.count_nonzero(corners[i] != corners[j]) == 1:
                (line,) = ax.plot(*corners[[i, j]].T, color=color, linewidth=linewidth)
                lines.append(line)
    return lines


def camera_frustum(camera: Camera, T_world_camera: np.ndarray, depth_mm: float = 200.0) -> np.ndarray:
    """The camera's viewing pyramid in world coordinates: apex and the image's corners at ``depth_mm``.

    Parameters
    ----------
    camera : Camera
    T_world_camera : array_like, shape (4, 4)
        The camera's pose in the world, mm.
    depth_mm : float
        Depth of the pyramid's base along the optical axis, mm.

    Returns
    -------
    ndarray, shape (5, 3)
        World frame, mm. Row 0 is the camera centre; rows 1-4 are the rays through the image's
        outer corners (TL, TR, BR, BL of the image, at pixel edges -0.5 and w - 0.5) cut at depth
        ``depth_mm``. Distortion is ignored (the pinhole pyramid).

    Raises
    ------
    TransformError
        If ``T_world_camera`` is not a rigid transform.
    """
    T = frames.check_transform(T_world_camera, name="T_world_camera")
    w, h = camera.image_size
    px = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    rays = np.column_stack([(px[:, 0] - camera.cx) / camera.fx, (px[:, 1] - camera.cy) / camera.fy, np.ones(4)])
    pts_camera = np.vstack([np.zeros(3), rays * depth_mm])
    return frames.transform_points(T, pts_camera)


def draw_camera(
    ax: Axes3D,
    camera: Camera,
    T_world_camera: np.ndarray,
    *,
    scale_mm: float = 200.0,
    color: str = "tab:orange",
    label: str | None = None,
    show_axes: bool = True,
) -> list:
    """Draw a camera as its viewing pyramid (frustum) at its pose.

    The pyramid's apex is the camera centre, its base the image at depth
    ``scale_mm``; the image's top edge is drawn thicker so "up in the image" can
    be read off the picture. With ``show_axes`` the camera's own x (red), y
    (green), z (blue, the optical axis) are drawn too.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        A 3D Axes in mm (:func:`new_axes_3d`).
    camera : Camera
    T_world_camera : array_like, shape (4, 4)
        The camera's pose in the world, mm.
    scale_mm : float
        Depth of the pyramid, mm.
    color : str
    label : str, optional
    show_axes : bool

    Returns
    -------
    list of Line3D
        Four edges from the apex to the image corners TL, TR, BR, BL, then the base outline
        (closed, starting at TL).
    """
    f = camera_frustum(camera, T_world_camera, scale_mm)
    lines = []
    for k in range(1, 5):
        (line,) = ax.plot(*np.column_stack([f[0], f[k]]), color=color, linewidth=1.2)
        lines.append(line)
    base = f[[1, 2, 3, 4, 1]]
    (line,) = ax.plot(*base.T, color=color, linewidth=1.2)
    lines.append(line)
    ax.plot(*f[[1, 2]].T, color=color, linewidth=3.0)  # the image's top edge
    if show_axes:
        draw_frame(ax, T_world_camera, length_mm=0.5 * scale_mm, linewidth=1.5)
    if label:
        ax.text(*f[0], f" {label}", fontsize=9, color=color)
    return lines


def _pose_matrix(pose) -> np.ndarray:
    T = getattr(pose, "T_world_camera", pose)
    return frames.check_transform(T, name="pose")


def plot_scene(
    marker_map: MarkerMap | None = None,
    poses: Sequence = (),
    *,
    camera: Camera | None = None,
    labels: Sequence[str | None] | None = None,
    ax: Axes3D | None = None,
    scale_mm: float | None = None,
    world_axes_mm: float | None = None,
    title: str | None = None,
    show_corners: bool = False,
    extra_points: np.ndarray | None = None,
    room_mm: Sequence[Sequence[float]] | None = None,
    elev: float = 20.0,
    azim: float = -35.0,
) -> Figure:
    """The room in 3D: world axes, the markers of a map and the cameras at their poses.

    Parameters
    ----------
    marker_map : MarkerMap, optional
    poses : sequence
        Camera poses: (4, 4) ``T_world_camera`` arrays (mm) or objects with a
        ``T_world_camera`` attribute (a ``Pose``).
    camera : Camera, optional
        Gives the frustums their shape; without it each pose is drawn as axes.
    labels : sequence of str or None, optional
        One label per pose (None for none).
    scale_mm : float, optional
        Depth of the drawn frustums; by default a fifth of the scene's size.
    extra_points : array_like, shape (N, 3), optional
        More points (mm) the view must include.
    room_mm : pair of (3,) points, optional
        Opposite corners of the room (mm): its outline is drawn (:func:`draw_box`).

    Returns
    -------
    Figure
        With one equal-aspect 3D Axes.

    Raises
    ------
    PlotError
        If the labels do not match the poses.
    TransformError
        If a pose is not a rigid transform.
    """
    ax = new_axes_3d(ax, elev=elev, azim=azim)
    Ts = [_pose_matrix(p) for p in poses]
    if labels is not None and len(labels) != len(Ts):
        raise PlotError(f"plot_scene: {len(labels)} labels for {len(Ts)} poses")
    pts = [np.zeros((1, 3))]
    if marker_map is not None:
        pts += list(marker_map.corners().values())
    pts += [T[:3, 3][None] for T in Ts]
    if extra_points is not None:
        pts.append(np.asarray(extra_points, dtype=float).reshape(-1, 3))
    if room_mm is not None:
        pts.append(np.asarray(room_mm, dtype=float).reshape(2, 3))
        draw_box(ax, room_mm[0], room_mm[1])
    allp = np.vstack(pts)
    size = float(np.ptp(allp, axis=0).max()) if len(allp) > 1 else 1000.0
    size = size if size > 0 else 1000.0
    if scale_mm is None:
        scale_mm = 0.2 * size
    if world_axes_mm is None:
        world_axes_mm = 0.25 * size
    draw_world_axes(ax, world_axes_mm)
    pts.append(np.eye(3) * world_axes_mm)
    if marker_map is not None:
        draw_markers(ax, marker_map, show_corners=show_corners)
    for i, T in enumerate(Ts):
        label = labels[i] if labels is not None else (f"camera {i}" if len(Ts) > 1 else "camera")
        if camera is not None:
            draw_camera(ax, camera, T, scale_mm=scale_mm, label=label)
            pts.append(camera_frustum(camera, T, scale_mm))
        else:
            draw_frame(ax, T, length_mm=scale_mm, label=label)
            pts.append(frames.transform_points(T, np.eye(3) * scale_mm))
    set_axes_equal(ax, np.vstack(pts))
    if title:
        ax.set_title(title)
    return ax.figure


def draw_trajectory(
    ax: Axes3D,
    poses: Sequence,
    *,
    color: str = "tab:purple",
    label: str | None = None,
    camera: Camera | None = None,
    every: int = 0,
    scale_mm: float = 100.0,
    linestyle: str = "-",
):
    """Draw a moving camera's path in 3D: its positions joined in order, optionally a frustum every N poses.

    Parameters
    ----------
    poses : sequence
        (4, 4) ``T_world_camera`` arrays (mm) or objects with ``T_world_camera``, in time order.
    camera : Camera, optional
        With ``every`` > 0, draw this camera's frustum at every ``every``-th pose.

    Returns
    -------
    Line3D
        The path; its vertices are the camera positions (mm, world).

    Raises
    ------
    PlotError
        If there is no pose.
    """
    Ts = [_pose_matrix(p) for p in poses]
    if not Ts:
        raise PlotError("draw_trajectory: no poses")
    pts = np.array([T[:3, 3] for T in Ts])
    (line,) = ax.plot(*pts.T, color=color, linestyle=linestyle, linewidth=1.5, label=label)
    ax.scatter(*pts[0], color=color, s=20, depthshade=False)
    if camera is not None and every > 0:
        for T in Ts[::every]:
            draw_camera(ax, camera, T, scale_mm=scale_mm, color=color, show_axes=False)
    return line
