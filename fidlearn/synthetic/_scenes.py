"""Scenes of printed markers taped to walls, seen by a known camera, with the true corners."""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _cv, frames
from .._io import write_text_atomic
from ..camera import Camera
from ..errors import FidlearnError
from ..markermap import MarkerMap
from ._calibration_views import _charuco_sheet
from ._checks import DEFAULT_GRAYS, _check_scene
from ._renderer import _marker_sheet, _projected_size_px, _render, _texels_per_cell


def visible_markers(
    marker_map: MarkerMap, camera: Camera, T_world_camera: np.ndarray, margin_px: float = 2.0
) -> dict[int, np.ndarray]:
    """True pixel corners of the markers a camera sees whole.

    A marker counts as visible when its four corners are in front of the
    camera, inside the image with ``margin_px`` to spare (pixel-centre
    convention: the image spans -0.5 .. width - 0.5) and its printed face
    points toward the camera. Corners are ``camera.project`` of the marker's
    3D corners (TL, TR, BR, BL), i.e. ``cv2.projectPoints``. Occlusion by
    another sheet is not considered: a marker hidden behind a nearer one is
    drawn hidden but still listed.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers' placements (mm, world). The map comes first, then the camera.
    camera : Camera
        Intrinsics, distortion and image size.
    T_world_camera : array_like, shape (4, 4)
        The camera's pose in the world, mm.
    margin_px : float
        How far inside the image every corner must be, pixels.

    Returns
    -------
    dict of int to ndarray, shape (4, 2)
        ``{id: corners_px}``, float64, TL, TR, BR, BL, pixel centres at integers.

    Raises
    ------
    FidlearnError
        If the map or the camera is not one (a swapped call says so).
    TransformError
        If ``T_world_camera`` is not a rigid transform.

    Examples
    --------
    >>> from fidlearn import Camera, MarkerMap, data_path, look_at
    >>> wall = MarkerMap.load(data_path("world_map.json"))
    >>> seen = visible_markers(wall, Camera.from_fov(60, (640, 480)), look_at([1200, 200, 250], [0, 200, 250]))
    >>> sorted(seen), seen[0].shape
    ([0, 1, 2], (4, 2))
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
        far = np.any(ideal < [lo_u - slack, lo_v - slack]) or np.any(ideal > [hi_u + slack, hi_v + slack])
        if far and camera.model == "pinhole":  # the fisheye's angle-based model does not fold back there
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
    wall_texture_std_gray: float = 3.0,
    paper_gray: float = DEFAULT_GRAYS["paper"],
    ink_gray: float = DEFAULT_GRAYS["ink"],
    margin_cells: float = 1.0,
    margin_px: float = 2.0,
    bgr: bool = False,
) -> Scene:
    """Render what a camera sees of printed markers taped to walls, with the true corners.

    Parameters
    ----------
    marker_map : MarkerMap
        The markers' placements (mm, world), size and dictionary. The map comes first, then the camera.
    camera : Camera
        Intrinsics, distortion and image size of the picture.
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
    wall_gray, wall_texture_std_gray, paper_gray, ink_gray : float
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
    Scene
        The picture (``.image``), the true corners of every marker seen whole (``.truth``) and
        what it was rendered from; :meth:`Scene.save_truth` writes them down.

    Raises
    ------
    FidlearnError
        If the map or the camera is not one (a swapped call says the map comes first), or an option
        is out of range (``supersample`` 1 to 16, ``blur_px``, ``noise_std_gray`` and
        ``wall_texture_std_gray`` finite and >= 0, ``margin_cells`` >= 0).
    CameraError
        If the camera has a tilted sensor (more than 12 distortion coefficients in use).
    TransformError
        If ``T_world_camera`` is not a rigid transform.

    Examples
    --------
    >>> from fidlearn import Camera, MarkerMap, data_path, look_at
    >>> cam = Camera.from_fov(60, (640, 480))
    >>> wall = MarkerMap.load(data_path("world_map.json"))
    >>> scene = render_scene(wall, cam, look_at([1200, 200, 250], [0, 200, 250]))
    >>> scene.image.shape, scene.image.dtype, sorted(scene.truth)
    ((480, 640), dtype('uint8'), [0, 1, 2])
    >>> np.allclose(scene.truth[0], cam.project(wall.marker_corners(0), scene.T_world_camera))
    True
    """
    _check_scene(marker_map, camera, where="render_scene")
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 16:
        raise FidlearnError(f"supersample must be a whole number from 1 to 16, got {supersample!r}")
    T_world_camera = frames.check_transform(T_world_camera, name="T_world_camera")
    _check_looks(gradient, gradient_angle_deg, wall_gray, paper_gray, ink_gray, margin_cells, margin_px)
    grays = {"wall": float(wall_gray), "paper": float(paper_gray), "ink": float(ink_gray)}
    T_camera_world = frames.invert_transform(T_world_camera)
    sheets, on_boards = _charuco_sheets(marker_map, camera, T_camera_world, int(supersample), grays)
    for mid in marker_map.ids:
        if mid in on_boards:  # printed on its board's sheet, chess squares and all
            continue
        cells = _cv.dictionary_marker_bits(marker_map.marker_dictionary(mid)) + 2
        size = _projected_size_px(marker_map.marker_corners(mid), camera, T_camera_world)
        tpc = _texels_per_cell(size, cells, int(supersample))
        sheets.append(_marker_sheet(marker_map, mid, tpc, _margin(marker_map, mid, cells, margin_cells), grays))
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
        wall_texture_std_gray=wall_texture_std_gray,
        bgr=bgr,
    )
    truth = visible_markers(marker_map, camera, T_world_camera, margin_px=margin_px)
    return Scene(image, truth, T_world_camera, camera, marker_map, seed, noise_std_gray, blur_px)


def _check_looks(gradient, gradient_angle_deg, wall_gray, paper_gray, ink_gray, margin_cells, margin_px) -> None:
    """FidlearnError naming the option of :func:`render_scene`'s picture that is not a number in its range."""
    for name, value, lo, hi in (
        ("gradient", gradient, 0.0, 2.0),
        ("gradient_angle_deg", gradient_angle_deg, -3600.0, 3600.0),
        ("wall_gray", wall_gray, 0.0, 255.0),
        ("paper_gray", paper_gray, 0.0, 255.0),
        ("ink_gray", ink_gray, 0.0, 255.0),
        ("margin_cells", margin_cells, 0.0, 10.0),
        ("margin_px", margin_px, 0.0, 1e4),
    ):
        ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not (ok and math.isfinite(value) and lo <= value <= hi):
            raise FidlearnError(f"{name} must be a number from {lo:g} to {hi:g}, got {value!r:.40}")


