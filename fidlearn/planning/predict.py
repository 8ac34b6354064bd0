"""Predicted accuracy of a pose before any photo is taken.

For a camera at a given pose in a mapped room, :func:`predict_accuracy` says which markers it
would find, how noisy their corners would be, the covariance of the pose that
:func:`fidlearn.estimate_pose` would return, and how likely the planar flip is.

The covariance is first-order error propagation through ``estimate_pose``'s least squares
(every corner weighted alike): ``(J^T J)^-1 J^T S J (J^T J)^-1``, ``J`` the Jacobian of the
corners' pixels with respect to the pose (:func:`fidlearn.pose.pose_jacobian`) and ``S`` the
covariance of the corners, block diagonal by marker (:func:`noise.corner_covariance`: the corners
of one marker share its sides' fitted lines). Four independent corners per marker would
overstate the error of a pose from five or more markers by about 1.3 to 1.4 times (rendered
rooms, 75 scenes per image size): such a pose rests on where each marker is, and a marker's
centre is known twice as well (in variance) as four independent corners of the same noise would
make it. A size error of the printed markers (``marker_size_rel_std``: one scale for all, a printer's;
``marker_size_rel_std_each``: each marker its own) is a nuisance parameter of the same fit: the map's
size is taken as exact, and the pose error that size error induces through the least squares is added.
A size error known to be the same in every photo (``marker_size_rel_error``: real markers look a little
smaller than printed) is a bias, not a spread: the median error is that of the covariance about it.
The median, 90th percentile and RMS of the position error are those of draws (:mod:`.sampling`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import _lens, frames
from ..camera import Camera
from ..errors import FidlearnError, TransformError
from ..markermap import MarkerMap
from ..pose import pose_jacobian
from . import finding, noise, sampling
from ._checks import _check_px, _check_rel
from ._fisheye_noise import edge_offset_px, side_variance
from ._noise_model import covariance_and_bias
from .flip import FLIP_MIN_ANGLE_DEG, _flip, flip_probability

__all__ = ["Prediction", "predict_accuracy", "flip_probability", "FLIP_MIN_ANGLE_DEG"]

#: A prediction says ``flip_likely`` when the wrong planar branch wins in more than this
#: fraction of frames.
FLIP_LIKELY = 0.01


@dataclass(frozen=True, repr=False)
class Prediction:
    """What a camera at ``T_world_camera`` would get from the map, before any photo is taken.

    Attributes
    ----------
    T_world_camera : ndarray, shape (4, 4)
        The camera pose asked about (mm).
    marker_ids : list of int
        The markers it would find: whole in the picture, facing it, seen at most
        :data:`~fidlearn.planning.noise.MAX_VIEW_ANGLE_DEG` off their axis, large enough for
        the detector (:func:`~fidlearn.planning.noise.min_perimeter_px`,
        :data:`~fidlearn.planning.noise.MIN_SHORT_SIDE_PX`).
    side_px : dict of int to float
        Each found marker's mean apparent side (px).
    corner_sigma_px : dict of int to float
        The corner noise assumed for each (px per axis).
    covariance : ndarray, shape (6, 6), or None
        The predicted covariance of the pose, in the coordinates of
        :attr:`fidlearn.Pose.covariance`: ``[a small rotation in world axes (rad), the camera
        centre (mm)]``, propagated from the corner noise of :func:`noise.corner_covariance`
        through ``estimate_pose``'s least squares. None when no pose is possible.
    position_std_mm : ndarray, shape (3,)
        Standard deviation of the camera centre along world X, Y, Z (mm); inf without a pose.
    position_error_mm : float
        Predicted median distance between the estimated and the true camera centre (mm), the
        systematic part ``position_bias_mm``, the planar flip (``flip_probability``) and the markers
        the detector may miss (``found_probability``) included; given that a pose is found.
    flip_probability : float
        Chance that the other planar solution fits the corners better (0 when the markers are
        not coplanar or seen obliquely enough), over the subsets of markers that may be found.
    flip_likely : bool
        ``flip_probability > FLIP_LIKELY``: expect ``Pose.ambiguous`` and an occasional flip.
    reason : str
        Why no pose is possible, or ``""``.
    lost : dict of int to str
        Why each marker of the map that is not found is not.
    position_bias_mm : ndarray, shape (3,)
        The systematic error of the camera centre (mm) that a known size error of the markers
        (``marker_size_rel_error``) causes; ``covariance`` is the spread about it.
    position_p90_mm : float
        Predicted 90th percentile of the distance between the estimated and the true camera centre
        (mm): nine poses in ten are at least this close. Its tail is that of the solutions, not of the
        linearization (:mod:`~fidlearn.planning.sampling` where the rotation is poorly known) and holds
        the planar flip (``flip_probability``); inf without a pose.
    position_rms_mm : float
        Predicted root mean square of that distance (mm), likewise; inf without a pose.
    found_probability : dict of int to float
        Each of ``marker_ids``' chance of being found (:func:`~fidlearn.planning.finding.found_probability`):
        markers near the detector's limit are missed now and then, and the pose from those that are
        left is worse (a single one may flip). The median, 90th percentile and RMS are over the
        subsets that may be found (:func:`~fidlearn.planning.finding.found_subsets`); ``covariance`` and
        ``position_std_mm`` are those of a pose from all of ``marker_ids``.
    pose_probability : float
        Chance that at least one marker is found, and so that there is a pose at all.
    """

    T_world_camera: np.ndarray
    marker_ids: list[int]
    side_px: dict[int, float]
    corner_sigma_px: dict[int, float]
    covariance: np.ndarray | None
    position_std_mm: np.ndarray
    position_error_mm: float
    flip_probability: float
    reason: str = ""
    lost: dict[int, str] = field(default_factory=dict)
    position_bias_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    position_p90_mm: float = math.inf
    position_rms_mm: float = math.inf
    found_probability: dict[int, float] = field(default_factory=dict)
    pose_probability: float = 1.0

    @property
    def possible(self) -> bool:
        """Whether a pose can be computed from this place."""
        return self.covariance is not None

    @property
    def flip_likely(self) -> bool:
        return self.flip_probability > FLIP_LIKELY

    @property
    def rotation_std_deg(self) -> np.ndarray:
        """Standard deviation of the small rotation about world X, Y, Z (degrees); inf without a pose."""
        if self.covariance is None:
            return np.full(3, np.inf)
        return np.degrees(np.sqrt(np.diag(self.covariance)[:3]))

    def __repr__(self) -> str:
        C = self.T_world_camera[:3, 3]
        where = f"camera at [{C[0]:.0f}, {C[1]:.0f}, {C[2]:.0f}] mm"
        if not self.possible:
            return f"Prediction({where}: no pose, {self.reason})"
        std = ", ".join(f"{s:.1f}" for s in self.position_std_mm)
        flip = f", flip {100 * self.flip_probability:.0f} %" if self.flip_likely else ""
        sides = ", ".join(f"{i}: {self.side_px[i]:.0f} px" for i in self.marker_ids)
        bias = ""
        if np.any(self.position_bias_mm):
            parts = (f"{b:.1f}" for b in self.position_bias_mm)
            bias = ", bias [" + ", ".join("0.0" if t == "-0.0" else t for t in parts) + "] mm"
        return (
            f"Prediction({where}: markers {sides}; position error {self.position_error_mm:.1f} mm "
            f"(median), std [{std}] mm{bias}{flip})"
        )


class _CachedMap:
    """A map's ids, corners and normals, computed once: a plan asks for them at every place and heading."""

    def __init__(self, marker_map: MarkerMap):
        self.ids = marker_map.ids
        self._corners = {i: marker_map.marker_corners(i) for i in self.ids}
        self._normals = {i: marker_map.normal(i) for i in self.ids}

    def marker_corners(self, marker_id: int) -> np.ndarray:
        return self._corners[marker_id]

    def normal(self, marker_id: int) -> np.ndarray:
        return self._normals[marker_id]


