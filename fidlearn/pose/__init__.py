"""The camera's pose in the world from detected markers: PnP over every known marker at once.

The pipeline: every detected marker that the map knows gives four 2D-3D
correspondences (its pixel corners and its world corners, TL, TR, BR, BL).
A PnP solver finds ``T_camera_world`` (OpenCV's rvec/tvec, the extrinsics);
Levenberg-Marquardt then minimises the reprojection error; the camera's pose
in the world is the closed-form inverse ``T_world_camera``.

``method="auto"`` picks the solver the data calls for:

* one marker: ``IPPE_SQUARE`` in the marker's own frame;
* several markers on one plane (the corners actually seen are coplanar within
  1 mm, or within 1 % of their extent, after which IPPE runs on the points
  flattened onto their best plane): ``IPPE`` over all corners;
* markers on several walls (IPPE fails outright on points off a plane): ``SQPNP``
  (when the corners are nearly on one plane, off by less than 10 % of their
  extent, IPPE's flattened solutions compete with it).

A planar target has two poses that explain the image almost equally well when
it is seen nearly face-on or from afar (the "flip" ambiguity). IPPE gives both;
both are refined (the second only when it starts close enough to rival the
first); the better one is returned, the other is kept as
:attr:`Pose.alternative`, and :attr:`Pose.ambiguous` says when the data cannot
tell them apart (see :func:`estimate_pose`).

A marker measured wrongly on the wall is found by leave-one-out (only when the
residuals look suspicious, so the usual cost is one IPPE and one short LM run)
and reported in :attr:`Pose.rejected_ids`. Answers no camera can give are refused
with a :class:`PoseError` that says what to check: a marker whose image corners are
not a convex quad running clockwise on screen (mirrored, shuffled or collinear
corners), a pose that would see a marker from behind or have corners behind the
camera (never chosen while another candidate is possible), and a best fit whose
reprojection error is above ``BAD_FIT_REL`` marker sides. The uncertainty comes as a 6x6
covariance of the camera pose from the Jacobian of the corners
(:func:`pose_jacobian`).

A pose that cannot be found is never returned as None: :func:`estimate_pose`, :func:`locate` and
:meth:`fidlearn.MarkerTracker.locate` all raise a :class:`~fidlearn.errors.FidlearnError`
that says why. :class:`NoMarkersError` when no marker of the map is found (the
message lists the ids seen, the map's ids and dictionary, and what to check);
:class:`PoseError` when the corners give no pose a camera can have.

Conventions: millimetres, OpenCV camera frame (x right, y down, z forward),
pixel centres at integer coordinates, ``T_a_b`` maps frame b into frame a.

The package holds one concept per file: ``_result.py`` (:class:`Pose`), ``_estimate.py``
(:func:`estimate_pose` in named steps), ``_locate.py`` (:func:`locate`), ``_inputs.py`` (the
checks of arguments and options), ``_solvers.py`` (the PnP solvers and the ranking of their
candidates), ``_checks.py`` (corners and poses no camera can give), ``_refine.py``
(:func:`pose_jacobian`, :func:`refine_pose_lm`, the Levenberg-Marquardt), ``_stats.py`` (noise,
covariance, chi-square, Mahalanobis), ``_outliers.py`` (the rejection of misplaced markers) and
``_observations.py`` (the corners the solvers work on, the map's corners and faces, cached).

Examples
--------
>>> import numpy as np, fidlearn
>>> from fidlearn.detection import Detection
>>> m = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> T_world_camera = fidlearn.make_transform(
...     fidlearn.rotation_from_rpy_deg(-90, 0, 90), [1000, 150, 250])   # facing the wall (-X)
>>> dets = [Detection(i, cam.project(c, T_world_camera)) for i, c in m.corners().items()]
>>> pose = estimate_pose(dets, m, cam)
>>> np.round(pose.position_mm, 3).tolist()
[1000.0, 150.0, 250.0]
"""

from __future__ import annotations

import inspect as _inspect

from ._estimate import BAD_FIT_MIN_PX as BAD_FIT_MIN_PX
from ._estimate import BAD_FIT_REL as BAD_FIT_REL
from ._estimate import estimate_pose as estimate_pose
from ._locate import locate as locate
from ._outliers import DISPLACEMENT_MIN_RMS_PX as DISPLACEMENT_MIN_RMS_PX
from ._outliers import DISPLACEMENT_P as DISPLACEMENT_P
from ._outliers import OUTLIER_CHI2 as OUTLIER_CHI2
from ._outliers import OUTLIER_MIN_RMS_PX as OUTLIER_MIN_RMS_PX
from ._outliers import OUTLIER_P as OUTLIER_P
from ._outliers import OUTLIER_POOR_FIT_PX as OUTLIER_POOR_FIT_PX
from ._outliers import OUTLIER_SIGMA_FLOOR_PX as OUTLIER_SIGMA_FLOOR_PX
from ._outliers import SCREEN_P as SCREEN_P
from ._refine import PoseRefinement as PoseRefinement
from ._refine import pose_jacobian as pose_jacobian
from ._refine import refine_pose_lm as refine_pose_lm
from ._result import Pose as Pose
from ._solvers import METHODS as METHODS
from ._solvers import REFINE_GAP_CHI2 as REFINE_GAP_CHI2
from ._stats import AMBIGUITY_CHI2 as AMBIGUITY_CHI2
from ._stats import AMBIGUITY_MAX_SIGMA_PX as AMBIGUITY_MAX_SIGMA_PX
from ._stats import MIN_SIGMA_PX as MIN_SIGMA_PX
from ._stats import PRIOR_DOF as PRIOR_DOF
from ._stats import PRIOR_SIGMA_PX as PRIOR_SIGMA_PX

__all__ = [
    "Pose",
    "estimate_pose",
    "locate",
    "METHODS",
    "pose_jacobian",
    "refine_pose_lm",
    "PoseRefinement",
    "AMBIGUITY_CHI2",
    "AMBIGUITY_MAX_SIGMA_PX",
    "BAD_FIT_MIN_PX",
    "BAD_FIT_REL",
    "DISPLACEMENT_MIN_RMS_PX",
    "DISPLACEMENT_P",
    "MIN_SIGMA_PX",
    "OUTLIER_CHI2",
    "OUTLIER_MIN_RMS_PX",
    "OUTLIER_P",
    "OUTLIER_POOR_FIT_PX",
    "OUTLIER_SIGMA_FLOOR_PX",
    "PRIOR_DOF",
    "PRIOR_SIGMA_PX",
    "REFINE_GAP_CHI2",
    "SCREEN_P",
]

# The public names say they are fidlearn.pose's: help(), repr() and the docs show the path to import
# (and the doctests of Pose's methods run with the class).
_methods = [f for f in vars(Pose).values() if _inspect.isfunction(f)]
for _public in (Pose, estimate_pose, locate, pose_jacobian, refine_pose_lm, *_methods):
    _public.__module__ = __name__
del _public, _methods, _inspect
