"""The robot's own files: the odometry CSV and the mount JSON (formats in ``docs/conventions.md``).

Odometry CSV: a header line then one row per sample, the base's pose in the odometry frame
(ROS's ``odom`` -> ``base_link``, as ``nav_msgs/Odometry`` gives it) in time order::

    t_s,x_m,y_m,z_m,qx,qy,qz,qw
    0.000,0.0,0.0,0.0,0.0,0.0,0.0,1.0

The tracker uses only its motion between frames (the odometry frame's own origin drifts and
does not matter); each step's covariance is ``drift`` (a fraction, 0.02 = 2 %) of the
distance and of the angle moved in that step, plus a floor of 0.1 mm and 0.0001 rad.

Mount JSON: where the camera sits on the robot, as a pose of the camera in the base frame
(REP-103 base: x forward, y left, z up)::

    {"units": "mm", "camera_in_base": {"translation": [200, 0, 300], "rpy_deg": [0, 0, 0]},
     "camera_axes": "link"}

``rpy_deg`` as everywhere in fidlearn (``R = Rz(yaw) Ry(pitch) Rx(roll)``, fixed axes);
``camera_axes`` ``"link"`` (default) means the rotation is that of REP-103's camera body (x
forward, y left, z up: rpy 0 looks along the base's x), ``"optical"`` that of the camera's
optical frame (x right, y down, z forward). Or give ``"T_camera_base"``: the 4x4 matrix
(optical camera frame, units as ``"units"``) directly.
"""

from __future__ import annotations

import csv
import io
import math
import os

import numpy as np

from .. import _files, frames
from .._io import read_json
from ..errors import OdometryRangeError, RosFormatError, TransformError
from ..filtering._so3 import exp_so3, log_so3, rotation_from_xyzw
from ._pose import R_OPTICAL_LINK

#: How far from its origin a robot's odometry may be, mm (1000 km): farther is a broken file.
MAX_ODOMETRY_MM = 1e9

ODOMETRY_COLUMNS = ("t_s", "x_m", "y_m", "z_m", "qx", "qy", "qz", "qw")
_UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "ft": 304.8}


