"""The calibration run: find the board in every image, keep the usable views, calibrate, reject outliers.

Everything here is shared by :func:`~fidlearn.calibration.calibrate_checkerboard` and
:func:`~fidlearn.calibration.calibrate_charuco`; the board finders are in
:mod:`fidlearn.calibration.boards`, the quality checks in :mod:`fidlearn.calibration.quality`.
"""

from __future__ import annotations

import functools
import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from .._cv_threads import opencv_single_thread
from ..camera import Camera
from ..detection import as_gray
from ..errors import CalibrationError, ImageError
from ..images import load_image
from . import _models, _stats
from .quality import coverage_grid, quality_warnings
from .result import Calibration, ViewResult, _short

__all__ = ["MIN_VIEWS", "INTRINSIC_NAMES", "OUTLIER_FACTOR", "OUTLIER_MARGIN_PX"]

#: Fewest usable views a calibration accepts.
MIN_VIEWS = 3

#: Names of the intrinsics (``cv2.calibrateCameraExtended``'s ``stdDeviationsIntrinsics`` entries), in order.
INTRINSIC_NAMES = (
    "fx",
    "fy",
    "cx",
    "cy",
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
    "k4",
    "k5",
    "k6",
    "s1",
    "s2",
    "s3",
    "s4",
    "tau_x",
    "tau_y",
)

#: Outlier rule: a view is an outlier above max(OUTLIER_FACTOR * median, median + OUTLIER_MARGIN_PX).
OUTLIER_FACTOR = 3.0
OUTLIER_MARGIN_PX = 0.5

ProgressFn = Callable[[int, int, str], Any]


@dataclass
class _View:
    name: str
    status: str = "used"
    reason: str = ""
    size: tuple[int, int] | None = None
    points: dict = field(default_factory=dict)  # layout key -> (obj, img) or reason
    obj: np.ndarray | None = None
    img: np.ndarray | None = None
    rms_px: float | None = None
    n_found: int = 0


def _read_gray(name: str, item: Any) -> np.ndarray:
    image = load_image(item) if isinstance(item, (str, os.PathLike)) else item
    return as_gray(image, where=name)


def _detect_all(entries, find: Callable[[np.ndarray], dict], progress: ProgressFn | None, keep_failed: int = 3):
    """Detect the board in every entry; returns views and up to ``keep_failed`` gray images where nothing was found."""
    views: list[_View] = []
    failed_grays: list[np.ndarray] = []
    n = len(entries)
    for i, (name, item) in enumerate(entries):
        view = _View(name)
        try:
            gray = _read_gray(name, item)
        except ImageError as exc:
            view.status, view.reason = "unreadable", str(exc)
        else:
            view.size = (gray.shape[1], gray.shape[0])
            view.points = find(gray)
            if all(isinstance(p, str) for p in view.points.values()) and len(failed_grays) < keep_failed:
                failed_grays.append(gray)
        views.append(view)
        if progress is not None:
            progress(i + 1, n, name)
    return views, failed_grays


def _choose_size(views: list[_View]) -> tuple[int, int] | None:
    """The most common size of the views that show the board (of every view when none does): photos where no
    board was found do not decide the resolution calibrated at."""
    sizes = [v.size for v in views if v.size is not None and v.status == "used"]
    sizes = sizes or [v.size for v in views if v.size is not None]
    if not sizes:
        return None
    counts = Counter(sizes)
    best = max(counts.values())
    return next(s for s in sizes if counts[s] == best)  # the most common; on a tie, the first seen


def _points(view: _View) -> tuple[np.ndarray, np.ndarray]:
    """A used view's board points (mm) and image points (px)."""
    assert view.obj is not None, "a used view has its points"
    assert view.img is not None, "a used view has its points"
    return view.obj, view.img


def _reject_duplicates(views: list[_View], tol_px: float = 1.0) -> None:
    """Reject views whose board sits where an earlier view's did: they add no information, only weight."""
    kept: list[_View] = []
    for v in views:
        if v.status != "used":
            continue
        v_obj, v_img = _points(v)
        for k in kept:
            k_obj, k_img = _points(k)
            if k_img.shape != v_img.shape or not np.allclose(k_obj, v_obj):
                continue
            d = min(np.abs(k_img - v_img).max(), np.abs(k_img[::-1] - v_img).max())
            if d < tol_px:
                v.status = "duplicate"
                v.reason = (
                    f"the board sits where it sat in {k.name} (every corner within {tol_px:g} px): "
                    "move or tilt the board between photos"
                )
                break
        else:
            kept.append(v)


