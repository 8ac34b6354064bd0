"""``fidlearn locate BAG``: the frames of a ROS 2 bag in, and ``-o OUT.mcap``: the poses as a ROS 2 bag out.

The bag's images are one run (a video: one :class:`fidlearn.MarkerTracker`), timed by their header
stamps; the camera is the bag's CameraInfo unless ``--camera`` is given, which then stands in for
it. Either way the camera's resolution must be the images' (a bag knows its camera: nothing is
rescaled).
"""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..errors import CameraError, FidlearnWarning, UsageError
from ..images import Frame
from ..ros import BagWriter, is_bag, read_bag, read_bag_odometry

BAG_HELP = """\
ROS 2 bags: give a bag folder (metadata.yaml) or a .mcap file (or a ROS 1 .bag file) as the only input.
Its sensor_msgs/msg/Image (mono8, mono16, bgr8, rgb8, bgra8, rgba8, bayer_*8, yuv422) or CompressedImage topic
is read (--image-topic when it has several), timed by the header stamps (--track uses them; t = 0 at the
first image; an image whose stamp is not after the last one's is left out of the track, with a warning;
-o in the tum and ros formats writes the stamps themselves); the camera is the CameraInfo beside it
(--camera-info-topic), or --camera, which then stands in for it (image_rect topics, rectified: the
CameraInfo's projection P, without distortion). -o OUT.mcap (or -o FOLDER --format bag) writes a ROS 2
bag: /fidlearn/pose (geometry_msgs/msg/PoseWithCovarianceStamped, frame map, at each image's stamp),
/fidlearn/odometry (nav_msgs/msg/Odometry, with --track), /tf (map -> the camera's frame, or map ->
base_link with --mount), /tf_static (base_link -> camera: the mount) and /fidlearn/markers
(visualization_msgs/msg/MarkerArray: the map). With --track, --odometry-topic TOPIC reads the robot's
odometry (nav_msgs/msg/Odometry, its pose in the odom frame at each header stamp) from the bag, as
--odometry reads it from a CSV file (--odometry-drift applies)."""


def add_bag_options(p) -> None:
    """The ROS 2 bag options of ``fidlearn locate``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The ``locate`` parser.
    """
    g = p.add_argument_group("ROS 2 bags (see below)")
    g.add_argument("--image-topic", metavar="TOPIC", help="the bag's image topic (default its only one)")
    g.add_argument(
        "--camera-info-topic", metavar="TOPIC", help="the bag's CameraInfo topic (default beside the images)"
    )
    g.add_argument(
        "--odometry-topic", metavar="TOPIC", help="with --track: the robot's odometry from the bag (nav_msgs/Odometry)"
    )
    g.add_argument(
        "--annotated-images",
        action="store_true",
        help="with -o OUT.mcap: each frame drawn (markers, axes, pose) on /fidlearn/image_annotated/compressed",
    )


def bag_input(args) -> Path | None:
    """The bag given as input (None for pictures and videos), its options checked.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    Path or None
        The bag.

    Raises
    ------
    UsageError
        A bag among other inputs or with a live camera; bag options without a bag; no --camera for
        pictures or videos; a bag output without a bag input.
    """
    bags = [Path(p) for p in args.inputs if is_bag(p)]
    if not bags:
        for option, value in (
            ("--image-topic", args.image_topic),
            ("--camera-info-topic", args.camera_info_topic),
            ("--odometry-topic", args.odometry_topic),
        ):
            if value is not None:
                raise UsageError(
                    f"{option} chooses a topic of a ROS 2 bag: give the bag (a folder, a .mcap or a .bag file)"
                )
        if args.camera is None:
            raise UsageError("--camera CAMERA is needed (a ROS 2 bag's CameraInfo can stand in for it)")
        if _bag_output(args):
            raise UsageError(f"-o {args.output} writes each pose at its image's stamp: give a ROS 2 bag as input")
        if getattr(args, "annotated_images", False):
            raise UsageError("--annotated-images writes the frames into an output bag: give a bag and -o OUT.mcap")
        return None
    if getattr(args, "annotated_images", False) and not _bag_output(args):
        raise UsageError("--annotated-images writes the frames into the output bag: add -o OUT.mcap")
    if len(args.inputs) > 1 or args.camera_index is not None:
        raise UsageError(f"{bags[0]}: a ROS 2 bag is read alone; give it as the only input")
    return bags[0]


def _bag_output(args) -> bool:
    return args.output is not None and (args.format == "bag" or Path(args.output).suffix.lower() == ".mcap")


def _same(a: Camera | None, b: Camera) -> bool:
    if a is None:
        return False
    da, db = (np.asarray(c.dist, dtype=float).reshape(-1) for c in (a, b))
    return (a.width, a.height) == (b.width, b.height) and np.array_equal(a.K, b.K) and np.array_equal(da, db)


#: How many images left out of a track (their stamps not increasing) are named one by one.
MAX_WARNINGS = 3


def _warn_stamp(name: str, stamp: int, last: int) -> None:
    """The warning for an image left out of a track: its stamp is not after the last image's."""
    said = "repeats" if stamp == last else f"is {(last - stamp) / 1e9:.9f} s before"
    warnings.warn(
        f"{name}: its header stamp {stamp // 10**9}.{stamp % 10**9:09d} s {said} the last image's; "
        "left out of the track (a track needs increasing stamps)",
        FidlearnWarning,
        stacklevel=3,
    )


