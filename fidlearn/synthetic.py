"""A synthetic world with ground truth: printed markers and boards seen by a known camera.

Every picture fidlearn renders comes with the answer: the true camera, the true
pose and the true pixel corners of each visible marker, so detection, pose
and calibration can be checked against known numbers.

How a frame is made (the realism that matters for detection and accuracy):

* Each printed sheet (an ArUco marker with its white quiet zone, a checkerboard
  or a ChArUco board with a white margin) is a textured plane in the world;
  the wall behind it is mid gray with a faint, smooth, seeded texture (fixed
  to the image, not to the wall: it is there so that nothing is perfectly flat).
* For every pixel of a supersampled image (``supersample`` x ``supersample``
  sub-pixels per pixel) the renderer finds the ray through it, undistorting
  with the camera's own model (``cv2.undistortPoints`` refined by Newton
  steps to 1e-9 px), intersects the ray with each plane through the plane's
  homography and looks the texture up (``cv2.remap``). The nearest plane wins;
  a plane seen from behind is not drawn.
* The supersampled image is averaged down block by block, so each pixel holds
  the area integral of the scene over its footprint (edges land at sub-pixel
  positions, as on a real sensor). A sub-pixel ``u_h`` of the fine grid sits at
  ``u = (u_h + 0.5) / k - 0.5`` in the output (pixel centres at integers).
* Then, optionally: Gaussian blur (defocus), an illumination gradient and
  Gaussian sensor noise, all from ``numpy.random.default_rng(seed)``.

The truth of a marker is ``camera.project(marker_map.marker_corners(id),
T_world_camera)``: exactly what ``cv2.projectPoints`` gives for its 3D corners.
Checked against plain OpenCV (``tests/test_synthetic.py``): checkerboard
X-corners found by ``cv2.cornerSubPix`` sit within a few thousandths of a
pixel of the truth on average, through strong distortion.

Same inputs, same OpenCV build: the same pixels, run after run (OpenCV 4.14
and 5.0 agree bit for bit). Another release may round ``cv2.remap``'s
bilinear weights differently, which moves a gray level here and there at
edges (see ``data/README.md``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from . import _cv, frames
from .camera import Camera
from .errors import CameraError, FidlearnError
from .markermap import MarkerMap

__all__ = [
    "render_scene",
    "visible_markers",
    "look_at",
    "render_calibration_views",
    "CalibrationViews",
    "trajectory_poses",
    "render_trajectory",
    "Trajectory",
    "DEFAULT_GRAYS",
]

#: Gray levels of the synthetic world: the wall, the paper and the printed ink.
DEFAULT_GRAYS = {"wall": 120.0, "paper": 230.0, "ink": 25.0}

_MAX_TEXELS_PER_CELL = 256
_STRIP_SUBPIXELS = 1 << 20  # process the fine grid in strips of about a million sub-pixels


# ----------------------------------------------------------------------------------------------
# Camera rays: the normalized (undistorted) coordinates of every pixel.
# ----------------------------------------------------------------------------------------------

#: Most samples (pixels times supersample squared) one picture is rendered from.
MAX_RENDER_SAMPLES = 1_000_000_000
#: Most frames a trajectory may have.
MAX_FRAMES = 100_000


def _check_scene(marker_map, camera, with_camera: bool = True, where: str = "render_scene") -> None:
    """Raise a FidlearnError unless ``marker_map`` is a MarkerMap and ``camera`` a Camera (map first)."""
    order = f"{where}(marker_map, camera, ...): the map comes first, then the camera"
    if with_camera and isinstance(marker_map, Camera) and isinstance(camera, MarkerMap):
        raise FidlearnError(f"{order}; the arguments are swapped")
    if not isinstance(marker_map, MarkerMap):
        raise FidlearnError(
            f"marker_map must be a fidlearn.MarkerMap (MarkerMap.load reads a file), got {type(marker_map).__name__}; "
            f"{order}"
        )
    if with_camera and not isinstance(camera, Camera):
        raise FidlearnError(
            f"camera must be a fidlearn.Camera (Camera.load reads a file), got {type(camera).__name__}; {order}"
        )


def _check_seed(seed) -> int:
    """A seed for ``numpy.random.default_rng``: a whole number from 0 to 2**63 - 1."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**63:
        raise FidlearnError(f"seed must be a whole number from 0 to 2**63 - 1, got {seed!r}")
    return int(seed)


def _distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's distortion model on normalized points (N, 2): ideal -> distorted normalized."""
    d = np.zeros(14)
    d[: dist.size] = dist
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d[:12]
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
    return np.stack([xd, yd], axis=1)


