"""The pinhole camera with lens distortion: intrinsics K, distortion and image size.

Pixel convention: OpenCV's. The centre of the top-left pixel is at (0, 0), so
the image spans -0.5 .. width-0.5 horizontally. Every corner position that
fidlearn compares uses this convention.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _files, _lens, frames
from ._camera_checks import (
    _ALIASES,
    CAMERA_FIELDS,
    DIST_LENGTHS,
    _as_dist,
    _as_K,
    _as_size,
    _short_source,
)
from ._filestorage import read_filestorage, write_filestorage
from ._io import read_json, write_json_atomic
from .errors import CameraError, FidlearnWarning
from .frames._checks import as_float_array

__all__ = ["Camera", "DIST_LENGTHS"]

#: File names that hold pictures, never a camera (a swapped --camera argument).


@dataclass(eq=False)
class Camera:
    """A calibrated camera: pinhole intrinsics ``K`` (3, 3), distortion ``dist`` and ``image_size``.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    dist : array_like, shape (4,), (5,), (8,), (12,) or (14,), optional
        OpenCV distortion coefficients (k1, k2, p1, p2, k3, ...). ``None`` for none.
    image_size : (int, int)
        ``(width, height)`` in pixels of the images the camera was calibrated at.
    source : str
        What produced this camera (a file, a calibration run), for the record.

    Examples
    --------
    >>> cam = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, (640, 480))
    >>> cam.project([[0, 0, 1000]], np.eye(4)).round(1)
    array([[319.5, 239.5]])
    """

    K: np.ndarray
    dist: np.ndarray | None
    image_size: tuple[int, int]
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.source, os.PathLike):
            self.source = os.fspath(self.source)
        if not isinstance(self.source, str):
            raise CameraError(f"source must be text (what produced the camera), got {type(self.source).__name__}")
        where = self.source or "camera"
        self.K = _as_K(self.K, where)
        self.dist = _as_dist(self.dist, where)
        self.image_size = _as_size(self.image_size, where)

    # -- read-only views -------------------------------------------------------------
    @property
    def fx(self) -> float:
        """Focal length along x, in pixels."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along y, in pixels."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """Principal point x, in pixels (pixel-centre convention)."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """Principal point y, in pixels (pixel-centre convention)."""
        return float(self.K[1, 2])

    @property
    def width(self) -> int:
        """Image width, in pixels."""
        return self.image_size[0]

    @property
    def height(self) -> int:
        """Image height, in pixels."""
        return self.image_size[1]

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view in degrees (pinhole, ignoring distortion)."""
        w, h = self.image_size
        return (math.degrees(2 * math.atan(w / (2 * self.fx))), math.degrees(2 * math.atan(h / (2 * self.fy))))

    @property
    def has_distortion(self) -> bool:
        """Whether any distortion coefficient is non-zero."""
        return bool(np.any(self.dist != 0))

    @classmethod
    def from_fov(cls, hfov_deg: float, image_size: tuple[int, int], dist=None, source: str = "") -> Camera:
        """An ideal camera (square pixels, centred principal point) with a horizontal field of view.

        Parameters
        ----------
        hfov_deg : float
            Horizontal field of view, degrees, strictly between 0 and 180.
        image_size : (int, int)
            ``(width, height)`` in pixels.
        dist : array_like, optional
            OpenCV distortion coefficients; ``None`` for none.
        source : str
            What made the camera, for the record; by default it says the field of view.

        Returns
        -------
        Camera
            ``fx = fy = (width / 2) / tan(hfov / 2)``, ``cx = (width - 1) / 2``, ``cy = (height - 1) / 2``
            (pixel centres at integers).

        Raises
        ------
        CameraError
            If ``hfov_deg`` is not a number between 0 and 180 or ``image_size`` is not two positive whole
            numbers.

        Examples
        --------
        >>> cam = Camera.from_fov(90, (640, 480))
        >>> round(cam.fx, 6), cam.cx, cam.cy
        (320.0, 319.5, 239.5)
        >>> [round(v, 1) for v in cam.fov_deg]
        [90.0, 73.7]
        """
        w, h = _as_size(image_size, source or "camera")
        if isinstance(hfov_deg, (bool, str, bytes)) or not isinstance(hfov_deg, (int, float, np.integer, np.floating)):
            raise CameraError(f"hfov_deg must be a number of degrees between 0 and 180, got {hfov_deg!r}")
        if not 0 < hfov_deg < 180:
            raise CameraError(f"hfov_deg must be between 0 and 180 degrees, got {hfov_deg}")
        f = (w / 2) / math.tan(math.radians(hfov_deg) / 2)
        K = [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]]
        return cls(K, dist, (w, h), source=source or f"ideal camera, {hfov_deg:g} deg horizontal FOV")

    def __repr__(self) -> str:
        w, h = self.image_size
        d = ", ".join(f"{v:.4g}" for v in self.dist)
        # a file's name, not its absolute path: reprs are printed in notebooks and logs
        src = f", source={_short_source(self.source)!r}" if self.source else ""
        return (
            f"Camera({w}x{h}, fx={self.fx:.2f}, fy={self.fy:.2f}, cx={self.cx:.2f}, cy={self.cy:.2f}, dist=[{d}]{src})"
        )

    # -- projection -----------------------------------------------------------------
    def project(self, points_world: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
        """Project world points to pixels for a camera at ``T_world_camera``.

        Agrees with ``cv2.projectPoints`` (distortion included: ``fidlearn._lens``, the model
        :meth:`undistort_points` inverts). Points behind the
        camera are projected too (their pixels are meaningless): use
        :meth:`points_in_front` to tell.

        Parameters
        ----------
        points_world : array_like, shape (N, 3) or (3,)
            Points in the world frame, mm.
        T_world_camera : array_like, shape (4, 4)
            The camera's pose in the world (mm); the camera frame is OpenCV's (x right, y down, z forward).

        Returns
        -------
        ndarray, shape (N, 2) or (2,)
            Pixel coordinates (u, v), pixel centres at integers; (2,) for a single point.

        Raises
        ------
        CameraError
            If ``points_world`` is not (N, 3).
        TransformError
            If ``T_world_camera`` is not a rigid transform.

        Examples
        --------
        >>> cam = Camera.from_fov(90, (640, 480))
        >>> T_world_camera = np.eye(4)   # at the origin, looking along world +Z
        >>> cam.project([[0, 0, 1000], [500, 0, 1000]], T_world_camera).round(1)
        array([[319.5, 239.5],
               [479.5, 239.5]])
        """
        pts = as_float_array(points_world, "points_world", CameraError)
        single = pts.ndim == 1
        pts = np.atleast_2d(pts)
        if pts.ndim == 0 or pts.shape[-1] != 3 or pts.size == 0:
            raise CameraError(f"points_world has shape {np.shape(points_world)}, expected (N, 3) in mm")
        in_camera = frames.transform_points(frames.invert_transform(T_world_camera), pts)
        px = _lens.project_points(in_camera, self.K, self.dist)
        return px[0] if single else px

    def points_in_front(
        self, points_world: np.ndarray, T_world_camera: np.ndarray, min_depth_mm: float = 1.0
    ) -> np.ndarray:
        """Which points are in front of the camera, deeper than ``min_depth_mm``.

        Parameters
        ----------
        points_world : array_like, shape (N, 3)
            Points in the world frame, mm.
        T_world_camera : array_like, shape (4, 4)
            The camera's pose in the world, mm.
        min_depth_mm : float
            Smallest depth (camera z, mm) that counts as in front.

        Returns
        -------
        ndarray of bool, shape (N,)
            True where the point's camera z is above ``min_depth_mm``.
        """
        pts_cam = frames.transform_points(frames.invert_transform(T_world_camera), np.atleast_2d(points_world))
        return pts_cam[:, 2] > min_depth_mm

    def undistort_points(self, points_px: np.ndarray, exact: bool = True) -> np.ndarray:
        """Remove lens distortion from pixel points: the inverse of the lens model in :meth:`project`.

        Parameters
        ----------
        points_px : array_like, shape (N, 2)
            Observed (distorted) pixel coordinates.
        exact : bool
            True: Newton steps to 1e-9 px. False: ``cv2.undistortPoints`` (faster; 0.5 px off at wide corners).

        Returns
        -------
        ndarray, shape (N, 2)
            The ideal pinhole pixels (the ideal normalized points through ``K``).

        Raises
        ------
        CameraError
            If the points are not (N, 2) or hold NaN or infinity.
        """
        pts = as_float_array(points_px, "points_px", CameraError)
        if pts.size == 0:
            return np.zeros((0, 2))
        if pts.ndim == 0 or pts.shape[-1] != 2:
            raise CameraError(f"points_px has shape {pts.shape}, expected (N, 2) pixels")
        if not np.all(np.isfinite(pts)):
            raise CameraError("points_px contains NaN or infinity")
        return _lens.undistort_pixels(pts.reshape(-1, 2), self.K, self.dist, exact)

    # -- resolution ------------------------------------------------------------------
    def scaled(self, image_size: tuple[int, int], tol: float = 0.01) -> Camera:
        """The same camera at another resolution with the same aspect ratio.

        A sensor read out at a lower resolution (binning, resizing) keeps its
        geometry, so K scales; pixel centres move with the pixel-centre
        convention (``c' = (c + 0.5) * s - 0.5``). Another aspect ratio means
        the sensor was cropped differently, which no scaling can undo.

        Parameters
        ----------
        image_size : (int, int)
            The new ``(width, height)`` in pixels.
        tol : float
            Largest relative difference of the two scale factors still taken as the same aspect ratio.

        Returns
        -------
        Camera
            ``self`` when the size is unchanged, else a new camera (same distortion).

        Raises
        ------
        CameraError
            If the aspect ratio differs (width and height swapped is said so): calibrate at the resolution
            you run at.
        """
        new_w, new_h = _as_size(image_size, "image_size")
        if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)) or not 0 <= tol <= 1:
            raise CameraError(f"tol must be a fraction from 0 to 1 (0.01: 1 %), got {tol!r:.40}")
        w, h = self.image_size
        if (new_w, new_h) == (w, h):
            return self
        sx, sy = new_w / w, new_h / h
        if abs(sx / sy - 1.0) > tol:
            if (new_w, new_h) == (h, w):  # numpy's image.shape[:2] is (height, width)
                raise CameraError(
                    f"camera made for {w}x{h} (width x height) used on {new_w}x{new_h} images: width and height "
                    "are swapped. If the camera's image_size came from image.shape[:2], that is (height, width): "
                    "give (image.shape[1], image.shape[0]). If the pictures are turned to portrait, K does not "
                    "apply to them: rotate them back, or calibrate at the resolution you run at"
                )
            raise CameraError(
                f"camera calibrated at {w}x{h} (aspect {w / h:.3f}) cannot be used on {new_w}x{new_h} "
                f"images (aspect {new_w / new_h:.3f}): another aspect ratio crops the sensor differently, "
                "so K does not scale; calibrate at the resolution you run at"
            )
        K = self.K.copy()
        K[0, 0] *= sx
        K[0, 1] *= sx
        K[1, 1] *= sy
        K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        src = f"{self.source or 'camera'} scaled from {w}x{h} to {new_w}x{new_h}"
        return Camera(K, self.dist.copy(), (new_w, new_h), source=src)

    def for_image(self, image_or_size, warn: bool = True) -> Camera:
        """The camera fitted to an image, rescaled (with a warning) when the image has another size.

        Parameters
        ----------
        image_or_size : ndarray or (int, int)
            An image (H, W) or (H, W, 3), or its ``(width, height)`` in pixels.
        warn : bool
            Emit a :class:`FidlearnWarning` when the camera had to be rescaled.

        Returns
        -------
        Camera
            ``self`` or :meth:`scaled` to the image's size.

        Raises
        ------
        CameraError
            If the image's aspect ratio differs (see :meth:`scaled`).
        """
        if isinstance(image_or_size, np.ndarray):
            size = (image_or_size.shape[1], image_or_size.shape[0])
        else:
            size = tuple(image_or_size)
        if tuple(size) == self.image_size:
            return self
        cam = self.scaled(size)
        if warn:
            warnings.warn(
                f"camera calibrated at {self.width}x{self.height} rescaled to {size[0]}x{size[1]}; "
                "calibrating at the resolution you run at is more accurate",
                FidlearnWarning,
                stacklevel=3,
            )
        return cam

    # -- files -------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """fidlearn's JSON layout of the camera.

        Returns
        -------
        dict
            ``camera_matrix`` (3x3 list), ``dist_coeffs`` (list), ``image_size`` [width, height] and ``source``.
        """
        return {
            "camera_matrix": self.K.tolist(),
            "dist_coeffs": self.dist.tolist(),
            "image_size": list(self.image_size),
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, d: dict, source: str = "camera") -> Camera:
        """A camera from fidlearn's JSON layout (as :meth:`to_dict` writes it).

        Parameters
        ----------
        d : dict
            ``camera_matrix`` (3x3, pixels), ``dist_coeffs`` (optional), ``image_size`` [width, height] and
            ``source`` (optional); no other field.
        source : str
            Where ``d`` came from, named in error messages.

        Returns
        -------
        Camera

        Raises
        ------
        CameraError
            If ``d`` is a world map, has an unknown field (with a guess at the meant one), misses a field or
            holds a malformed value.
        """
        if not isinstance(d, dict):
            raise CameraError(f"{source}: expected a JSON object with camera_matrix, dist_coeffs, image_size")
        if "camera_matrix" not in d and (
            "markers" in d or "units" in d or any(isinstance(v, dict) and "translation" in v for v in d.values())
        ):
            raise CameraError(
                f"{source}: missing field camera_matrix: this is a world map (marker placements), not a camera "
                "file; give the camera file "
                "(camera_matrix, dist_coeffs, image_size, as 'fidlearn calibrate' writes it) as the camera "
                "(command line: --camera) and the map as the map (--map)"
            )
        unknown = [k for k in d if k not in CAMERA_FIELDS]
        if unknown:
            hint = _files.did_you_mean(unknown[0], CAMERA_FIELDS, _ALIASES)
            raise CameraError(
                f"{source}: unknown field {unknown[0]!r}{hint}; a camera file holds {', '.join(CAMERA_FIELDS)}"
            )
        missing = [k for k in ("camera_matrix", "image_size") if k not in d]
        if missing:
            raise CameraError(
                f"{source}: missing field {', '.join(missing)}; a camera file needs camera_matrix (3x3), "
                "dist_coeffs and image_size [width, height]"
            )
        return cls(d["camera_matrix"], d.get("dist_coeffs"), d["image_size"], source=str(d.get("source") or source))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the camera to a file, atomically.

        Parameters
        ----------
        path : path-like
            ``.yml``, ``.yaml`` or ``.xml`` for OpenCV FileStorage (``camera_matrix``,
            ``distortion_coefficients``, ``image_width``, ``image_height``), anything else for fidlearn's JSON.

        Returns
        -------
        Path
            The file written.
        """
        path = Path(path)
        if path.suffix.lower() in (".yml", ".yaml", ".xml"):
            return write_filestorage(path, self.K, self.dist, self.image_size)
        return write_json_atomic(path, self.to_dict())

    @classmethod
    def load(cls, path: str | os.PathLike, image_size: tuple[int, int] | None = None) -> Camera:
        """Read a camera file: fidlearn's JSON or OpenCV FileStorage YAML/XML.

        FileStorage files need ``camera_matrix`` and ``distortion_coefficients``;
        ``image_width``/``image_height`` are read when present. A file without
        them (OpenCV's tutorial files) needs ``image_size`` from the caller: the
        resolution the camera was calibrated at.

        Parameters
        ----------
        path : path-like
            The camera file.
        image_size : (int, int), optional
            ``(width, height)`` in pixels; must agree with the file when it says its own.

        Returns
        -------
        Camera
            Its ``source`` is the file's path.

        Raises
        ------
        CameraError
            If the file is missing, unreadable, an image or a map, malformed, or disagrees with ``image_size``.
        """
        path = _files.as_path(path, CameraError, "camera")
        if path.suffix.lower() in (".yml", ".yaml", ".xml"):
            return cls._load_filestorage(path, image_size)
        if path.suffix.lower() in _files.IMAGE_SUFFIXES + _files.VIDEO_SUFFIXES:
            raise CameraError(
                f"{path}: this is an image, not a camera file; give the camera.json that 'fidlearn calibrate' "
                "wrote (or OpenCV's calibration YAML) as the camera, and the image as an image"
            )
        d = read_json(path, CameraError, "camera")
        cam = cls.from_dict(d, source=str(path))
        if image_size is not None and tuple(image_size) != cam.image_size:
            raise CameraError(
                f"{path}: the file says image_size {list(cam.image_size)}, the caller says {list(image_size)}; "
                "use Camera.scaled() to change resolution"
            )
        return cam

    @classmethod
    def _load_filestorage(cls, path: Path, image_size) -> Camera:
        path, K, dist, size = read_filestorage(path, image_size)
        return cls(K, dist, size, source=str(path))
