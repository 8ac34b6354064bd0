"""Planning before printing: predicted pose accuracy for a camera pose and over a room.

:func:`predict_accuracy` answers "how well would a camera here know where it is?" from the map
and the camera alone; :func:`plan_room` maps that answer over a room seen from above and
:func:`suggest_markers` says what to print and where to put it to reach a target error;
:func:`coach` says how far a calibration can be trusted across the picture, and which photo to
take next.
"""

from ._checks import MAX_NOISE_PX
from .coach import CalibrationCoach, NextView, coach, coach_calibration
from .noise import MeasuredNoise, PhotoNoise, corner_sigma_px, min_perimeter_px, noise_from_photo, noise_from_pose
from .predict import Prediction, flip_probability, predict_accuracy
from .room import RoomPlan, default_area, default_step, plan_room
from .suggest import Suggestion, suggest_markers

__all__ = [
    "MAX_NOISE_PX",
    "Prediction",
    "predict_accuracy",
    "flip_probability",
    "corner_sigma_px",
    "min_perimeter_px",
    "PhotoNoise",
    "noise_from_pose",
    "noise_from_photo",
    "MeasuredNoise",
    "RoomPlan",
    "Suggestion",
    "plan_room",
    "suggest_markers",
    "default_area",
    "default_step",
    "CalibrationCoach",
    "NextView",
    "coach",
    "coach_calibration",
]
