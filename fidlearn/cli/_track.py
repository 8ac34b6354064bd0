"""``fidlearn locate --track``: the frames' poses through a :class:`fidlearn.PoseTracker`, written as JSON lines,
a TUM trajectory or ROS messages.

The frames are taken in the order given, ``1 / --fps`` seconds apart (the first at t = 0 s);
:func:`fidlearn.track` gives each frame's pose as ``fidlearn locate`` gives it without ``--track``
and the tracked pose of one PoseTracker for the whole run. This module prints and writes them.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from pathlib import Path

import numpy as np

from .. import frames
from ..detection import dictionaries_in
from ..drawing import draw_pose
from ..errors import FidlearnWarning, UsageError
from ..filtering import TrackedPose
from ..images import read_frames
from ..ros import read_mount_json, read_odometry_csv, ros_pose, tum_line
from ..sequences import NO_MARKER, FramePose, check_picture_sizes, track
from ._bag import BagRun, BagSink
from ._common import _check_output, _exit_status, _refuse_clobber, _signal_name, _StreamFile
from ._live import LiveRun

FORMATS = {"jsonl": (".jsonl", ".json"), "tum": (".txt", ".tum"), "ros": (".jsonl", ".json"), "bag": (".mcap", "")}

TRACK_HELP = """\
tracking (--track): the frames are one run, 1/--fps seconds apart from t = 0 s, in the order given.
Each frame's pose goes through a Kalman filter on the pose (fidlearn.PoseTracker): ambiguous
frames take the solution that agrees with the track (no flips), a frame that disagrees beyond
the chi-square gate (0.999) is rejected and said so, frames without a marker are bridged.

--odometry ODOM.csv   the robot base's pose in its odometry frame over time, metres and a
                      quaternion, times in seconds on the frames' clock (t = 0 at the first frame):
                        t_s,x_m,y_m,z_m,qx,qy,qz,qw
                        0.000,0.0,0.0,0.0,0.0,0.0,0.0,1.0
                      only the motion between frames is used; its uncertainty is --odometry-drift
                      (default 0.02: 2 % of the distance and of the angle of each step). Without
                      --mount the odometry is taken as the camera's own pose (its optical frame:
                      x right, y down, z forward); a robot's odometry (x forward) needs --mount.
--mount MOUNT.json    where the camera sits on the robot (REP-103 base: x forward, y left, z up):
                        {"units": "mm", "camera_in_base": {"translation": [200, 0, 300],
                         "rpy_deg": [0, 0, 0]}, "camera_axes": "link"}
                      camera_axes "link": rpy 0 looks along the base's x; "optical": the rotation of
                      the camera's optical frame (x right, y down, z forward). Or {"units": "mm",
                      "T_camera_base": 4x4}. With it the output is the robot base's pose (base_link).
