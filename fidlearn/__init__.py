"""fidlearn: learn and do camera localization from ArUco fiducials with OpenCV.

The pipeline: calibrate the camera (:class:`Camera`), write down where the
markers are (:class:`MarkerMap`), detect them in an image, solve PnP, and
invert the extrinsics to get the camera's pose in the world.

Importing fidlearn has no side effects.
"""

from __future__ import annotations

__version__ = "0.1.0"

try:
    from .boards import Board
    from .calibration import Calibration, calibrate_charuco, calibrate_checkerboard, compare_calibrations
    from .camera import Camera
    from .data import data_dir, data_path
    from .detection import Detection, detect_markers, detect_markers_with_rejected
    from .drawing import draw_detections
    from .errors import (
        BoardError,
        CalibrationError,
        CameraError,
        DetectionError,
        DictionaryError,
        ExerciseError,
        FidlearnError,
        FidlearnWarning,
        GradingError,
        ImageError,
        MapError,
        NoMarkersError,
        PlotError,
        PoseError,
        PrintError,
        RosFormatError,
        StrictModeError,
        SurveyError,
        TrackingError,
        TransformError,
        UsageError,
        WebcamError,
    )
    from .filtering import PoseTracker, TrackedPose, smooth
    from .frames import (
        compose,
        invert_transform,
        look_at,
        make_transform,
        rotation_from_rpy_deg,
        rpy_deg_from_rotation,
        rvec_tvec_from_transform,
        transform_from_rvec_tvec,
        transform_points,
    )
    from .markermap import MarkerKey, MarkerMap, MarkerPlacement
    from .planning import Prediction, plan_room, predict_accuracy
    from .pose import Pose, estimate_pose, locate
    from .printables import board_pdf, markers_pdf
    from .sequences import FrameLocator, track
    from .survey import Survey, Suspect, survey
    from .synthetic import (
        CalibrationViews,
        Trajectory,
        render_calibration_views,
        render_scene,
        render_trajectory,
        trajectory_poses,
    )
    from .tracking import MarkerTracker
except Exception as _exc:  # noqa: BLE001 - numpy, OpenCV or matplotlib is broken (see fidlearn.doctor)
    _BROKEN = _exc

    def __getattr__(name: str):
        if name not in __all__:  # a submodule (fidlearn.doctor works without numpy and OpenCV)
            raise AttributeError(f"module 'fidlearn' has no attribute {name!r}")
        reason = " ".join(f"{type(_BROKEN).__name__}: {_BROKEN}".split())
        raise ImportError(
            f"fidlearn cannot load ({reason}); run 'python -m fidlearn doctor' to see which package is broken "
            "and the pip command that mends it"
        ) from _BROKEN


__all__ = [
    "Camera",
    "MarkerMap",
    "MarkerPlacement",
    "MarkerKey",
    "FidlearnError",
    "FidlearnWarning",
    "MapError",
    "CameraError",
    "TransformError",
    "ImageError",
    "DictionaryError",
    "DetectionError",
    "NoMarkersError",
    "CalibrationError",
    "PoseError",
    "ExerciseError",
    "GradingError",
    "UsageError",
    "WebcamError",
    "StrictModeError",
    "TrackingError",
    "RosFormatError",
    "compose",
    "invert_transform",
    "make_transform",
    "rotation_from_rpy_deg",
    "rpy_deg_from_rotation",
    "rvec_tvec_from_transform",
    "transform_from_rvec_tvec",
    "transform_points",
    "data_dir",
    "data_path",
    "Detection",
    "detect_markers",
    "detect_markers_with_rejected",
    "draw_detections",
    "render_scene",
    "look_at",
    "Pose",
    "estimate_pose",
    "locate",
    "MarkerTracker",
    "PoseTracker",
    "TrackedPose",
    "smooth",
    "render_calibration_views",
    "CalibrationViews",
    "render_trajectory",
    "trajectory_poses",
    "Trajectory",
    "Board",
    "BoardError",
    "Calibration",
    "calibrate_checkerboard",
    "calibrate_charuco",
    "compare_calibrations",
    "markers_pdf",
    "board_pdf",
    "PrintError",
    "PlotError",
    "Prediction",
    "predict_accuracy",
    "plan_room",
    "survey",
    "Survey",
    "Suspect",
    "SurveyError",
    "track",
    "FrameLocator",
    "__version__",
]
