"""Interactive views for the notebooks, each built on a pure function that tests call directly.

:func:`intrinsics_explorer` shows what fx, fy, cx, cy and the radial
distortion k1 do to the picture of a flat grid; its drawing is
:func:`render_intrinsics_view`, a pure function (parameters in, Figure out)
that never touches pyplot's global state, so it can be tested without a
browser. Sliders use ``continuous_update=False``: the picture is redrawn when
a slider is released.

Nothing here is imported by ``import fidlearn``: use ``from fidlearn import widgets``.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import cast

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ._webcam import Webcam
from .camera import Camera
from .errors import CameraError

__all__ = [
    "grid_polylines_mm",
    "intrinsics_view_polylines",
    "render_intrinsics_view",
    "figure_png",
    "intrinsics_explorer",
    "Webcam",
]

#: The scene the intrinsics view looks at: a flat grid facing the camera (camera frame, mm).
GRID_DEPTH_MM = 1500.0
GRID_HALF_WIDTH_MM = 1000.0
GRID_HALF_HEIGHT_MM = 750.0
GRID_STEP_MM = 125.0


def grid_polylines_mm(
    depth_mm: float = GRID_DEPTH_MM,
    *,
    half_width_mm: float = GRID_HALF_WIDTH_MM,
    half_height_mm: float = GRID_HALF_HEIGHT_MM,
    step_mm: float = GRID_STEP_MM,
    samples: int = 41,
) -> list[np.ndarray]:
    """Lines of a flat grid square to the optical axis, in the camera frame.

    Parameters
    ----------
    depth_mm : float
        Distance of the grid from the camera along z, mm.
    half_width_mm, half_height_mm : float
        Half the grid's width (x) and height (y), mm.
    step_mm : float
        Spacing of the grid lines, mm.
    samples : int
        Points per line: dense, so lens distortion shows as curvature.

    Returns
    -------
    list of ndarray, shape (samples, 3)
        Camera frame (x right, y down, z forward), mm: vertical lines first, then horizontal ones.

    Examples
    --------
    >>> lines = grid_polylines_mm()
    >>> len(lines), lines[0].shape
    (30, (41, 3))
    """
    xs = np.arange(-half_width_mm, half_width_mm + 1e-9, step_mm)
    ys = np.arange(-half_height_mm, half_height_mm + 1e-9, step_mm)
    tx = np.linspace(-half_width_mm, half_width_mm, samples)
    ty = np.linspace(-half_height_mm, half_height_mm, samples)
    lines = [np.column_stack([np.full(samples, x), ty, np.full(samples, depth_mm)]) for x in xs]
    lines += [np.column_stack([tx, np.full(samples, y), np.full(samples, depth_mm)]) for y in ys]
    return lines


def _camera(fx: float, fy: float, cx: float, cy: float, k1: float, image_size: Sequence[int]) -> Camera:
    return Camera(
        np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]),
        np.array([k1, 0.0, 0.0, 0.0, 0.0]),
        cast("tuple[int, int]", tuple(image_size)),  # Camera checks that it is two whole numbers
        source="intrinsics explorer",
    )


def intrinsics_view_polylines(
    fx: float, fy: float, cx: float, cy: float, *, k1: float = 0.0, image_size: Sequence[int] = (640, 480)
) -> list[np.ndarray]:
    """The grid of :func:`grid_polylines_mm` projected by a camera with these intrinsics.

    The camera sits at the origin looking along +z, so the grid's centre lands exactly on (cx, cy).

    Parameters
    ----------
    fx, fy : float
        Focal lengths, pixels.
    cx, cy : float
        Principal point, pixels.
    k1 : float
        First radial distortion coefficient.
    image_size : (int, int)
        (width, height), pixels.

    Returns
    -------
    list of ndarray, shape (samples, 2)
        Pixel polylines (OpenCV pixel-centre convention), in the order of :func:`grid_polylines_mm`.
    """
    cam = _camera(fx, fy, cx, cy, k1, image_size)
    return [cam.project(line, np.eye(4)) for line in grid_polylines_mm()]


def render_intrinsics_view(
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    *,
    k1: float = 0.0,
    image_size: Sequence[int] = (640, 480),
    figsize: tuple[float, float] = (6.4, 5.2),
) -> Figure:
    """Draw what a camera with these intrinsics sees of a flat grid 1.5 m away.

    Pure: the same parameters give the same Figure, and pyplot's list of open
    figures is not touched (nothing to close). The Axes spans the image
    (pixels, y down); the red cross is the principal point (cx, cy), the grey
    one the image centre; the grid's centre line is drawn thicker.

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels.
    k1 : float
        First radial distortion coefficient (negative: barrel, positive: pincushion).
    image_size : (int, int)
        (width, height) in pixels.

    Returns
    -------
    Figure
        One Axes; its first len(grid) lines are the projected grid lines.
    """
    w, h = (int(v) for v in image_size)
    cam = _camera(fx, fy, cx, cy, k1, (w, h))
    polylines = intrinsics_view_polylines(fx, fy, cx, cy, k1=k1, image_size=(w, h))
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    n_vertical = len(np.arange(-GRID_HALF_WIDTH_MM, GRID_HALF_WIDTH_MM + 1e-9, GRID_STEP_MM))
    for k, line in enumerate(polylines):
        centre_line = (k == n_vertical // 2) or (k == n_vertical + (len(polylines) - n_vertical) // 2)
        ax.plot(line[:, 0], line[:, 1], color="tab:blue", linewidth=2.0 if centre_line else 0.8)
    ax.plot([cx], [cy], "+", color="tab:red", markersize=16, markeredgewidth=2, label="principal point (cx, cy)")
    ax.plot([(w - 1) / 2], [(h - 1) / 2], "x", color="0.5", markersize=10, label="image centre")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    hfov, vfov = cam.fov_deg
    ax.set_title(
        f"fx={fx:.0f} fy={fy:.0f} cx={cx:.1f} cy={cy:.1f} k1={k1:+.2f}\n"
        f"field of view {hfov:.1f} x {vfov:.1f} deg; grid 2.0 x 1.5 m at 1.5 m",
        fontsize=10,
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


def figure_png(fig: Figure, dpi: float = 80) -> bytes:
    """A Figure as PNG bytes (works whatever matplotlib backend is active).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    dpi : float
        Resolution, dots per inch.

    Returns
    -------
    bytes
        The PNG file's content.
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def intrinsics_explorer(camera: Camera | None = None, image_size: Sequence[int] = (640, 480)):
    """Sliders for fx, fy, cx, cy and k1 above the picture of :func:`render_intrinsics_view`.

    Parameters
    ----------
    camera : Camera, optional
        Starting values (and image size); default a 60 degree camera.

    Returns
    -------
    ipywidgets.VBox
        Its first child holds the sliders (descriptions ``fx``, ``fy``,
        ``cx``, ``cy``, ``k1``, all with ``continuous_update=False``); its last
        child is the Output widget that shows the picture, redrawn on every
        change.

    Raises
    ------
    CameraError
        A fisheye camera (the picture is OpenCV's pinhole lens).
    """
    import ipywidgets as W
    from IPython.display import Image, display

    if camera is None:
        camera = Camera.from_fov(60.0, cast("tuple[int, int]", tuple(image_size)))
    if camera.model != "pinhole":
        raise CameraError(
            f"intrinsics_explorer draws OpenCV's pinhole lens, and {camera.source or 'the camera'} is a fisheye "
            "(its k1 is another model's): explore it with a pinhole camera, e.g. Camera.from_fov"
        )
    w, h = camera.image_size
    k1 = float(camera.dist[0]) if camera.dist is not None and camera.dist.size else 0.0
    f_most = max(2000.0, 1.5 * max(camera.fx, camera.fy))  # a long lens's fx must fit, or the slider clamps it
    style = {"description_width": "30px"}
    layout = W.Layout(width="330px")

    def slider(name: str, value: float, lo: float, hi: float, step: float, fmt: str) -> W.FloatSlider:
        return W.FloatSlider(
            value=value,
            min=lo,
            max=hi,
            step=step,
            description=name,
            readout_format=fmt,
            continuous_update=False,
            style=style,
            layout=layout,
        )

    controls = {
        "fx": slider("fx", camera.fx, 100.0, f_most, 10.0, ".0f"),
        "fy": slider("fy", camera.fy, 100.0, f_most, 10.0, ".0f"),
        "cx": slider("cx", camera.cx, 0.0, float(w - 1), 1.0, ".0f"),
        "cy": slider("cy", camera.cy, 0.0, float(h - 1), 1.0, ".0f"),
        "k1": slider("k1", k1, min(-0.5, k1), max(0.5, k1), 0.01, "+.2f"),
    }

    def draw(fx: float, fy: float, cx: float, cy: float, k1: float) -> None:
        fig = render_intrinsics_view(fx, fy, cx, cy, k1=k1, image_size=(w, h))
        display(Image(data=figure_png(fig), format="png"))

    out = W.interactive_output(draw, controls)
    sliders = W.VBox(
        [W.HBox([controls["fx"], controls["fy"]]), W.HBox([controls["cx"], controls["cy"]]), W.HBox([controls["k1"]])]
    )
    return W.VBox([sliders, out])