def _pixels_from_normalized(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    xd = _distort_normalized(xy, dist)
    return np.stack([K[0, 0] * xd[:, 0] + K[0, 1] * xd[:, 1] + K[0, 2], K[1, 1] * xd[:, 1] + K[1, 2]], axis=1)


def _undistort_exact(px: np.ndarray, K: np.ndarray, dist: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Normalized ideal coordinates (N, 2) of pixels (N, 2), exact to about 1e-9 px.

    ``cv2.undistortPoints`` alone stops after a few fixed-point steps (up to
    half a pixel off at the corners of a wide lens); Newton steps on OpenCV's
    own distortion model finish the job.
    """
    xy = cv2.undistortPoints(px.reshape(-1, 1, 2).astype(np.float64), K, dist).reshape(-1, 2)
    if not np.any(dist):
        return xy
    h = 1e-7
    for _ in range(iterations):
        base = _pixels_from_normalized(xy, K, dist)
        r = base - px
        if np.abs(r).max() < 1e-9:
            break
        jx = (_pixels_from_normalized(xy + [h, 0.0], K, dist) - base) / h
        jy = (_pixels_from_normalized(xy + [0.0, h], K, dist) - base) / h
        det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (jy[:, 1] * r[:, 0] - jy[:, 0] * r[:, 1]) / det
        dy = (-jx[:, 1] * r[:, 0] + jx[:, 0] * r[:, 1]) / det
        xy = xy - np.stack([dx, dy], axis=1)
    return xy


@lru_cache(maxsize=4)
def _normalized_map_cached(key: bytes, width: int, height: int) -> np.ndarray:
    K_dist = np.frombuffer(key, dtype=np.float64)
    K, dist = K_dist[:9].reshape(3, 3), K_dist[9:]
    u, v = np.meshgrid(np.arange(-1.0, width + 1.0), np.arange(-1.0, height + 1.0))
    px = np.stack([u.ravel(), v.ravel()], axis=1)
    xy = _undistort_exact(px, K, dist)
    out = xy.reshape(height + 2, width + 2, 2).astype(np.float32)
    out.setflags(write=False)
    return out


def _normalized_map(camera: Camera) -> np.ndarray:
    """Normalized ray coordinates (H + 2, W + 2, 2), float32, of every pixel, with a one-pixel margin.

    Entry ``[j, i]`` belongs to the pixel centre ``u = i - 1``, ``v = j - 1``.
    """
    if camera.dist.size == 14 and np.any(camera.dist[12:]):
        raise CameraError(
            f"{camera.source or 'camera'}: the renderer does not model a tilted sensor (tau_x, tau_y = "
            f"{camera.dist[12]:g}, {camera.dist[13]:g}); use at most 12 distortion coefficients"
        )
    key = np.concatenate([camera.K.ravel(), camera.dist.ravel()]).astype(np.float64).tobytes()
    return _normalized_map_cached(key, camera.width, camera.height)


def _fine_rays(nmap: np.ndarray, u0: int, u1: int, v0: int, v1: int, k: int) -> np.ndarray:
    """Normalized coordinates (k (v1 - v0), k (u1 - u0), 2), float32, of the sub-pixels of output pixels ``u0..u1-1``, ``v0..v1-1``.

    Bilinear interpolation of the per-pixel map (the distortion is smooth: error
    below 1e-4 px). ``cv2.resize`` maps a fine sample ``x_d`` to the coarse
    coordinate ``(x_d + 0.5) / k - 0.5``, the same pixel-centre rule as the
    supersampling, and the one-pixel margin keeps it from clamping at the edge.
    """
    patch = nmap[v0 : v1 + 2, u0 : u1 + 2]
    if k == 1:
        return np.ascontiguousarray(patch[1:-1, 1:-1])
    h, w = patch.shape[:2]
    fine = cv2.resize(patch, (w * k, h * k), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(fine[k : k + k * (v1 - v0), k : k + k * (u1 - u0)])


# ----------------------------------------------------------------------------------------------
# Printed sheets: a texture and where it lies in the world.
# ----------------------------------------------------------------------------------------------


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
    cells = _cv.dictionary_marker_bits(marker_map.dictionary) + 2
    n = cells * texels_per_cell
    m = int(round(margin_cells * texels_per_cell))
    marker = _cv.generate_marker(marker_map.dictionary, marker_id, n).astype(np.float32) / 255.0
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


# ----------------------------------------------------------------------------------------------
# The renderer.
# ----------------------------------------------------------------------------------------------


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
    wall_texture: float,
    bgr: bool,
) -> np.ndarray:
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 16:
        raise FidlearnError(f"supersample must be a whole number from 1 to 16, got {supersample!r}")
    k = int(supersample)
    if camera.width * camera.height * k * k > MAX_RENDER_SAMPLES:
        raise FidlearnError(
            f"a {camera.width}x{camera.height} picture at supersample {k} is more than "
            f"{MAX_RENDER_SAMPLES / 1e9:g} billion samples; use a smaller picture or supersample"
        )
    for name, value in (("blur_px", blur_px), ("noise_std_gray", noise_std_gray), ("wall_texture", wall_texture)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise FidlearnError(f"{name} must be a finite number >= 0, got {value!r}")
        if not (math.isfinite(value) and value >= 0):
            raise FidlearnError(f"{name} must be a finite number >= 0, got {value!r}")
    width, height = camera.image_size
    rng = np.random.default_rng(_check_seed(seed))
    T_camera_world = frames.invert_transform(T_world_camera)
    nmap = _normalized_map(camera)

    # the wall: mid gray with a faint, smooth, seeded texture (fixed to the image, not the wall)
    img = np.full((height, width), wall_gray, dtype=np.float32)
    if wall_texture > 0:
        coarse = rng.standard_normal((height // 24 + 3, width // 24 + 3)).astype(np.float32)
        img += np.float32(wall_texture) * cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)

    # which sheets face the camera, and which output pixels may see them
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

    if todo:
        # supersample only the pixels that see a sheet; the wall is uniform within a pixel
        U0 = min(t[2][0] for t in todo)
        U1 = max(t[2][1] for t in todo)
        V0 = min(t[2][2] for t in todo)
        V1 = max(t[2][3] for t in todo)
        canvas = np.repeat(np.repeat(img[V0:V1, U0:U1], k, axis=0), k, axis=1)
        # a depth test only where sheets' regions overlap: the nearest sheet wins
        overlaps = [
            any(
                j != i and r[0] < q[1] and q[0] < r[1] and r[2] < q[3] and q[2] < r[3]
                for j, (_, _, q, _) in enumerate(todo)
            )
            for i, (_, _, r, _) in enumerate(todo)
        ]
        wbuf = np.zeros_like(canvas) if any(overlaps) else None  # inverse depth (1/mm) of the nearest sheet so far
        for (sheet, Hinv, (u0, u1, v0, v1), crossing), depth_test in zip(todo, overlaps):
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
                looked = cv2.remap(
                    tex2, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0)
                )
                ink, alpha = looked[..., 0], looked[..., 1]
                sl = (slice((s0 - V0) * k, (s1 - V0) * k), slice((u0 - U0) * k, (u1 - U0) * k))
                if depth_test:
                    wb = wbuf[sl]
                    hidden = w <= wb
                    alpha[hidden] = 0.0
                    ink[hidden] = 0.0
                    opaque = alpha >= 0.5
                    wb[opaque] = w[opaque]
                view = canvas[sl]
                view *= 1.0 - alpha
                view += ink
        # each pixel is the mean of its k x k sub-pixels: the area integral over its footprint
        h, w_ = V1 - V0, U1 - U0
        img[V0:V1, U0:U1] = canvas.reshape(h, k, w_ * k).sum(axis=1).reshape(h, w_, k).sum(axis=2) / np.float32(k * k)

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


# ----------------------------------------------------------------------------------------------
# Scenes of markers on walls.
# ----------------------------------------------------------------------------------------------


def look_at(
    eye_mm: Sequence[float], target_mm: Sequence[float], up: Sequence[float] = (0.0, 0.0, 1.0), roll_deg: float = 0.0
) -> np.ndarray:
    """The pose ``T_world_camera`` (4, 4) of a camera at ``eye_mm`` looking at ``target_mm``.

    The camera frame is OpenCV's (x right, y down, z forward); ``up`` (world)
    points up in the image, and ``roll_deg`` then turns the camera about its
    optical axis (positive: clockwise as the image shows it).

    Examples
    --------
    >>> T = look_at([1500, 0, 300], [0, 0, 300])   # 1.5 m in front of the north wall
    >>> T[:3, 2].round(3).tolist()                 # the camera looks along -X
    [-1.0, 0.0, 0.0]
    """
    eye, target = (
        frames.as_float_array(v, name, FidlearnError).reshape(-1)
        for v, name in ((eye_mm, "look_at: eye_mm"), (target_mm, "look_at: target_mm"))
    )
    if eye.shape != (3,) or target.shape != (3,) or not np.all(np.isfinite(eye)) or not np.all(np.isfinite(target)):
        raise FidlearnError(
            f"look_at: eye_mm and target_mm must be 3 finite numbers (x, y, z in mm), got "
            f"{np.shape(eye_mm)} and {np.shape(target_mm)}"
        )
    z = target - eye
    if np.linalg.norm(z) < 1e-9:
        raise FidlearnError(f"look_at: the eye {eye.tolist()} and the target are the same point; move one of them")
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=float))
    if np.linalg.norm(x) < 1e-9:
        raise FidlearnError(
            f"look_at: the view direction {z.round(3).tolist()} is parallel to up={list(up)}; choose another up"
        )
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.column_stack([x, y, z]) @ frames.rot_z(math.radians(roll_deg))
    return frames.make_transform(R, eye)


def visible_markers(
    marker_map: MarkerMap, camera: Camera, T_world_camera: np.ndarray, margin_px: float = 2.0
) -> dict[int, np.ndarray]:
    """True pixel corners of the markers a camera sees whole: ``{id: (4, 2) float64}``.

    A marker counts as visible when its four corners are in front of the
    camera, inside the image with ``margin_px`` to spare (pixel-centre
    convention: the image spans -0.5 .. width - 0.5) and its printed face
    points toward the camera. Corners are ``camera.project`` of the marker's
    3D corners (TL, TR, BR, BL), i.e. ``cv2.projectPoints``. Occlusion by
    another sheet is not considered: a marker hidden behind a nearer one is
    drawn hidden but still listed.
    """
    _check_scene(marker_map, camera, where="visible_markers")
    T_world_camera = frames.check_transform(T_world_camera, name="T_world_camera")
    T_camera_world = frames.invert_transform(T_world_camera)
    eye = T_world_camera[:3, 3]
    out: dict[int, np.ndarray] = {}
    lo_u, lo_v = -0.5 + margin_px, -0.5 + margin_px
    hi_u, hi_v = camera.width - 0.5 - margin_px, camera.height - 0.5 - margin_px
    for mid in marker_map.ids:
        c = marker_map.marker_corners(mid)
        pc = c @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
        if np.any(pc[:, 2] <= 1.0):
            continue
        if float(marker_map.normal(mid) @ (eye - c.mean(axis=0))) <= 0:
            continue
        # far outside the field of view the distortion polynomial folds back: test the pinhole first
        xy = pc[:, :2] / pc[:, 2:3]
        ideal = xy * [camera.fx, camera.fy] + [camera.cx, camera.cy]
        slack = 0.5 * max(camera.width, camera.height)
        if np.any(ideal < [lo_u - slack, lo_v - slack]) or np.any(ideal > [hi_u + slack, hi_v + slack]):
            continue
        px = camera.project(c, T_world_camera)
        if np.all((px[:, 0] >= lo_u) & (px[:, 0] <= hi_u) & (px[:, 1] >= lo_v) & (px[:, 1] <= hi_v)):
            out[mid] = px
    return out


def render_scene(
    marker_map: MarkerMap,
    camera: Camera,
    T_world_camera: np.ndarray,
    *,
    seed: int = 0,
    blur_px: float = 0.0,
    noise_std_gray: float = 0.0,
    gradient: float = 0.0,
    gradient_angle_deg: float = 30.0,
    supersample: int = 4,
    wall_gray: float = DEFAULT_GRAYS["wall"],
    wall_texture: float = 3.0,
    paper_gray: float = DEFAULT_GRAYS["paper"],
    ink_gray: float = DEFAULT_GRAYS["ink"],
    margin_cells: float = 1.0,
    margin_px: float = 2.0,
    bgr: bool = False,
) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Render what a camera sees of printed markers taped to walls, with the true corners.

    Parameters
    ----------
    camera : Camera
        Intrinsics, distortion and image size of the picture.
    marker_map : MarkerMap
        The markers' placements (mm, world), size and dictionary.
    T_world_camera : ndarray, shape (4, 4)
        The camera's pose in the world (mm), camera frame OpenCV's.
    seed : int
        Seed of ``numpy.random.default_rng`` for the wall texture and the noise.
    blur_px : float
        Standard deviation (pixels) of a Gaussian blur (defocus); 0 for none.
    noise_std_gray : float
        Standard deviation (gray levels) of Gaussian sensor noise; 0 for none.
    gradient : float
        Illumination change across the image as a fraction (0.3: 30 % brighter
        on one side than the other), along ``gradient_angle_deg`` from the x axis.
    supersample : int
        Sub-pixels per pixel side; each pixel is the mean of ``supersample**2`` samples.
    wall_gray, wall_texture, paper_gray, ink_gray : float
        Gray levels of the wall, its texture's standard deviation, the paper and the ink.
    margin_cells : float
        White quiet zone around each marker, in marker cells (a cell is
        ``marker_size_mm / (bits + 2)``).
    margin_px : float
        How far inside the image a marker's corners must be to count as visible.
    bgr : bool
        Return a (H, W, 3) BGR image instead of gray.

    Returns
    -------
    image : ndarray, shape (H, W) or (H, W, 3), uint8
        The picture, at ``camera.image_size``.
    truth : dict
        ``{id: (4, 2) float64}``: the true pixel corners (TL, TR, BR, BL,
        pixel centres at integers) of every marker seen whole, facing the
        camera (see :func:`visible_markers`). Markers partly outside the image
        or behind the camera are drawn as far as they are seen but left out.

    Examples
    --------
    >>> from fidlearn import Camera, MarkerMap, data_path
    >>> cam = Camera.from_fov(60, (640, 480))
    >>> wall = MarkerMap.load(data_path("world_map.json"))
    >>> image, truth = render_scene(wall, cam, look_at([1200, 200, 250], [0, 200, 250]))
    >>> image.shape, image.dtype, sorted(truth)
    ((480, 640), dtype('uint8'), [0, 1, 2])
    >>> np.allclose(truth[0], cam.project(wall.marker_corners(0), look_at([1200, 200, 250], [0, 200, 250])))
    True
    """
    _check_scene(marker_map, camera, where="render_scene")
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 16:
        raise FidlearnError(f"supersample must be a whole number from 1 to 16, got {supersample!r}")
    T_world_camera = frames.check_transform(T_world_camera, name="T_world_camera")
    grays = {"wall": float(wall_gray), "paper": float(paper_gray), "ink": float(ink_gray)}
    if margin_cells < 0:
        raise FidlearnError(f"margin_cells must be >= 0 (the white quiet zone in marker cells), got {margin_cells}")
    T_camera_world = frames.invert_transform(T_world_camera)
    cells = _cv.dictionary_marker_bits(marker_map.dictionary) + 2
    sheets = []
    for mid in marker_map.ids:
        size = _projected_size_px(marker_map.marker_corners(mid), camera, T_camera_world)
        tpc = _texels_per_cell(size, cells, int(supersample))
        sheets.append(_marker_sheet(marker_map, mid, tpc, margin_cells, grays))
    image = _render(
        camera,
        T_world_camera,
        sheets,
        seed=seed,
        supersample=supersample,
        blur_px=blur_px,
        noise_std_gray=noise_std_gray,
        gradient=gradient,
        gradient_angle_deg=gradient_angle_deg,
        wall_gray=wall_gray,
        wall_texture=wall_texture,
        bgr=bgr,
    )
    return image, visible_markers(marker_map, camera, T_world_camera, margin_px=margin_px)


# ----------------------------------------------------------------------------------------------
# Calibration views: a printed checkerboard or ChArUco board held in front of the camera.
# ----------------------------------------------------------------------------------------------


@dataclass(eq=False)
class CalibrationViews:
    """Synthetic calibration pictures of a board, with the truth behind them.

    The world frame is the board's own (OpenCV's object-point frame): x along
    the pattern's rows, y down the board, z into the paper (the printed face
    looks along -z), mm.

    Attributes
    ----------
    images : list of ndarray (H, W) uint8
        The pictures.
    camera : Camera
        The true camera that took them.
    T_world_camera : list of ndarray (4, 4)
        The camera's pose in the board frame (mm), per view.
    object_points : ndarray (N, 3)
        The board's corners in the board frame (mm), in the order OpenCV
        reports them (``cv2.findChessboardCorners`` for a checkerboard,
        ``getChessboardCorners()`` ids 0..N-1 for ChArUco).
    image_points : list of ndarray (N, 2)
        True pixel positions of those corners per view (``cv2.projectPoints``).
    pattern_size : (int, int)
        Checkerboard: inner corners (columns, rows); ChArUco: squares (x, y).
    square_size_mm, marker_size_mm : float
        The printed sizes (``marker_size_mm`` is 0 for a checkerboard).
    charuco : bool
        Whether the board is ChArUco.
    dictionary : str
        ChArUco's marker dictionary ("" for a checkerboard).
    """

    images: list
    camera: Camera
    T_world_camera: list
    object_points: np.ndarray
    image_points: list
    pattern_size: tuple
    square_size_mm: float
    marker_size_mm: float = 0.0
    charuco: bool = False
    dictionary: str = ""
    seed: int = 0
    render_kwargs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def T_camera_board(self) -> list:
        """The board's pose in each camera frame (4, 4), mm: what ``cv2.calibrateCamera`` estimates."""
        return [frames.invert_transform(T) for T in self.T_world_camera]

    def board(self):
        """The ``cv2.aruco.CharucoBoard`` (ChArUco only), sizes in mm."""
        if not self.charuco:
            raise FidlearnError("a checkerboard has no cv2.aruco board; use pattern_size and square_size_mm")
        return _cv.charuco_board(self.pattern_size, self.square_size_mm, self.marker_size_mm, self.dictionary)

    def __repr__(self) -> str:
        kind = (
            f"ChArUco {self.pattern_size[0]}x{self.pattern_size[1]} squares, {self.dictionary}"
            if self.charuco
            else f"checkerboard {self.pattern_size[0]}x{self.pattern_size[1]} inner corners"
        )
        w, h = self.camera.image_size
        return (
            f"CalibrationViews({len(self)} views {w}x{h}, {kind}, square {self.square_size_mm:g} mm, {self.camera!r})"
        )


def _checkerboard_sheet(
    pattern_size: tuple[int, int], square_size_mm: float, tps: int, margin_squares: float, grays: dict
) -> _Sheet:
    cols, rows = pattern_size[0] + 1, pattern_size[1] + 1  # squares
    m = int(round(margin_squares * tps))
    jj, ii = np.mgrid[0:rows, 0:cols]
    squares = np.where((ii + jj) % 2 == 0, grays["ink"], grays["paper"]).astype(np.float32)  # top-left square black
    tex = np.full((rows * tps + 2 * m, cols * tps + 2 * m), grays["paper"], dtype=np.float32)
    tex[m : m + rows * tps, m : m + cols * tps] = np.kron(squares, np.ones((tps, tps), dtype=np.float32))
    step = square_size_mm / tps
    # inner corner (0, 0) is the board's origin; the outer edge of the squares is one square before it
    off = 0.5 * step - (square_size_mm + m * step)
    A = np.array([[step, 0.0, off], [0.0, step, off], [0.0, 0.0, 0.0]])
    return _Sheet(tex, A, label="checkerboard")


def _charuco_sheet(
    board, squares_xy: tuple[int, int], square_size_mm: float, tps: int, margin_squares: float, grays: dict
) -> _Sheet:
    m = int(round(margin_squares * tps))
    size = (squares_xy[0] * tps + 2 * m, squares_xy[1] * tps + 2 * m)
    img = board.generateImage(size, marginSize=m, borderBits=1).astype(np.float32) / 255.0
    tex = (grays["ink"] + (grays["paper"] - grays["ink"]) * img).astype(np.float32)
    step = square_size_mm / tps
    off = (0.5 - m) * step  # the board's origin (its top-left outer corner) is texel edge m - 0.5
    A = np.array([[step, 0.0, off], [0.0, step, off], [0.0, 0.0, 0.0]])
    return _Sheet(tex, A, label="charuco")


def _board_pose(
    camera: Camera,
    rng: np.random.Generator,
    target_px,
    distance_mm: float,
    tilt_deg: float,
    roll_deg: float,
    centre_board: np.ndarray,
) -> np.ndarray:
    """``T_camera_board``: the board's centre on the ray through ``target_px`` at ``distance_mm``, tilted."""
    ray = camera.undistort_points(np.asarray(target_px, dtype=float).reshape(1, 2))[0]
    ray = np.array([(ray[0] - camera.cx) / camera.fx, (ray[1] - camera.cy) / camera.fy, 1.0])
    centre_cam = ray / np.linalg.norm(ray) * distance_mm
    axis_angle = rng.uniform(0, 2 * math.pi)
    axis = np.array([math.cos(axis_angle), math.sin(axis_angle), 0.0])
    R_tilt, _ = cv2.Rodrigues(axis * math.radians(tilt_deg))
    R = R_tilt @ frames.rot_z(math.radians(roll_deg))
    # face the camera roughly: the board's z (into the paper) along the viewing ray, then tilt
    z = centre_cam / np.linalg.norm(centre_cam)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_face = np.column_stack([x, y, z])
    R_camera_board = R_face @ R
    t = centre_cam - R_camera_board @ centre_board
    return frames.make_transform(R_camera_board, t)


def render_calibration_views(
    camera: Camera,
    n_views: int = 20,
    pattern_size: tuple[int, int] = (9, 6),
    square_size_mm: float = 25.0,
    seed: int = 0,
    charuco: bool = False,
    *,
    marker_size_mm: float | None = None,
    dictionary: str = "6X6_250",
    tilt_range_deg: tuple[float, float] = (10.0, 45.0),
    fill_range: tuple[float, float] = (0.35, 0.7),
    margin_squares: float = 1.0,
    blur_px: float = 0.4,
    noise_std_gray: float = 1.5,
    gradient: float = 0.15,
    supersample: int = 4,
    wall_texture: float = 3.0,
    views: Sequence[int] | None = None,
) -> CalibrationViews:
    """Pictures of a printed calibration board held as a careful person would, with the truth.

    The board visits the image's corners, edges and centre in turn (a 3 x 3
    grid, then again with jitter), at several distances (it spans
    ``fill_range`` of the image width) and tilted 10 to 45 degrees about a
    random axis, with a random roll of up to 20 degrees. Every corner of the
    pattern stays inside the image.

    Parameters
    ----------
    camera : Camera
        The true camera (its distortion included).
    n_views : int
        How many pictures.
    pattern_size : (int, int)
        Checkerboard: inner corners (columns, rows), OpenCV's ``patternSize``.
        ChArUco: squares (x, y); ``(9, 6)`` is taken to mean the usual
        ``(5, 7)`` when ``charuco=True``.
    square_size_mm : float
        Side of a printed square (mm). ChArUco defaults to 40 mm squares
        with 20 mm markers when ``square_size_mm`` is left at 25.
    seed : int
        Seed of ``numpy.random.default_rng``: poses, wall texture and noise.
    charuco : bool
        A ChArUco board (``cv2.aruco.CharucoBoard``) instead of a checkerboard.
    marker_size_mm, dictionary :
        ChArUco's marker side (default half a square) and dictionary.
    blur_px, noise_std_gray, gradient, supersample, wall_texture :
        As for :func:`render_scene`, applied to every view.
    views : sequence of int, optional
        Render only these views (indices into the ``n_views`` poses, which are
        drawn all the same): view ``i`` comes out identical to view ``i`` of
        the full set. The result then holds only those views.

    Returns
    -------
    CalibrationViews
        Images, the true camera, the true poses and corner pixels.

    Examples
    --------
    >>> cam = Camera([[600, 0, 320], [0, 600, 240], [0, 0, 1]], [-0.1, 0.02, 0, 0, 0], (640, 480))
    >>> views = render_calibration_views(cam, n_views=2, seed=1)
    >>> len(views), views.images[0].shape, views.image_points[0].shape
    (2, (480, 640), (54, 2))
    """
    if charuco:
        if tuple(pattern_size) == (9, 6):
            pattern_size = (5, 7)
        if square_size_mm == 25.0 and marker_size_mm is None:
            square_size_mm, marker_size_mm = 40.0, 20.0
        if marker_size_mm is None:
            marker_size_mm = square_size_mm / 2
        if not 0 < marker_size_mm < square_size_mm:
            raise FidlearnError(
                f"marker_size_mm ({marker_size_mm}) must be between 0 and square_size_mm ({square_size_mm})"
            )
        board = _cv.charuco_board(pattern_size, square_size_mm, marker_size_mm, dictionary)
        object_points = np.asarray(board.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
        squares = tuple(int(v) for v in pattern_size)
        centre = np.array([squares[0] * square_size_mm / 2, squares[1] * square_size_mm / 2, 0.0])
        board_w = squares[0] * square_size_mm
    else:
        pattern_size = tuple(int(v) for v in pattern_size)
        if min(pattern_size) < 2:
            raise FidlearnError(f"pattern_size {pattern_size} must count at least 2 x 2 inner corners")
        jj, ii = np.mgrid[0 : pattern_size[1], 0 : pattern_size[0]]
        object_points = np.column_stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)]) * float(square_size_mm)
        centre = np.array([(pattern_size[0] - 1) * square_size_mm / 2, (pattern_size[1] - 1) * square_size_mm / 2, 0.0])
        board_w = (pattern_size[0] + 1) * square_size_mm
    if n_views < 1:
        raise FidlearnError(f"n_views must be at least 1, got {n_views}")

    rng = np.random.default_rng(_check_seed(seed))
    w, h = camera.image_size
    grid = [(gx, gy) for gy in (0.22, 0.5, 0.78) for gx in (0.2, 0.5, 0.8)]
    # the outline that must stay in view: the pattern's corners plus a little of the outer squares
    lo, hi = object_points.min(axis=0), object_points.max(axis=0)
    pad = 0.6 * square_size_mm
    outline = np.array(
        [
            [lo[0] - pad, lo[1] - pad, 0],
            [hi[0] + pad, lo[1] - pad, 0],
            [hi[0] + pad, hi[1] + pad, 0],
            [lo[0] - pad, hi[1] + pad, 0],
        ]
    )
    poses, points, images = [], [], []
    render_kwargs = dict(
        blur_px=blur_px,
        noise_std_gray=noise_std_gray,
        gradient=gradient,
        supersample=supersample,
        wall_texture=wall_texture,
    )
    grays = dict(DEFAULT_GRAYS)
    for view in range(n_views):
        gx, gy = grid[view % len(grid)]
        for attempt in range(200):
            shrink = 1.0 - min(attempt, 100) / 120.0  # pull the target toward the centre if it keeps failing
            jitter = rng.uniform(-0.06, 0.06, size=2) if view >= len(grid) else np.zeros(2)
            tx = (0.5 + (gx - 0.5) * shrink + jitter[0]) * (w - 1)
            ty = (0.5 + (gy - 0.5) * shrink + jitter[1]) * (h - 1)
            fill = rng.uniform(*fill_range)
            distance = camera.fx * board_w / (fill * w)
            tilt = rng.uniform(*tilt_range_deg)
            roll = rng.uniform(-20.0, 20.0)
            T_camera_board = _board_pose(camera, rng, (tx, ty), distance, tilt, roll, centre)
            T_world_camera = frames.invert_transform(T_camera_board)
            if not np.all(camera.points_in_front(outline, T_world_camera, min_depth_mm=50.0)):
                continue
            px = camera.project(outline, T_world_camera)
            if np.all((px >= 8) & (px <= [w - 9, h - 9])):
                break
        else:
            raise FidlearnError(
                f"could not place the board in view {view} of a {w}x{h} camera; try a smaller fill_range"
            )
        poses.append(T_world_camera)
        points.append(camera.project(object_points, T_world_camera))

    # one texture for all views, fine enough for the closest one
    cells = pattern_size[0] if charuco else pattern_size[0] + 1
    tps = int(np.clip(math.ceil(fill_range[1] * w * 1.2 * supersample / cells), 8, 160))
    if charuco:
        sheet = _charuco_sheet(board, squares, square_size_mm, tps, margin_squares, grays)
    else:
        sheet = _checkerboard_sheet(pattern_size, square_size_mm, tps, margin_squares, grays)
    chosen = list(range(n_views)) if views is None else [int(v) for v in views]
    bad = [v for v in chosen if not 0 <= v < n_views]
    if bad:
        raise FidlearnError(f"views {bad} do not exist; there are {n_views} views, 0 to {n_views - 1}")
    for view in chosen:
        images.append(
            _render(
                camera,
                poses[view],
                [sheet],
                seed=int(seed) * 1000 + view,
                gradient_angle_deg=(137.5 * view) % 360.0,
                wall_gray=grays["wall"],
                bgr=False,
                **render_kwargs,
            )
        )
    poses = [poses[v] for v in chosen]
    points = [points[v] for v in chosen]
    return CalibrationViews(
        images=images,
        camera=camera,
        T_world_camera=poses,
        object_points=object_points,
        image_points=points,
        pattern_size=tuple(pattern_size),
        square_size_mm=float(square_size_mm),
        marker_size_mm=float(marker_size_mm or 0.0),
        charuco=bool(charuco),
        dictionary=_cv.dictionary_name(dictionary) if charuco else "",
        seed=int(seed),
        render_kwargs=render_kwargs,
    )