class BagRun:
    """A bag's frames as :class:`fidlearn.images.Frame` (one video), their stamps and their camera.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``--camera``, ``--image-topic``, ``--camera-info-topic``).
    path : Path
        The bag.
    camera : Camera or None
        ``--camera``'s camera, which stands in for the bag's CameraInfo.

    Raises
    ------
    FidlearnError
        The bag's own errors (see :func:`fidlearn.ros.read_bag`); no camera at all.
    """

    def __init__(self, args, path: Path, camera: Camera | None):
        self.bag = read_bag(path, args.image_topic, args.camera_info_topic, camera=camera)
        cameras = self.bag.cameras()
        if camera is None and not cameras:
            raise UsageError(f"{path}: no CameraInfo beside {self.bag.image_topic}; give --camera CAMERA")
        self.given = camera is not None
        self.camera: Camera = camera if camera is not None else cameras[0][1]
        self.stamps: list[int] = []
        self.name = path.name

    def frames(self, increasing: bool = False):
        """The frames, each stamp kept in :attr:`stamps` as its frame is read.

        Parameters
        ----------
        increasing : bool
            For a track: an image whose stamp is not after the last image's (a driver that stamps twice
            alike, a clock set back) is left out, with a warning.

        Yields
        ------
        Frame
            ``BAG#k``, kind ``"video"``.
        """
        left_out = 0
        for k, bf in enumerate(self.bag):
            if increasing and self.stamps and bf.stamp <= self.stamps[-1]:
                left_out += 1
                if left_out <= MAX_WARNINGS:
                    _warn_stamp(f"{self.name}#{k}", bf.stamp, self.stamps[-1])
                continue
            size = (bf.image.shape[1], bf.image.shape[0])
            if (self.camera.width, self.camera.height) != size:
                said = "--camera" if self.given else f"the CameraInfo on {self.bag.camera_info_topic}"
                raise CameraError(
                    f"{self.name}#{k}: the image is {size[0]}x{size[1]}, {said} is for "
                    f"{self.camera.width}x{self.camera.height}; give the camera of these images"
                )
            if not self.given and not _same(bf.camera, self.camera):
                raise CameraError(
                    f"{self.name}#{k}: the CameraInfo changes here; fidlearn locates a run with one camera: "
                    "give --camera CAMERA to use one for every image"
                )
            self.stamps.append(bf.stamp)
            yield Frame(f"{self.name}#{k}", bf.image, str(self.bag.path), "video")
        if left_out > MAX_WARNINGS:
            warnings.warn(
                f"{self.name}: {left_out} images in all were left out of the track, their stamps not after "
                "the image before; check the camera driver's clock",
                FidlearnWarning,
                stacklevel=2,
            )

    def odometry(self, topic: str, drift: float):
        """The robot's odometry on ``topic``, timed from the first image's stamp as the frames are.

        Parameters
        ----------
        topic : str
            The ``nav_msgs/msg/Odometry`` topic (``--odometry-topic``).
        drift : float
            ``--odometry-drift``.

        Returns
        -------
        fidlearn.ros.Odometry
            Its samples.

        Raises
        ------
        RosFormatError
            No such topic, fewer than two messages, a message that is no pose.
        """
        return read_bag_odometry(self.bag.path, topic, drift, image_topic=self.bag.image_topic)

    def times(self):
        """Each frame's time, seconds from the first frame's stamp (for :func:`fidlearn.track`).

        Yields
        ------
        float
            One per frame read so far.
        """
        for n in itertools.count():
            yield (self.stamps[n] - self.stamps[0]) / 1e9


class BagSink:
    """``-o OUT.mcap``: the poses written at their images' stamps; the bag kept whole on an interruption.

    Parameters
    ----------
    path : Path
        The output bag.
    run : BagRun
        The input bag's run (its stamps and the camera's frame).
    marker_map : MarkerMap
        Written as markers.
    mount : ndarray or None
        ``T_camera_base`` (``--mount``).
    """

    def __init__(self, path: Path, run: BagRun, marker_map, mount=None):
        self.path, self.run, self.marker_map, self.mount = path, run, marker_map, mount
        self.writer: BagWriter | None = None
        self.count = 0

    def __enter__(self) -> BagSink:
        return self

    def put(self, index: int, pose) -> None:
        """Frame ``index``'s pose (a Pose without covariance is left out).

        Parameters
        ----------
        index : int
            The frame's number in the bag.
        pose : Pose or TrackedPose
            Its pose.
        """
        if pose is None or pose.covariance is None:
            return
        self._writer().write(self.run.stamps[index], pose)
        self.count += 1

    def image(self, index: int, drawn) -> None:
        """Frame ``index`` drawn (``--annotated-images``), at its image's stamp.

        Parameters
        ----------
        index : int
            The frame's number in the bag.
        drawn : ndarray
            The frame with its detections and pose drawn.
        """
        self._writer().write_image(self.run.stamps[index], drawn)

    def _writer(self) -> BagWriter:
        if self.writer is None:
            frame = self.run.bag.frame_id or "camera"
            self.writer = BagWriter(self.path, self.marker_map, T_camera_base=self.mount, camera_frame=frame)
        return self.writer

    def __exit__(self, exc_type, exc, tb) -> None:
        if self.writer is None or self.count == 0:  # drawn frames without a single pose: no bag
            if self.writer is not None:
                self.writer.abort()
            if exc_type is None:
                raise UsageError(f"-o {self.path}: no frame gave a pose with a covariance; nothing was written")
            return
        if exc_type is None or issubclass(exc_type, KeyboardInterrupt):
            self.writer.close()
        else:
            self.writer.abort()


__all__ = ["BAG_HELP", "BagRun", "BagSink", "add_bag_options", "bag_input"]
