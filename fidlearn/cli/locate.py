"""``fidlearn locate``: the camera's pose in the world in pictures, videos and a live camera.

The poses come from the library: :func:`fidlearn.locate` for each picture, one
:class:`fidlearn.MarkerTracker` for each video (and the live camera), so the command line
and a program give the same answers. This module reads the frames, prints the table, writes
``--json`` (one line per frame, flushed as each is done) and ``--annotate`` pictures.
"""

from __future__ import annotations

import contextlib
import statistics
import sys
from pathlib import Path

import numpy as np

from ..drawing import draw_pose
from ..errors import UsageError
from ..images import expand_inputs, read_frames
from ..pose import Pose
from ..sequences import NO_MARKER, FrameLocator, FramePose, check_picture_sizes
from ._bag import BAG_HELP, BagRun, BagSink, add_bag_options, bag_input
from ._common import (
    _add_image_size_option,
    _add_map_options,
    _check_output,
    _commit,
    _exit_status,
    _Interrupted,
    _load_camera,
    _load_map,
    _outputs,
    _refuse_clobber,
    _signal_name,
    _Staging,
    _StreamFile,
)
from ._live import LiveRun, add_live_option
from ._track import (
    TRACK_HELP,
    HelpFormatter,
    add_track_options,
    check_track_args,
    run_tracked,
    say_other_dictionaries,
)


def add(sub) -> None:
    """Register the command on the ``fidlearn`` parser's subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``fidlearn`` parser's subcommands (``parser.add_subparsers()``).
    """
    p = sub.add_parser(
        "locate",
        help="camera pose in the world from the markers in images or a video",
        description=(
            "Find the camera's pose in the world for every image, every frame of a video "
            "(.mp4, .avi, ...) or a live camera: detect the map's markers, solve PnP over all "
            "of them, invert. One line per frame: position x, y, z (mm, world), roll, pitch, yaw "
            "(deg, the camera frame's rotation in the world, as 'fidlearn render --pose' takes "
            "it), the markers used, the RMS reprojection error (px) and whether a second pose "
            "explains the image as well (ambiguous). A frame with no marker of the map is "
            "reported, not an error. --json and --annotate are written only when the whole run "
            "succeeds: --json goes to a hidden temporary file, flushed frame by frame, renamed at "
            "the end; annotated images are staged in a hidden folder and moved into DIR at the end. "
            "With --track the poses go through a Kalman filter over time (see below)."
        ),
        epilog=TRACK_HELP + "\n\n" + BAG_HELP,
        formatter_class=HelpFormatter,
    )
    p.add_argument(
        "inputs",
        nargs="*",
        type=Path,
        metavar="IMAGE_OR_FOLDER_OR_VIDEO_OR_BAG",
        help="images, folders of images, videos, or one bag (a ROS 2 folder with metadata.yaml, a .mcap file, "
        "or a ROS 1 .bag file)",
    )
    p.add_argument(
        "--camera",
        type=Path,
        metavar="CAMERA",
        help="camera file (fidlearn JSON or OpenCV YAML); a bag's CameraInfo stands in for it when not given",
    )
    _add_image_size_option(p)
    _add_map_options(p)
    p.add_argument(
        "--camera-index", type=int, metavar="N", help="also read a live camera (0 is the first); Ctrl-C stops"
    )
    p.add_argument("--json", type=Path, metavar="POSES.jsonl", help="write one JSON line per frame with T_world_camera")
    p.add_argument(
        "--annotate", type=Path, metavar="DIR", help="save each frame with the markers and the world axes drawn"
    )
    p.add_argument(
        "--refine", choices=["edges", "subpix", "contour", "apriltag", "none"], help="corner refinement (default edges)"
    )
    p.add_argument(
        "--max-megapixels",
        type=float,
        default=100.0,
        metavar="MP",
        help="largest picture read, in megapixels (default 100): a larger one is refused from its header",
    )
    add_track_options(p)
    add_bag_options(p)
    add_live_option(p)
    p.set_defaults(run=run)


def _fmt_row(name: str, width: int, pose=None, note: str = "") -> str:
    if pose is None:
        return f"{name:<{width}}  {note}"
    x, y, z = np.round(pose.position_mm, 1) + 0.0  # + 0.0 turns -0.0 into 0.0
    r, pi, yw = np.round(pose.rpy_deg, 1) + 0.0
    ids = ",".join(str(i) for i in pose.marker_ids)
    flag = "AMBIGUOUS" if pose.ambiguous else "-"
    row = (
        f"{name:<{width}} {x:9.1f} {y:9.1f} {z:9.1f} {r:7.1f} {pi:7.1f} {yw:7.1f}  {ids:<9} "
        f"{pose.reprojection_rms_px:6.2f}  {flag}"
    )
    return row + (f"  {note}" if note else "")


