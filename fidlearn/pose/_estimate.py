"""estimate_pose: the camera's pose in the world from detected markers, in named steps."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..detection import Detection
from ..errors import NoMarkersError, PoseError
from ..markermap import MarkerMap
from ._checks import _check_quads, _cheirality
from ._chess import _with_chess
from ._inputs import (
    _check_inputs_lens,
    _check_options,
    _chess_pairs,
    _lens_covariance,
    _lens_jacobians,
    _lens_refine,
    _lens_sse,
    _rim_markers,
)
from ._noise import _calibration_covariance, _NoiseParts
from ._noise_fast import _noise_parts_fast as _noise_parts  # the same numbers in closed forms
from ._noise_fast import _pose_covariance_fast
from ._observations import _Candidate, _make_obs, _Obs, _side_px, _world
from ._outliers import _reject_outliers
from ._refine import _residuals, _residuals_and_jacobians, pose_jacobian
from ._result import Pose
from ._solvers import _solve
from ._stats import (
    AMBIGUITY_CHI2,
    AMBIGUITY_MAX_SIGMA_PX,
    PRIOR_DOF,
    _alternative_weight,
    _ambiguity_limit,
    _covariance_from,
    _estimated_sigma_inflation,
    _mahalanobis2,
    _relative_rotvec,
    _sigma,
)

__all__ = ["estimate_pose"]

#: A fit whose RMS reprojection error is above ``max(BAD_FIT_MIN_PX, BAD_FIT_REL * s)``,
#: ``s`` the median side of the markers in the image (px), is not returned as a pose: the
#: corners do not fit the map (:class:`PoseError`). Detectors place corners within a pixel or
#: two. Measured (six or three markers, 25-80 px wide): a marker moved by 8-14 cm on a map of
#: 150 mm markers drags the pose and leaves 0.15-0.32 side widths of RMS residual (still a pose,
#: its residuals telling, see ``Pose.marker_rms_px``); positions in the wrong units (mm, cm,
#: inch, foot, metre taken for another) leave 0.47-3.5, a corner order mixed up 0.67-5.
BAD_FIT_REL = 0.4
BAD_FIT_MIN_PX = 5.0


def estimate_pose(
    detections: Sequence[Detection],
    marker_map: MarkerMap,
    camera: Camera,
    method: str = "auto",
    *,
    refine_lm: bool | None = None,
    reject_outliers: bool = True,
    corner_sigma_px: float | None = None,
    board_corners: Mapping[str, tuple] | None = None,
) -> Pose:
    """The camera's pose in the world from detected markers, using every marker the map knows.

    Parameters
    ----------
    detections : list of Detection
        Detected markers (pixel corners TL, TR, BR, BL). Ids not in the map are
        ignored and listed in ``Pose.ignored_ids``. An id detected twice keeps
        its largest detection.
    marker_map : MarkerMap or path
        Where the markers are (world corners, mm). A path (str or
        ``pathlib.Path``) is read with :meth:`MarkerMap.load`.
    camera : Camera or path
        Intrinsics and distortion at the resolution the corners were detected
        at. A path is read with :meth:`Camera.load`.
    method : {"auto", "ippe", "ippe_square", "sqpnp", "iterative", "epnp"}
        ``"auto"`` (default) chooses by the data: ``ippe_square`` for one marker,
        ``ippe`` for coplanar corners (both solutions kept), ``sqpnp`` for
        markers on several planes, always followed by Levenberg-Marquardt on the
        reprojection error. A named method runs that OpenCV solver alone (no
        LM unless ``refine_lm=True``) so solvers can be compared; ``"iterative"``
        is OpenCV's own LM from a DLT/homography start.
    refine_lm : bool, optional
        Refine with Levenberg-Marquardt on the reprojection error (fidlearn's
        own, :func:`refine_pose_lm`: it minimises what ``cv2.solvePnPRefineLM``
        does but runs to the optimum on far, poorly conditioned views).
        Default: True for ``"auto"``, False for a named method.
    reject_outliers : bool
        With 3 or more markers, leave out a marker that disagrees with the
        others (a marker measured wrongly on the wall) and list it in
        ``Pose.rejected_ids``. First a screen that fires on pure noise with
        probability ``SCREEN_P`` (1 %), computed from the one fit of all markers,
        of two tests: a marker moved in its own plane (the way a marker is
        misplaced on a wall: 2 degrees of freedom, chi-square(2) or 2 F(2, nu),
        at ``DISPLACEMENT_P`` = 0.2 % per frame), and any misfit (the chi-square
        of the whole fit when ``corner_sigma_px`` is given, else each marker's
        share of the sum of squares that leaving it out would remove: a Beta,
        i.e. F, test free of the unknown noise). A fit of all leaving more than
        ``OUTLIER_POOR_FIT_PX`` RMS is tested whatever the screen says. A marker
        whose move passes and explains more than ``DISPLACEMENT_MIN_RMS_PX`` RMS
        is rejected when the others, solved afresh without it (as if only they
        had been seen: both planar solutions, refined), agree. Otherwise each
        marker is left out in turn (the 3 likeliest beyond 8 markers) and the
        others solved afresh; the marker whose move passes is still rejected
        unless leaving out another explains the others clearly better (by more
        than the limit below). Else the marker whose absence explains the others best is
        rejected when its residual, predicted from the pose of the others
        (solved without it), fails the nested-model test at
        ``OUTLIER_P`` (chi-square with 8 degrees of freedom when
        ``corner_sigma_px`` is given, else F(8, nu) with the noise estimated from
        the others) and its RMS is above ``OUTLIER_MIN_RMS_PX``. A marker so named
        is still kept when its misfit is what a bent board or a model error does
        (small, shared): under ``MODEL_ERROR_REL`` (a tenth) of its side, or
        (with 4 other markers or more) no larger than the others' own shifts and
        size errors, measured from their residuals, make likely.
        With 2 markers nobody can tell which is wrong: nothing is rejected, but
        ``Pose.marker_rms_px`` shows the disagreement.
        Whatever this option, a fisheye's marker with a corner so near 90
        degrees off the axis that a one-pixel error in the picture bends its
        ideal pinhole pixel as much as it moves it (``RIM_PICTURE_PX``; 89.8
        degrees for an equidistant lens of 286 px per radian) is left out
        before the solve and listed in ``Pose.rejected_ids``, unless no
        other marker is left (:func:`~._inputs._rim_markers`); one with a
        corner at 90 degrees or more always is (it has no pinhole picture).
    corner_sigma_px : float, optional
        Standard deviation (px, per coordinate) of the corner noise. If None it
        is estimated from the residuals with ``2N - 6`` degrees of freedom,
        blended with a prior of ``PRIOR_SIGMA_PX`` worth ``PRIOR_DOF`` degrees of
        freedom (so one marker's 2 degrees of freedom do not claim a perfect
        fit), and never below ``MIN_SIGMA_PX``. The covariance measures more than
        this from the residuals (each marker's shift and size error too) and is
        widened for the uncertainty of those estimates (see :attr:`Pose.covariance`).
    board_corners : mapping of str to (ids, corners_px), optional
        Chess corners of the map's ChArUco board entries, by entry name: ids (N,) on the board and pixels
        (N, 2), as OpenCV's ChArUco interpolation gives them (:func:`locate` finds them). They join the
        marker corners with their own noise, measured from their residuals (:mod:`fidlearn.pose._chess`);
        the pose's ``method`` then ends in ``"+chess"``. Pinhole cameras only (a fisheye's are not used).

    Returns
    -------
    Pose
        ``Pose.ambiguous`` is True when the second planar solution's extra sum
        of squared residuals is below ``AMBIGUITY_CHI2 * sigma^2`` with
        ``corner_sigma_px`` given: the likelihood ratio of the two poses is
        then above ``exp(-9/2)`` and the corners cannot rule out the
        alternative. With sigma estimated from ``nu = 2N - 6 + PRIOR_DOF``
        degrees of freedom the limit is ``F(1, nu; 0.9973) * sigma^2`` (the
        same level, allowing for the estimate: 44 sigma^2 for one marker, 12
        for three, 9.8 for eight). Only when the fit is good: a sigma estimated
        from the residuals counts at most ``AMBIGUITY_MAX_SIGMA_PX`` here
        (larger residuals are a wrong map or camera, not noise, and make no
        second pose "as good"; the limit is then the chi-square one).

    Raises
    ------
    NoMarkersError
        No detected marker is in the map.
    PoseError
        Bad inputs; a marker whose image corners are not a convex
        quadrilateral running clockwise on screen (TL, TR, BR, BL as detection
        reports them: collinear, repeated, mirrored or shuffled corners); no
        pose that sees every used marker from its printed side with every
        corner in front of the camera (a marker turned the wrong way in the
        map); a best fit whose RMS reprojection error is above
        ``max(BAD_FIT_MIN_PX, BAD_FIT_REL * median marker side in px)`` (the
        corners do not fit the map: wrong positions, rotations, units, marker
        size or camera); or a named method that cannot solve this data.

    A missing pose is never returned as None: :func:`locate` and
    :meth:`fidlearn.MarkerTracker.locate` raise the same errors.

    Examples
    --------
    Corners projected from a known pose, with 0.3 px of noise:

    >>> import numpy as np, fidlearn
    >>> from fidlearn.detection import Detection
    >>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    >>> cam = fidlearn.Camera.from_fov(60, (640, 480))
    >>> T_world_camera = fidlearn.make_transform(fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])
    >>> rng = np.random.default_rng(1)
    >>> dets = [Detection(i, cam.project(c, T_world_camera) + rng.normal(0, 0.3, (4, 2)))
    ...         for i, c in m.corners().items()]
    >>> pose = estimate_pose(dets, m, cam, corner_sigma_px=0.3)
    >>> pose.marker_ids, pose.method
    ((0, 1, 2), 'ippe+lm')
    >>> pose.position_ellipsoid_contains(T_world_camera[:3, 3])   # the truth is inside the 95 % ellipsoid
    True
    """
    dets, marker_map, camera, lens, beyond = _check_inputs_lens(detections, marker_map, camera)
    method = _check_options(method, refine_lm, reject_outliers, corner_sigma_px)
    if refine_lm is None:
        refine_lm = method == "auto"
    refine_lm = bool(refine_lm)
    obj_c, img_c = _chess_pairs(board_corners, marker_map)

    # a fisheye's markers with a corner 90 degrees or more off its axis: no pinhole picture (_as_pinhole)
    beyond_keys = list(dict.fromkeys(marker_map.key(d.id, d.dictionary) for d in beyond))
    past = sorted(k for k in beyond_keys if k in marker_map)
    if past and not any(marker_map.key(d.id, d.dictionary) in marker_map for d in dets):
        raise PoseError(
            f"markers {past} have a corner 90 degrees or more off the fisheye's axis, where a pose cannot use them, "
            "and no other marker of the map is in the detections; turn the camera towards the markers"
        )
    corners_px, ignored = _known_corners(dets, marker_map)
    ignored += [k for k in beyond_keys if k not in marker_map and k not in ignored]
    world, faces = _world(marker_map)
    # and those at the rim, whose ideal pixels the pinhole stage cannot read (RIM_PICTURE_PX)
    rejected = sorted(set(past) | set(_rim_markers(corners_px, lens))) if lens is not None else []
    obs = _make_obs(sorted(k for k in corners_px if k not in rejected), corners_px, world, faces)
    _check_quads(obs.ids, obs.img)
    cands, unrefined, method_used = _solve(obs, marker_map, camera, method, refine_lm)
    if reject_outliers and len(obs.ids) >= 3:
        obs, cands, unrefined, screened = _reject_outliers(
            obs, marker_map, camera, method, refine_lm, corner_sigma_px, cands, unrefined
        )
        rejected += screened
    _check_fit(obs, cands[0])
    data = _Data(obs, camera, world, corners_px, ignored, rejected, corner_sigma_px)
    if lens is not None:  # a fisheye's corners, undistorted: their noise is wider near the edge
        data.lens_D = _lens_jacobians(lens, obs.img)
        cands[0] = _weighted(data, cands[0])
    pose = _pose_from(data, cands, unrefined, method_used)
    return pose if lens is not None else _with_chess(pose, obs.obj, obs.img, camera, obj_c, img_c)


def _known_corners(dets: list[Detection], marker_map: MarkerMap) -> tuple[dict[int, np.ndarray], list[int]]:
    """The corners (4, 2), px, of each detected map marker (its largest detection), and the ids not in the map.

    Raises :class:`NoMarkersError` when no detected marker is in the map.
    """
    corners_px: dict[int, np.ndarray] = {}
    ignored: list[int] = []
    for d in dets:
        # a marker is (dictionary, id); a Detection's id is a checked int, its own key in the map's dictionary
        key = d.id if d.dictionary is None else marker_map.key(d.id, d.dictionary)
        if key not in marker_map:
            if key not in ignored:
                ignored.append(key)
            continue
        if key in corners_px and corners_px[key] is not None:
            prev = Detection(d.id, corners_px[key])
            if prev.side_px >= d.side_px:
                continue
        corners_px[key] = d.corners_px
    if not corners_px:
        raise _no_markers_error(dets, marker_map)
    return corners_px, ignored


def _no_markers_error(dets: list[Detection], marker_map: MarkerMap) -> NoMarkersError:
    """The error for detections none of which is in the map: what was seen, what the map holds, what to check."""
    seen = sorted({d.id for d in dets})
    what = f"the image shows markers {seen}, none of which is in the map" if seen else "no marker was detected"
    return NoMarkersError(
        f"{what}; the map ({marker_map.source}) has ids {marker_map.ids} in dictionary "
        f"{' and '.join(marker_map.dictionaries)}. Check that the printed markers come from "
        f"{' and '.join(marker_map.dictionaries)} "
        "(detect with the map's dictionary), that the map lists the ids on the wall, and that the "
        "markers are in view, in focus and large enough"
    )


def _check_fit(obs: _Obs, best: _Candidate) -> None:
    """Raise :class:`PoseError` when the best pose fits too badly, or is none a camera can have.

    ``best`` breaks :func:`_cheirality` only when every candidate does (``_solve`` puts the others
    first). The fit is too bad when its RMS reprojection error is above ``max(BAD_FIT_MIN_PX,
    BAD_FIT_REL * median marker side in px)``.
    """
    problem = _cheirality(obs, best)
    rms = math.sqrt(best.sse / len(obs.obj))
    side = float(np.median(_side_px(obs.img))) if rms > BAD_FIT_MIN_PX else 0.0  # the limit is at least the floor
    if rms > max(BAD_FIT_MIN_PX, BAD_FIT_REL * side):
        what = (
            f"reprojection error {rms:.1f} px for markers {obs.ids}, which are about {side:.0f} px wide in the "
            "image (a pose that fits leaves a pixel or two); check the map's positions and rotations, the marker "
            "size, the units, the corner order (TL, TR, BR, BL) and the camera file"
        )
        note = f" ({best.problem_short})" if problem is not None else ""
        raise PoseError(f"the corners do not fit the map: {what}{note}")
    if problem is not None:
        raise PoseError(problem)


@dataclass
class _Data:
    """What every :class:`Pose` of one estimate shares: the data, then (from :func:`_pose_from`) noise and flip."""

    obs: _Obs
    camera: Camera
    world: dict[int, np.ndarray]  # the map's corners (4, 3), mm, by id
    corners_px: dict[int, np.ndarray]  # the detected corners (4, 2), px, by id
    ignored: list[int]
    rejected: list[int]
    corner_sigma_px: float | None
    dof: int = 0  # 2N - 6
    sigma: float = 0.0  # the corner noise of the covariance, px
    sigma_amb: float = 0.0  # the corner noise of the ambiguity test, px
    nu_amb: float | None = None  # its degrees of freedom (None: given, or capped at AMBIGUITY_MAX_SIGMA_PX)
    alt: _Candidate | None = None  # the other planar solution, when it is distinct
    ambiguous: bool = False
    noise: _NoiseParts | None = None  # what the best pose's residuals hold: the noise of every pose's covariance
    noise_J: np.ndarray | None = None  # the Jacobian (2N, 6) it was measured at (its sums are noise.sums)
    lens_D: np.ndarray | None = None  # a fisheye's d(picture px) / d(ideal px) (N, 2, 2) at the corners
    weighted: _Candidate | None = None  # the candidate refined with those weights (:func:`_weighted`)
    weighted_J: np.ndarray | None = None  # its weighted Jacobian (2N, 6)


def _pose_from(data: _Data, cands: list[_Candidate], unrefined: list[_Candidate], method_used: str) -> Pose:
    """The :class:`Pose` of the best candidate, with its noise, covariance and alternative."""
    obs, camera, best = data.obs, data.camera, cands[0]
    if best.J is not None and best.r is not None:  # a fisheye's weighted fit computed them there
        r0, J0 = best.r, best.J
    else:
        r0, J0 = _residuals(obs.obj, obs.img, camera.K, camera.dist, best.R_wc, best.C, True)
    if best.r is None:
        best.r, best.sse = r0, float(r0 @ r0)
    JtJ0 = best.JtJ if J0 is best.J else None  # LM's J^T J of that same Jacobian
    data.noise = _noise_parts(r0, J0, obs.img.reshape(-1, 4, 2), data.corner_sigma_px, JtJ0)
    data.noise_J = J0
    data.dof = 2 * len(obs.obj) - 6
    data.sigma = _sigma(_picture_sse(data, cands[0]), data.dof, data.corner_sigma_px)
    # The ambiguity test's noise: residuals far above any detector's noise are a wrong map or
    # camera, not noise, and must not make a poorer second pose look "as good" (nor hide the
    # first pose's misfit behind it).
    data.sigma_amb = data.sigma if data.corner_sigma_px is not None else min(data.sigma, AMBIGUITY_MAX_SIGMA_PX)
    JtJ = cands[0].JtJ if cands[0].JtJ is not None else J0.T @ J0
    alt = data.alt = _alternative(obs, cands, unrefined, JtJ, data.sigma_amb)
    # sigma estimated (not given, nor capped): its uncertainty widens the test (F instead of chi-square)
    estimated = data.corner_sigma_px is None and data.sigma < AMBIGUITY_MAX_SIGMA_PX
    nu = data.nu_amb = data.dof + PRIOR_DOF if estimated else None
    data.ambiguous = alt is not None and (alt.sse - cands[0].sse) < _ambiguity_limit(nu) * data.sigma_amb**2
    alt_how = method_used if alt is not None and alt.refined else method_used.replace("+lm", "") + " (not refined)"
    if alt is None:
        return _build(data, cands[0], None, method_used)
    if data.ambiguous:  # its covariance enters this pose's
        return _build(data, cands[0], _build(data, alt, None, alt_how), method_used)
    return _build(data, cands[0], lambda: _build(data, alt, None, alt_how), method_used)


def _weighted(data: _Data, c: _Candidate) -> _Candidate:
    """Candidate ``c`` refined to fit the fisheye's picture pixels (:func:`~._inputs._lens_refine`)."""
    obs, camera = data.obs, data.camera
    assert data.lens_D is not None, "set for a fisheye before the weighted fit"
    start = (c.r, c.J) if c.r is not None and c.J is not None else None  # a fit's own, at c's pose
    R_wc, C, data.weighted_J, r, J = _lens_refine(obs.obj, obs.img, camera, data.lens_D, c.R_wc, c.C, start)
    data.weighted = _Candidate(R_wc, C, float(r @ r), r, refined=c.refined, JtJ=J.T @ J, J=J)
    return data.weighted