def _calibrate_points(obj: list, img: list, image_size, flags: int, criteria, model: str = "pinhole"):
    """``cv2.calibrateCamera`` (``cv2.fisheye.calibrate``) and the per-view errors; the standard deviations wait
    in ``std_from``."""
    if model == "fisheye":
        return _calibrate_fisheye(obj, img, image_size, flags, criteria)
    args: dict[str, Any] = dict(flags=int(flags))
    if criteria is not None:
        args["criteria"] = criteria
    obj = [o.astype(np.float32).reshape(-1, 1, 3) for o in obj]
    img = [p.astype(np.float32).reshape(-1, 1, 2) for p in img]
    try:
        size = tuple(int(v) for v in image_size)
        with opencv_single_thread():  # the same answer to the last bit, from any number of threads
            rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, size, None, None, **args)
    except cv2.error as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "failed"
        raise CalibrationError(
            f"cv2.calibrateCamera failed ({msg}); take more views with the board tilted in different directions"
        ) from None
    dist = np.asarray(dist, dtype=np.float64).reshape(-1)
    rotations = [cv2.Rodrigues(r)[0] for r in rvecs]
    per_view = _stats.per_view_rms(obj, img, K, dist, rotations, tvecs)
    std_from = functools.partial(_std_dict, obj, K, dist, rvecs, tvecs, float(rms), int(flags))
    return float(rms), K, dist, rotations, tvecs, std_from, per_view


def _calibrate_fisheye(obj: list, img: list, image_size, flags: int, criteria):
    """As :func:`_calibrate_points`, with ``cv2.fisheye.calibrate``; the RMS over every point, as OpenCV's pinhole
    one is (``cv2.fisheye.calibrate`` reports another measure)."""
    size = (int(image_size[0]), int(image_size[1]))
    _, K, dist, rvecs, tvecs = _models.calibrate_fisheye(obj, img, size, int(flags), criteria)
    rotations = [cv2.Rodrigues(np.asarray(r, np.float64).reshape(3))[0] for r in rvecs]
    tvecs = [np.asarray(t, np.float64).reshape(3, 1) for t in tvecs]
    per_view = _stats.per_view_rms(obj, img, K, dist, rotations, tvecs, "fisheye")
    counts = np.array([len(np.reshape(o, (-1, 3))) for o in obj])
    rms = float(np.sqrt(np.sum(per_view**2 * counts) / counts.sum()))
    std_from = functools.partial(_std_dict_fisheye, obj, K, dist, rvecs, tvecs, rms, int(flags))
    return rms, K, dist, rotations, tvecs, std_from, per_view


def _std_dict_fisheye(obj, K, dist, rvecs, tvecs, rms_px: float, flags: int) -> dict:
    std = _stats.std_intrinsics_fisheye(obj, K, dist, rvecs, tvecs, rms_px, _models.fisheye_free(flags))
    return {n: float(v) for n, v in zip(_models.FISHEYE_NAMES, std)}


def _std_dict(obj, K, dist, rvecs, tvecs, rms_px: float, flags: int) -> dict:
    """``Calibration.std_intrinsics``: {name: standard deviation}, computed when first read."""
    std = _stats.std_intrinsics(obj, K, dist, rvecs, tvecs, rms_px, flags)
    return {n: float(v) for n, v in zip(INTRINSIC_NAMES[: 4 + len(dist)], std)}


def _too_few(views: list[_View], hint: str, min_views: int) -> CalibrationError:
    n_used = sum(v.status == "used" for v in views)
    groups: dict[str, list[str]] = {}
    for v in views:
        if v.status != "used":
            groups.setdefault(v.status, []).append(v.name)
    parts = []
    for status, names in groups.items():
        shown = ", ".join(_short(os.path.basename(n) or n, 30) for n in names[:4]) + (", ..." if len(names) > 4 else "")
        first = next(v.reason for v in views if v.status == status)
        parts.append(f"{status}: {len(names)} ({shown}; {first})")
    why = "; ".join(parts) if parts else f"the board was found in every one, {min_views} are needed"
    fix = hint[0].upper() + hint[1:] + ". " if hint else ""
    return CalibrationError(
        f"calibration needs at least {min_views} views with the board found, got {n_used} of {len(views)}: {why}. "
        f"{fix}Take 10 to 20 sharp photos of the whole board at different tilts and positions"
    )


def _choose_layout(views: list[_View], finder) -> None:
    """One board layout for every view (ChArUco legacy 'auto': the one that finds more corners)."""
    keys = list(next((v.points for v in views if v.points), {0: None}).keys())
    if len(keys) > 1:
        totals = {
            k: sum(len(v.points[k][0]) for v in views if v.points and not isinstance(v.points[k], str)) for k in keys
        }
        key = max(keys, key=lambda k: totals[k])
        finder.legacy = key
    else:
        key = keys[0]
    for v in views:
        if v.status != "used":
            continue
        found = v.points[key]
        if isinstance(found, str):
            v.status, v.reason = "not found", found
        else:
            v.obj, v.img = found
            v.n_found = len(v.img)


def _reject_other_sizes(views: list[_View], size) -> None:
    """Leave out the views of another size than ``size``, saying why (a picture turned a quarter, or another
    resolution)."""
    for v in views:
        if v.size is not None and v.size != size:
            v.status = "other size"
            v.reason = (
                f"image is {v.size[0]}x{v.size[1]} but the others are {size[0]}x{size[1]}; "
                "calibrate at the resolution you run at, with every photo at that one resolution"
            )
            if v.size == size[::-1]:
                v.reason = (
                    f"image is {v.size[0]}x{v.size[1]}, turned a quarter from the others' {size[0]}x{size[1]} "
                    "(the camera held the other way, or the picture turned by a program); a turned picture has "
                    "its axes and principal point swapped: leave it out, or take every photo the same way up"
                )
            v.obj = v.img = None


