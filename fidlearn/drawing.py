"""Drawing on pictures with OpenCV: detected markers, a located camera's axes, a calibration view.

Every function returns a BGR copy (the input is never modified), draws at sub-pixel precision
where OpenCV allows it, and sizes its text by the picture (readable on 640x480). Figures drawn
with matplotlib are in :mod:`fidlearn.plotting`.

Pixel convention: OpenCV's (the centre of the top-left pixel is (0, 0)); colours are (b, g, r).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from .boards import Board
from .detection import CORNER_NAMES, Detection, as_gray
from .errors import DetectionError
from .images import load_image

__all__ = ["draw_detections", "draw_pose", "draw_calibration_view", "wrap_to_width"]

_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _as_bgr(image: np.ndarray) -> np.ndarray:
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3:
        return image.copy()
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return cv2.cvtColor(as_gray(image), cv2.COLOR_GRAY2BGR)


def _label(
    img: np.ndarray, text: str, org: tuple[float, float], scale: float, thick: int, color, center: bool = True
) -> None:
    """Text with a dark box behind it so it reads on any background; ``org`` is its centre."""
    (tw, th), base = cv2.getTextSize(text, _FONT, scale, thick)
    x = int(round(org[0] - tw / 2)) if center else int(round(org[0]))
    y = int(round(org[1] + th / 2))
    H, W = img.shape[:2]
    x = min(max(x, 1), max(W - tw - 2, 1))
    y = min(max(y, th + 2), max(H - base - 1, th + 2))
    pad = max(1, thick)
    cv2.rectangle(img, (x - pad, y - th - pad), (x + tw + pad, y + base), (0, 0, 0), -1)
    cv2.putText(img, text, (x, y), _FONT, scale, color, thick, cv2.LINE_AA)


def _checked_detections(detections: Any) -> list[Detection]:
    if isinstance(detections, (str, bytes)) or not hasattr(detections, "__iter__"):
        raise DetectionError(
            f"detections must be a list of Detection (from detect_markers), got {type(detections).__name__}"
        )
    detections = list(detections)
    for det in detections:
        if not isinstance(det, Detection):
            raise DetectionError(
                f"detections must hold Detection objects (from detect_markers), got {type(det).__name__}"
            )
    return detections


def draw_detections(
    image: np.ndarray,
    detections: Sequence[Detection],
    color: tuple[int, int, int] = (0, 200, 0),
    *,
    corner_labels: bool = True,
    show_ids: bool = True,
    rejected: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """A BGR copy of ``image`` with each marker's outline, id and named corners drawn.

    The outline is drawn at sub-pixel precision; the first corner (TL) is a
    filled red dot and every corner carries its name (TL, TR, BR, BL) outside
    the marker, so the winding order is visible; the id sits in the middle.
    Text size follows the image size (readable on 640x480).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3) or (H, W, 4)
        Gray, BGR or BGRA image (not modified).
    detections : sequence of Detection
        The markers to draw (corners in pixels).
    color : (b, g, r)
        Outline colour.
    corner_labels, show_ids : bool
        Draw the corner names / the ids.
    rejected : sequence of ndarray, shape (4, 2), optional
        Candidate quads that did not decode (from :func:`fidlearn.detect_markers_with_rejected`),
        drawn thin in magenta.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The annotated copy.

    Raises
    ------
    DetectionError
        ``detections`` is not a list of :class:`~fidlearn.detection.Detection`.

    Examples
    --------
    >>> d = Detection(3, [[20, 20], [60, 20], [60, 60], [20, 60]])
    >>> draw_detections(np.full((80, 80), 255, np.uint8), [d]).shape
    (80, 80, 3)
    """
    out = _as_bgr(image)
    detections = _checked_detections(detections)
    H, W = out.shape[:2]
    unit = max(H, W) / 640.0
    thick = max(1, int(round(1.5 * unit)))
    scale = 0.42 * unit
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    for quad in rejected or ():
        q = np.round((np.asarray(quad, np.float64).reshape(4, 2)) * (1 << shift)).astype(np.int32)
        cv2.polylines(out, [q], True, (255, 0, 255), 1, cv2.LINE_AA, shift)
    for det in detections:
        c = np.asarray(det.corners_px, np.float64).reshape(4, 2)
        q = np.round(c * (1 << shift)).astype(np.int32)
        cv2.polylines(out, [q], True, color, thick, cv2.LINE_AA, shift)
        centre = c.mean(axis=0)
        for k, (name, p) in enumerate(zip(CORNER_NAMES, c)):
            dot = (0, 0, 255) if k == 0 else (255, 128, 0)
            at_px = tuple(int(v) for v in np.round(p * (1 << shift)))
            cv2.circle(out, at_px, int(round((2.5 + thick) * (1 << shift))), dot, -1, cv2.LINE_AA, shift)
            if corner_labels:
                away = p - centre
                away = away / max(float(np.linalg.norm(away)), 1e-9)
                at = p + away * 10.0 * unit
                _label(out, name, (float(at[0]), float(at[1])), 0.8 * scale, max(1, thick - 1), (255, 255, 255))
        if show_ids:
            _label(out, str(det.id), (float(centre[0]), float(centre[1])), scale * 1.2, thick, (0, 255, 255))
    return out


def _draw_world_axes(out: np.ndarray, camera, pose, length: float) -> None:
    """The world's X (red), Y (green), Z (blue) axes, ``length`` mm long, where the camera sees them."""
    axes = np.array([[0, 0, 0], [length, 0, 0], [0, length, 0], [0, 0, length]], dtype=float)
    if not np.all(camera.points_in_front(axes, pose.T_world_camera)):
        return
    px = camera.project(axes, pose.T_world_camera)
    if not np.all(np.abs(px) < 1e5):
        return
    o = tuple(int(round(v)) for v in px[0])
    for k, colour in ((1, (0, 0, 255)), (2, (0, 200, 0)), (3, (255, 0, 0))):  # X red, Y green, Z blue
        cv2.arrowedLine(out, o, tuple(int(round(v)) for v in px[k]), colour, 2, cv2.LINE_AA, tipLength=0.15)
        at = tuple(int(round(v)) + 4 for v in px[k])
        cv2.putText(out, "XYZ"[k - 1], at, _FONT, 0.6, colour, 2, cv2.LINE_AA)


