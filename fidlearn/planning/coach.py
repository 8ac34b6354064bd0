"""A calibration coach: how uncertain the calibrated camera is across the picture, and what photo to take next.

A small RMS reprojection error says the board points fit the model; it does not say the model is
right. With the views all face-on, or the picture's corners never covered, a calibration can fit
its own views to 0.1 px and still be a wrong camera elsewhere. Following mrcal's approach, the
coach propagates the uncertainty of the intrinsics (the covariance of the least-squares fit, with
every view's board pose marginalised out) to the pixels: how far the projection of a point seen
at a given pixel would move if the calibration were redone with new noise. It then tries
candidate board placements and says which one shrinks that uncertainty the most.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..calibration.quality import MIN_GOOD_VIEWS, coverage_grid, few_views_warning
from ..camera import Camera
from ..errors import CalibrationError
from . import _checks
from ._candidate_views import board_in_picture as _board_in_picture  # noqa: F401  (its old home, still importable)
from ._candidate_views import candidates as _candidates
from ._candidate_views import in_picture as _in_picture
from ._candidate_views import printed_outline as _printed_outline  # noqa: F401  (its old home, still importable)
from ._candidate_views import printed_points as _printed_points
from ._lens_jacobians import n_intrinsics, pixel_rays, ray_jacobians, view_jacobians
from .bent_board import BENT_FALSE_ALARM, bend_flag, bent_views, board_bends

__all__ = [
    "BENT_FALSE_ALARM",
    "CalibrationCoach",
    "NextView",
    "bent_views",
    "coach",
    "intrinsics_information",
    "uncertainty_map",
]

#: Reprojection uncertainty (px) under which a part of the picture counts as well calibrated.
GOOD_UNCERTAINTY_PX = 0.3
#: Fewer used views than this is flagged: a camera with 9 unknowns and every view's pose needs more
#: (the calibration's own warnings use the same count and words).
MIN_VIEWS = MIN_GOOD_VIEWS
#: A view whose board is tilted less than this (deg) from face-on counts as face-on.
FACE_ON_DEG = 15.0
#: The picture is cut into this grid (columns, rows) for coverage and the uncertainty map.
GRID = (8, 6)


def _marginal_information(camera: Camera, points_mm: np.ndarray, T_camera_board: np.ndarray) -> np.ndarray:
    """One view's information on the intrinsics, its own board pose marginalised out (Schur complement)."""
    _, Je, Ji = view_jacobians(camera, points_mm, T_camera_board)
    A, B, D = Ji.T @ Ji, Ji.T @ Je, Je.T @ Je
    return A - B @ np.linalg.solve(D + 1e-12 * np.eye(6), B.T)


def intrinsics_information(camera: Camera, board_points_mm: dict, T_camera_board: dict) -> np.ndarray:
    """Fisher information (per px^2 of corner noise) on ``[fx, fy, cx, cy, dist...]`` from the views.

    For a fisheye camera (``model="fisheye"``) the intrinsics are ``[fx, fy, cx, cy, k1, k2, k3, k4]``, through
    ``cv2.fisheye.projectPoints``'s Jacobian.

    Parameters
    ----------
    camera : Camera
        The calibrated camera.
    board_points_mm : dict of str to ndarray, shape (N, 3)
        Each view's board points (mm, board frame).
    T_camera_board : dict of str to ndarray, shape (4, 4)
        Each view's board pose in the camera frame (mm).

    Returns
    -------
    ndarray, shape (4 + n_dist, 4 + n_dist)
        ``sigma^2`` times its inverse is the covariance of the intrinsics.

    Raises
    ------
    CalibrationError
        If the camera is not a Camera, or a view is missing or malformed (the message names it).
    """
    board_points_mm, _, T_camera_board = _checks.check_views(
        camera, board_points_mm, None, T_camera_board, pixels=False
    )
    n = n_intrinsics(camera)
    info = np.zeros((n, n))
    for name, T in T_camera_board.items():
        info += _marginal_information(camera, board_points_mm[name], T)
    return info


