"""The renderer: printed sheets (textured planes in the world) drawn into a supersampled picture.

See :mod:`fidlearn.synthetic` for how a frame is made.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from .. import _cv, frames
from ..camera import Camera
from ..errors import FidlearnError
from ..markermap import MarkerMap
from ._checks import MAX_RENDER_SAMPLES, _check_seed
from ._rays import _fine_rays, _normalized_map

_MAX_TEXELS_PER_CELL = 256
_STRIP_SUBPIXELS = 1 << 20  # process the fine grid in strips of about a million sub-pixels


@dataclass
class _Sheet:
    """A printed, flat sheet: texture (h, w) gray levels, and texel (s, t) -> world mm."""

    texture: np.ndarray
    A_world: np.ndarray  # (3, 3): world point = A_world @ (s, t, 1), texel centres at integers
    label: str = ""

    def camera_homography(self, T_camera_world: np.ndarray) -> np.ndarray:
        """(3, 3) map from texels (s, t, 1) to camera-frame points (rays scaled by depth)."""
        R, t = T_camera_world[:3, :3], T_camera_world[:3, 3]
        H = R @ self.A_world
        H[:, 2] += t
        return H

    def outline_world(self) -> np.ndarray:
        """The sheet's four outer corners (4, 3), mm, world."""
        h, w = self.texture.shape[:2]
        st = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1], [-0.5, h - 0.5, 1]])
        return st @ self.A_world.T


def _marker_sheet(
    marker_map: MarkerMap, marker_id: int, texels_per_cell: int, margin_cells: float, grays: dict
) -> _Sheet:
    dictionary = marker_map.marker_dictionary(marker_id)  # each marker its own dictionary and size
    cells = _cv.dictionary_marker_bits(dictionary) + 2
    n = cells * texels_per_cell
    m = int(round(margin_cells * texels_per_cell))
    marker = _cv.generate_marker(dictionary, int(marker_id), n).astype(np.float32) / 255.0
    tex = np.full((n + 2 * m, n + 2 * m), grays["paper"], dtype=np.float32)
    tex[m : m + n, m : m + n] = grays["ink"] + (grays["paper"] - grays["ink"]) * marker
    c = marker_map.marker_corners(marker_id)
    e_s = (c[1] - c[0]) / n  # one texel along TL -> TR
    e_t = (c[3] - c[0]) / n  # one texel along TL -> BL
    # the marker's outer edge runs along texel edges: its TL corner is at texel (m - 0.5, m - 0.5)
    origin = c[0] - (m - 0.5) * (e_s + e_t)
    return _Sheet(tex, np.column_stack([e_s, e_t, origin]), label=f"marker {marker_id}")


def _projected_size_px(corners_world: np.ndarray, camera: Camera, T_camera_world: np.ndarray) -> float | None:
    """Longest side (pinhole pixels) of a quad seen by the camera, or None when part is behind it."""
    pc = corners_world @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
    if np.any(pc[:, 2] <= 1.0):
        return None
    xy = pc[:, :2] / pc[:, 2:3] * [camera.fx, camera.fy]
    return float(np.max(np.linalg.norm(xy - np.roll(xy, -1, axis=0), axis=1)))


def _texels_per_cell(side_px: float | None, cells: int, k: int) -> int:
    """Texels per cell so that one texel is at most about one sub-pixel."""
    if side_px is None:
        return 32
    return int(np.clip(math.ceil(side_px * k / cells), 4, _MAX_TEXELS_PER_CELL))