def _check_pose(T_world_camera) -> np.ndarray:
    try:
        T = np.asarray(T_world_camera, dtype=float)
    except (TypeError, ValueError):
        raise TransformError("T_world_camera must be a 4x4 pose matrix (mm)") from None
    return frames.check_transform(T, "T_world_camera")


def _seen(marker_map: MarkerMap, camera: Camera, T_world_camera: np.ndarray) -> tuple[dict, dict]:
    """``({id: (4, 2) pixel corners}, {id: why it is not found})`` for every marker of the map."""
    T_camera_world = frames.invert_transform(T_world_camera)
    eye = T_world_camera[:3, 3]
    min_perimeter = noise.min_perimeter_px(camera.image_size)
    cos_max = math.cos(math.radians(noise.MAX_VIEW_ANGLE_DEG))
    seen, lost = {}, {}
    for mid in marker_map.ids:
        c = marker_map.marker_corners(mid)
        pc = c @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
        if np.any(pc[:, 2] <= 1.0):
            lost[mid] = "behind the camera"
            continue
        view = eye - c.mean(axis=0)
        cos_view = float(marker_map.normal(mid) @ view) / float(np.linalg.norm(view))
        if cos_view <= 0:
            lost[mid] = "seen from behind"
            continue
        if cos_view < cos_max:
            lost[mid] = f"seen {math.degrees(math.acos(cos_view)):.0f} deg off its axis"
            continue
        w, h = camera.image_size
        if _beyond_the_lens(pc, camera):
            lost[mid] = "beyond the fisheye's fold" if camera.model == "fisheye" else "outside the picture"
            continue
        px = camera.project(c, T_world_camera)
        if np.any(px < -0.5) or np.any(px[:, 0] > w - 0.5) or np.any(px[:, 1] > h - 0.5):
            lost[mid] = "not whole in the picture"
            continue
        sides = np.linalg.norm(px - np.roll(px, 1, axis=0), axis=1)
        perimeter = float(np.sum(sides))
        if perimeter < min_perimeter:
            lost[mid] = f"too small ({perimeter / 4:.0f} px sides, the detector needs {min_perimeter / 4:.0f})"
            continue
        if float(np.min(sides)) < noise.MIN_SHORT_SIDE_PX:
            lost[mid] = (
                f"seen too obliquely (a side of {np.min(sides):.0f} px, "
                f"the detector needs {noise.MIN_SHORT_SIDE_PX:.0f})"
            )
            continue
        seen[mid] = px
    return seen, lost


