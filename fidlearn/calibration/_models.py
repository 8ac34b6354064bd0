"""The lens model a calibration fits, and the held-out comparison that chooses one (``model="auto"``).

* ``"pinhole"``: ``cv2.calibrateCamera`` (OpenCV's 5 coefficients by default);
* ``"fisheye"``: ``cv2.fisheye.calibrate`` (Kannala-Brandt, 4 coefficients, no skew), started from an
  equidistant lens whose picture spans 180 degrees across its width: OpenCV's own start (f from the
  image size alone) fails on a lens of 160 degrees and more;
* ``"auto"``: both, judged on views they did not see. The usable views are dealt into ``FOLDS`` groups; for
  each group the camera is calibrated on the other views, then each held-out view's board pose is fitted
  with that camera (its intrinsics fixed) and its corners' reprojection error measured over every held-out
  corner. A pinhole model fitted to a fisheye lens bends wrong away from the views it was fitted to; on a
  plain lens the fisheye model's 4 coefficients fit as well as the pinhole's 5 (held-out RMS within 1 % on
  ``data/calibration`` and OpenCV's ``right*.jpg``), so the fisheye is chosen only when its held-out RMS is
  below ``FISHEYE_MARGIN`` times the pinhole's: the pinhole model is the one every other OpenCV function
  takes. Measured on the fisheye photos of ``data/real/fisheye_checkerboard``: 0.64 px against 0.84 px on
  six photos, 0.47 against 2.4 px and more on the whole sets.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares

from .. import _lens
from .._cv_threads import opencv_single_thread
from ..errors import CalibrationError

__all__: list[str] = []

#: The values ``model`` takes in ``calibrate_*``.
MODELS = ("pinhole", "fisheye", "auto")
#: Groups of views held out in turn by ``model="auto"``.
FOLDS = 5
#: ``model="auto"`` chooses the fisheye when its held-out RMS is below this times the pinhole's.
FISHEYE_MARGIN = 0.9
#: Names of a fisheye calibration's intrinsics (``std_intrinsics`` keys), in order.
FISHEYE_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")


def fisheye_flag(name: str) -> int:
    """A ``cv2.fisheye.calibrate`` flag: ``cv2.fisheye.CALIB_*`` in OpenCV 4, ``cv2.CALIB_*`` in OpenCV 5."""
    return int(getattr(cv2.fisheye, name) if hasattr(cv2.fisheye, name) else getattr(cv2, name))


def default_fisheye_flags() -> int:
    """Extrinsics recomputed at each step, no skew (a :class:`~fidlearn.Camera` has none)."""
    return fisheye_flag("CALIB_RECOMPUTE_EXTRINSIC") | fisheye_flag("CALIB_FIX_SKEW")


def fisheye_flags_used(flags: int) -> int:
    """The flags ``cv2.fisheye.calibrate`` is called with: the caller's (else :func:`default_fisheye_flags`), from
    fidlearn's start (``CALIB_USE_INTRINSIC_GUESS``) and always without skew, which a Camera cannot hold."""
    base = flags or default_fisheye_flags()
    return base | fisheye_flag("CALIB_USE_INTRINSIC_GUESS") | fisheye_flag("CALIB_FIX_SKEW")


def fisheye_free(flags: int) -> np.ndarray:
    """Which of ``fx, fy, cx, cy, k1..k4`` (:data:`FISHEYE_NAMES`) ``cv2.fisheye.calibrate`` fits under
    :func:`fisheye_flags_used` of ``flags``."""
    used = fisheye_flags_used(flags)
    held = ["CALIB_FIX_FOCAL_LENGTH"] * 2 + ["CALIB_FIX_PRINCIPAL_POINT"] * 2 + [f"CALIB_FIX_K{k}" for k in range(1, 5)]
    return np.array([not used & fisheye_flag(name) for name in held], dtype=bool)


def check_model(model: Any, flags: int) -> str:
    """``model`` checked; flags belong to one model's OpenCV function, so ``"auto"`` takes none."""
    if not isinstance(model, str) or model not in MODELS:
        raise CalibrationError(
            f"model must be 'pinhole' (cv2.calibrateCamera), 'fisheye' (cv2.fisheye.calibrate) or 'auto' "
            f"(the one with the lower error on held-out views), got {model!r:.40}"
        )
    if model == "auto" and flags:
        raise CalibrationError(
            "flags are cv2.calibrateCamera's or cv2.fisheye.calibrate's, not both: with flags, choose "
            "model='pinhole' or model='fisheye'"
        )
    return model