def _sheet_region(sheet: _Sheet, H: np.ndarray, nmap: np.ndarray, width: int, height: int):
    """Output pixels ``(u0, u1, v0, v1)`` that may see the sheet and whether it crosses the camera's plane.

    None when no pixel can see it.
    """
    h, w = sheet.texture.shape[:2]
    st = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1], [-0.5, h - 0.5, 1]])
    pc = st @ H.T
    near = 1e-3  # mm
    crossing = bool(np.any(pc[:, 2] <= near))
    if crossing:
        pc = _clip_polygon_in_front(pc, near)
        if len(pc) < 3:
            return None
    xy = pc[:, :2] / pc[:, 2:3]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    inner = nmap[1:-1, 1:-1]
    inside = (inner[..., 0] >= lo[0]) & (inner[..., 0] <= hi[0]) & (inner[..., 1] >= lo[1]) & (inner[..., 1] <= hi[1])
    rows = np.flatnonzero(inside.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(inside[rows[0] : rows[-1] + 1].any(axis=0))
    return (max(cols[0] - 2, 0), min(cols[-1] + 3, width), max(rows[0] - 2, 0), min(rows[-1] + 3, height)), crossing


def _clip_polygon_in_front(points: np.ndarray, near: float) -> np.ndarray:
    """The part (M, 3) of a convex polygon (N, 3), camera frame, with depth z >= ``near`` (Sutherland-Hodgman)."""
    out = []
    n = len(points)
    for i in range(n):
        p, q = points[i], points[(i + 1) % n]
        p_in, q_in = p[2] >= near, q[2] >= near
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (near - p[2]) / (q[2] - p[2])
            out.append(p + t * (q - p))
    return np.array(out).reshape(-1, 3)


def _check_render_options(camera: Camera, supersample, blur_px, noise_std_gray, wall_texture_std_gray) -> int:
    """The supersampling factor ``k``, after checking the options; :class:`FidlearnError` names a wrong one."""
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 16:
        raise FidlearnError(f"supersample must be a whole number from 1 to 16, got {supersample!r}")
    k = int(supersample)
    samples = camera.width * camera.height * k * k
    if samples > MAX_RENDER_SAMPLES:
        raise FidlearnError(
            f"a {camera.width}x{camera.height} picture at supersample {k} is {samples / 1e6:.4g} "
            f"million samples, more than the limit of {MAX_RENDER_SAMPLES / 1e6:g} million (MAX_RENDER_SAMPLES, a few "
            "seconds of work); render a smaller picture (fidlearn render --size, Camera.scaled) or a lower supersample"
        )
    for name, value, most in (
        ("blur_px", blur_px, 100.0),
        ("noise_std_gray", noise_std_gray, 255.0),
        ("wall_texture_std_gray", wall_texture_std_gray, 255.0),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise FidlearnError(f"{name} must be a number from 0 to {most:g}, got {value!r:.40}")
        if not (math.isfinite(value) and 0 <= value <= most):
            raise FidlearnError(f"{name} must be a number from 0 to {most:g}, got {value!r:.40}")
    return k


def _wall(
    rng: np.random.Generator, width: int, height: int, wall_gray: float, wall_texture_std_gray: float
) -> np.ndarray:
    """The wall (height, width) float32: mid gray with a faint, smooth, seeded texture (fixed to the image)."""
    img = np.full((height, width), wall_gray, dtype=np.float32)
    if wall_texture_std_gray > 0:
        coarse = rng.standard_normal((height // 24 + 3, width // 24 + 3)).astype(np.float32)
        img += np.float32(wall_texture_std_gray) * cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    return img


def _sheets_in_view(
    sheets: Sequence[_Sheet], T_camera_world: np.ndarray, nmap: np.ndarray, width: int, height: int
) -> list:
    """``(sheet, inverse homography, (u0, u1, v0, v1), crossing)`` of each sheet facing the camera and in view."""
    todo = []
    for sheet in sheets:
        H = sheet.camera_homography(T_camera_world)
        # the printed face points along -(e_s x e_t); a sheet seen from behind is not drawn
        face = -np.cross(H[:, 0], H[:, 1])
        if float(face @ (-H[:, 2])) <= 0 or abs(np.linalg.det(H)) < 1e-12:
            continue
        found = _sheet_region(sheet, H, nmap, width, height)
        if found is not None:
            todo.append((sheet, np.linalg.inv(H), *found))
    return todo


def _overlaps(todo: list) -> list[bool]:
    """Per sheet in view, whether its pixel region overlaps another's (only there is a depth test needed)."""
    return [
        any(
            j != i and r[0] < q[1] and q[0] < r[1] and r[2] < q[3] and q[2] < r[3]
            for j, (_, _, q, _) in enumerate(todo)
        )
        for i, (_, _, r, _) in enumerate(todo)
    ]


def _draw_sheet(
    canvas: np.ndarray,
    wbuf: np.ndarray | None,
    item: tuple,
    depth_test: bool,
    nmap: np.ndarray,
    T_camera_world: np.ndarray,
    k: int,
    origin: tuple[int, int],
) -> None:
    """Draw one sheet onto the supersampled ``canvas`` (whose pixel (0, 0) is output pixel ``origin`` (U0, V0))."""
    sheet, Hinv, (u0, u1, v0, v1), crossing = item
    U0, V0 = origin
    # premultiplied texture: the second channel (ones) is the coverage at the sheet's edge; a
    # border texel of zeros all round, so that OpenCV's (0, 0) for a ray parallel to the sheet is empty
    tex2 = np.zeros((sheet.texture.shape[0] + 2, sheet.texture.shape[1] + 2, 2), dtype=np.float32)
    tex2[1:-1, 1:-1, 0] = sheet.texture
    tex2[1:-1, 1:-1, 1] = 1.0
    # rays -> texels (+1 for the border); Hinv's w is 1 / depth (mm): scale it to about 1 on the sheet
    depth_mm = max(
        float(np.abs(sheet.outline_world() @ T_camera_world[:3, :3].T + T_camera_world[:3, 3])[:, 2].max()), 1.0
    )
    Hmap = np.array([[1.0, 0, 1.0], [0, 1.0, 1.0], [0, 0, 1.0]]) @ Hinv * depth_mm
    rows = max(1, _STRIP_SUBPIXELS // (k * k * (u1 - u0)))
    for s0 in range(v0, v1, rows):
        s1 = min(s0 + rows, v1)
        rays = _fine_rays(nmap, u0, u1, s0, s1, k)
        maps = cv2.perspectiveTransform(rays, Hmap)
        if crossing or depth_test:
            w = Hinv[2, 0] * rays[..., 0] + Hinv[2, 1] * rays[..., 1] + np.float32(Hinv[2, 2])
        if crossing:
            maps[w <= 0] = -10.0  # behind the camera
        np.clip(maps, -10.0, 1e6, out=maps)
        # OpenCV's stub wants a map2; a two-channel float map1 has none
        looked = cv2.remap(tex2, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))  # type: ignore[call-overload]
        ink, alpha = looked[..., 0], looked[..., 1]
        sl = (slice((s0 - V0) * k, (s1 - V0) * k), slice((u0 - U0) * k, (u1 - U0) * k))
        if depth_test:
            assert wbuf is not None  # made whenever sheets overlap
            wb = wbuf[sl]
            hidden = w <= wb
            alpha[hidden] = 0.0
            ink[hidden] = 0.0
            opaque = alpha >= 0.5
            wb[opaque] = w[opaque]
        view = canvas[sl]
        view *= 1.0 - alpha
        view += ink


def _draw_sheets(img: np.ndarray, todo: list, nmap: np.ndarray, T_camera_world: np.ndarray, k: int) -> None:
    """Draw the sheets in view into ``img`` (in place), supersampled ``k`` x ``k`` and averaged down."""
    # supersample only the pixels that see a sheet; the wall is uniform within a pixel
    U0 = min(t[2][0] for t in todo)
    U1 = max(t[2][1] for t in todo)
    V0 = min(t[2][2] for t in todo)
    V1 = max(t[2][3] for t in todo)
    canvas = np.repeat(np.repeat(img[V0:V1, U0:U1], k, axis=0), k, axis=1)
    # a depth test only where sheets' regions overlap: the nearest sheet wins
    overlaps = _overlaps(todo)
    wbuf = np.zeros_like(canvas) if any(overlaps) else None  # inverse depth (1/mm) of the nearest sheet so far
    for item, depth_test in zip(todo, overlaps):
        _draw_sheet(canvas, wbuf, item, depth_test, nmap, T_camera_world, k, (U0, V0))
    # each pixel is the mean of its k x k sub-pixels: the area integral over its footprint
    h, w_ = V1 - V0, U1 - U0
    img[V0:V1, U0:U1] = canvas.reshape(h, k, w_ * k).sum(axis=1).reshape(h, w_, k).sum(axis=2) / np.float32(k * k)


def _finish(
    img: np.ndarray,
    rng: np.random.Generator,
    blur_px: float,
    gradient: float,
    gradient_angle_deg: float,
    noise_std_gray: float,
    bgr: bool,
) -> np.ndarray:
    """Blur, illumination gradient and sensor noise on the area-averaged picture, then uint8 (gray or BGR)."""
    width, height = img.shape[1], img.shape[0]
    img = img.astype(np.float64)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), float(blur_px), borderType=cv2.BORDER_REFLECT)
    if gradient:
        th = math.radians(gradient_angle_deg)
        uu = (np.arange(width) / max(width - 1, 1) - 0.5) * math.cos(th)
        vv = (np.arange(height) / max(height - 1, 1) - 0.5) * math.sin(th)
        img = img * (1.0 + float(gradient) * (uu[None, :] + vv[:, None]))
    if noise_std_gray > 0:
        img = img + rng.normal(0.0, float(noise_std_gray), size=img.shape)
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if bgr:
        out = cv2.cvtColor(out, cv2.COLOR_GRAY2BGR)
    return out


def _render(
    camera: Camera,
    T_world_camera: np.ndarray,
    sheets: Sequence[_Sheet],
    *,
    seed: int,
    supersample: int,
    blur_px: float,
    noise_std_gray: float,
    gradient: float,
    gradient_angle_deg: float,
    wall_gray: float,
    wall_texture_std_gray: float,
    bgr: bool,
) -> np.ndarray:
    """The picture (H, W) or (H, W, 3) uint8 the camera at ``T_world_camera`` (mm, world) takes of the sheets."""
    k = _check_render_options(camera, supersample, blur_px, noise_std_gray, wall_texture_std_gray)
    width, height = camera.image_size
    rng = np.random.default_rng(_check_seed(seed))
    T_camera_world = frames.invert_transform(T_world_camera)
    nmap = _normalized_map(camera)
    img = _wall(rng, width, height, wall_gray, wall_texture_std_gray)
    todo = _sheets_in_view(sheets, T_camera_world, nmap, width, height)
    if todo:
        _draw_sheets(img, todo, nmap, T_camera_world, k)
    return _finish(img, rng, blur_px, gradient, gradient_angle_deg, noise_std_gray, bgr)