def _picture_sse(data: _Data, c: _Candidate) -> float:
    """Candidate ``c``'s sum of squared residuals in the picture's pixels (a fisheye's, not the ideal ones)."""
    if data.lens_D is None:
        return c.sse
    if c.r is None:
        c.r, _ = _residuals(data.obs.obj, data.obs.img, data.camera.K, data.camera.dist, c.R_wc, c.C, False)
        c.sse = float(c.r @ c.r)
    return _lens_sse(data.lens_D, c.r)


def _alternative(
    obs: _Obs, cands: list[_Candidate], unrefined: list[_Candidate], JtJ: np.ndarray, sigma_amb: float
) -> _Candidate | None:
    """The other planar solution (the "flip"), or None when no candidate is distinct from the best.

    Refined, when LM keeps it apart as a second minimum; else as IPPE gave it, when LM ran from it
    into the first one along a flat valley. It counts as another answer when it lies outside the
    3-sigma ellipsoid of the best pose (squared Mahalanobis distance above AMBIGUITY_CHI2); it is
    "as good" (ambiguous) when its extra sum of squared residuals is below AMBIGUITY_CHI2 sigma^2 (F(1, nu)
    sigma^2 with sigma estimated, see :func:`_ambiguity_limit`).
    Near a single quadratic minimum the two numbers are equal, so a merely nearby pose is never
    called ambiguous; both hold only when the error surface is far from quadratic, which is the
    flip. Only a pose a camera can have counts (:func:`_cheirality`).
    """
    alt = next(
        (
            c
            for c in cands[1:]
            if _mahalanobis2(cands[0], c, JtJ, sigma_amb) > AMBIGUITY_CHI2 and _cheirality(obs, c) is None
        ),
        None,
    )
    if alt is None and unrefined is not cands:
        far = [
            c
            for c in unrefined
            if c.sse > cands[0].sse
            and _mahalanobis2(cands[0], c, JtJ, sigma_amb) > AMBIGUITY_CHI2
            and _cheirality(obs, c) is None
        ]
        alt = min(far, key=lambda c: c.sse) if far else None
    return alt