# ----------------------------------------------------------------------------------------------
# A robot's drive through the room.
# ----------------------------------------------------------------------------------------------


@dataclass(eq=False)
class Trajectory:
    """Frames of a camera on a robot driving past the markers, with the truth of every frame.

    Attributes
    ----------
    images : list of ndarray (H, W) uint8
        The frames, in driving order.
    T_world_camera : list of ndarray (4, 4)
        The camera's true pose (mm, world) in each frame.
    truth : list of dict
        Per frame, ``{id: (4, 2) float64}`` true pixel corners of the markers seen whole.
    marker_map : MarkerMap
        The markers' true placements.
    camera : Camera
        The true camera.
    """

    images: list
    T_world_camera: list
    truth: list
    marker_map: MarkerMap
    camera: Camera
    seed: int = 0
    render_kwargs: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.images)

    @property
    def positions_mm(self) -> np.ndarray:
        """Camera positions (N, 3), mm, world."""
        return np.array([T[:3, 3] for T in self.T_world_camera])

    def __repr__(self) -> str:
        w, h = self.camera.image_size
        seen = sum(len(t) for t in self.truth)
        d = np.linalg.norm(np.diff(self.positions_mm, axis=0), axis=1).sum() if len(self) > 1 else 0.0
        return f"Trajectory({len(self)} frames {w}x{h}, {d / 1000:.2f} m driven, {seen} marker sightings, seed={self.seed})"