def _beyond_the_lens(pc: np.ndarray, camera: Camera) -> bool:
    """Whether points ``pc`` (N, 3) in the camera frame, in front of it, are where the lens model cannot put them in
    the picture: a pinhole's far outside its field of view (the distortion polynomial folds back there), a fisheye's
    beyond its fold (the ray's angle off the axis is not the one its pixel gives back)."""
    w, h = camera.image_size
    if camera.model == "fisheye":
        theta = np.arctan2(np.hypot(pc[:, 0], pc[:, 1]), pc[:, 2])
        px = _lens.project_points(pc, camera.K, camera.dist, "fisheye")
        back = _lens.fisheye_angles(px, camera.K, camera.dist)[0]
        return bool(np.any(~(np.abs(back - theta) < 1e-6)))  # NaN: no ray reaches that pixel
    ideal = pc[:, :2] / pc[:, 2:3] * [camera.fx, camera.fy] + [camera.cx, camera.cy]
    return bool(np.any(ideal < -0.5 * max(w, h)) or np.any(ideal > 1.5 * max(w, h)))


def predict_accuracy(
    marker_map: MarkerMap,
    camera: Camera,
    T_world_camera: np.ndarray,
    *,
    corner_sigma_px: float | None = None,
    marker_shift_px: float = 0.0,
    marker_size_rel_std: float = 0.0,
    marker_size_rel_std_each: float = 0.0,
    marker_size_rel_error: float = 0.0,
) -> Prediction:
    """Predict the pose accuracy a camera at ``T_world_camera`` would get from ``marker_map``.

    Parameters
    ----------
    marker_map : MarkerMap
        Where the markers are (mm, world).
    camera : Camera
        Intrinsics, distortion and image size: OpenCV's pinhole lens or a fisheye (``model="fisheye"``),
        whose markers are seen, sized and weighed as its picture draws them (compressed towards the
        edge), within 90 degrees of its axis (the rays :func:`fidlearn.estimate_pose` can use).
    T_world_camera : ndarray, shape (4, 4)
        The camera pose to ask about (mm, world; camera frame OpenCV's).
    corner_sigma_px : float, optional
        Corner noise (px per axis) for every marker. By default it depends on each marker's
        apparent size, as measured on fidlearn's renders (:func:`noise.corner_sigma_px`; a fisheye's
        own table of its sides' lines, with the outline's offset, the four sides out or in together,
        its spread and its bias, :mod:`fidlearn.planning._fisheye_noise`);
        for real photos give your own camera's, with ``marker_shift_px``, both from a pose of
        your own with many markers (:func:`noise.noise_from_pose`).
        Either way the corners of one marker move together as the ``edges`` refinement makes
        them (:func:`noise.corner_covariance`), and the covariance is that of
        ``estimate_pose``'s unweighted least squares under that noise.
    marker_shift_px : float
        A shift common to the four corners of each marker (px per axis, independent from marker
        to marker; :func:`noise.marker_shift_covariance`), added to the corner noise; 0 (the
        default) as on renders. Real photos have one: on OpenCV's ChArUco photos 0.15 to 0.20 px
        beside 0.10 to 0.36 px of corner noise. It does not average down over a marker's corners,
        so without it the poses from 2 to 17 markers of those photos were predicted about 2 times
        too good (``benchmarks/planning_real.py``). Measure both on a pose of your own from many
        markers (:func:`noise.noise_from_pose`).
    marker_size_rel_std : float
        Standard deviation of the markers' printed size relative to the map's
        ``marker_size_mm``, one factor common to all markers (a printer's scale: 0.01 for 1 %);
        0 (the default) for markers exactly the map's size. ``estimate_pose`` uses the map's size,
        so a marker 1 % larger puts the camera about 1 % of its distance too close; the pose
        error that induces, ``(J^T J)^-1 J^T u`` per unit of relative size (``u`` the corners'
        pixel motion as the markers grow), adds ``v v^T marker_size_rel_std^2`` to the
        covariance. Each marker grows from its top-left corner, the point its placement gives
        (:class:`~fidlearn.MarkerMap`): a printed marker stuck where its top-left corner was
        measured. A marker whose outline only looks smaller (blur and gamma eat into a dark
        border) shrinks about its centre instead; the two differ by a shift of every marker by
        half its size change, which moves the camera by as much (0.14 mm for 1 % of 20 mm).
        A size error you have measured, the same in every photo, is ``marker_size_rel_error``.
    marker_size_rel_std_each : float
        The same for a size error of each marker on its own, independent from marker to marker
        (markers printed one by one); 0 by default. It adds ``u_m u_m^T`` times its square to
        each marker's corner covariance.
    marker_size_rel_error : float
        A size error known to be common to all markers (not a spread: -0.0125 when they look
        1.25 % smaller than the map says), about each marker's centre: the markers' outlines as the
        detector sees them, where blur and gamma eat into a dark border. It moves the pose by
        ``(J^T J)^-1 J^T u`` times itself (``u`` the corners' pixel motion as every marker grows
        about its centre), :attr:`Prediction.position_bias_mm`, and the median error is that of
        the covariance about it. On OpenCV's ChArUco photos the markers look 1.2 to 1.3 % smaller
        than printed, in every photo alike (``benchmarks/planning_real.py``): taken as a spread
        instead, the error of a pose from two markers was predicted 0.79 times the measured. Measure it with
        the others on a photo of your own (:func:`noise.noise_from_pose`); for markers printed
        at the wrong size, correct ``marker_size_mm`` in the map instead.

    Returns
    -------
    Prediction

    Examples
    --------
    >>> import fidlearn
    >>> world = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    >>> camera = fidlearn.Camera.load(fidlearn.data_path("scenes/camera.json"))
    >>> T = fidlearn.look_at([1000, 190, 230], [0, 190, 230])
    >>> p = fidlearn.predict_accuracy(world, camera, T)
    >>> p.marker_ids, p.possible
    ([0, 1, 2], True)
    """
    if not isinstance(marker_map, MarkerMap):
        raise FidlearnError(f"marker_map must be a fidlearn.MarkerMap, got {type(marker_map).__name__}")
    if not isinstance(camera, Camera):
        raise FidlearnError(f"camera must be a fidlearn.Camera, got {type(camera).__name__}")
    return _predict(
        marker_map,
        camera,
        _check_pose(T_world_camera),
        corner_sigma_px,
        with_flip=True,
        shift_px=marker_shift_px,
        size_rel_std=marker_size_rel_std,
        size_rel_std_each=marker_size_rel_std_each,
        size_rel_error=marker_size_rel_error,
    )