--format              how -o is written: jsonl (one JSON line per frame: the tracked pose in mm and
                      degrees, its covariance, status, the odometry scale learnt so far), tum (t x y z
                      qx qy qz qw, metres), ros (one geometry_msgs/PoseWithCovarianceStamped per line
                      as JSON: frame map, metres, quaternion x y z w, covariance in x y z rotX rotY
                      rotZ order, m and rad; tum and ros time a bag's frames by their images' header
                      stamps, seconds since 1970, and other frames from t = 0 s), bag (a ROS 2
                      bag: -o OUT.mcap, or a new folder; see ROS 2 bags below; chosen by the name
                      .mcap)."""


def say_other_dictionaries(frame, located: FramePose, marker_map) -> None:
    """Warn that ``frame`` shows no marker of the map's dictionaries but markers of others, naming them.

    A detector finds only its own dictionary's markers: a map written for the wrong dictionary finds
    nothing in any frame, and this says which dictionary the pictures show instead.

    Parameters
    ----------
    frame : Frame
        The frame (its ``name`` and ``image``).
    located : FramePose
        What the frame gave: nothing is said unless it saw no marker at all (:data:`NO_MARKER`, no id).
    marker_map : MarkerMap
        The world map (its dictionaries).
    """
    if located.reason != NO_MARKER or located.seen_ids:
        return
    mine = marker_map.dictionaries
    found = dictionaries_in(frame.image, exclude=mine)
    if not found:
        return
    best = max(found, key=lambda name: len(found[name]))
    seen = "; ".join(f"{name}: ids {', '.join(map(str, ids))}" for name, ids in found.items())
    print(
        f"warning: {frame.name} shows no marker of the map's dictionary {', '.join(mine)} but markers of another "
        f"dictionary ({seen}): a detector finds only its own dictionary's markers; if those are the markers you "
        f'placed, write "dictionary": "{best}" in the map (or give --dictionary {best} for a map that does not '
        "name one)",
        file=sys.stderr,
    )


class HelpFormatter(argparse.HelpFormatter):
    """Wraps the description as usual, keeps the tracking notes (text with line breaks) as written."""

    def _fill_text(self, text, width, indent):
        if "\n" in text:
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def add_track_options(p) -> None:
    """The ``--track`` options of ``fidlearn locate``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The ``locate`` parser.
    """
    g = p.add_argument_group("tracking (see below)")
    g.add_argument("--track", action="store_true", help="filter the poses over time (fidlearn.PoseTracker)")
    g.add_argument("--fps", type=float, help="frames per second of the run (default 30)")
    g.add_argument("--odometry", type=Path, metavar="ODOM.csv", help="the robot's odometry (format below)")
    g.add_argument("--odometry-drift", type=float, metavar="FRACTION", help="default 0.02")
    g.add_argument("--mount", type=Path, metavar="MOUNT.json", help="the camera's place on the robot (below)")
    g.add_argument("--format", choices=list(FORMATS), help="how -o is written (default jsonl)")
    g.add_argument("-o", "--output", type=Path, metavar="TRACK", help="write the tracked poses here")


def _refuse_tracking_options(args) -> None:
    """UsageError for an option of tracking given without --track (--fps also stamps a --live view)."""
    bag = args.format == "bag"
    used = [o for o, v in (("--odometry", args.odometry), ("--odometry-topic", args.odometry_topic),
                           ("--mount", args.mount), ("--odometry-drift", args.odometry_drift),
                           ("--fps", None if getattr(args, "live", None) is not None else args.fps),
                           ("--format", None if bag else args.format), ("-o", None if bag else args.output))
            if v is not None]  # fmt: skip
    if used:
        raise UsageError(f"{used[0]} belongs to tracking: add --track")


def check_track_args(args, inputs: list[Path]) -> Path | None:
    """The tracking options checked before any work; the output path (None without -o).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    inputs : list of Path
        The input files (the output may be none of them).

    Returns
    -------
    Path or None
        The checked output path.

    Raises
    ------
    UsageError
        A tracking option without --track, --format without -o, a bad --fps or drift, a clobbered input.
    """
    if args.output is not None and args.format is None and Path(args.output).suffix.lower() == ".mcap":
        args.format = "bag"
    if not args.track:
        _refuse_tracking_options(args)
        return _output(args, inputs)
    args.fps = 30.0 if args.fps is None else args.fps
    args.odometry_drift = 0.02 if args.odometry_drift is None else args.odometry_drift
    if not 0.1 <= args.fps <= 10000:
        raise UsageError(f"--fps {args.fps:g}: give the frames per second, 0.1 to 10000")
    if not 0.0 < args.odometry_drift < 1.0:
        raise UsageError(f"--odometry-drift {args.odometry_drift:g}: give a fraction between 0 and 1 (0.02 is 2 %)")
    if args.format is not None and args.output is None:
        raise UsageError("--format says how -o is written: give -o FILE")
    if args.odometry is not None and args.odometry_topic is not None:
        raise UsageError("give the odometry once: --odometry ODOM.csv or --odometry-topic TOPIC (from the bag)")
    if args.camera_index is not None:
        raise UsageError("--track runs over files (videos, pictures); a live camera is not tracked yet")
    if args.json is not None or args.annotate is not None:
        raise UsageError(
            "with --track the output is -o FILE (see --format); --json and --annotate are for untracked runs"
        )
    return _output(args, inputs)


def _output(args, inputs: list[Path]) -> Path | None:
    if args.format is not None and args.output is None:
        raise UsageError("--format says how -o is written: give -o FILE")
    if args.output is None:
        return None
    out = _check_output(args.output, FORMATS[args.format or "jsonl"], "-o")
    _refuse_clobber([("-o", out), ("--json", args.json)], inputs + [args.camera, args.map, args.odometry, args.mount])
    if args.format == "bag" and out.exists():
        raise UsageError(f"-o {out} exists; a bag is never written over: give a new name")
    return out


class _LineFile(_StreamFile):
    """A stream of text lines (TUM) or JSON lines, written to a hidden file renamed at the end."""

    def write(self, record) -> None:
        if isinstance(record, str):
            try:
                self.file.write(record + "\n")
                self.file.flush()
            except OSError as exc:
                raise UsageError(f"{self.option} {self.path}: cannot write it ({exc.strerror})") from None
            self.count += 1
        else:
            super().write(record)


def _record(name: str, out: TrackedPose, fmt: str, stamp_ns: int | None = None) -> str | dict:
    """The frame's line: a bag's frames carry their images' stamps (``stamp_ns``) in the tum and ros formats."""
    if fmt == "tum":
        T = out.T_world_base if out.T_world_base is not None else out.T_world_camera
        if stamp_ns is None:
            return tum_line(out.t_s, T)
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)  # exact: a float of seconds since 1970 keeps 0.2 us
        return f"{sec}.{nanosec:09d}" + tum_line(0.0, T)[len("0.000000000") :]
    if fmt == "ros":
        msg = ros_pose(out)
        if stamp_ns is not None:  # builtin_interfaces/msg/Time, exact
            sec, nanosec = divmod(stamp_ns, 1_000_000_000)
            msg["header"]["stamp"] = {"sec": sec, "nanosec": nanosec}
        return msg
    base = out.T_world_base is not None
    T = out.T_world_base if out.T_world_base is not None else out.T_world_camera
    cov = out.base_covariance if base else out.covariance
    assert cov is not None  # the tracker gives the base's covariance with its pose
    return {
        "frame": name,
        "t_s": out.t_s,
        "body": "base" if base else "camera",
        "T_world_body": T.tolist(),
        "position_mm": T[:3, 3].tolist(),
        "rpy_deg": frames.rpy_deg_from_rotation(T[:3, :3]).tolist(),
        "covariance": cov.tolist(),
        "status": out.status,
        "flip_resolved": out.flip_resolved,
        "reason": out.reason,
        "odometry_scale": out.odometry_scale,
        "odometry_scale_std": out.odometry_scale_std,
    }