def trajectory_poses(
    marker_map: MarkerMap,
    n_frames: int = 40,
    seed: int = 0,
    *,
    start_distance_mm: float = 2200.0,
    end_distance_mm: float = 700.0,
    start_lateral_mm: float = -700.0,
    end_lateral_mm: float = 500.0,
    height_mm: float | None = None,
    wobble_deg: float = 3.0,
) -> list[np.ndarray]:
    """True poses ``T_world_camera`` (4, 4), mm, of a camera on a robot driving toward the markers.

    The robot drives a gentle arc on the floor: from ``start_distance_mm`` in
    front of the markers (along their mean facing direction) and
    ``start_lateral_mm`` to the side (the direction to the camera's right when
    it faces the wall) to ``end_distance_mm`` and ``end_lateral_mm``. The
    camera sits at the markers' height (``height_mm``, default their mean
    centre height), keeps pointing at the markers' centre, and sways a little
    (``wobble_deg``, smooth, seeded) with a millimetre of vibration.

    Examples
    --------
    >>> from fidlearn import MarkerMap, data_path
    >>> poses = trajectory_poses(MarkerMap.load(data_path("world_map.json")), n_frames=5)
    >>> len(poses), poses[0].shape
    (5, (4, 4))
    """
    _check_scene(marker_map, None, with_camera=False, where="trajectory_poses")
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or not 1 <= n_frames <= MAX_FRAMES:
        raise FidlearnError(f"n_frames must be a whole number from 1 to {MAX_FRAMES}, got {n_frames!r}")
    for name, value in (
        ("start_distance_mm", start_distance_mm),
        ("end_distance_mm", end_distance_mm),
        ("start_lateral_mm", start_lateral_mm),
        ("end_lateral_mm", end_lateral_mm),
        ("height_mm", 0.0 if height_mm is None else height_mm),
        ("wobble_deg", wobble_deg),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)
            or abs(value) > 1e7
        ):
            raise FidlearnError(f"{name} must be a finite number (mm, or degrees for wobble_deg), got {value!r}")
    rng = np.random.default_rng(_check_seed(seed))
    centres = np.array([marker_map.marker_corners(i).mean(axis=0) for i in marker_map.ids])
    normals = np.array([marker_map.normal(i) for i in marker_map.ids])
    centre = centres.mean(axis=0)
    facing = normals.mean(axis=0)
    facing[2] = 0.0
    if np.linalg.norm(facing) < 1e-6:
        raise FidlearnError(
            f"{marker_map.source}: the markers do not face a common horizontal direction (on the floor or "
            "facing each other), so there is no wall to drive toward; give poses of your own"
        )
    facing /= np.linalg.norm(facing)
    lateral = np.cross(-facing, [0.0, 0.0, 1.0])  # the camera's right when it faces the wall
    z = centre[2] if height_mm is None else float(height_mm)
    phases = rng.uniform(0, 2 * math.pi, size=6)
    tau = np.linspace(0.0, 1.0, n_frames)
    poses = []
    for i, s in enumerate(tau):
        d = start_distance_mm + (end_distance_mm - start_distance_mm) * s
        lat = (
            start_lateral_mm
            + (end_lateral_mm - start_lateral_mm) * s
            + 0.25 * abs(end_lateral_mm - start_lateral_mm) * math.sin(math.pi * s)
        )
        eye = centre + facing * d + lateral * lat
        eye[2] = z + float(rng.normal(0.0, 1.0))
        pan = wobble_deg * math.sin(2 * math.pi * 1.3 * s + phases[0]) + 0.3 * wobble_deg * math.sin(
            2 * math.pi * 3.1 * s + phases[1]
        )
        tilt = 0.5 * wobble_deg * math.sin(2 * math.pi * 0.9 * s + phases[2])
        roll = 0.3 * wobble_deg * math.sin(2 * math.pi * 2.3 * s + phases[3])
        T = look_at(eye, [centre[0], centre[1], z], roll_deg=roll)
        R = T[:3, :3] @ frames.rot_y(math.radians(pan)) @ frames.rot_x(math.radians(tilt))
        poses.append(frames.make_transform(R, eye))
    return poses