def _predict(
    marker_map: MarkerMap,
    camera: Camera,
    T: np.ndarray,
    corner_sigma_px: float | None,
    with_flip: bool,
    shift_px: float = 0.0,
    size_rel_std: float = 0.0,
    size_rel_std_each: float = 0.0,
    size_rel_error: float = 0.0,
) -> Prediction:
    """:func:`predict_accuracy` on checked arguments; the flip (0) and the sampled tail are left out unless
    ``with_flip``."""
    _check_px(corner_sigma_px, "corner_sigma_px", zero=False)
    shift_px = 0.0 if shift_px is None else shift_px
    _check_px(shift_px, "marker_shift_px", zero=True)
    size_rel_std = _check_rel(size_rel_std, "marker_size_rel_std")
    size_rel_std_each = _check_rel(size_rel_std_each, "marker_size_rel_std_each")
    size_rel_error = _check_rel(size_rel_error, "marker_size_rel_error", signed=True)
    seen, lost = _seen(marker_map, camera, T)
    ids = sorted(seen)
    sides = {i: float(np.mean(np.linalg.norm(seen[i] - np.roll(seen[i], 1, axis=0), axis=1))) for i in ids}
    fixed = None if corner_sigma_px is None else float(corner_sigma_px)
    sigmas = {i: fixed if fixed is not None else float(noise.corner_sigma_px(sides[i], camera.model)) for i in ids}
    if not ids:
        why = "; ".join(f"{i}: {r}" for i, r in sorted(lost.items())) or "the map has no markers"
        return Prediction(T, [], {}, {}, None, np.full(3, np.inf), math.inf, 0.0, f"no marker found ({why})", lost)
    # the default model of a fisheye's corners: each side's line (as it lies on the pixel grid) and the outline's offset
    fisheye = fixed is None and camera.model == "fisheye"
    edges = {i: (*edge_offset_px(sides[i]), side_variance(seen[i])) for i in ids} if fisheye else {}
    model = (shift_px, size_rel_std, size_rel_std_each, size_rel_error, edges)
    full = _pose_model(marker_map, camera, T, ids, seen, sigmas, model, with_flip)
    if full is None:
        why = "the markers found do not fix the pose"
        return Prediction(T, ids, sides, sigmas, None, np.full(3, np.inf), math.inf, 0.0, why, lost)
    cov, bias = full[0], full[1]
    found, pose_probability, components = {}, 1.0, [(1.0, *full[2:])]
    if with_flip:  # the markers near the detector's limit may be missed: mix the subsets that may be found
        found = {i: finding.found_probability(sides[i]) for i in ids}
        subsets, pose_probability = finding.found_subsets(found)
        components = [(w, *m[2:]) for w, m in _subset_models(marker_map, camera, T, subsets, full, seen, sigmas, model)]
    median, p90, rms = sampling._error_stats(components)
    p_flip = sum(c[0] * c[2] for c in components) / sum(c[0] for c in components)
    return Prediction(
        T,
        ids,
        sides,
        sigmas,
        cov,
        np.sqrt(np.diag(cov[3:, 3:])),
        median,
        p_flip,
        "",
        lost,
        bias,
        p90,
        rms,
        found,
        pose_probability,
    )