def _charuco_sheets(marker_map: MarkerMap, camera: Camera, T_camera_world: np.ndarray, supersample: int, grays: dict):
    """One sheet for each ChArUco board entry of the map (OpenCV's own picture of the board, its chess squares
    with its markers, and a white margin of half a square), and the keys of the markers it prints."""
    from ..markermap_entries import BoardEntry  # noqa: PLC0415

    sheets: list = []
    keys: set[int] = set()
    for name, e in marker_map.entries.items():
        if not (isinstance(e, BoardEntry) and e.kind == "charuco" and e.square_size_mm):
            continue
        square = float(e.square_size_mm)
        cells = _cv.dictionary_marker_bits(e.dictionary) + 2
        first = next(key for key, owner in marker_map.owner.items() if owner == name)
        size = _projected_size_px(marker_map.marker_corners(first), camera, T_camera_world)
        tps = _texels_per_square(_texels_per_cell(size, cells, supersample), cells, e.marker_size_mm / square)
        sheet = _charuco_sheet(e.cv_board(), e.counts, square, tps, 0.5, grays)
        along_s, along_t, origin = e.to_world(sheet.A_world.T)  # texel (s, t, 1) -> board (x, y, 0) -> world
        sheet.A_world = np.column_stack([along_s - e.translation_mm, along_t - e.translation_mm, origin])
        sheet.label = f"board {name}"
        sheets.append(sheet)
        keys.update(key for key, owner in marker_map.owner.items() if owner == name)
    return sheets, keys


def _margin(marker_map: MarkerMap, key: int, cells: int, margin_cells: float) -> float:
    """The white margin (cells) drawn round a marker: a grid board's markers share one sheet, so at most half the
    gap to their neighbours (a whole cell's margin covered the next marker's border)."""
    from ..markermap_entries import BoardEntry  # noqa: PLC0415

    entry = marker_map.entries.get(marker_map.owner.get(key, ""))
    if not (isinstance(entry, BoardEntry) and entry.kind == "grid" and entry.separation_mm is not None):
        return margin_cells
    return min(margin_cells, 0.5 * float(entry.separation_mm) / (entry.marker_size_mm / cells))


def _texels_per_square(texels_per_cell: int, cells: int, ratio: float) -> int:
    """Texels per square of a ChArUco board's picture, at least those of ``texels_per_cell``, such that OpenCV
    draws each marker (``ratio`` of a square, ``cells`` cells) with whole texels per cell, centred on a texel edge:
    the one that comes closest, up to four times finer (OpenCV rounds a marker's side and place to whole texels)."""
    base = max(int(math.ceil(texels_per_cell * cells / ratio)), 8)
    best, err = base, math.inf
    for t in range(base, 4 * base + 1):
        j = max(round(ratio * t / cells), 1)
        e = (abs(ratio * t - j * cells) + 0.5 * ((t - j * cells) % 2)) / t  # texels off, per texel of a square
        if e < err - 1e-12:
            best, err = t, e
    return best


