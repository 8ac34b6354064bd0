"""What the detector delivers: corner noise against marker size, and the smallest marker it finds.

Both models were measured on fidlearn's own renders (``fidlearn.synthetic.render_scene`` with
the bundled scenes' settings: blur 0.5 px, sensor noise 1.2 gray levels, illumination gradient
0.2) with the default ``edges`` corner refinement; ``python benchmarks/bench_planning.py
--noise`` measures the noise table again, and the benchmark checks both against other renders.
A real camera (motion blur, JPEG, a soft print) is noisier, and there the four corners of a
marker also move together (:func:`marker_shift_covariance`) and the markers look a little smaller
or larger than printed: measure all of it on a photo of your own with many markers
(:func:`noise_from_pose`, a :class:`PhotoNoise`) and pass it to ``predict_accuracy``.

The four corners of one marker are not independent: the ``edges`` refinement fits a straight
line to each side and intersects neighbouring lines, so the two corners of a side share that
side's line. :func:`corner_covariance` gives their joint covariance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from ..errors import PoseError
from ._checks import check_number, float_array
from ._corner_lines import line_end_matrix
from ._fisheye_noise import FISHEYE_NOISE_SIDE_PX, FISHEYE_NOISE_SIGMA_PX

#: Apparent marker side (px, mean of the four sides) at which the corner noise was measured ...
NOISE_SIDE_PX = np.array([11, 13, 15, 18, 22, 27, 33, 40, 50, 65, 85, 110, 150, 200], dtype=float)
#: ... and the measured corner noise per axis (px) at that side: the robust sigma (1.4826 times
#: the median absolute error, which ``estimate_pose``'s outlier test makes the relevant one: a
#: corner a pixel off is rejected, not averaged) over every marker detected in 150 rendered rooms
#: (walls of 1 to 12 markers seen from 0.5 to 4 m, 640x480 to 1920x1080; 744 markers, 5 to 126
#: per bin). The RMS is the same from 18 px up and 2 to 3 times larger below, where a few
#: corners land a pixel off.
NOISE_SIGMA_PX = np.array(
    [0.231, 0.099, 0.082, 0.082, 0.071, 0.079, 0.069, 0.050, 0.041, 0.032, 0.034, 0.031, 0.023, 0.023]
)

#: The decoder needs about 1.2 px per cell of a 7-cell marker: below this perimeter (px) it
#: fails whatever the image size (measured: half of the face-on markers found at 8.4 px sides,
#: 640x480, six rolls per distance).
DECODE_MIN_PERIMETER_PX = 34.0
#: OpenCV's ``minMarkerPerimeterRate`` default: candidates whose contour is shorter than this
#: fraction of the image's larger side are dropped before decoding ...
PERIMETER_RATE = 0.03
#: ... measured on the marker's outer edge, which is longer than the thresholded contour
#: OpenCV measures: half of the markers are found at 1.14 times the rule's perimeter
#: (1280x720: 11.5 px sides, 1920x1080: 16.5 px).
PERIMETER_RULE_SLACK = 1.14
#: A marker seen obliquely is lost when its shortest side gets below this (px): 30 px markers
#: were found up to 70 deg off their axis (10 px short sides) and lost at 74 deg (8 px);
#: 60 px markers came and went between 74 and 82 deg (17 to 8 px).
MIN_SHORT_SIDE_PX = 9.0
#: The largest angle (deg) between a marker's normal and the line of sight at which it was
#: measured to be found (120 px markers at 82 deg); beyond it, a marker counts as lost.
MAX_VIEW_ANGLE_DEG = 82.0


#: Variance of a side's fitted line at its two ends, in units of the variance of the line's mean
#: offset: a line fitted to points spread evenly along the side is known 1 at its middle, its
#: slope puts ``3`` more at either end, with opposite signs (ends at +/- L/2 of points spread over L).
LINE_END_COVARIANCE = np.array([[4.0, -2.0], [-2.0, 4.0]])


def corner_sigma_px(side_px: float | np.ndarray, model: str = "pinhole") -> float | np.ndarray:
    """Predicted RMS corner error per axis (px) of a marker whose sides measure ``side_px``.

    Linear interpolation of the measured table (:data:`NOISE_SIDE_PX`,
    :data:`NOISE_SIGMA_PX`; a fisheye's :data:`FISHEYE_NOISE_SIDE_PX`, :data:`FISHEYE_NOISE_SIGMA_PX`, the noise
    of its sides' lines alone, beside which its outline moves as one, :mod:`._fisheye_noise`), held constant
    outside it.

    Parameters
    ----------
    side_px : float or ndarray
        Apparent marker side (px, mean of the four sides).
    model : {"pinhole", "fisheye"}
        The camera's lens model (:attr:`fidlearn.Camera.model`).

    Returns
    -------
    float or ndarray
        Corner noise per axis (px), the shape of ``side_px``.

    Examples
    --------
    >>> round(float(corner_sigma_px(50.0)), 3), round(float(corner_sigma_px(50.0, "fisheye")), 3)
    (0.041, 0.021)

    Raises
    ------
    PoseError
        If ``side_px`` is not a number or an array of numbers, or holds NaN, or ``model`` is not a lens model.
    """
    if model not in ("pinhole", "fisheye"):
        raise PoseError(f"model must be 'pinhole' or 'fisheye', got {model!r:.40}")
    try:
        side = np.asarray(side_px, dtype=float)
    except (TypeError, ValueError, OverflowError):
        side = None
    if side is None or np.isnan(side).any() or side.size > 10_000_000:
        raise PoseError(f"side_px must be a number of pixels (or an array of them, no NaN), got {side_px!r:.80}")
    table = (FISHEYE_NOISE_SIDE_PX, FISHEYE_NOISE_SIGMA_PX) if model == "fisheye" else (NOISE_SIDE_PX, NOISE_SIGMA_PX)
    out = np.interp(side, *table)
    return float(out) if out.ndim == 0 and not isinstance(side_px, np.ndarray) else out


def min_perimeter_px(image_size: tuple[int, int]) -> float:
    """The smallest marker perimeter (px) the default detector finds in a picture of ``image_size``.

    Parameters
    ----------
    image_size : (int, int)
        Width and height of the picture (px).

    Returns
    -------
    float
        The perimeter (px) below which markers are lost: the decoder's own limit or OpenCV's
        ``minMarkerPerimeterRate`` rule, whichever is larger.

    Examples
    --------
    >>> round(min_perimeter_px((1920, 1080)), 1)
    65.7
    >>> min_perimeter_px((640, 480))
    34.0

    Raises
    ------
    PoseError
        If ``image_size`` is not two positive numbers of pixels (up to 1e6).
    """
    w: object
    h: object
    try:
        w, h = image_size
    except (TypeError, ValueError):
        w = h = None
    for v in (w, h):
        check_number(v, "image_size (width, height)", 1, 1e6, PoseError, " px")
    return max(DECODE_MIN_PERIMETER_PX, PERIMETER_RATE * PERIMETER_RULE_SLACK * max(image_size))


def corner_covariance(corners_px: np.ndarray, corner_sigma_px: float, side_variance=None) -> np.ndarray:
    """Joint covariance of one marker's four corners, as the ``edges`` refinement makes them.

    Each side's line is fitted to edge points spread along it: its mean offset has a variance
    ``v`` and its slope moves the side's two ends by ``+/-`` a further ``3 v``
    (:data:`LINE_END_COVARIANCE`); a corner is where its two sides' lines meet. Two corners of
    one side therefore move against each other along that side's normal (correlation -0.5 on a
    square) and the marker's centre is known twice as well (in variance) as four independent
    corners of the same noise would make it; its scale too, its rotation worse. ``v`` is set so
    that the mean variance of the eight coordinates is ``corner_sigma_px ** 2``, the per-axis corner
    noise of :func:`corner_sigma_px`. Measured on the renders of the noise table (667 markers of
    15 px or more): the centre has 0.6, the scale 0.5 and the rotation 1.4 times the variance of
    independent corners; this model says 0.5, 0.5 and 1.5.

    Parameters
    ----------
    corners_px : array-like, shape (4, 2)
        The marker's corners in the picture (px), in order around it (TL, TR, BR, BL).
    corner_sigma_px : float
        Corner noise per axis (px).
    side_variance : array-like, shape (4,), optional
        Each side's line variance (side ``k`` from corner ``k`` to ``k + 1``) against a side at 1, whose marker's
        corner noise ``corner_sigma_px`` is; all alike by default (a fisheye's: :mod:`._fisheye_noise`).

    Returns
    -------
    ndarray, shape (8, 8)
        Covariance of ``[x0, y0, x1, y1, x2, y2, x3, y3]`` (px^2).

    Examples
    --------
    >>> C = corner_covariance([[0, 0], [10, 0], [10, 10], [0, 10]], 0.1)
    >>> round(float(C[1, 3] / C[1, 1]), 2)  # y of the top corners: one line, opposite ends
    -0.5
    >>> centre_x = np.tile([0.25, 0.0], 4)
    >>> round(float(centre_x @ C @ centre_x / (0.1**2 / 4)), 2)  # against independent corners
    0.5

    Raises
    ------
    PoseError
        If ``corners_px`` is not four finite (x, y) pixels or ``corner_sigma_px`` not a number of pixels from 0 to 1e6.
    """
    q = float_array(corners_px, "corners_px", (4, 2), PoseError)
    corner_sigma_px = check_number(corner_sigma_px, "corner_sigma_px", 0.0, 1e6, PoseError, " px")
    S = np.kron(np.eye(4), LINE_END_COVARIANCE)
    try:
        Mi = np.linalg.inv(line_end_matrix(q))
    except np.linalg.LinAlgError:  # a degenerate quad: no line model, independent corners
        return float(corner_sigma_px) ** 2 * np.eye(8)
    C = Mi @ S @ Mi.T
    scale = 8.0 * float(corner_sigma_px) ** 2 / np.trace(C)
    if side_variance is not None:
        C = Mi @ np.kron(np.diag(np.asarray(side_variance, dtype=float)), LINE_END_COVARIANCE) @ Mi.T
    return (C + C.T) / 2 * scale


def marker_shift_covariance(shift_px: float) -> np.ndarray:
    """Covariance (8, 8) of a marker's corners that all move by one common shift of ``shift_px`` per axis.

    On real photos the corners of one marker also move together, by more than the ``edges``
    refinement's own noise (:func:`corner_covariance`) makes them: a marker printed or stuck a
    little off its mapped place, a paper not quite flat, or the picture's blur, shading and
    compression pulling its outline one way. To the pose that is a shift of the whole marker, and
    it does not average down over the corners of that marker. Measured on OpenCV's ChArUco photos
    against each photo's pose from its chessboard corners (``benchmarks/planning_real.py``): the
    variance of a marker's centre is 1.3 (x) and 2.7 (y) times the mean variance of its corners,
    where :func:`corner_covariance` alone says 0.5; the rotation and shape of the marker vary
    0.3 to 0.5 times it, where that says 1.1 to 1.5.

    Parameters
    ----------
    shift_px : float
        Standard deviation of the common shift per axis (px).

    Returns
    -------
    ndarray, shape (8, 8)
        Covariance of ``[x0, y0, x1, y1, x2, y2, x3, y3]`` (px^2).

    Examples
    --------
    >>> C = marker_shift_covariance(0.2)
    >>> round(float(C[0, 6]), 3), float(C[0, 1])  # x of TL and of BL move together; x and y do not
    (0.04, 0.0)

    Raises
    ------
    PoseError
        If ``shift_px`` is not a number of pixels from 0 to 1e6.
    """
    shift_px = check_number(shift_px, "shift_px", 0.0, 1e6, PoseError, " px")
    return float(shift_px) ** 2 * np.kron(np.ones((4, 4)), np.eye(2))


#: Most markers :func:`noise_from_residuals` takes (its matrices grow as their square).
MAX_MARKERS = 200


class PhotoNoise(NamedTuple):
    """What a picture's corners carry beyond the pose, as :func:`noise_from_residuals` measures it.

    The field names are :func:`~fidlearn.planning.predict_accuracy`'s keywords:
    ``predict_accuracy(world, camera, T, **noise.kwargs())``.

    Attributes
    ----------
    corner_sigma_px : float
        Corner noise per axis, as :func:`corner_covariance` takes it (px).
    marker_shift_px : float
        A shift common to the four corners of each marker, independent from marker to marker
        (px per axis; :func:`marker_shift_covariance`).
    marker_size_rel_std_each : float
        Each marker's own apparent size error about its centre, relative (0.01 for 1 %).
    marker_size_rel_error : float
        The apparent size error common to all markers, relative to the map's size (-0.01: the
        markers look 1 % smaller than the map says; blur and gamma eat into a dark border).
    """

    corner_sigma_px: float
    marker_shift_px: float
    marker_size_rel_std_each: float
    marker_size_rel_error: float

    def kwargs(self) -> dict:
        """The four as keyword arguments of :func:`~fidlearn.planning.predict_accuracy`.

        Returns
        -------
        dict
            ``{field name: value}``; :func:`~fidlearn.planning.plan_room` and
            :func:`~fidlearn.planning.suggest_markers` take them too.
        """
        return self._asdict()


def noise_from_residuals(residuals_px, jacobian: np.ndarray, corners_px) -> PhotoNoise:
    """The corner noise, marker shift and marker size errors that explain a pose's residuals.

    The markers' common apparent size error is a seventh parameter of the fit: the residuals are
    regressed on the pose's Jacobian and on every marker's growth about its own centre (``q - c``
    per unit of relative size), and its coefficient is ``marker_size_rel_error``. What remains,
    ``r = (I - H) e`` (``H`` the hat matrix of those seven columns), has the covariance
    ``(I - H) (a C1 + b C2 + c C3) (I - H)^T``: ``C1`` the :func:`corner_covariance` of unit
    noise, ``C2`` the :func:`marker_shift_covariance` of a unit shift and ``C3`` a unit relative
    size error of each marker on its own, marker by marker. Three statistics of ``r`` have
    expectations linear in ``a``, ``b`` and ``c``: the spread of the markers' means, of their
    sizes, and of what is left of each marker's corners (its rotation and shape). Matching them
    (non-negative least squares: a part the residuals do not show is 0) gives ``sigma = sqrt(a)``,
    ``shift = sqrt(b)`` and ``size_each = sqrt(c)``. The fit's own degrees of freedom are
    accounted for, so a pose from many markers (``locate`` on a photo of your own) gives the noise
    to pass to :func:`~fidlearn.planning.predict_accuracy`. Needs at least four markers.

    Telling the three apart matters for one marker: its tilt rests on the rotation and shape of its
    corners, which on real photos vary 2 to 3 times less (in variance) than independent corners of
    the same overall noise would, and 3 times less than :func:`corner_covariance` makes them
    (OpenCV's ChArUco photos, ``benchmarks/planning_real.py --diagnose``).

    Parameters
    ----------
    residuals_px : array-like, shape (M, 4, 2)
        Observed minus reprojected corners of the M markers the pose used (px), TL, TR, BR, BL.
    jacobian : ndarray, shape (8M, 6)
        The corners' pixels against the pose at the solution (:func:`fidlearn.pose.pose_jacobian`),
        rows in the order of ``residuals_px``.
    corners_px : array-like, shape (M, 4, 2)
        The markers' corners in the picture (px).

    Returns
    -------
    PhotoNoise

    Raises
    ------
    PoseError
        Fewer than four markers or more than :data:`MAX_MARKERS`, shapes that do not agree, or NaN or infinity.
    """
    q = float_array(corners_px, "corners_px", (-1, 4, 2), PoseError)
    M = len(q)
    if M > MAX_MARKERS:
        raise PoseError(f"corners_px has {M} markers, more than {MAX_MARKERS}: measure the noise on fewer")
    r = float_array(residuals_px, "residuals_px", (M, 4, 2), PoseError).reshape(-1)
    J = float_array(jacobian, "jacobian", (8 * M, 6), PoseError)
    if M < 4:
        raise PoseError(
            f"need the residuals (M, 4, 2), Jacobian (8M, 6) and corners (M, 4, 2) of at least 4 markers, "
            f"got {r.size // 8} markers, a Jacobian of shape {J.shape} and {M} corner sets"
        )
    grow = (q - q.mean(axis=1, keepdims=True)).reshape(M, 8)  # each marker's corners per unit of relative size
    A7 = np.column_stack([J, grow.ravel()])
    coef = np.linalg.lstsq(A7, r, rcond=None)[0]
    P = np.eye(8 * M) - A7 @ np.linalg.pinv(A7)
    r = P @ r
    C1, C3, size = (np.zeros((8 * M, 8 * M)) for _ in range(3))
    for m in range(M):
        block = slice(8 * m, 8 * m + 8)
        C1[block, block] = corner_covariance(q[m], 1.0)
        C3[block, block] = np.outer(grow[m], grow[m])
        size[block, block] = C3[block, block] / float(grow[m] @ grow[m])
    C2 = np.kron(np.eye(M), marker_shift_covariance(1.0))
    from scipy.optimize import nnls  # scipy loads on first use: ``import fidlearn`` stays quick

    mean = np.kron(np.eye(M), np.kron(np.full((4, 4), 0.25), np.eye(2)))  # each marker's mean, repeated
    stats = [mean, size, np.eye(8 * M) - mean - size]  # quadratic forms: the markers' means, sizes, the rest
    spread = [P @ C @ P for C in (C1, C2, C3)]  # each part's covariance of the residuals
    A = np.array([[float(np.sum(S * R)) for R in spread] for S in stats])  # trace(S R), both symmetric
    a, b, c = nnls(A, np.array([r @ S @ r for S in stats]))[0]
    return PhotoNoise(float(np.sqrt(a)), float(np.sqrt(b)), float(np.sqrt(c)), float(coef[6]))


def noise_from_pose(pose, marker_map, camera) -> PhotoNoise:
    """Corner noise, marker shift and marker size errors of the picture a pose came from.

    :func:`noise_from_residuals` on ``pose.residuals_px`` of the markers the pose used (a fisheye's
    carried from the undistorted pixels back into its picture's, through its projection). Take a
    pose from many markers (ten or more for a shift known to about 20 %) in a picture like the
    ones you will take, and pass the result to :func:`~fidlearn.planning.predict_accuracy`
    (``**noise.kwargs()``).

    Parameters
    ----------
    pose : fidlearn.Pose
        From :func:`fidlearn.estimate_pose` or :func:`fidlearn.locate`, at least four markers used.
    marker_map : MarkerMap
        The map the pose was computed with (world, mm).
    camera : Camera
        The camera the pose was computed with.

    Returns
    -------
    PhotoNoise

    Raises
    ------
    PoseError
        The pose used fewer than four markers, or the arguments are not a Pose, a MarkerMap holding its
        markers and a Camera.
    """
    from ..camera import Camera
    from ..markermap import MarkerMap
    from ..pose import Pose, pose_jacobian

    for value, name, kind in ((pose, "pose", Pose), (marker_map, "marker_map", MarkerMap), (camera, "camera", Camera)):
        if not isinstance(value, kind):
            raise PoseError(f"{name} must be a fidlearn {kind.__name__}, got {type(value).__name__}")
    ids = list(pose.marker_ids)
    if any(i not in marker_map for i in ids):
        raise PoseError(f"the pose used markers {ids}, not all in the map: give the map the pose was computed with")
    if len(ids) < 4:
        raise PoseError(
            f"the pose used {len(ids)} markers; at least 4 markers are needed to tell a shift from the pose"
        )
    P = np.concatenate([marker_map.marker_corners(i) for i in ids])
    residuals = np.array([pose.residuals_px[i] for i in ids])
    projected = camera.project(P, pose.T_world_camera).reshape(-1, 4, 2)
    if camera.model == "fisheye":  # the pose's residuals are in the undistorted pixels: back to the picture's
        ideal = Camera(camera.K, None, camera.image_size).project(P, pose.T_world_camera).reshape(-1, 4, 2)
        seen = np.linalg.solve(camera.K, np.vstack([(ideal + residuals).reshape(-1, 2).T, np.ones(len(P))])).T
        residuals = camera.project(seen, np.eye(4)).reshape(-1, 4, 2) - projected  # each observed corner's ray
    return noise_from_residuals(residuals, pose_jacobian(P, pose.T_world_camera, camera), projected + residuals)


@dataclass
class MeasuredNoise:
    """The noise measured on a photo (:func:`noise_from_photo`) and the pose it was measured with.

    Attributes
    ----------
    noise : PhotoNoise
        The corner noise, marker shift and marker size errors.
    pose : fidlearn.Pose
        The photo's pose, from every marker of the map in it.
    """

    noise: PhotoNoise
    pose: Any

    def kwargs(self) -> dict:
        """The noise as keyword arguments of :func:`~fidlearn.planning.predict_accuracy` (:meth:`PhotoNoise.kwargs`).

        Returns
        -------
        dict
            ``{field name: value}``, as :func:`~fidlearn.planning.plan_room` takes them too.
        """
        return self.noise.kwargs()


def noise_from_photo(image: np.ndarray, marker_map, camera) -> MeasuredNoise:
    """Corner noise, marker shift and marker size errors measured on one photo of the map's markers.

    The photo's markers are detected (the map's dictionary), its pose estimated
    (:func:`fidlearn.estimate_pose`) and :func:`noise_from_pose` measures what its residuals hold.
    Take the photo as the ones you will take (same camera, distance, light), with many markers in it.

    Parameters
    ----------
    image : ndarray
        The photo (gray or BGR; :func:`fidlearn.images.load_image` reads a file), at the resolution
        the camera was calibrated at.
    marker_map : MarkerMap
        The world map (mm).
    camera : Camera
        The camera the photo was taken with.

    Returns
    -------
    MeasuredNoise
        The noise (``.noise``; ``.kwargs()`` for :func:`~fidlearn.planning.plan_room`) and the pose.

    Raises
    ------
    CameraError
        The photo has another size than the camera's calibration.
    NoMarkersError
        No marker of the map is in the photo.
    PoseError
        Fewer than four markers gave the pose, or the corners give no pose.
    ImageError
        ``image`` is not an image.

    Examples
    --------
    OpenCV's ChArUco photo and its published camera: the markers look 1.3 % smaller than printed.

    >>> import fidlearn
    >>> from fidlearn.images import load_image
    >>> real = fidlearn.data_path("real", "opencv_charuco")
    >>> cam = fidlearn.Camera.load(real / "tutorial_camera_charuco.yml", image_size=(640, 480))
    >>> board = fidlearn.MarkerMap.load(real / "board_map.json")
    >>> measured = noise_from_photo(load_image(real / "img_00.jpg"), board, cam)
    >>> len(measured.pose.marker_ids), round(100 * measured.noise.marker_size_rel_error, 1)
    (17, -1.3)
    """
    from ..camera import Camera
    from ..detection import detect_markers
    from ..errors import CameraError, ImageError
    from ..markermap import MarkerMap
    from ..pose import estimate_pose

    for value, name, kind in ((marker_map, "marker_map", MarkerMap), (camera, "camera", Camera)):
        if not isinstance(value, kind):
            raise PoseError(f"{name} must be a fidlearn {kind.__name__}, got {type(value).__name__}")
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.size == 0:
        raise ImageError(f"image must be a picture (a numpy array, H x W or H x W x 3), got {type(image).__name__}")
    size = (image.shape[1], image.shape[0])
    if size != camera.image_size:
        raise CameraError(
            f"the photo is {size[0]}x{size[1]} and the camera {camera.image_size[0]}x{camera.image_size[1]}; "
            "take it at the resolution the camera was calibrated at"
        )
    pose = estimate_pose(detect_markers(image, marker_map.dictionary), marker_map, camera)
    return MeasuredNoise(noise_from_pose(pose, marker_map, camera), pose)