def _row(name: str, width: int, out: TrackedPose | None) -> str:
    if out is None:
        return f"{name:<{width}}  no pose yet (the track starts at the first frame with a pose)"
    T = out.T_world_base if out.T_world_base is not None else out.T_world_camera
    cov = out.base_covariance if out.T_world_base is not None else out.covariance
    assert cov is not None  # the tracker gives the base's covariance with its pose
    x, y, z = np.round(T[:3, 3], 1) + 0.0
    r, p, yw = np.round(frames.rpy_deg_from_rotation(T[:3, :3]), 1) + 0.0
    std = float(np.sqrt(max(np.trace(cov[3:, 3:]), 0.0)))
    note = "flip resolved" if out.flip_resolved else ""
    if out.rejected:
        note = out.reason.split(":")[0]
    return (
        f"{name:<{width}} {out.t_s:8.3f} {x:9.1f} {y:9.1f} {z:9.1f} {r:7.1f} {p:7.1f} {yw:7.1f} {std:7.1f}  "
        f"{out.status:<9} {note}"
    ).rstrip()


class _Run:
    """The frames done so far and what happened to them."""

    def __init__(self, args, sink, bag_run: BagRun | None = None):
        self.args, self.sink, self.bag_run = args, sink, bag_run
        self.fmt = args.format or "jsonl"
        self.frames = 0
        self.counts: dict[str, int] = {}
        self.last: TrackedPose | None = None

    def frame(self, name: str, out: TrackedPose | None) -> None:
        """One frame's tracked pose counted and its record written."""
        if out is not None:
            self.last = out
            self.counts[out.status] = self.counts.get(out.status, 0) + 1
            self.counts["flips resolved"] = self.counts.get("flips resolved", 0) + out.flip_resolved
            if isinstance(self.sink, BagSink):
                self.sink.put(self.frames, out)
            elif self.sink is not None:
                stamps = self.bag_run.stamps if self.bag_run is not None else None
                self.sink.write(_record(name, out, self.fmt, stamps[self.frames] if stamps else None))
        self.frames += 1


def _loop(run: _Run, steps, width: int, live: LiveRun | None, marker_map=None) -> None:
    if run.sink is not None and run.fmt == "tum":
        run.sink.write("# timestamp tx ty tz qx qy qz qw")
    drawn = isinstance(run.sink, BagSink) and run.args.annotated_images
    searched = False  # the other dictionaries are searched once, in the first frame that shows none of the map's
    for step in steps:
        name = step.located.frame.name
        if not searched and run.last is None and step.located.reason == NO_MARKER and not step.located.seen_ids:
            searched = True
            say_other_dictionaries(step.located.frame, step.located, marker_map)
        if live is not None:
            live.frame(run.frames, step.located, step.tracked)
        if drawn:  # the frame as the camera saw it: its detections and its own located pose
            at = step.located
            run.sink.image(run.frames, draw_pose(at.frame.image, at.detections, marker_map, at.camera, at.pose))
        run.frame(name, step.tracked)
        print(_row(name, width, step.tracked), flush=True)


