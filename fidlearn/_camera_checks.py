"""The checks a camera's numbers pass (K, distortion, image size), each error with its fix."""

from __future__ import annotations

import numbers
from pathlib import Path
from typing import Any

import numpy as np

from .errors import CameraError

#: Distortion vector lengths OpenCV understands: (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]).
DIST_LENGTHS = (4, 5, 8, 12, 14)


def _short_source(source: str) -> str:
    path = Path(source)
    return path.name if path.is_absolute() else source


def _fmt_matrix(M: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{v:.6g}" for v in row) + "]" for row in M) + "]"


#: The fields of fidlearn's camera JSON; any other is refused (a misspelt distortion field was
#: silently ignored, leaving a camera without distortion).
CAMERA_FIELDS = ("camera_matrix", "dist_coeffs", "image_size", "source", "model", "intrinsics_covariance")
#: Names other tools use for them, so the error can say which one was meant.
#: The smallest focal length (px) a camera file may hold.
MIN_FOCAL_PX = 1.0

_ALIASES = {
    "distortion": "dist_coeffs",
    "dist": "dist_coeffs",
    "dist_coefs": "dist_coeffs",
    "distcoeffs": "dist_coeffs",
    "distortion_coefficients": "dist_coeffs",
    "d": "dist_coeffs",
    "k": "camera_matrix",
    "intrinsics": "camera_matrix",
    "matrix": "camera_matrix",
    "cameramatrix": "camera_matrix",
    "intrinsic_matrix": "camera_matrix",
    "size": "image_size",
    "resolution": "image_size",
    "imagesize": "image_size",
    "image_width": "image_size",
    "image_height": "image_size",
    "distortion_model": "model",
    "camera_model": "model",
    "lens_model": "model",
}
#: Largest image side a camera file may declare (pixels).
MAX_IMAGE_SIDE = 100_000


