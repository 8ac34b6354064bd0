"""Pictures for the course: the room in 3D (world axes, markers, cameras) and images with points.

Every function draws on an Axes it is given (or makes one) and returns what it
drew, so a test can check the geometry without a browser. Nothing here is
imported by ``import fidlearn``: use ``from fidlearn import plotting``.

Conventions drawn here are the library's: world right-handed, Z up, mm;
``T_world_camera`` is the camera's pose; the camera frame is OpenCV's (x right,
y down, z forward); images are OpenCV's BGR arrays and pixel centres sit at
integer coordinates, which is also where ``imshow`` puts them. World axes are
drawn X red, Y green, Z blue.

Examples
--------
>>> import numpy as np
>>> from fidlearn import Camera, MarkerMap, data_path, look_at, plotting
>>> m = MarkerMap.load(data_path("world_map.json"))
>>> cam = Camera.from_fov(60, (640, 480))
>>> T_world_camera = look_at([1500, 200, 250], [0, 120, 230])
>>> fig = plotting.plot_scene(m, poses=[T_world_camera], camera=cam)
>>> len(fig.axes)
1
>>> import matplotlib.pyplot as plt; plt.close(fig)
"""

from __future__ import annotations

from ..markermap import CORNER_NAMES
from ._images import (
    draw_corner_labels,
    draw_points,
    draw_projected_markers,
    draw_quads,
    draw_reprojection,
    plot_detections,
    show_image,
    show_images,
)
from ._markers3d import draw_markers
from ._room import (
    AXIS_COLORS,
    AxesCube,
    camera_frustum,
    draw_box,
    draw_camera,
    draw_frame,
    draw_trajectory,
    draw_world_axes,
    new_axes_3d,
    plot_scene,
    set_axes_equal,
)
from ._top_view import plot_top_view

__all__ = [
    "AXIS_COLORS",
    "CORNER_NAMES",
    "new_axes_3d",
    "set_axes_equal",
    "AxesCube",
    "draw_frame",
    "draw_world_axes",
    "draw_markers",
    "draw_box",
    "camera_frustum",
    "draw_camera",
    "plot_scene",
    "draw_trajectory",
    "plot_top_view",
    "show_image",
    "show_images",
    "draw_points",
    "draw_corner_labels",
    "draw_quads",
    "plot_detections",
    "draw_reprojection",
    "draw_projected_markers",
]