def _timed_frames(args, items, bag_run: BagRun | None):
    """The frames and their times: a bag's by their stamps, else None (1 / --fps apart)."""
    if bag_run is not None:
        return bag_run.frames(increasing=True), bag_run.times()
    return read_frames(items, None, int(args.max_megapixels * 1_000_000)), None


def _odometry(args, bag_run: BagRun | None):
    """The odometry of --odometry or --odometry-topic; None without."""
    odometry = read_odometry_csv(args.odometry, args.odometry_drift) if args.odometry else None
    if args.odometry_topic is not None and bag_run is not None:
        odometry = bag_run.odometry(args.odometry_topic, args.odometry_drift)
    return odometry


def _say_odometry(args, last: TrackedPose | None) -> None:
    """The closing lines of a run with odometry: the scale learnt, and a warning when no --mount said where the
    camera sits on the base whose motion the odometry gives."""
    if last is not None:
        scale, std = last.odometry_scale, last.odometry_scale_std
        print(f"odometry scale learnt from the poses: {scale:.4f} +/- {std:.4f} (what its distances are multiplied by)")
    if args.mount is None:
        warnings.warn(
            "odometry without --mount: it was taken as the camera's own motion in its optical frame (x right, y down, "
            "z forward); for a robot's odometry (x forward, y left, z up) give --mount MOUNT.json, where the camera "
            "sits on the robot (see 'fidlearn locate --help')",
            FidlearnWarning,
            stacklevel=2,
        )


def _sink(args, out_path: Path | None, bag_run, marker_map, mount) -> _LineFile | BagSink | None:
    if out_path is None:
        return None
    return BagSink(out_path, bag_run, marker_map, mount) if args.format == "bag" else _LineFile(out_path, "-o")


def run_tracked(args, items, marker_map, camera, out_path: Path | None, bag_run: BagRun | None = None) -> int:
    """Every frame through :func:`fidlearn.track`; the table, the closing line and the output file.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    items : list
        The inputs as :func:`fidlearn.images.expand_inputs` gives them.
    marker_map : MarkerMap
        The world map.
    camera : Camera
        The camera file's camera.
    out_path : Path or None
        The output file (checked).
    bag_run : BagRun, optional
        The input bag: its frames, timed by their stamps.

    Returns
    -------
    int
        0 when done; 128 + signal when interrupted.
    """
    if bag_run is None:
        check_picture_sizes(items, camera, args.max_megapixels * 1e6)
    mount = read_mount_json(args.mount) if args.mount else None
    odometry = _odometry(args, bag_run)
    frames_in, times = _timed_frames(args, items, bag_run)
    steps = track(
        frames_in, marker_map, camera, fps=args.fps, refine=args.refine, T_camera_base=mount, odometry=odometry,
        times=times,
    )  # fmt: skip
    width = min(max([len(p.name) + 8 for _, p in items] + [5]), 40)
    print(
        f"{'frame':<{width}} {'t_s':>8} {'x_mm':>9} {'y_mm':>9} {'z_mm':>9} {'roll':>7} {'pitch':>7} {'yaw':>7} "
        f"{'std_mm':>7}  status"
    )
    sink = _sink(args, out_path, bag_run, marker_map, mount)
    run = _Run(args, sink, bag_run)
    live = LiveRun(args, marker_map, bag_run, mount) if args.live is not None else None
    try:
        with sink if sink is not None else contextlib.nullcontext():
            _loop(run, steps, width, live, marker_map)
    except KeyboardInterrupt as exc:
        if live is not None:
            live.close()
        what = "poses" if isinstance(sink, BagSink) else "whole lines"
        kept = f"; {out_path} holds {sink.count} {what}" if sink is not None else ""
        print(f"error: interrupted by {_signal_name(exc)} after {run.frames} frames{kept}", file=sys.stderr)
        return _exit_status(exc)
    said = ", ".join(f"{v} {k}" for k, v in run.counts.items() if v)
    print(f"{run.frames} frames tracked: {said or 'no pose'}")
    if odometry is not None:
        _say_odometry(args, run.last)
    if out_path is not None:
        print(f"{run.fmt} track written to {out_path}")
    if live is not None:
        live.hold()
    return 0


__all__ = [
    "add_track_options",
    "check_track_args",
    "run_tracked",
    "say_other_dictionaries",
    "TRACK_HELP",
    "HelpFormatter",
]