def render_trajectory(
    marker_map: MarkerMap,
    camera: Camera,
    n_frames: int = 40,
    seed: int = 0,
    *,
    poses: Sequence[np.ndarray] | None = None,
    frames_to_render: Sequence[int] | None = None,
    blur_px: float = 0.5,
    noise_std_gray: float = 1.5,
    gradient: float = 0.1,
    supersample: int = 4,
    wall_texture: float = 3.0,
    **trajectory_options: Any,
) -> Trajectory:
    """Render a robot's drive past the markers (see :func:`trajectory_poses`), frame by frame.

    Frame ``i`` is ``render_scene(marker_map, camera, poses[i], seed=seed * 1000 + i, ...)``.
    ``poses`` replaces the default drive; other keywords go to :func:`trajectory_poses`.
    ``frames_to_render`` keeps only those frame indices (each identical to the
    same frame of the whole drive).

    Examples
    --------
    >>> from fidlearn import Camera, MarkerMap, data_path
    >>> cam = Camera.from_fov(60, (320, 240))
    >>> drive = render_trajectory(MarkerMap.load(data_path("world_map.json")), cam, n_frames=3)
    >>> len(drive), drive.images[0].shape, sorted(drive.truth[-1])
    (3, (240, 320), [0, 1, 2])
    """
    _check_scene(marker_map, camera, where="render_trajectory")
    if poses is None:
        poses = trajectory_poses(marker_map, n_frames, seed, **trajectory_options)
    elif trajectory_options:
        raise FidlearnError(f"give either poses or trajectory options ({', '.join(trajectory_options)}), not both")
    render_kwargs = dict(
        blur_px=blur_px,
        noise_std_gray=noise_std_gray,
        gradient=gradient,
        supersample=supersample,
        wall_texture=wall_texture,
    )
    chosen = list(range(len(poses))) if frames_to_render is None else [int(i) for i in frames_to_render]
    bad = [i for i in chosen if not 0 <= i < len(poses)]
    if bad:
        raise FidlearnError(f"frames {bad} do not exist; the drive has {len(poses)} frames, 0 to {len(poses) - 1}")
    images, truths = [], []
    for i in chosen:
        image, truth = render_scene(marker_map, camera, poses[i], seed=int(seed) * 1000 + i, **render_kwargs)
        images.append(image)
        truths.append(truth)
    kept = [np.asarray(poses[i], dtype=float) for i in chosen]
    return Trajectory(images, kept, truths, marker_map, camera, seed=int(seed), render_kwargs=render_kwargs)