def _as_K(K: Any, where: str) -> np.ndarray:
    try:
        K = np.array(K, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise CameraError(
            f"{where}: camera_matrix is not numeric; expected 3x3 numbers [[fx,0,cx],[0,fy,cy],[0,0,1]]"
        ) from None
    if K.size == 9 and K.shape != (3, 3):
        K = K.reshape(3, 3)
    if K.shape != (3, 3):
        raise CameraError(f"{where}: camera_matrix has shape {K.shape}, expected 3x3 [[fx,0,cx],[0,fy,cy],[0,0,1]]")
    if not np.all(np.isfinite(K)):
        raise CameraError(f"{where}: camera_matrix contains NaN or infinity")
    if np.abs(K).max() > 1e8:
        raise CameraError(
            f"{where}: camera_matrix holds {np.abs(K).max():.3g}, beyond any camera (fx, fy, cx, cy are "
            "pixels, a few hundred to a few thousand); check the file's units"
        )
    fx, fy = K[0, 0], K[1, 1]
    if fx <= 0 or fy <= 0:
        raise CameraError(
            f"{where}: camera_matrix has focal lengths fx={fx:g}, fy={fy:g}; both must be positive "
            "(in pixels); was the matrix transposed or written in another unit?"
        )
    if min(fx, fy) < MIN_FOCAL_PX:  # a view wider than any lens's across a handful of pixels
        raise CameraError(
            f"{where}: camera_matrix has focal lengths fx={fx:g}, fy={fy:g}; at least {MIN_FOCAL_PX:g} pixel is "
            "a camera's (a phone's is about 0.8 times the image width): was it written in metres or millimetres?"
        )
    if abs(K[0, 1]) > 1e-9:
        raise CameraError(
            f"{where}: camera_matrix has a skew term K[0][1] = {K[0, 1]:g}; OpenCV's projectPoints, solvePnP and "
            "calibrateCamera ignore it, so every pose would be off by its effect; calibrate without skew "
            "(OpenCV's default) or write 0 there"
        )
    if abs(K[1, 0]) > 1e-9 or abs(K[2, 0]) > 1e-9 or abs(K[2, 1]) > 1e-9 or abs(K[2, 2] - 1.0) > 1e-9:
        hint = (
            " (it looks transposed: cx, cy belong in the last column)" if abs(K[2, 0]) > 1 or abs(K[2, 1]) > 1 else ""
        )
        raise CameraError(f"{where}: camera_matrix must be [[fx,0,cx],[0,fy,cy],[0,0,1]]; got {_fmt_matrix(K)}{hint}")
    return K


#: The lens models a camera may have (``fidlearn._lens``).
MODELS = ("pinhole", "fisheye")


def _as_model(model: Any, where: str) -> str:
    if not isinstance(model, str) or model not in MODELS:
        fix = (
            " (cv2.fisheye's Kannala-Brandt lens is 'fisheye')" if str(model).lower() in ("equidistant", "kb4") else ""
        )
        raise CameraError(
            f"{where}: model must be 'pinhole' (OpenCV's 4 to 14 coefficients) or 'fisheye' (cv2.fisheye's 4), "
            f"got {model!r:.40}{fix}"
        )
    return model


def _as_dist(dist: Any, where: str, model: str = "pinhole") -> np.ndarray:
    if dist is None:
        return np.zeros(4 if model == "fisheye" else 5)
    try:
        dist = np.array(dist, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise CameraError(f"{where}: dist_coeffs is not a list of numbers") from None
    if dist.size == 0:
        return np.zeros(4 if model == "fisheye" else 5)
    if model == "fisheye" and dist.size != 4:
        raise CameraError(
            f"{where}: a fisheye camera has 4 distortion coefficients (k1 k2 k3 k4, cv2.fisheye's), got "
            f"{dist.size}; use model='pinhole' for OpenCV's 5, 8, 12 or 14"
        )
    if dist.size not in DIST_LENGTHS:
        raise CameraError(
            f"{where}: dist_coeffs has {dist.size} values; OpenCV takes 4, 5, 8, 12 or 14 "
            "(k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]); use [] for no distortion"
        )
    if not np.all(np.isfinite(dist)):
        raise CameraError(f"{where}: dist_coeffs contains NaN or infinity")
    return dist


def _as_size(image_size: Any, where: str) -> tuple[int, int]:
    try:  # numbers only: a string's characters ("64" -> 6 x 4) and bools (True == 1) are not pixels
        if isinstance(image_size, (str, bytes)) or not all(
            isinstance(v, numbers.Real) and not isinstance(v, bool) for v in image_size
        ):
            raise TypeError
        w, h = (int(v) for v in image_size)
        ok = all(float(v) == int(v) for v in image_size)
    except (TypeError, ValueError, OverflowError):
        raise CameraError(f"{where}: image_size must be [width, height] in pixels, got {image_size!r:.60}") from None
    if not ok or w <= 0 or h <= 0:
        raise CameraError(
            f"{where}: image_size must be two positive whole numbers [width, height], got {list(image_size)}"
        )
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE:
        raise CameraError(
            f"{where}: image_size {w}x{h} is beyond any camera ({MAX_IMAGE_SIDE} pixels a side at most); "
            "is it [width, height] in pixels?"
        )
    return (w, h)


def size_of(image_or_size: Any) -> tuple[int, int]:
    """``(width, height)`` of an image array (H, W) or (H, W, C), or a size checked as :func:`_as_size` does."""
    if isinstance(image_or_size, np.ndarray) and image_or_size.ndim in (2, 3) and image_or_size.size:
        return (image_or_size.shape[1], image_or_size.shape[0])
    if isinstance(image_or_size, np.ndarray) and image_or_size.ndim != 1:
        raise CameraError(f"expected an image (H, W) or (H, W, C), got an array of shape {image_or_size.shape}")
    return _as_size(image_or_size, "image_size")


def principal_point_inside(K: np.ndarray, size: tuple[int, int], where: str) -> tuple[int, int]:
    """``size``, or CameraError when the principal point lies outside the picture: a calibration's K with another
    resolution's image_size (a 640x480 calibration read as 320x240 puts cx at 324 on a 320-wide picture)."""
    (w, h), cx, cy = size, float(K[0, 2]), float(K[1, 2])
    if -0.5 <= cx <= w - 0.5 and -0.5 <= cy <= h - 0.5:
        return size
    raise CameraError(
        f"{where}: the principal point ({cx:g}, {cy:g}) lies outside the {w}x{h} picture; image_size must be the "
        f"resolution the camera was calibrated at (about {round(2 * cx + 1)}x{round(2 * cy + 1)} for this K), "
        "and Camera.scaled() changes it"
    )


def _check_aspect(size: tuple[int, int], new: tuple[int, int], tol: float) -> None:
    """CameraError when a camera of ``size`` cannot be scaled to ``new`` (another aspect ratio)."""
    (w, h), (new_w, new_h) = size, new
    if abs((new_w / w) / (new_h / h) - 1.0) <= tol:
        return
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


def _as_alpha(alpha: Any) -> float:
    if isinstance(alpha, bool) or not isinstance(alpha, (int, float, np.integer, np.floating)) or not 0 <= alpha <= 1:
        raise CameraError(f"alpha must be a number from 0 (crop to the picture) to 1 (keep it all), got {alpha!r:.40}")
    return float(alpha)


def _check_picture(image: Any, size: tuple[int, int]) -> None:
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.size == 0:
        raise CameraError("image must be a picture array (H, W) or (H, W, C); read it with fidlearn.load_image")
    if image.dtype not in (np.uint8, np.uint16, np.int16, np.float32, np.float64):  # what cv2.remap takes
        raise CameraError(
            f"image is of type {image.dtype}; a picture is uint8 or uint16 (or float32): read it with "
            "fidlearn.load_image, or convert it (image.astype(np.uint8))"
        )
    if (image.shape[1], image.shape[0]) != tuple(size):
        raise CameraError(
            f"image is {image.shape[1]}x{image.shape[0]}, the camera {size[0]}x{size[1]}; "
            "undistort with camera.for_image(image) when the picture was resized"
        )


def refuse_fisheye(camera: Any, what: str, error: type[Exception]) -> None:
    """``error`` when ``camera`` is a fisheye and ``what`` models OpenCV's pinhole lens only, with the mend."""
    if getattr(camera, "model", "pinhole") == "fisheye":
        raise error(
            f"{what} models OpenCV's pinhole lens only, and {camera.source or 'the camera'} is a fisheye: "
            "undistort the pictures (camera.undistort_image(image)) and use the undistorted camera "
            "(camera.undistorted()), or a pinhole calibration of the lens"
        )


def _check_hfov(hfov_deg: Any) -> None:
    if isinstance(hfov_deg, (bool, str, bytes)) or not isinstance(hfov_deg, (int, float, np.integer, np.floating)):
        raise CameraError(f"hfov_deg must be a number of degrees between 0 and 180, got {hfov_deg!r}")
    if not 0 < hfov_deg < 180:
        raise CameraError(f"hfov_deg must be between 0 and 180 degrees, got {hfov_deg}")


def _as_intrinsics_cov(cov: Any, n: int, where: str) -> np.ndarray | None:
    """A calibration's covariance (n, n) of ``fx, fy, cx, cy`` and the ``n - 4`` distortion coefficients, or None."""
    if cov is None:
        return None
    try:
        C = np.array(cov, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise CameraError(f"{where}: intrinsics_covariance is not a matrix of numbers") from None
    if C.shape != (n, n):
        raise CameraError(
            f"{where}: intrinsics_covariance has shape {C.shape}, expected ({n}, {n}): fx, fy, cx, cy and the "
            f"{n - 4} distortion coefficients, in that order (0 for a parameter held fixed)"
        )
    if not np.all(np.isfinite(C)):
        raise CameraError(f"{where}: intrinsics_covariance contains NaN or infinity")
    scale = max(float(np.abs(C).max()), 1e-300)
    if not np.allclose(C, C.T, rtol=1e-6, atol=1e-9 * scale) or np.linalg.eigvalsh((C + C.T) / 2)[0] < -1e-9 * scale:
        raise CameraError(
            f"{where}: intrinsics_covariance is not a covariance (symmetric, no negative variance); take it "
            "from fidlearn.calibration.intrinsics_uncertainty"
        )
    return (C + C.T) / 2


def _as_pixels(points_px: Any) -> np.ndarray:
    """Pixel points (N, 2), or CameraError."""
    from .frames._checks import as_float_array

    pts = as_float_array(points_px, "points_px", CameraError)
    if pts.size == 0:
        return np.zeros((0, 2))
    if pts.ndim == 0 or pts.shape[-1] != 2:
        raise CameraError(f"points_px has shape {pts.shape}, expected (N, 2) pixels")
    if not np.all(np.isfinite(pts)):
        raise CameraError("points_px contains NaN or infinity")
    return pts.reshape(-1, 2)


def _scaled(K: np.ndarray, cov: np.ndarray | None, sx: float, sy: float) -> tuple[np.ndarray, np.ndarray | None]:
    """K at another resolution (pixel centres: ``c' = (c + 0.5) s - 0.5``) and its covariance scaled alike."""
    K = K.copy()
    K[0, 0] *= sx
    K[0, 1] *= sx
    K[1, 1] *= sy
    K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
    K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
    if cov is None:
        return K, None
    s = np.r_[sx, sy, sx, sy, np.ones(len(cov) - 4)]
    return K, cov * np.outer(s, s)
