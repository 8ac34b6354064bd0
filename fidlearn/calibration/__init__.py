"""Camera calibration from photos of a checkerboard or a ChArUco board.

Calibration finds the camera's intrinsics ``K`` and lens distortion from
several views of a flat board whose geometry is known: each view gives
pairs (board point in mm, its pixel), and ``cv2.calibrateCamera`` finds the
camera (and each view's board pose) that reprojects the board points onto
their pixels best. The result is a :class:`Calibration`: the
:class:`~fidlearn.camera.Camera`, the reprojection error overall and per
view, the standard deviations of the intrinsics, and every rejected image
with its reason.

How the checkerboard corners are found, and why
-----------------------------------------------
``cv2.findChessboardCorners`` then ``cv2.cornerSubPix``, the recipe of
OpenCV's own calibration sample, with the refinement window capped so it
cannot reach the next corner: half-size ``min(11, floor(0.6 * s))`` px, ``s``
the shortest corner spacing in the view (the sample's fixed 11 whenever
squares are at least 19 px apart). Measured with OpenCV 5.0
(``benchmarks/bench_calibration.py`` repeats these):

* ``data/calibration`` (20 synthetic 640x480 views, true corners known):
  corners 0.046 px RMS from the truth (max 0.12), fx 0.01 % off, 0.2 s;
  ``cv2.findChessboardCornersSB`` with ``CALIB_CB_ACCURACY``: 0.096 px RMS
  (max 0.39), fx 0.43 % off, about 40 times slower.
* A harder rendered set (20 views, k1 = -0.28, blur 1 px, tilts 30 to 55
  degrees, squares 8 to 22 px apart at their narrowest): this recipe
  0.036 px RMS, fx 0.01 % off; OpenCV's fixed 11 px half-window reaches the
  next corner on the small squares: corners 3.4 px RMS (12 px at worst), fx
  8 % off; the sector detector 0.15 px, fx 0.3 % off.
* OpenCV's 13 ``right*.jpg`` photos: this recipe finds the board in all 13
  and agrees with OpenCV's sample exactly (fx 542.35, RMS 0.459 px); the
  sector detector misses one and lands 1.4 % lower in fx (534.6) with a
  lower RMS (0.25 px), which the synthetic bias above suggests is not a
  better camera.

``corner_finder="sb"`` selects ``findChessboardCornersSB`` for comparison
(both finders exist unchanged from OpenCV 4.0 to 5.x).

ChArUco
-------
``cv2.aruco.CharucoDetector`` finds the markers and interpolates the chess
corners between them (each corner has an id, so a partly hidden board still
counts); ``board.matchImagePoints`` pairs them with the board's points; then
the same ``cv2.calibrateCamera``. Boards printed before OpenCV 4.6 with an
even number of rows use another marker layout (``legacy=True``); the
default ``legacy="auto"`` tries both on such boards and keeps the one that
finds more corners (for an odd number of rows the layouts are the same).

Outlier views
-------------
After a first calibration, a view whose RMS reprojection error exceeds
``max(3 x median, median + 0.5 px)`` (median over the views) is rejected and
the camera is calibrated again without it, once. A blurred photo or a
mis-refined corner shows up this way; the rejection is reported with the
view's error.

Board frame (``T_camera_board``), mm, z into the paper: a checkerboard's
origin is the first inner corner OpenCV reports, x along the pattern's first
row, y down the board (the pattern is symmetric, so a view's origin may sit at
the opposite end of the board); a ChArUco board's is its own: the outer corner
of the top-left square, x along the top edge (``board.getChessboardCorners()``).

Uncertainty and cross-validation
--------------------------------
``std_intrinsics`` are OpenCV's: white corner noise only. Real views also share errors within a
view (a board not quite flat, a lens the model describes a little wrong), and two independent
sets of one camera then differ by several of those standard deviations.
:func:`intrinsics_uncertainty` inflates the covariance by the views' measured pull beyond white
noise (:mod:`fidlearn.calibration.uncertainty`); :func:`compare_calibrations` says whether two
calibrations project alike across the picture within that noise (:mod:`fidlearn.calibration.compare`).

Quality
-------
A small RMS does not make a trustworthy camera: :class:`Calibration` also carries
``coverage`` (board points per ninth of the picture) and ``warnings`` (too few views,
views too alike, parts of the picture empty), from :mod:`fidlearn.calibration.quality`.

Speed
-----
``cv2.calibrateCamera`` runs once (twice when outlier views are rejected). The per-view
errors come from one projection of every view's points with the returned camera and poses;
the standard deviations of the intrinsics from the normal matrix ``cv2.calibrateCameraExtended``
inverts, reduced to the intrinsics, when ``std_intrinsics`` is first read (``_stats``): the
same numbers, without the inversion that made ``calibrateCameraExtended`` cost up to twice
``calibrateCamera``. ``benchmarks/bench_calibration.py`` times the whole run against plain OpenCV.

The board itself is a :class:`fidlearn.Board` (:mod:`fidlearn.boards`). Layout: ``api`` (the two
functions), ``boards`` (finding the board), ``run`` (the shared
calibration run), ``result`` (:class:`Calibration`), ``quality`` (coverage and variety), ``_stats`` (per-view
errors and standard deviations), ``uncertainty`` (the covariance with the views' own error),
``compare`` (two calibrations side by side).
"""

from __future__ import annotations

from . import quality  # noqa: F401 - fidlearn.calibration.quality
from .api import calibrate_charuco, calibrate_checkerboard
from .boards import find_checkerboard_corners
from .compare import CalibrationComparison, compare_calibrations
from .quality import DuplicateViews, ViewDiversity, coverage_grid, quality_warnings, view_diversity
from .result import Calibration, ViewResult
from .run import INTRINSIC_NAMES, MIN_VIEWS, OUTLIER_FACTOR, OUTLIER_MARGIN_PX, ProgressFn
from .uncertainty import IntrinsicsUncertainty, camera_with_uncertainty, intrinsics_uncertainty

__all__ = [
    "Calibration",
    "ViewResult",
    "calibrate_checkerboard",
    "calibrate_charuco",
    "find_checkerboard_corners",
    "compare_calibrations",
    "CalibrationComparison",
    "intrinsics_uncertainty",
    "camera_with_uncertainty",
    "IntrinsicsUncertainty",
    "coverage_grid",
    "view_diversity",
    "ViewDiversity",
    "DuplicateViews",
    "quality_warnings",
    "MIN_VIEWS",
    "INTRINSIC_NAMES",
    "OUTLIER_FACTOR",
    "OUTLIER_MARGIN_PX",
    "ProgressFn",
]