def _build(
    data: _Data,
    c: _Candidate,
    alternative: Pose | Callable[[], Pose] | None,
    how: str,
) -> Pose:
    """The :class:`Pose` of candidate ``c`` (``alternative`` may be a function that builds it on first use)."""
    obs, camera = data.obs, data.camera
    if c.r is None:
        c.r, _ = _residuals(obs.obj, obs.img, camera.K, camera.dist, c.R_wc, c.C, False)
        c.sse = float(c.r @ c.r)
    residuals = dict(zip(obs.ids, c.r.reshape(-1, 4, 2)))  # each marker's (4, 2) view
    for i in data.rejected:
        if i not in data.corners_px:  # a fisheye's marker past 90 degrees: no undistorted corners to compare
            continue
        ri, _ = _residuals(data.world[i], data.corners_px[i], camera.K, camera.dist, c.R_wc, c.C, False)
        residuals[i] = ri.reshape(4, 2)
    return Pose._trusted(
        T_world_camera=c.T_world_camera,
        marker_ids=tuple(obs.ids),
        residuals_px=dict(sorted(residuals.items())) if data.rejected else residuals,  # (obs.ids are sorted)
        reprojection_rms_px=math.sqrt(_picture_sse(data, c) / len(obs.obj)),  # a fisheye: in its picture
        covariance=_covariance(data, c, alternative),
        corner_sigma_px=data.sigma,
        ambiguous=data.ambiguous,
        alternative=alternative,
        ignored_ids=tuple(data.ignored),
        rejected_ids=tuple(data.rejected),
        method=how,
    )