def _pixel_grid(camera: Camera, grid=GRID) -> np.ndarray:
    cols, rows = grid
    u = (np.arange(cols) + 0.5) * camera.width / cols - 0.5
    v = (np.arange(rows) + 0.5) * camera.height / rows - 0.5
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def uncertainty_map(camera: Camera, covariance: np.ndarray, distance_mm: float, grid=GRID) -> np.ndarray:
    """Reprojection uncertainty (px, per axis) over a grid of the picture: ``(rows, cols)``.

    For the pixel at each cell's centre, the point at ``distance_mm`` along its ray is projected
    with the intrinsics, and the first-order change of its pixel under ``covariance`` is taken,
    less what a small rotation of the camera absorbs: a principal point a pixel off moves every
    pixel alike, and the pose found with that camera turns by as much, so a localization never
    sees it (mrcal makes the same correction). The result is ``sqrt(trace(P J C J^T P^T) / 2)``
    per cell, ``P`` removing the best-fitting rotation over the whole grid.

    A fisheye camera's rays are taken by their angle from the axis, so the corners of a lens of 180
    degrees and more (rays at 90 degrees and beyond) have their uncertainty too; a cell whose pixel no
    ray reaches (beyond the fold of the model's polynomial) is NaN. Its rotation is fitted over the
    cells near the middle of the picture (:func:`turn_cells`), as mrcal's default focus region, not
    the whole grid: a fisheye's corners see rays far beyond any view, whose uncertainty, hundreds of
    pixels, would otherwise set the rotation for every pixel.

    Parameters
    ----------
    camera : Camera
        The calibrated camera.
    covariance : ndarray, shape (n, n)
        Covariance of its intrinsics ``[fx, fy, cx, cy, dist...]`` (px, and unitless for the
        distortion), as :attr:`CalibrationCoach.covariance`.
    distance_mm : float
        Distance along each ray at which the point is taken (mm); the views' median distance.
    grid : (int, int)
        Cells across and down the picture.

    Returns
    -------
    ndarray, shape (grid[1], grid[0])
        The uncertainty (px per axis), row 0 at the top of the picture; NaN where no ray reaches.

    Raises
    ------
    CalibrationError
        If the camera is not a Camera, the covariance not a finite (n, n) array, the distance not a
        positive number of mm, or the grid not two whole numbers from 1 to 200.
    """
    _checks.check_camera(camera, allow_fisheye=True)
    covariance = _checks.check_covariance(covariance, n_intrinsics(camera))
    _checks.finite_distance(distance_mm)  # the camera only turns: any distance along the rays gives the same map
    grid = _checks.check_grid(grid)
    px = _pixel_grid(camera, grid)
    rays = pixel_rays(camera, px)
    ok = np.all(np.isfinite(rays), axis=1)
    u = np.full(len(rays), np.nan)
    if ok.any():
        Ji, Jr = ray_jacobians(camera, rays[ok])  # (2G, n) intrinsics, (2G, 3) a small rotation of the camera
        fit = np.repeat(turn_cells(camera, px[ok]), 2)
        field = Ji - Jr @ np.linalg.lstsq(Jr[fit], Ji[fit], rcond=None)[0]
        var = np.einsum("kj,jl,kl->k", field, covariance, field).reshape(-1, 2).sum(axis=1) / 2
        u[ok] = np.sqrt(np.clip(var, 0, None))
    return u.reshape(grid[1], grid[0])


def turn_cells(camera: Camera, px: np.ndarray) -> np.ndarray:
    """Which of the cells at ``px`` (G, 2) the uncertainty map fits its small rotation of the camera over.

    Every cell for a pinhole camera; for a fisheye, those within a sixth of the picture's smaller side
    of the principal point (mrcal's default focus region), or the nearest one if none is.

    Parameters
    ----------
    camera : Camera
        The calibrated camera.
    px : ndarray, shape (G, 2)
        The cells' centres (px).

    Returns
    -------
    ndarray of bool, shape (G,)
    """
    px = np.asarray(px, dtype=float).reshape(-1, 2)
    if camera.model != "fisheye":
        return np.ones(len(px), dtype=bool)
    d = np.hypot(px[:, 0] - camera.K[0, 2], px[:, 1] - camera.K[1, 2])
    near = d <= min(camera.image_size) / 6
    return near if near.any() else d == d.min()


