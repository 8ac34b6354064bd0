"""Where the coach's next board view could go, and whether the whole printed board would be in the picture."""

from __future__ import annotations

import math

import cv2
import numpy as np

from .. import _lens, frames
from ..camera import Camera
from ._lens_jacobians import pixel_rays


def candidates(camera: Camera, board_points_mm: np.ndarray, distance_mm: float):
    """Board poses: centred on 3x3 places of the picture, face-on or tilted 35 deg four ways.

    A fisheye's places reach further out (its edges are where its calibration is weakest), its board at
    ``distance_mm`` along the ray and turned to face the camera before it is tilted.
    """
    centre = board_points_mm.mean(axis=0)
    fisheye = camera.model == "fisheye"
    places = {
        (0, 0): "at the top left",
        (1, 0): "at the top",
        (2, 0): "at the top right",
        (0, 1): "at the left",
        (1, 1): "in the middle",
        (2, 1): "at the right",
        (0, 2): "at the bottom left",
        (1, 2): "at the bottom",
        (2, 2): "at the bottom right",
    }
    tilts = {
        "face-on": np.eye(3),
        "its top tilted away from the camera": frames.rot_x(math.radians(-35)),
        "its bottom tilted away from the camera": frames.rot_x(math.radians(35)),
        "its left side tilted away from the camera": frames.rot_y(math.radians(35)),
        "its right side tilted away from the camera": frames.rot_y(math.radians(-35)),
    }
    edge = 0.1 if fisheye else 0.2
    for (i, j), where in places.items():
        px = np.array([[edge + (0.5 - edge) * i, edge + (0.5 - edge) * j]]) * camera.image_size
        ray = pixel_rays(camera, px)[0]
        if not np.all(np.isfinite(ray)):
            continue
        C = ray * distance_mm if fisheye else ray / ray[2] * distance_mm
        facing = _facing(ray) if fisheye else np.eye(3)
        for tilt, R in tilts.items():
            R = facing @ R
            name = "turned to face the camera" if fisheye and tilt == "face-on" else tilt
            yield frames.make_transform(R, C - R @ centre), where, name


def _facing(ray: np.ndarray) -> np.ndarray:
    """The smallest rotation that turns the board's normal (its z, along the optical axis face-on) onto ``ray``."""
    axis = np.cross([0.0, 0.0, 1.0], ray)
    angle = math.atan2(float(np.linalg.norm(axis)), float(ray[2]))
    return cv2.Rodrigues(axis / max(float(np.linalg.norm(axis)), 1e-300) * angle)[0]


def printed_outline(board_mm: np.ndarray, per_side: int = 8) -> np.ndarray:
    """Points along the edge of the printed board (board frame, mm): the rectangle of its inner corners
    grown by one square on every side, since a detector needs the outer row of squares too."""
    P = np.asarray(board_mm, dtype=float).reshape(-1, 3)
    gaps = np.linalg.norm(P[:, None, :2] - P[None, :, :2], axis=-1)
    square = float(gaps[gaps > 1e-9].min()) if len(P) > 1 else 0.0
    x0, y0 = P[:, :2].min(axis=0) - square
    x1, y1 = P[:, :2].max(axis=0) + square
    t = np.linspace(0.0, 1.0, per_side, endpoint=False)
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    edge = np.concatenate([a + t[:, None] * (b - a) for a, b in zip(corners, np.roll(corners, -1, axis=0))])
    return np.column_stack([edge, np.full(len(edge), P[:, 2].mean())])


def printed_points(board_mm: np.ndarray) -> np.ndarray:
    """The board's inner corners and the edge of its print (board frame, mm): what must be in the picture."""
    return np.concatenate([np.asarray(board_mm, dtype=float).reshape(-1, 3), printed_outline(board_mm)])


def board_in_picture(camera: Camera, board_mm: np.ndarray, T_camera_board: np.ndarray) -> bool:
    """Whether the whole printed board (its inner corners and the outer row of squares) is in the picture."""
    return in_picture(camera, printed_points(board_mm), T_camera_board)


def in_picture(camera: Camera, pts: np.ndarray, T_camera_board: np.ndarray) -> bool:
    """Whether every point of ``pts`` (board frame, mm; :func:`printed_points`) is in front and in the picture."""
    P = pts @ T_camera_board[:3, :3].T + T_camera_board[:3, 3]
    if np.any(P[:, 2] <= 1.0):
        return False
    px = _lens.project_points(P, camera.K, camera.dist, camera.model)
    return bool(np.all(px >= 0) and np.all(px[:, 0] <= camera.width - 1) and np.all(px[:, 1] <= camera.height - 1))
