"""ROS's conventions in and out: poses as ``geometry_msgs/PoseWithCovarianceStamped`` (REP-103 axes,
REP-105 ``map`` -> ``base_link``, metres, radians, quaternions x, y, z, w), TUM trajectory files,
camera files as ``camera_info`` YAML, and the robot's odometry CSV and mount JSON.

No ROS installation is needed: everything is plain Python data and text files.

Examples
--------
>>> import fidlearn
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> back = camera_from_camera_info(camera_info_yaml(cam))
>>> bool((back.K == cam.K).all()), back.image_size
(True, (640, 480))
"""

from __future__ import annotations

from ._camera_info import camera_from_camera_info, camera_info_yaml, load_camera_info, save_camera_info
from ._inputs import ODOMETRY_COLUMNS, Odometry, read_mount_json, read_odometry_csv
from ._pose import BODIES, R_OPTICAL_LINK, ros_covariance, ros_pose, tum_line, write_tum

__all__ = [
    "ros_pose",
    "ros_covariance",
    "tum_line",
    "write_tum",
    "camera_info_yaml",
    "save_camera_info",
    "load_camera_info",
    "camera_from_camera_info",
    "Odometry",
    "read_odometry_csv",
    "read_mount_json",
    "ODOMETRY_COLUMNS",
    "BODIES",
    "R_OPTICAL_LINK",
]