@dataclass(eq=False)
class Scene:
    """A rendered picture with its truth: what :func:`render_scene` returns.

    Attributes
    ----------
    image : ndarray, shape (H, W) or (H, W, 3), uint8
        The picture, at ``camera.image_size``.
    truth : dict of int to ndarray, shape (4, 2)
        The true pixel corners (TL, TR, BR, BL, pixel centres at integers) of every marker seen
        whole, facing the camera (see :func:`visible_markers`). Markers partly outside the image or
        behind the camera are drawn as far as they are seen but left out.
    T_world_camera : ndarray, shape (4, 4)
        The camera's pose in the world (mm).
    camera : Camera
        The camera of the picture.
    marker_map : MarkerMap
        The markers rendered.
    seed : int
        The seed of the wall texture and the noise.
    noise_std_gray : float
        The sensor noise (gray levels).
    blur_px : float
        The defocus blur (px).
    """

    image: np.ndarray
    truth: dict[int, np.ndarray]
    T_world_camera: np.ndarray
    camera: Camera
    marker_map: MarkerMap
    seed: int = 0
    noise_std_gray: float = 0.0
    blur_px: float = 0.0

    def truth_record(self, image_name: str, map_name: str | None = None) -> dict:
        """The truth file's content: the camera, the pose (mm, deg) and each marker's corners (px).

        Parameters
        ----------
        image_name : str
            The picture's file name, written as ``image``.
        map_name : str, optional
            The map file, written as ``map``; the map's own ``source`` when None.

        Returns
        -------
        dict
            ``image``, ``camera`` (:meth:`Camera.to_dict`), ``map``, ``dictionary``, ``marker_size_mm``,
            ``T_world_camera`` (4x4, mm), ``position_mm``, ``rpy_deg``, ``markers_px`` (id to 4x2,
            by id), ``pixel_convention``, ``seed``, ``noise_std_gray``, ``blur_px``.
        """
        T = np.asarray(self.T_world_camera)
        return {
            "image": str(image_name),
            "camera": self.camera.to_dict(),
            "map": self.marker_map.source if map_name is None else str(map_name),
            "dictionary": self.marker_map.dictionary,
            "marker_size_mm": self.marker_map.marker_size_mm,
            "T_world_camera": T.tolist(),
            "position_mm": T[:3, 3].tolist(),
            "rpy_deg": frames.rpy_deg_from_rotation(T[:3, :3]).tolist(),
            "markers_px": {str(k): v.tolist() for k, v in sorted(self.truth.items())},
            "pixel_convention": "pixel centres at integer coordinates; corners TL, TR, BR, BL",
            "seed": self.seed,
            "noise_std_gray": self.noise_std_gray,
            "blur_px": self.blur_px,
        }

    def save_truth(self, path: str | os.PathLike, image_name: str, map_name: str | None = None) -> Path:
        """Write the truth file (:meth:`truth_record` as indented JSON, one matrix row a line), atomically.

        Parameters
        ----------
        path : str or os.PathLike
            The JSON file to write.
        image_name : str
            The picture's file name, written as ``image``.
        map_name : str, optional
            The map file, written as ``map``; the map's own ``source`` when None.

        Returns
        -------
        Path
            The file written (with the other outputs of an active :class:`fidlearn.io.StagedOutputs`).

        Examples
        --------
        >>> import json, tempfile, pathlib
        >>> from fidlearn import Camera, MarkerMap, data_path, look_at
        >>> wall = MarkerMap.load(data_path("world_map.json"))
        >>> scene = render_scene(wall, Camera.from_fov(60, (320, 240)), look_at([1200, 200, 250], [0, 200, 250]))
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     truth = json.loads(scene.save_truth(pathlib.Path(folder) / "truth.json", "scene.png").read_text())
        >>> sorted(truth["markers_px"]), truth["position_mm"]
        (['0', '1', '2'], [1200.0, 200.0, 250.0])
        """
        return write_text_atomic(path, _json_text(self.truth_record(image_name, map_name)))


def _json_text(obj) -> str:
    """Indented JSON with each innermost list of numbers on one line (readable matrices)."""
    text = json.dumps(obj, indent=2)
    return (
        re.sub(
            r"\[\s+([-+0-9.eE,\s]+?)\s+\]",
            lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]",
            text,
        )
        + "\n"
    )