def _pinhole_covariance(data: _Data, c: _Candidate) -> np.ndarray | None:
    """Candidate ``c``'s covariance from the noise the best pose's residuals hold (:attr:`_Data.noise`), and the
    calibration's own error when the camera has one; None if not determined."""
    obs, camera, noise = data.obs, data.camera, data.noise
    if noise is None:
        return None
    if c.J is not None and c.JtJ is not None and camera.intrinsics_covariance is None:
        J, JtJ, J_k = c.J, c.JtJ, None  # LM's last Jacobian, at this very pose
    else:
        _, J, J_k = _residuals_and_jacobians(obs.obj, obs.img, camera.K, camera.dist, c.R_wc, c.C)
        JtJ = J.T @ J
    sums = noise.sums if J is data.noise_J else None  # at the noise's own Jacobian: its sums and inverse
    cov = _pose_covariance_fast(J, obs.img.reshape(-1, 4, 2), noise, JtJ, sums)
    if cov is not None and camera.intrinsics_covariance is not None and J_k is not None:  # calibration's own error
        cov = cov + _calibration_covariance(J, J_k, camera.intrinsics_covariance)
    return cov


def _covariance(data: _Data, c: _Candidate, alternative: Pose | Callable[[], Pose] | None) -> np.ndarray | None:
    """The covariance (6, 6) of candidate ``c``'s pose (see :attr:`Pose.covariance`); None if not determined."""
    obs, camera = data.obs, data.camera
    if data.lens_D is None:  # the noise each pose's own residuals hold (corner noise, marker shift and size)
        cov = _pinhole_covariance(data, c)
    else:  # a fisheye: corner noise in the picture's pixels, carried through the lens
        if c is data.weighted and data.weighted_J is not None:  # the weighted fit: sigma^2 (J_w^T J_w)^-1
            cov = _covariance_from(data.weighted_J.T @ data.weighted_J, data.sigma)
        else:  # a candidate fitted in ideal pixels alike
            J = c.J if c.J is not None else pose_jacobian(obs.obj, c.T_world_camera, camera)
            cov = _lens_covariance(data.lens_D, J, data.sigma)
        if cov is not None and data.corner_sigma_px is None:
            cov = cov * _estimated_sigma_inflation(data.dof + PRIOR_DOF)
    alt = data.alt
    if (
        data.ambiguous
        and alt is not None
        and isinstance(alternative, Pose)
        and cov is not None
        and alternative.covariance is not None
    ):
        # Two poses explain the corners: report the second moment about this pose of the
        # two-pose mixture, weighted by likelihood (the noise integrated out when estimated: Student's
        # tail), so its ellipsoid reaches the other one.
        w_alt = _alternative_weight(alt.sse - c.sse, data.sigma_amb, data.nu_amb)
        d = np.concatenate((_relative_rotvec(alt.R_wc, c.R_wc), alt.C - c.C))
        cov = (1 - w_alt) * cov + w_alt * (alternative.covariance + np.outer(d, d))
    return cov