def draw_pose(image: np.ndarray, detections: Sequence[Detection], marker_map, camera, pose) -> np.ndarray:
    """The frame with the detections, the world axes and the camera's pose written on it.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3) or (H, W, 4)
        The frame (not modified).
    detections : sequence of Detection
        The markers found in it (corners in pixels).
    marker_map : MarkerMap
        The world map; the axes drawn are twice its marker side long (mm).
    camera : Camera
        The camera fitted to the frame's size.
    pose : Pose or None
        The camera's pose in the world (mm); None writes "no known marker" in red.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The annotated copy: position (mm), roll, pitch, yaw (deg), RMS (px) in a black band at the top.
    """
    out = draw_detections(image, detections, corner_labels=False)
    if pose is None:
        cv2.putText(out, "no known marker", (10, 25), _FONT, 0.7, (0, 0, 255), 2, cv2.LINE_AA)
        return out
    _draw_world_axes(out, camera, pose, 2.0 * marker_map.marker_size_mm)
    x, y, z = np.round(pose.position_mm) + 0.0
    r, p, yw = np.round(pose.rpy_deg, 1) + 0.0
    text = f"x {x:.0f} y {y:.0f} z {z:.0f} mm  rpy {r:.1f} {p:.1f} {yw:.1f} deg  rms {pose.reprojection_rms_px:.2f} px"
    if pose.ambiguous:
        text += "  AMBIGUOUS"
    scale = 0.45 * max(out.shape[:2]) / 640
    (tw, th), base = cv2.getTextSize(text, _FONT, scale, 1)
    cv2.rectangle(out, (0, 0), (tw + 16, th + base + 12), (0, 0, 0), -1)
    cv2.putText(out, text, (8, th + 6), _FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def draw_calibration_view(path: str | os.PathLike, view, points_px, board: Board) -> np.ndarray:
    """One calibration photo with its board corners drawn and what became of it written on top.

    Parameters
    ----------
    path : str or os.PathLike
        The photo.
    view : ViewResult
        What the calibration made of it (status, RMS in px, reason).
    points_px : ndarray, shape (N, 2), or None
        The board corners found (pixels); None when the board was not found.
    board : Board
        The board; a ChArUco board's corners are drawn as circles (OpenCV's checkerboard drawing
        needs the full grid).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The annotated photo.

    Raises
    ------
    ImageError
        The photo cannot be read.
    """
    out = _as_bgr(load_image(path))
    unit = max(out.shape[:2]) / 640
    if points_px is not None:
        pts = np.asarray(points_px, dtype=np.float32).reshape(-1, 1, 2)
        if board.is_charuco:
            for u, v in pts.reshape(-1, 2):
                centre = (int(round(u * 16)), int(round(v * 16)))
                cv2.circle(out, centre, int(4 * unit * 16), (0, 200, 0), 1, cv2.LINE_AA, 4)
        else:
            cv2.drawChessboardCorners(out, board.inner_corners, pts, True)
        text = f"{view.status}: {len(pts)} corners, rms {view.rms_px:.3f} px"
        colour = (0, 160, 0)
    else:
        text = f"{view.status}: {view.reason}"
        colour = (0, 0, 255)
    scale = 0.45 * unit
    lines = wrap_to_width(text, out.shape[1] - 16, scale)
    (_, th), base = cv2.getTextSize("Ay", _FONT, scale, 1)
    step = th + base + 4
    tw = max(cv2.getTextSize(line, _FONT, scale, 1)[0][0] for line in lines)
    cv2.rectangle(out, (0, 0), (tw + 16, step * len(lines) + 8), (255, 255, 255), -1)
    for k, line in enumerate(lines):
        cv2.putText(out, line, (8, th + 6 + k * step), _FONT, scale, colour, 1, cv2.LINE_AA)
    return out


def wrap_to_width(text: str, width_px: int, scale: float) -> list[str]:
    """``text`` in lines no wider than ``width_px`` in OpenCV's simplex font of ``scale``.

    Parameters
    ----------
    text : str
        Words separated by spaces.
    width_px : int
        Widest line, pixels.
    scale : float
        The font scale given to ``cv2.putText``.

    Returns
    -------
    list of str
        The lines (a word too long for one line stays whole; ``[""]`` for no words).

    Examples
    --------
    >>> wrap_to_width("a b c", 1000, 0.5)
    ['a b c']
    >>> len(wrap_to_width("calibration view rejected: too blurred", 60, 0.5)) > 1
    True
    """
    lines: list[str] = []
    for word in text.split():
        trial = f"{lines[-1]} {word}" if lines else word
        if lines and cv2.getTextSize(trial, _FONT, scale, 1)[0][0] <= width_px:
            lines[-1] = trial
        else:
            lines.append(word)
    return lines or [""]