class Odometry:
    """Odometry samples (the base's pose in the odometry frame over time) and the motion between two times.

    Parameters
    ----------
    times_s : array_like, shape (N,)
        Sample times, seconds, increasing.
    T_odom_base : sequence of ndarray (4, 4)
        The base's pose in the odometry frame at each sample, mm.
    drift : float
        The standard deviation of each step's translation and rotation, as a fraction of the
        distance and of the angle moved (0.02: 2 %).

    Raises
    ------
    RosFormatError
        Times not increasing, a bad drift, poses that are not rigid transforms.
    """

    def __init__(self, times_s, T_odom_base, drift: float = 0.02):
        self.times_s = _times(times_s)
        if not (isinstance(drift, (int, float)) and not isinstance(drift, bool) and 0 < drift < 1):
            raise RosFormatError(f"odometry drift must be a fraction between 0 and 1 (0.02 for 2 %), got {drift!r}")
        if not isinstance(T_odom_base, (list, tuple, np.ndarray)) or len(T_odom_base) != self.times_s.size:
            raise RosFormatError(
                f"T_odom_base must be a list of 4x4 poses, one per time ({self.times_s.size}), "
                f"got {type(T_odom_base).__name__}"
            )
        try:
            self.poses = [frames.check_transform(T, "odometry pose") for T in T_odom_base]
        except TransformError as exc:
            raise RosFormatError(str(exc)) from None
        far = next((k for k, T in enumerate(self.poses) if not np.abs(T[:3, 3]).max() <= MAX_ODOMETRY_MM), None)
        if far is not None:
            raise RosFormatError(
                f"odometry pose {far} is {np.abs(self.poses[far][:3, 3]).max() / 1000:.3g} m from its origin; "
                f"a robot's odometry stays within {MAX_ODOMETRY_MM / 1e6:g} km of it (are the positions in metres?)"
            )
        self.drift = float(drift)

    def pose_at(self, t_s: float) -> np.ndarray:
        """The base's pose (4, 4, mm) at ``t_s``, interpolated (linear position, geodesic rotation).

        Raises :class:`RosFormatError` when ``t_s`` is not a finite number, :class:`OdometryRangeError`
        when it is outside the samples.
        """
        if (
            isinstance(t_s, bool)
            or not isinstance(t_s, (int, float, np.integer, np.floating))
            or not math.isfinite(t_s)
        ):
            raise RosFormatError(f"an odometry time must be a finite number of seconds, got {t_s!r:.40}")
        ts = self.times_s
        if not ts[0] <= t_s <= ts[-1]:
            raise OdometryRangeError(
                f"no odometry at {t_s:g} s: its samples run from {ts[0]:g} to {ts[-1]:g} s; record the odometry "
                "over the whole video, or start the video's clock at the odometry's (the CSV's t_s column)"
            )
        k = int(np.searchsorted(ts, t_s, side="right")) - 1
        if k >= len(ts) - 1:
            return self.poses[-1].copy()
        a, b = self.poses[k], self.poses[k + 1]
        u = (t_s - ts[k]) / (ts[k + 1] - ts[k])
        T = np.eye(4)
        T[:3, :3] = a[:3, :3] @ exp_so3(u * log_so3(a[:3, :3].T @ b[:3, :3]))
        T[:3, 3] = (1 - u) * a[:3, 3] + u * b[:3, 3]
        return T

    def between(self, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The base's motion ``T_prev_curr`` (4, 4, mm) from ``t0_s`` to ``t1_s`` and its covariance (6, 6).

        Parameters
        ----------
        t0_s, t1_s : float
            The two times, seconds.

        Returns
        -------
        (ndarray, ndarray)
            The motion and its covariance ``[rotation (rad), translation (mm)]``, as
            :meth:`fidlearn.PoseTracker.update` takes them.

        Raises
        ------
        OdometryRangeError
            A time is outside the odometry's samples.
        RosFormatError
            A time is not a finite number.
        """
        a, b = self.pose_at(t0_s), self.pose_at(t1_s)
        rel = frames.invert_transform(a) @ b
        angle = float(np.linalg.norm(log_so3(rel[:3, :3])))
        dist = float(np.linalg.norm(rel[:3, 3]))
        s_rot = self.drift * angle + 1e-4
        s_pos = self.drift * dist + 0.1
        return rel, np.diag([s_rot**2] * 3 + [s_pos**2] * 3)


def _times(times_s) -> np.ndarray:
    """The odometry's times as a float array: finite, strictly increasing, at most 1e12 s; RosFormatError."""
    try:
        ts = np.asarray(times_s, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        ts = np.zeros(0)
    if ts.size < 2 or np.any(np.diff(ts) <= 0) or not (np.abs(ts) <= 1e12).all():
        raise RosFormatError(
            "odometry times must be a list of two or more finite, strictly increasing seconds (at most 1e12): the "
            "motion between two samples is what the tracker uses"
        )
    return ts


def read_odometry_csv(path: str | os.PathLike, drift: float = 0.02) -> Odometry:
    """Read an odometry CSV file (header ``t_s,x_m,y_m,z_m,qx,qy,qz,qw``; see the module's docstring).

    Parameters
    ----------
    path : path-like
        The CSV file.
    drift : float
        As for :class:`Odometry`.

    Returns
    -------
    Odometry

    Raises
    ------
    RosFormatError
        A missing file, a wrong header, a row that is not 8 numbers, times not increasing, a zero quaternion.
    """
    path, data = _files.read_bytes(path, RosFormatError, "odometry CSV", _files.MAX_TEXT_BYTES)
    try:
        rows = list(csv.reader(io.StringIO(data.decode("utf-8-sig"))))  # a spreadsheet's byte-order mark too
    except (UnicodeDecodeError, csv.Error) as exc:
        raise RosFormatError(f"{path}: cannot read it as CSV text ({exc})") from None
    rows = [r for r in rows if r and not r[0].lstrip().startswith("#")]
    if not rows or tuple(c.strip() for c in rows[0]) != ODOMETRY_COLUMNS:
        raise RosFormatError(f"{path}: the first line must be the header {','.join(ODOMETRY_COLUMNS)}")
    times, poses = [], []
    for n, row in enumerate(rows[1:], start=2):
        try:
            v = [float(c) for c in row]
        except ValueError:
            v = []
        if len(v) != 8 or not all(math.isfinite(x) for x in v):
            raise RosFormatError(f"{path}: row {n}: expected 8 numbers ({','.join(ODOMETRY_COLUMNS)})")
        if max(abs(x) for x in v[1:4]) > MAX_ODOMETRY_MM / 1000:
            raise RosFormatError(
                f"{path}: row {n}: a position of {max(abs(x) for x in v[1:4]):.3g} m; a robot's odometry stays "
                f"within {MAX_ODOMETRY_MM / 1e6:g} km of its origin (x_m, y_m, z_m are metres)"
            )
        if np.linalg.norm(v[4:8]) < 1e-9:
            raise RosFormatError(f"{path}: row {n}: the quaternion is zero")
        times.append(v[0])
        try:
            R = rotation_from_xyzw(np.array(v[4:8]))
        except TransformError as exc:
            raise RosFormatError(f"{path}: row {n}: {exc}") from None
        poses.append(frames.make_transform(R, np.array(v[1:4]) * 1000.0))
    try:
        return Odometry(times, poses, drift)
    except RosFormatError as exc:
        raise RosFormatError(f"{path}: {exc}") from None


def read_mount_json(path: str | os.PathLike) -> np.ndarray:
    """Read a mount JSON file (see the module's docstring): ``T_camera_base`` (4, 4), mm, optical camera frame.

    Parameters
    ----------
    path : path-like
        The JSON file.

    Returns
    -------
    ndarray, shape (4, 4)
        ``T_camera_base``: base points into the camera's optical frame (mm), as
        :class:`fidlearn.PoseTracker` takes it.

    Raises
    ------
    RosFormatError
        A missing or malformed file, unknown units or axes, a matrix that is not a rigid transform.
    """
    d = read_json(path, RosFormatError, "mount JSON file")
    _check_mount_keys(d, path)
    k = _UNITS_MM[d["units"]]
    try:
        if "T_camera_base" in d:
            T = np.array(d["T_camera_base"], dtype=float)
            if T.shape == (4, 4):
                T[:3, 3] *= k
            T = frames.check_transform(T, "T_camera_base")
            _check_mount_reach(T[:3, 3], path)
            return T
        m = d["camera_in_base"]
        axes = d.get("camera_axes", "link")
        if not isinstance(axes, str) or axes not in ("link", "optical"):
            raise RosFormatError(f'{path}: camera_axes must be "link" or "optical", got {axes!r:.40}')
        R = frames.rotation_from_rpy_deg(*[float(v) for v in m["rpy_deg"]])
        if axes == "link":
            R = R @ R_OPTICAL_LINK.T  # R_base_optical = R_base_link @ R_link_optical
        if any(isinstance(v, bool) for v in m["translation"]) or any(isinstance(v, bool) for v in m["rpy_deg"]):
            raise RosFormatError(f"{path}: translation and rpy_deg are numbers, not true or false")
        t = np.array(m["translation"], dtype=float).reshape(3) * k
        _check_mount_reach(t, path)
        return frames.invert_transform(frames.make_transform(R, t))
    except RosFormatError:
        raise
    except TransformError as exc:
        raise RosFormatError(f"{path}: {exc}") from None
    except (TypeError, ValueError, OverflowError) as exc:
        raise RosFormatError(f"{path}: the mount's numbers are malformed ({exc})") from None


#: The keys of a mount file, and of its ``camera_in_base``.
MOUNT_KEYS = ("units", "camera_in_base", "camera_axes", "T_camera_base")
PLACEMENT_KEYS = ("translation", "rpy_deg")
#: Other names for the mount file's keys, so that the error can say which was meant.
_MOUNT_ALIASES = {
    "axes": "camera_axes",
    "camera_axis": "camera_axes",
    "frame": "camera_axes",
    "unit": "units",
    "camera": "camera_in_base",
    "pose": "camera_in_base",
    "mount": "camera_in_base",
    "transform": "T_camera_base",
    "matrix": "T_camera_base",
}
#: Farthest a camera may sit from the robot's base (mm): 100 m.
MAX_MOUNT_MM = 1e5


def _check_mount_keys(d, path) -> None:
    """Every key known (a misspelt ``camera_axes`` was ignored, leaving the default), the units, one pose."""
    if not isinstance(d, dict):
        raise RosFormatError(f"{path}: a mount file is a JSON object with the keys {', '.join(MOUNT_KEYS)}")
    for key in d:
        if key not in MOUNT_KEYS:
            raise RosFormatError(
                f"{path}: unknown key {key!r:.60}{_files.did_you_mean(key, MOUNT_KEYS, _MOUNT_ALIASES)}; "
                f"a mount file has {', '.join(MOUNT_KEYS)}"
            )
    units = d.get("units")
    if not isinstance(units, str) or units not in _UNITS_MM:
        raise RosFormatError(f'{path}: a mount file needs "units" (one of {", ".join(_UNITS_MM)})')
    if ("T_camera_base" in d) == ("camera_in_base" in d):
        raise RosFormatError(
            f'{path}: give either "camera_in_base": {{"translation": [x, y, z], "rpy_deg": [roll, pitch, yaw]}} '
            'or "T_camera_base" (4x4), ' + ("not both" if "T_camera_base" in d else "one of them")
        )
    m = d.get("camera_in_base", {"translation": 0, "rpy_deg": 0})
    if not isinstance(m, dict) or set(m) != set(PLACEMENT_KEYS):
        extra = [key for key in m if key not in PLACEMENT_KEYS] if isinstance(m, dict) else []
        said = f"unknown key {extra[0]!r:.60}{_files.did_you_mean(extra[0], PLACEMENT_KEYS)}; " if extra else ""
        raise RosFormatError(
            f'{path}: camera_in_base: {said}give {{"translation": [x, y, z], "rpy_deg": [roll, pitch, yaw]}}'
        )


def _check_mount_reach(t_mm: np.ndarray, path) -> None:
    if not np.all(np.abs(t_mm) <= MAX_MOUNT_MM):
        raise RosFormatError(
            f"{path}: the camera sits {np.abs(t_mm).max():g} mm from the base, more than {MAX_MOUNT_MM:g} mm; "
            'check "units"'
        )
