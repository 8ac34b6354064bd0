"""Every error a user of fidlearn can cause.

All of them derive from :class:`FidlearnError`, so a program (or the command
line) can catch that one class.  Each message says what is wrong, where (the
file and the field) and how to mend it.
"""

from __future__ import annotations

__all__ = [
    "FidlearnError",
    "FidlearnWarning",
    "MapError",
    "CameraError",
    "TransformError",
    "ImageError",
    "DictionaryError",
    "NoMarkersError",
    "DetectionError",
    "CalibrationError",
    "BoardError",
    "PoseError",
    "PlotError",
    "PrintError",
    "ExerciseError",
    "GradingError",
    "UsageError",
    "WebcamError",
    "StrictModeError",
    "TrackingError",
    "RosFormatError",
    "SurveyError",
    "BoardNotFoundError",
    "OdometryRangeError",
]


class FidlearnError(Exception):
    """Base class of every error a user of fidlearn can cause."""


class FidlearnWarning(UserWarning):
    """Something worked, but not quite as asked (for example a camera was rescaled)."""


class MapError(FidlearnError, ValueError):
    """A world map (marker placements) is malformed or inconsistent."""


class CameraError(FidlearnError, ValueError):
    """A camera (intrinsics, distortion, image size) is malformed or does not fit the image."""


class TransformError(FidlearnError, ValueError):
    """A matrix that should be a rigid transform is not one."""


class ImageError(FidlearnError, ValueError):
    """An image cannot be read or has a type fidlearn cannot use."""


class DictionaryError(FidlearnError, ValueError):
    """An ArUco dictionary name is unknown, or a marker id does not fit in it."""


class DetectionError(FidlearnError, ValueError):
    """A detection (marker id and pixel corners) is malformed."""


class NoMarkersError(FidlearnError):
    """No marker of the map was found in the image, so no pose can be computed."""


class CalibrationError(FidlearnError):
    """Calibration cannot run or cannot give a trustworthy camera."""


class PoseError(FidlearnError, ValueError):
    """Pose estimation cannot run on these inputs (wrong types, a solver that does not fit the data)."""


class ExerciseError(FidlearnError, KeyError):
    """An exercise that does not exist (a lesson, a question) or a lesson's files that cannot be read.

    It is also a :class:`KeyError`, as these were before, so ``except KeyError`` still catches it;
    unlike a plain KeyError its message prints without quotes.
    """

    def __str__(self) -> str:
        return str(self.args[0]) if len(self.args) == 1 else super().__str__()


class GradingError(FidlearnError):
    """A grading run cannot start: a missing secret, a bad roster, an unknown lesson."""


class UsageError(FidlearnError):
    """The command line itself is wrong (unknown option, missing argument, an output that would clobber an input)."""


class PlotError(FidlearnError, ValueError):
    """A figure cannot be drawn from these inputs (labels that do not match the points, no poses, not an image)."""


class PrintError(FidlearnError, ValueError):
    """A printable page cannot be laid out or written as asked (a size that does not fit, a bad id list)."""


class BoardError(CalibrationError, PrintError):
    """A calibration board (its counts, sizes, markers or dictionary) is malformed.

    It is both a :class:`CalibrationError` and a :class:`PrintError`: the same board is calibrated with and printed.
    """


class WebcamError(FidlearnError, ValueError):
    """A camera that cannot deliver, or a request the camera widget cannot honour."""


class StrictModeError(FidlearnError, ValueError):
    """An exercise strict mode that does not exist (``strict("yes")``); also a ValueError, as it was."""


class TrackingError(FidlearnError, ValueError):
    """A pose tracker or smoother cannot use its input: time going backwards, a malformed odometry or mount,
    a frame before the track has a pose."""


class RosFormatError(FidlearnError, ValueError):
    """A ROS or TUM file (camera_info YAML, odometry CSV, mount JSON) is malformed, or a camera or pose
    cannot be written in ROS's conventions (a distortion model ROS does not have)."""


class SurveyError(FidlearnError, ValueError):
    """A survey cannot run on these photos or options (too few photos, nothing tying them to the map)."""


class BoardNotFoundError(FidlearnError):
    """A calibration board is not in a picture (or not all of it): nothing to calibrate from in that view."""


class OdometryRangeError(FidlearnError):
    """A time outside the odometry's samples: the robot's motion there is not known."""
