"""The pose over time: :class:`PoseTracker` (a Kalman filter on the pose, live) and :func:`smooth` (offline).

Conventions: millimetres, radians inside (``_deg`` at the edges), ``T_a_b`` maps frame b into
frame a, world Z up. Covariances are 6x6 in :attr:`fidlearn.Pose.covariance`'s coordinates:
``[dtheta (rad; a small rotation in world axes on the left of R_world_camera), position (mm, world)]``.

The package: ``_so3.py`` (exp, log, quaternions), ``_filter.py`` (state, prediction, update),
``_track.py`` (measurements and odometry fed to the filter, flips and the gate), ``_adapt.py`` (the
motion noise and the poses' covariance scale learnt from the innovations, sudden manoeuvres),
``_tracker.py`` (:class:`PoseTracker`), ``_smoother.py`` (:func:`smooth`), ``_result.py``
(:class:`TrackedPose`).
"""

from __future__ import annotations

from ._adapt import MANOEUVRE_CHI2, PROCESS_NOISE_CEILING, PROCESS_NOISE_FLOOR, PROCESS_NOISE_START
from ._filter import AMBIGUOUS_INFLATION, GATE_CHI2, GATE_PROBABILITY, MAX_REJECTIONS
from ._result import TrackedPose
from ._smoother import smooth
from ._track import DEFAULT_PROCESS_NOISE
from ._tracker import PoseTracker

__all__ = [
    "PoseTracker",
    "TrackedPose",
    "smooth",
    "DEFAULT_PROCESS_NOISE",
    "GATE_CHI2",
    "GATE_PROBABILITY",
    "MAX_REJECTIONS",
    "AMBIGUOUS_INFLATION",
    "PROCESS_NOISE_START",
    "PROCESS_NOISE_FLOOR",
    "PROCESS_NOISE_CEILING",
    "MANOEUVRE_CHI2",
]