@dataclass(frozen=True)
class NextView:
    """A board placement to photograph next, and what it would bring.

    Attributes
    ----------
    T_camera_board : ndarray, shape (4, 4)
        The board's pose in the camera frame (mm).
    where : str
        The part of the picture it should fill, in words ("the top left").
    tilt : str
        How to tilt it, in words.
    distance_mm : float
        Distance from the camera to the board (mm).
    good_fraction_after : float
        Fraction of the picture under :data:`GOOD_UNCERTAINTY_PX` once this view is added.
    median_uncertainty_px_after : float
        Median reprojection uncertainty (px per axis) once this view is added.
    """

    T_camera_board: np.ndarray
    where: str
    tilt: str
    distance_mm: float
    good_fraction_after: float
    median_uncertainty_px_after: float

    def _distance(self) -> str:
        """The distance as a person measures it: in cm under a metre (24 cm, not 0.2 m), else in m."""
        if self.distance_mm < 995:
            return f"{self.distance_mm / 10:.0f} cm"
        return f"{self.distance_mm / 1000:.1f} m"

    def __str__(self) -> str:
        return (
            f"put the board {self.where} of the picture, {self.tilt}, about {self._distance()} "
            f"away: {100 * self.good_fraction_after:.0f} % of the picture under {GOOD_UNCERTAINTY_PX} px"
        )