def _pose_record(name: str, pose: Pose) -> dict:
    """One frame's JSON record: the pose (mm, deg), the markers used, the quality.

    Parameters
    ----------
    name : str
        The frame's name (a file name, ``"video.mp4#7"`` or ``"camera0#7"``).
    pose : Pose
        The frame's pose.

    Returns
    -------
    dict
        ``frame``, ``located`` (True), ``T_world_camera`` (4x4, mm), ``position_mm``, ``rpy_deg``,
        ``position_std_mm`` (None when not determined), ``marker_ids``, ``reprojection_rms_px``,
        ``ambiguous``, ``rejected_ids``, ``ignored_ids``, ``method`` and, for an ambiguous pose,
        ``alternative_position_mm``. Every value is JSON (no NaN).
    """
    return {"frame": name, "located": True, **pose.to_dict()}


def _row_and_record(name: str, width: int, located: FramePose) -> tuple[str, dict]:
    """The frame's line in the table and its JSON record."""
    pose, failure = located.pose, located.reason
    if pose is None:
        seen = located.seen_ids
        note = failure
        if failure == NO_MARKER and seen:
            note += f" (saw ids {', '.join(map(str, seen))}, not in the map)"
        return _fmt_row(name, width, None, note), {
            "frame": name,
            "located": False,
            "reason": failure,
            "detected_ids": seen,
        }
    note = f"rejected {list(pose.rejected_ids)}" if pose.rejected_ids else ""
    return _fmt_row(name, width, pose, note), _pose_record(name, pose)


class _Table:
    """The frames done so far: the printed table and the counts for the closing line."""

    def __init__(self, width: int):
        self.width = width
        self.frames = self.located = self.ambiguous = 0
        self.rms: list[float] = []
        self.searched_other_dictionaries = False

    def add(self, row: str, pose: Pose | None) -> None:
        if pose is not None:
            self.located += 1
            self.ambiguous += bool(pose.ambiguous)
            self.rms.append(pose.reprojection_rms_px)
        if self.frames == 0:
            w = self.width
            print(
                f"{'frame':<{w}} {'x_mm':>9} {'y_mm':>9} {'z_mm':>9} {'roll':>7} {'pitch':>7} {'yaw':>7}  "
                f"{'markers':<9} {'rms_px':>6}  ambiguous"
            )
        print(row, flush=True)

    def summary(self) -> str:
        med = f", median rms {statistics.median(self.rms):.2f} px" if self.rms else ""
        amb = f", {self.ambiguous} ambiguous" if self.ambiguous else ""
        n = self.frames
        return f"{n} frames, {self.located} located ({100.0 * self.located / max(n, 1):.0f} %){med}{amb}"


def _say_other_dictionaries(frame, located: FramePose, locator: FrameLocator, table: _Table) -> None:
    """Once a run, for the first frame where nothing of the map's dictionaries is seen: a warning naming the
    dictionaries whose markers the frame shows instead (a detector sees only its own dictionary's markers)."""
    if table.searched_other_dictionaries or located.reason != NO_MARKER or located.seen_ids or table.located:
        return
    table.searched_other_dictionaries = True
    say_other_dictionaries(frame, located, locator.marker_map)


def _process(args, frames_in, locator: FrameLocator, staging: _Staging, table: _Table, sink, bag_sink, live) -> None:
    """Every frame: its pose, its record (written first: a row on the screen is always in the file), its row."""
    with staging, bag_sink if bag_sink is not None else contextlib.nullcontext():
        try:
            for frame in frames_in:
                located = locator.locate(frame)
                _say_other_dictionaries(frame, located, locator, table)
                row, record = _row_and_record(frame.name, table.width, located)
                if sink is not None:
                    sink.write(record)
                if bag_sink is not None:
                    bag_sink.put(table.frames, located.pose)
                table.add(row, located.pose)
                image = draw_pose(frame.image, located.detections, locator.marker_map, located.camera, located.pose)
                staging.save(frame.name, image)
                if bag_sink is not None and args.annotated_images:
                    bag_sink.image(table.frames, image)
                if live is not None:
                    live.frame(table.frames, located, located.pose)
                table.frames += 1
        except KeyboardInterrupt as exc:
            if args.camera_index is None or isinstance(exc, _Interrupted):
                raise
            # Ctrl-C stopping a live camera is its normal end: keep what was seen


