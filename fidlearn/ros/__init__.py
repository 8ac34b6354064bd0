"""ROS's conventions in and out: poses as ``geometry_msgs/PoseWithCovarianceStamped`` (REP-103 axes,
REP-105 ``map`` -> ``base_link``, metres, radians, quaternions x, y, z, w), TUM trajectory files,
camera files as ``camera_info`` YAML, the robot's odometry CSV and mount JSON, and ROS 2 bags in
(:func:`read_bag`: images with their stamps and CameraInfo; :func:`read_bag_odometry`: the robot's
odometry) and out (:class:`BagWriter`: poses, odometry, TF and the map's markers).

No ROS installation is needed: text files are plain Python, bags are read and written with the
pure-Python ``rosbags`` library (MCAP and SQLite3 storage).

Examples
--------
>>> import fidlearn
>>> cam = fidlearn.Camera.from_fov(60, (640, 480))
>>> back = camera_from_camera_info(camera_info_yaml(cam))
>>> bool((back.K == cam.K).all()), back.image_size
(True, (640, 480))
"""

from __future__ import annotations

from ._bag import BagFrame, BagFrames, decode_image, is_bag, read_bag
from ._bag_images import write_image_bag
from ._bag_odometry import read_bag_odometry
from ._bag_out import BagWriter, marker_array
from ._camera_info import (
    camera_from_camera_info,
    camera_from_message,
    camera_info_yaml,
    load_camera_info,
    save_camera_info,
)
from ._inputs import ODOMETRY_COLUMNS, Odometry, read_mount_json, read_odometry_csv
from ._live import LiveView
from ._pose import BODIES, R_OPTICAL_LINK, ros_covariance, ros_pose, tum_line, write_tum

__all__ = [
    "read_bag",
    "read_bag_odometry",
    "BagFrame",
    "BagFrames",
    "is_bag",
    "decode_image",
    "camera_from_message",
    "BagWriter",
    "write_image_bag",
    "marker_array",
    "LiveView",
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