def _subset_models(marker_map, camera, T, subsets: list, full: tuple, seen: dict, sigmas: dict, model: tuple) -> list:
    """``[(weight, model)]`` of each subset of markers (:func:`_pose_model`; ``full`` that of all of them),
    those that fix the pose."""
    ids = sorted(seen)
    out = []
    for w, sub in subsets:
        m = full if sub == ids else _pose_model(marker_map, camera, T, sub, seen, sigmas, model, True)
        if m is not None:
            out.append((w, m))
    return out


def _pose_model(
    marker_map: MarkerMap,
    camera: Camera,
    T: np.ndarray,
    ids: list[int],
    seen: dict,
    sigmas: dict,
    model: tuple,
    with_flip: bool,
) -> tuple | None:
    """``(covariance, bias, position error draws with the bias, flip probability, flip's camera offset)`` of
    a pose from the markers ``ids`` under the noise ``model`` (shift, size spreads, size error); None when
    they do not fix the pose."""
    P = np.concatenate([marker_map.marker_corners(i) for i in ids])
    px = np.concatenate([seen[i] for i in ids])
    s = np.repeat([sigmas[i] for i in ids], 4)
    J = pose_jacobian(P, T, camera)
    JtJ = J.T @ J
    d = np.sqrt(np.diag(JtJ))
    if np.any(d <= 0) or np.linalg.cond(JtJ / np.outer(d, d)) > 1e12:  # columns in rad and mm: compare scaled
        return None
    cov, bias, blocks, common = covariance_and_bias(marker_map, ids, seen, sigmas, J, JtJ, *model)
    p_flip, C_other = _flip(P, px, camera, s, blocks) if with_flip else (0.0, np.full(3, np.nan))
    rotation_std_deg = math.degrees(math.sqrt(max(float(np.max(np.diag(cov)[:3])), 0.0)))
    errors = sampling._position_errors(
        P, T, camera, cov[3:, 3:], blocks, common, with_flip and rotation_std_deg > sampling.NONLINEAR_ROTATION_DEG
    )
    return cov, bias, errors + bias, p_flip, C_other - T[:3, 3]
