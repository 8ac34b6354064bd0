"""The camera: intrinsics K, lens distortion (OpenCV's pinhole model or ``cv2.fisheye``'s) and image size.

Pixel convention: OpenCV's. The centre of the top-left pixel is at (0, 0), so
the image spans -0.5 .. width-0.5 horizontally. Every corner position that
fidlearn compares uses this convention.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from . import _camera_checks, _camera_io, _lens, frames
from ._camera_checks import (
    DIST_LENGTHS,
    MODELS,
    _as_alpha,
    _as_dist,
    _as_intrinsics_cov,
    _as_K,
    _as_model,
    _as_pixels,
    _as_size,
    _check_aspect,
    _check_hfov,
    _check_picture,
    _scaled,
    _short_source,
)
from .errors import CameraError, FidlearnWarning
from .frames._checks import as_float_array

__all__ = ["Camera", "DIST_LENGTHS", "MODELS"]


@dataclass(eq=False, init=False)
class Camera:
    """A calibrated camera: intrinsics ``K`` (3, 3), lens distortion ``dist``, ``image_size`` and lens ``model``.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    dist : array_like, optional
        The distortion coefficients; ``None`` for none. Pinhole: OpenCV's 4, 5, 8, 12 or 14
        (k1, k2, p1, p2, k3, k4, k5, k6, s1..s4, tau_x, tau_y: rational and thin-prism terms, tilted
        sensor). Fisheye: ``cv2.fisheye``'s 4 (k1..k4).
    image_size : (int, int)
        ``(width, height)`` in pixels of the images the camera was calibrated at.
    source : str
        What produced this camera (a file, a calibration run), for the record.
    model : {"pinhole", "fisheye"}
        The lens model (keyword only): ``"pinhole"``, OpenCV's ``projectPoints``, or ``"fisheye"``,
        OpenCV's Kannala-Brandt model (``cv2.fisheye.projectPoints``) for lenses of 120 degrees and more.
    intrinsics_covariance : array_like, shape (4 + len(dist), 4 + len(dist)), optional
        The covariance of ``fx, fy, cx, cy, *dist`` (keyword only; ``calibration.camera_with_uncertainty``): a
        pinhole camera adds its effect to each pose's covariance. None: the intrinsics taken as exact.

    Examples
    --------
    >>> cam = Camera([[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], None, (640, 480))
    >>> cam.project([[0, 0, 1000]], np.eye(4)).round(1)
    array([[319.5, 239.5]])
    """

    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    source: str
    model: str
    intrinsics_covariance: np.ndarray | None

    def __init__(
        self,
        K: Any,
        dist: Any,
        image_size: Any,
        source: str | os.PathLike = "",
        *,
        model: str = "pinhole",
        intrinsics_covariance: Any = None,
    ) -> None:
        if isinstance(source, os.PathLike):
            source = os.fspath(source)
        if not isinstance(source, str):
            raise CameraError(f"source must be text (what produced the camera), got {type(source).__name__}")
        self.source = source
        where = source or "camera"
        self.model = _as_model(model, where)
        self.K = _as_K(K, where)
        self.dist = _as_dist(dist, where, self.model)
        self.image_size = _camera_checks.principal_point_inside(self.K, _as_size(image_size, where), where)
        self.intrinsics_covariance = _as_intrinsics_cov(intrinsics_covariance, 4 + len(self.dist), where)

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
        """Horizontal and vertical field of view in degrees (pinhole: ignoring distortion; fisheye: through it)."""
        w, h = self.image_size
        if self.model == "fisheye":
            return _lens.fisheye_fov_deg(self.K, self.dist, self.image_size)
        return (math.degrees(2 * math.atan(w / (2 * self.fx))), math.degrees(2 * math.atan(h / (2 * self.fy))))

    @property
    def has_distortion(self) -> bool:
        """Whether any distortion coefficient is non-zero."""
        return bool(np.any(self.dist != 0))

    @classmethod
    def from_fov(cls, hfov_deg: float, image_size: tuple[int, int], dist: Any = None, source: str = "") -> Camera:
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
        _check_hfov(hfov_deg)
        f = (w / 2) / math.tan(math.radians(hfov_deg) / 2)
        K = [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]]
        return cls(K, dist, (w, h), source=source or f"ideal camera, {hfov_deg:g} deg horizontal FOV")

    def __repr__(self) -> str:
        w, h = self.image_size
        d = ", ".join(f"{v:.4g}" for v in self.dist)
        # a file's name, not its absolute path: reprs are printed in notebooks and logs
        src = f", source={_short_source(self.source)!r}" if self.source else ""
        lens = ", model='fisheye'" if self.model == "fisheye" else ""
        return (
            f"Camera({w}x{h}, fx={self.fx:.2f}, fy={self.fy:.2f}, cx={self.cx:.2f}, cy={self.cy:.2f}, "
            f"dist=[{d}]{lens}{src})"
        )

    # -- projection -----------------------------------------------------------------
    def project(self, points_world: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
        """Project world points to pixels for a camera at ``T_world_camera``.

        Agrees with ``cv2.projectPoints`` (or ``cv2.fisheye.projectPoints`` for a fisheye; distortion
        included: ``fidlearn._lens``, the model :meth:`undistort_points` inverts). Points behind the
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
        px = _lens.project_points(in_camera, self.K, self.dist, self.model)
        return px[0] if single else px

    def points_in_front(self, points_world: np.ndarray, T_world_camera: np.ndarray, min_depth_mm: float = 1.0):
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
            True: Newton steps to 1e-9 px. False: ``cv2.undistortPoints`` (``cv2.fisheye.undistortPoints``;
            faster, 0.5 px off at wide corners).

        Returns
        -------
        ndarray, shape (N, 2)
            The ideal pinhole pixels (the ideal normalized points through ``K``). A fisheye pixel whose ray
            is 90 degrees or more off the axis (or beyond the lens's fold) has no pinhole pixel: NaN.

        Raises
        ------
        CameraError
            If the points are not (N, 2) or hold NaN or infinity.
        """
        pts = _as_pixels(points_px)
        if pts.size == 0:
            return pts
        return _lens.undistort_pixels(pts, self.K, self.dist, exact, self.model)

    # -- undistorted pictures -----------------------------------------------------------
    def undistorted(self, alpha: float = 0.0, image_size: tuple[int, int] | None = None) -> Camera:
        """The ideal camera (no distortion) of the undistorted picture that :meth:`undistort_image` makes.

        Parameters
        ----------
        alpha : float
            From 0 to 1: 0 keeps only pixels with picture behind them (cropped), 1 keeps every pixel of
            the picture (black borders). ``cv2.getOptimalNewCameraMatrix``'s ``alpha`` for a pinhole camera,
            ``cv2.fisheye.estimateNewCameraMatrixForUndistortRectify``'s ``balance`` for a fisheye (its edges
            seen over 80 degrees off the axis are kept up to 80: a pinhole picture cannot hold 90).
        image_size : (int, int), optional
            ``(width, height)`` of the undistorted picture; the camera's own by default.

        Returns
        -------
        Camera
            A pinhole camera without distortion; a CameraError if ``alpha`` is not a number from 0 to 1 or
            ``image_size`` not two positive whole numbers.
        """
        alpha = _as_alpha(alpha)
        size = self.image_size if image_size is None else _as_size(image_size, "image_size")
        new_K = _lens.new_camera_matrix(self.K, self.dist, self.model, self.image_size, alpha, size)
        new_K[0, 1] = 0.0  # no skew: OpenCV's estimate leaves rounding there
        src = f"{self.source or 'camera'} undistorted (alpha {alpha:g})"
        return Camera(new_K, None, size, source=src)

    def undistort_maps(self, alpha: float = 0.0, image_size: tuple[int, int] | None = None) -> tuple[np.ndarray, ...]:
        """The maps for ``cv2.remap`` that undistort a picture onto :meth:`undistorted`'s camera.

        Parameters
        ----------
        alpha, image_size :
            As for :meth:`undistorted`.

        Returns
        -------
        map_x, map_y : ndarray, shape (height, width), float32
            Where each undistorted pixel lies in the camera's picture (pixels), from the same lens model
            as :meth:`project`: ``cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR)``.
        """
        ideal = self.undistorted(alpha, image_size)
        return _lens.undistort_maps(self.K, self.dist, self.model, ideal.K, ideal.image_size)

    def undistort_image(
        self, image: np.ndarray, alpha: float = 0.0, image_size: tuple[int, int] | None = None
    ) -> np.ndarray:
        """The picture without lens distortion, as :meth:`undistorted`'s camera would have taken it.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
            A picture at the camera's ``image_size``.
        alpha, image_size :
            As for :meth:`undistorted`.

        Returns
        -------
        ndarray
            The undistorted picture (bilinear interpolation, black where no pixel of ``image`` lies); a
            CameraError if ``image`` is not a picture of the camera's size, or as for :meth:`undistorted`.
        """
        _check_picture(image, self.image_size)
        map_x, map_y = self.undistort_maps(alpha, image_size)
        return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)

    # -- resolution ------------------------------------------------------------------
    def scaled(self, image_size: tuple[int, int], tol: float = 0.01) -> Camera:
        """The same camera at another resolution with the same aspect ratio.

        A sensor read out at a lower resolution (binning, resizing) keeps its geometry, so K scales (and its
        covariance); pixel centres move with the pixel-centre convention (``c' = (c + 0.5) * s - 0.5``). Another
        aspect ratio means the sensor was cropped differently, which no scaling can undo.

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
        _check_aspect((w, h), (new_w, new_h), tol)
        K, cov = _scaled(self.K, self.intrinsics_covariance, sx, sy)
        src = f"{self.source or 'camera'} scaled from {w}x{h} to {new_w}x{new_h}"
        return Camera(K, self.dist.copy(), (new_w, new_h), src, model=self.model, intrinsics_covariance=cov)

    def for_image(self, image_or_size: Any, warn: bool = True) -> Camera:
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
            If the image's aspect ratio differs (:meth:`scaled`).
        """
        size = _camera_checks.size_of(image_or_size)
        if size == self.image_size:
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
            ``camera_matrix`` (3x3 list), ``dist_coeffs`` (list), ``image_size`` [width, height], ``source``,
            and ``model`` for a fisheye (a file without it is a pinhole camera).
        """
        return _camera_io.camera_to_dict(self)

    @classmethod
    def from_dict(cls, d: dict, source: str = "camera") -> Camera:
        """A camera from fidlearn's JSON layout (as :meth:`to_dict` writes it).

        Parameters
        ----------
        d : dict
            ``camera_matrix`` (3x3, pixels), ``dist_coeffs`` (optional), ``image_size`` [width, height],
            ``source`` (optional) and ``model`` (optional, ``"pinhole"`` by default); no other field.
        source : str
            Where ``d`` came from, named in error messages.

        Returns
        -------
        Camera
            Or CameraError if ``d`` is a world map, has an unknown field (with a guess at the meant one),
            misses a field or holds a malformed value.
        """
        cam: Camera = _camera_io.camera_from_dict(cls, d, source)
        return cam

    def save(self, path: str | os.PathLike) -> Path:
        """Write the camera to a file, atomically.

        Parameters
        ----------
        path : path-like
            ``.yml``, ``.yaml`` or ``.xml`` for OpenCV FileStorage (``camera_matrix``,
            ``distortion_coefficients``, ``image_width``, ``image_height``, and ``fisheye_model: 1`` for a
            fisheye, as OpenCV's calibration sample writes it), anything else for fidlearn's JSON.

        Returns
        -------
        Path
            The file written.
        """
        return _camera_io.save_camera(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike, image_size: tuple[int, int] | None = None) -> Camera:
        """Read a camera file: fidlearn's JSON or OpenCV FileStorage YAML/XML.

        FileStorage files need ``camera_matrix`` and ``distortion_coefficients``;
        ``image_width``/``image_height`` are read when present, and ``fisheye_model: 1`` makes a
        fisheye camera. A file without the size (OpenCV's tutorial files) needs ``image_size`` from the
        caller: the resolution the camera was calibrated at.

        Parameters
        ----------
        path : path-like
            The camera file.
        image_size : (int, int), optional
            ``(width, height)`` in pixels; must agree with the file when it says its own.

        Returns
        -------
        Camera
            Its ``source`` is the file's path; a CameraError if the file is missing, unreadable, an image or
            a map, malformed, or disagrees with ``image_size``.
        """
        cam: Camera = _camera_io.load_camera(cls, path, image_size)
        return cam