@dataclass(frozen=True, repr=False)
class CalibrationCoach:
    """How good a calibration is where it matters, in words and numbers.

    Attributes
    ----------
    uncertainty_px : ndarray, shape (rows, cols)
        Reprojection uncertainty over the picture (px per axis), at the views' median distance.
    good_fraction : float
        Fraction of the picture where it is under :data:`GOOD_UNCERTAINTY_PX`.
    covariance : ndarray
        Covariance of ``[fx, fy, cx, cy, dist...]`` (px, and unitless for the distortion).
    coverage : ndarray, shape (rows, cols)
        Board points per grid cell, over all used views.
    tilts_deg : dict of str to float
        Each view's angle between the board and the image plane (deg): 0 face-on.
    flags : list of str
        What is wrong with the set, in words (empty when nothing is).
    next_view : NextView or None
        The placement that would shrink the uncertainty most.
    """

    uncertainty_px: np.ndarray
    good_fraction: float
    covariance: np.ndarray
    coverage: np.ndarray
    tilts_deg: dict
    flags: list = field(default_factory=list)
    next_view: NextView | None = None

    @property
    def fx_std_px(self) -> float:
        return float(math.sqrt(self.covariance[0, 0]))

    def report(self, omit=()) -> str:
        """The verdict in words, as ``fidlearn calibrate`` prints it.

        Parameters
        ----------
        omit : collection of str
            Flags already said elsewhere (``fidlearn calibrate`` leaves out the calibration's own warnings).

        Returns
        -------
        str
            The uncertainty over the picture, one ``warning:`` line per flag, and the next photo.

        Raises
        ------
        CalibrationError
            If ``omit`` is not a collection.
        """
        lines = [
            f"reprojection uncertainty: median {_nan_stat(np.median, self.uncertainty_px):.2f} px, worst "
            f"{_nan_stat(np.max, self.uncertainty_px):.2f} px; under {GOOD_UNCERTAINTY_PX} px over "
            f"{100 * self.good_fraction:.0f} % of the picture"
        ]
        try:
            skip = {o for o in omit if isinstance(o, str)}
        except TypeError:
            raise CalibrationError(f"omit must be a collection of flags (str), got {omit!r:.60}") from None
        lines += [f"warning: {f}" for f in self.flags if f not in skip]
        if self.next_view is not None:
            lines.append(f"next photo: {self.next_view}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"CalibrationCoach(under {GOOD_UNCERTAINTY_PX} px over {100 * self.good_fraction:.0f} % of the picture, "
            f"{len(self.flags)} warning{'s' if len(self.flags) != 1 else ''})"
        )


def _nan_stat(stat, u: np.ndarray) -> float:
    """``stat`` over the cells some ray reaches (a fisheye's picture corners may have none); NaN if none does."""
    finite = u[np.isfinite(u)]
    return float(stat(finite)) if finite.size else math.nan


def _coverage(camera: Camera, image_points_px: dict, grid=GRID) -> np.ndarray:
    """Board points per cell of a ``grid`` (columns, rows) over the picture, row 0 at the top."""
    return coverage_grid(image_points_px.values(), camera.image_size, grid)


_NINTHS = ["top left", "top", "top right", "left", "middle", "right", "bottom left", "bottom", "bottom right"]


def _tilt_deg(T_camera_board: np.ndarray) -> float:
    """Angle between the board's plane and the image plane (deg): 0 for a board square to the optical axis."""
    return float(math.degrees(math.acos(min(1.0, abs(float(T_camera_board[2, 2]))))))


def _summary(camera: Camera, info: np.ndarray, sigma: float, distance_mm: float):
    cov = sigma**2 * np.linalg.pinv(info)
    u = uncertainty_map(camera, cov, distance_mm)
    return cov, u, _nan_stat(lambda f: np.mean(f < GOOD_UNCERTAINTY_PX), u) if np.isfinite(u).any() else 0.0


def coach(
    camera: Camera,
    board_points_mm: dict,
    image_points_px: dict,
    T_camera_board: dict,
    *,
    corner_sigma_px: float,
    other_sizes: int = 0,
) -> CalibrationCoach:
    """Judge a calibration set and say which photo to take next.

    Parameters
    ----------
    camera : Camera
        The calibrated camera.
    board_points_mm, image_points_px, T_camera_board : dict by view name
        Board points (N, 3) mm, their pixels (N, 2) and the board poses (4, 4) mm, as a
        :class:`~fidlearn.Calibration` holds them.
    corner_sigma_px : float
        Corner noise (px per axis): the calibration's RMS reprojection error over sqrt(2).
    other_sizes : int
        Photos left out because they had another resolution (a mixed set is flagged).

    Returns
    -------
    CalibrationCoach
        The uncertainty over the picture, the flags with their fixes, and the next view to take.

    Raises
    ------
    CalibrationError
        If there is no view, a view is missing or malformed (the message names it), the camera is not a
        Camera, ``corner_sigma_px`` is not a positive number of pixels (up to 100) or ``other_sizes`` not a count.
    """
    if not (_checks.is_number(corner_sigma_px) and 0 < corner_sigma_px <= 100):
        raise CalibrationError(f"corner_sigma_px must be a number of pixels, above 0 to 100, got {corner_sigma_px!r}")
    if isinstance(other_sizes, bool) or not isinstance(other_sizes, (int, np.integer)) or other_sizes < 0:
        raise CalibrationError(f"other_sizes must be a count of photos (0 or more), got {other_sizes!r}")
    board_points_mm, image_points_px, T_camera_board = _checks.check_views(
        camera, board_points_mm, image_points_px, T_camera_board
    )
    names = list(T_camera_board)
    if not names:
        raise CalibrationError("no views to judge: the calibration used none")
    distance = float(np.median([np.linalg.norm(T_camera_board[n][:3, 3]) for n in names]))
    info = intrinsics_information(camera, board_points_mm, T_camera_board)
    cov, u, good = _summary(camera, info, corner_sigma_px, distance)
    coverage = _coverage(camera, image_points_px)
    tilts = {n: _tilt_deg(T_camera_board[n]) for n in names}
    flags = _flags(camera, board_points_mm, image_points_px, T_camera_board, tilts, other_sizes)
    # the board as the view that shows most of it (a ChArUco view may show only part of the board)
    board = np.asarray(board_points_mm[max(names, key=lambda n: len(board_points_mm[n]))], dtype=float)
    best = _next_view(camera, board, info, corner_sigma_px, distance)
    return CalibrationCoach(u, good, cov, coverage, tilts, flags, best)


def _flags(camera, board_points_mm, image_points_px, T_camera_board, tilts: dict, other_sizes: int) -> list[str]:
    """What is wrong with the set, one sentence each."""
    names = list(T_camera_board)
    flags = []
    if len(names) < MIN_VIEWS:
        flags.append(few_views_warning(len(names)))
    if max(tilts.values()) < FACE_ON_DEG:
        flags.append(
            f"every view is face-on (the largest tilt is {max(tilts.values()):.0f} deg): the focal length "
            "and the distance cannot be told apart; tilt the board 20 to 45 deg in different directions"
        )
    ninths = _coverage(camera, image_points_px, (3, 3))
    empty = [_NINTHS[k] for k in np.flatnonzero(ninths.ravel() == 0)]
    if empty:
        flags.append(
            f"no board point in the {', '.join(empty)} of the picture; the distortion there is a guess: take "
            "views with the board reaching into it"
        )
    if other_sizes:
        flags.append(
            f"{other_sizes} photo{'s were' if other_sizes > 1 else ' was'} taken at another resolution and left "
            "out: calibrate at the resolution you will run at, all photos alike"
        )
    bent = board_bends(camera, board_points_mm, image_points_px, T_camera_board)
    if bent:
        flags.append(bend_flag(bent, len(names), camera.model))
    return flags


def _next_view(camera, board: np.ndarray, info, sigma: float, distance: float) -> NextView | None:
    """The candidate photo that lowers the uncertainty most (None when no candidate shows the whole board)."""
    best = None
    candidates = [c for d in (0.7 * distance, distance) for c in _candidates(camera, board, d)]
    printed = _printed_points(board)  # once for every candidate
    for T, where, tilt in candidates:
        if not _in_picture(camera, printed, T):
            continue
        _, u_after, good_after = _summary(camera, info + _marginal_information(camera, board, T), sigma, distance)
        # first the part of the picture under the threshold, up to 90 %; then the mean square uncertainty
        score = (min(good_after, 0.9), -_nan_stat(np.mean, u_after**2))
        if best is None or score > best[0]:
            best = (
                score,
                NextView(
                    T,
                    where,
                    tilt,
                    float(np.linalg.norm(T[:3, :3] @ board.mean(axis=0) + T[:3, 3])),
                    good_after,
                    _nan_stat(np.median, u_after),
                ),
            )
    return best[1] if best else None


def coach_calibration(calibration, other_sizes: int | None = None) -> CalibrationCoach:
    """:func:`coach` on a :class:`~fidlearn.Calibration`'s own views and RMS.

    Parameters
    ----------
    calibration : Calibration
        The result of :func:`fidlearn.calibrate_checkerboard` or :func:`fidlearn.calibrate_charuco`.
    other_sizes : int, optional
        Photos left out for another resolution; by default counted from the calibration's views.

    Returns
    -------
    CalibrationCoach
        The verdict, with the corner noise taken from the calibration's RMS (per axis).

    Raises
    ------
    CalibrationError
        If ``calibration`` is not a Calibration, or as :func:`coach`.
    """
    from ..calibration import Calibration

    if not isinstance(calibration, Calibration):
        raise CalibrationError(
            f"calibration must be a fidlearn Calibration (from calibrate_checkerboard or calibrate_charuco), "
            f"got {type(calibration).__name__}"
        )
    if other_sizes is None:
        other_sizes = sum(1 for v in calibration.views if v.status == "other size")
    # OpenCV's RMS is over the 2D distance of each point: per axis it is RMS / sqrt(2)
    return coach(
        calibration.camera,
        calibration.board_points_mm,
        calibration.image_points_px,
        calibration.T_camera_board,
        corner_sigma_px=max(calibration.rms_px / math.sqrt(2), 1e-3),
        other_sizes=other_sizes,
    )