def _reject_outliers(usable: list[_View], per_view: np.ndarray, min_views: int) -> bool:
    """Mark the views far above the median error as outliers; whether any was (then calibrate again)."""
    med = float(np.median(per_view))
    limit = max(OUTLIER_FACTOR * med, med + OUTLIER_MARGIN_PX)
    bad = [i for i, e in enumerate(per_view) if e > limit]
    if not bad or len(usable) - len(bad) < min_views:
        return False
    for i in bad:
        v = usable[i]
        v.status, v.rms_px = "outlier", float(per_view[i])
        v.reason = (
            f"reprojection RMS {per_view[i]:.2f} px, above {limit:.2f} px "
            f"(max of {OUTLIER_FACTOR:g} x the median {med:.2f} px and median + {OUTLIER_MARGIN_PX:g} px): "
            "blurred, or a corner found in the wrong place?"
        )
    return True


def _result(
    views: list[_View], usable: list[_View], size, fit: tuple, first_rms, finder, kind: str, model: tuple = ("pinhole",)
) -> Calibration:
    """The Calibration of the used views, with its coverage and warnings; ``model`` is (model, held-out errors)."""
    rms, K, dist, rotations, tvecs, std_from, per_view = fit
    T_camera_board = {}
    for v, e, R, t in zip(usable, per_view, rotations, tvecs):
        v.rms_px = float(e)
        T = np.eye(4)  # frames.transform_from_rvec_tvec's matrix: cv2.Rodrigues of OpenCV's own (finite) rvec
        T[:3, :3], T[:3, 3] = R, np.reshape(t, 3)
        T_camera_board[v.name] = T
    legacy = bool(getattr(finder, "legacy", False))
    board = finder.description + (", legacy layout" if legacy else "")
    lens = "" if model[0] == "pinhole" else f", {model[0]} model"
    source = (
        f"{kind}: {len(usable)} of {len(views)} views of a {board}{lens}, RMS {rms:.3f} px, OpenCV {cv2.__version__}"
    )
    camera = Camera(K, dist, size, source=source, model=model[0])
    image_points_px = {v.name: v.img for v in usable}
    grid = coverage_grid(image_points_px.values(), camera.image_size)
    return Calibration(
        camera=camera,
        rms_px=rms,
        per_view_rms_px={v.name: v.rms_px for v in usable},
        used=[v.name for v in usable],
        std_intrinsics=None,  # computed from std_from when first read
        rejected=[(v.name, f"{v.status}: {v.reason}") for v in views if v.status != "used"],
        T_camera_board=T_camera_board,
        views=[ViewResult(v.name, v.status, v.n_found, v.rms_px, v.reason) for v in views],
        board=finder.board,
        image_points_px=image_points_px,
        board_points_mm={v.name: v.obj for v in usable},
        first_rms_px=first_rms,
        coverage=grid,
        warnings=quality_warnings(len(usable), T_camera_board, grid),
        legacy_layout=legacy,
        _std_from=std_from,
        held_out_rms_px=model[1] if len(model) > 1 else None,
    )


def _run(
    entries,
    finder,
    find: Callable,
    progress,
    reject_outliers: bool,
    flags: int,
    criteria,
    kind: str,
    reject_duplicates: bool = False,
    min_views: int = MIN_VIEWS,
    model: str = "pinhole",
) -> Calibration:
    """Detect, select the usable views, choose the lens model (``"auto"``), calibrate (twice when outlier views
    are rejected)."""
    if not entries:
        raise CalibrationError(f"no images given; calibration needs at least {min_views} views of the board")
    views, failed_grays = _detect_all(entries, find, progress)
    _choose_layout(views, finder)
    size = _choose_size(views)
    _reject_other_sizes(views, size)
    if reject_duplicates:
        _reject_duplicates(views)
    usable = [v for v in views if v.status == "used"]
    if len(usable) < min_views:
        hint = finder.diagnose(failed_grays) if not usable else ""
        raise _too_few(views, hint, min_views)
    chosen: tuple = (model,)
    assert size is not None, "used views have a size"
    if model == "auto":
        chosen = _models.choose_model([v.obj for v in usable], [v.img for v in usable], size, criteria)
    fit = _calibrate_points([v.obj for v in usable], [v.img for v in usable], size, flags, criteria, chosen[0])
    first_rms = None
    if reject_outliers and len(usable) > min_views and _reject_outliers(usable, fit[6], min_views):
        first_rms = fit[0]
        usable = [v for v in views if v.status == "used"]
        fit = _calibrate_points([v.obj for v in usable], [v.img for v in usable], size, flags, criteria, chosen[0])
    return _result(views, usable, size, fit, first_rms, finder, kind, chosen)