def _check_args(args):
    """The inputs (a bag, or pictures and videos) and the --json path, checked before any file is read."""
    if not args.inputs and args.camera_index is None:
        raise UsageError(
            "give images, folders, videos or a ROS 2 bag to locate in, or --camera-index N for a live camera"
        )
    if args.camera_index is not None and not 0 <= args.camera_index <= 255:
        # cv2.VideoCapture(-1) crashes the interpreter (segmentation fault) on OpenCV 4.x and 5.x
        # when no camera is attached, and 2**31 overflows OpenCV's int: refuse both before OpenCV sees them.
        raise UsageError(f"--camera-index {args.camera_index}: cameras are numbered 0 (the first camera) to 255")
    if not 0.01 <= args.max_megapixels <= 2000:
        raise UsageError(f"--max-megapixels {args.max_megapixels:g}: give 0.01 to 2000")
    bag = bag_input(args)
    items = expand_inputs(args.inputs, videos=True) if bag is None else [("video", bag)]
    json_path = _check_output(args.json, (".jsonl", ".json"), "--json") if args.json else None
    _refuse_clobber([("--json", json_path)], [p for _, p in items] + [args.camera, args.map], args.annotate)
    return items, json_path, bag


def _frames_in(args, items, camera, bag_run):
    if bag_run is not None:
        return bag_run.frames()
    check_picture_sizes(items, camera, args.max_megapixels * 1e6)  # one error line, before any frame's row or warning
    return read_frames(items, args.camera_index, int(args.max_megapixels * 1_000_000))


def _say_interrupted(exc, args, table: _Table, streams, staging: _Staging) -> None:
    """The closing line of an interrupted run: what each output holds."""
    kept = []
    for path, sink, what in streams:
        if path is not None:
            n = sink.count if sink is not None else 0
            kept.append(f"{path} holds {n} {what}{'s' if n != 1 else ''}")
    if args.annotate:
        kept.append(staging.said())
    print(
        f"error: interrupted by {_signal_name(exc)} after {table.frames} frames"
        + (f"; {'; '.join(kept)}" if kept else ""),
        file=sys.stderr,
    )


def _inputs(args):
    """The checked inputs, the --json path, the bag output, the camera (or the bag's) and the bag being read."""
    items, json_path, bag = _check_args(args)
    track_out = check_track_args(args, [p for _, p in items])
    camera = _load_camera(args) if args.camera is not None else None  # first: a map given as --camera is named
    bag_run = BagRun(args, bag, camera) if bag is not None else None
    camera = bag_run.camera if bag_run is not None else camera
    return items, json_path, track_out, camera, bag_run


def _sinks(args, track_out, bag_run, marker_map):
    """Where the untracked poses go besides the table: a ROS 2 bag, the live view."""
    bag_sink = None
    if track_out is not None:
        assert bag_run is not None, "check_track_args allows a bag output only for a bag input"
        bag_sink = BagSink(track_out, bag_run, marker_map)
    live = LiveRun(args, marker_map, bag_run) if args.live is not None else None
    return bag_sink, live


def run(args) -> int:
    """Locate in every frame; print the table and the closing lines. 128 + signal when interrupted.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit status: 0 when done.

    Raises
    ------
    FidlearnError
        A user error (``UsageError`` for the command line itself); :func:`fidlearn.cli.main` prints it
        as one ``error:`` line and exits with status 2.
    """
    items, json_path, track_out, camera, bag_run = _inputs(args)
    if args.track:
        return run_tracked(args, items, _load_map(args), camera, track_out, bag_run)
    _outputs().keep_on_interrupt = True  # every finished frame is kept
    staging = _Staging(args.annotate)
    frames_in = _frames_in(args, items, camera, bag_run)
    marker_map = _load_map(args)
    assert camera is not None, "_check_args asks for --camera unless the input is a bag"
    locator = FrameLocator(marker_map, camera, refine=args.refine)
    bag_sink, live = _sinks(args, track_out, bag_run, marker_map)
    width = max(
        [len(p.name) + (8 if k == "video" else 0) for k, p in items] + [len(f"camera{args.camera_index}#00000"), 5]
    )
    table = _Table(min(width, 40))
    sink = None
    try:
        if json_path is not None:
            with _StreamFile(json_path, "--json") as sink:
                _process(args, frames_in, locator, staging, table, sink, bag_sink, live)
        else:
            _process(args, frames_in, locator, staging, table, None, bag_sink, live)
    except KeyboardInterrupt as exc:
        _commit()
        if live is not None:
            live.close()
        _say_interrupted(
            exc, args, table, [(json_path, sink, "whole frame record"), (track_out, bag_sink, "pose")], staging
        )
        return _exit_status(exc)
    _commit()
    if table.frames > 1 or args.camera_index is not None:
        print(table.summary())
    if json_path:
        print(f"poses written to {json_path}")
    if args.annotate:
        print(staging.said())
    if bag_sink is not None:
        print(f"{bag_sink.count} poses written to {track_out}")
    if live is not None:
        live.hold()
    return 0