def calibrate_fisheye(obj: list, img: list, size: tuple[int, int], flags: int, criteria: Any) -> tuple:
    """``cv2.fisheye.calibrate``: (rms px, K, dist (4,), rvecs, tvecs), or CalibrationError with a fix."""
    obj64 = [np.asarray(o, np.float64).reshape(1, -1, 3) for o in obj]
    img64 = [np.asarray(p, np.float64).reshape(1, -1, 2) for p in img]
    f0 = size[0] / math.pi
    K0 = np.array([[f0, 0.0, (size[0] - 1) / 2], [0.0, f0, (size[1] - 1) / 2], [0.0, 0.0, 1.0]])
    crit = criteria if criteria is not None else (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    use = fisheye_flags_used(flags)
    try:
        with opencv_single_thread():
            rms, K, D, rvecs, tvecs = cv2.fisheye.calibrate(
                obj64, img64, tuple(size), K0, np.zeros(4), flags=use, criteria=crit
            )
    except cv2.error as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "failed"
        raise CalibrationError(
            f"cv2.fisheye.calibrate failed ({msg}); take more views with the board tilted in different "
            "directions, or calibrate with model='pinhole' if the lens is not a fisheye"
        ) from None
    return float(rms), K, np.asarray(D, np.float64).reshape(-1), list(rvecs), list(tvecs)


def _fit(model: str, obj: list, img: list, size: tuple[int, int], criteria: Any) -> tuple[np.ndarray, np.ndarray]:
    if model == "fisheye":
        return calibrate_fisheye(obj, img, size, 0, criteria)[1:3]
    args = {} if criteria is None else {"criteria": criteria}
    with opencv_single_thread():
        _, K, dist, _, _ = cv2.calibrateCamera(
            [np.asarray(o, np.float32).reshape(-1, 1, 3) for o in obj],
            [np.asarray(p, np.float32).reshape(-1, 1, 2) for p in img],
            tuple(size),
            None,
            None,
            **args,
        )
    return K, np.asarray(dist, np.float64).reshape(-1)


def held_out_residuals(obj: np.ndarray, img: np.ndarray, K: np.ndarray, dist: np.ndarray, model: str) -> np.ndarray:
    """Residuals (N, 2), px, of one view's corners with the board pose fitted to them, the camera held fixed.

    The pose starts from ``cv2.solvePnP`` on the exactly undistorted corners (normalized coordinates; a
    corner beyond 90 degrees left out there) and is then fitted in pixels through the lens model.
    """
    obj = np.asarray(obj, np.float64).reshape(-1, 3)
    img = np.asarray(img, np.float64).reshape(-1, 2)
    xy = _lens.undistort_exact(img, K, dist, model=model)
    ok = np.isfinite(xy).all(axis=1)
    if ok.sum() < 4:
        return np.full_like(img, np.inf)
    found, rvec, tvec = cv2.solvePnP(obj[ok], xy[ok], np.eye(3), None)
    if not found:
        return np.full_like(img, np.inf)

    def residuals(p: np.ndarray) -> np.ndarray:
        P = obj @ cv2.Rodrigues(p[:3])[0].T + p[3:]
        return (_lens.project_points(P, K, dist, model) - img).ravel()

    fit = least_squares(residuals, np.r_[rvec.ravel(), tvec.ravel()], method="lm")
    return fit.fun.reshape(-1, 2)


def held_out_rms(obj: list, img: list, size: tuple[int, int], model: str, criteria: Any) -> float:
    """RMS (px) over every corner of every view, each with the camera calibrated without its group of views."""
    n = len(obj)
    groups = [list(range(i, n, min(FOLDS, n))) for i in range(min(FOLDS, n))]
    sq, count = 0.0, 0
    for held in groups:
        train = [i for i in range(n) if i not in held]
        try:
            K, dist = _fit(model, [obj[i] for i in train], [img[i] for i in train], size, criteria)
        except (CalibrationError, cv2.error):
            return math.inf
        for i in held:
            e = held_out_residuals(obj[i], img[i], K, dist, model)
            sq += float(np.sum(e * e))
            count += len(e)
    return math.sqrt(sq / count) if count else math.inf


def choose_model(obj: list, img: list, size: tuple[int, int], criteria: Any) -> tuple[str, dict]:
    """The model chosen (the fisheye when its held-out RMS is clearly lower), and {model: held-out RMS px}."""
    if len(obj) < 4:
        raise CalibrationError(
            f"model='auto' compares the models on held-out views and needs at least 4 usable views, got "
            f"{len(obj)}; take more photos or choose model='pinhole' or 'fisheye'"
        )
    errors = {m: held_out_rms(obj, img, size, m, criteria) for m in ("pinhole", "fisheye")}
    if not any(math.isfinite(e) for e in errors.values()):
        raise CalibrationError(
            "neither lens model could be calibrated on the held-out groups of views; take more views with the "
            "board tilted in different directions"
        )
    fisheye = errors["fisheye"] < FISHEYE_MARGIN * errors["pinhole"]
    return ("fisheye" if fisheye else "pinhole"), errors
