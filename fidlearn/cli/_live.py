"""``fidlearn locate ... --live``: the run shown in Foxglove as it goes (:class:`fidlearn.ros.LiveView`).

The server listens on 127.0.0.1 only. The command waits up to :data:`WAIT_S` seconds for a viewer
before the first frame (so nothing is missed), replays a bag at its recorded pace, and keeps serving
after the last frame until Ctrl-C, which then ends the command normally (status 0).
"""

from __future__ import annotations

import time

from ..drawing import draw_pose
from ..ros import LiveView
from ._bag import BagRun

#: How long the command waits for a viewer before it starts without one, seconds.
WAIT_S = 60.0


def add_live_option(p) -> None:
    """The ``--live [PORT]`` option of ``fidlearn locate``.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The ``locate`` parser.
    """
    p.add_argument(
        "--live",
        nargs="?",
        const=8765,
        type=int,
        metavar="PORT",
        help="show the run in Foxglove: serve it on ws://127.0.0.1:PORT (default 8765; 0 any free port), "
        "waiting for a viewer first; Ctrl-C closes it after the last frame",
    )


class LiveRun:
    """The frames of one run sent to a :class:`LiveView`, at their stamps.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``--live``, ``--fps``).
    marker_map : MarkerMap
        The world map (drawn on the frames and sent as markers).
    bag_run : BagRun or None
        The input bag: its stamps (and the frames are replayed at their pace).
    mount : ndarray or None
        ``T_camera_base``.
    """

    def __init__(self, args, marker_map, bag_run: BagRun | None, mount=None):
        self.marker_map, self.bag_run, self.fps = marker_map, bag_run, float(getattr(args, "fps", 30.0) or 30.0)
        frame = bag_run.bag.frame_id if bag_run is not None else None
        self.view = LiveView(args.live, marker_map, T_camera_base=mount, camera_frame=frame or "camera")
        self.start_ns = time.time_ns()
        self.clock: float | None = None
        print(
            f"live view: {self.view.url} (Foxglove: Open connection -> Foxglove WebSocket -> this URL); "
            f"waiting up to {WAIT_S:.0f} s for it",
            flush=True,
        )
        if not self.view.wait_for_viewer(WAIT_S):
            print("live view: no viewer yet; going on (one may still connect)", flush=True)

    def _stamp(self, index: int) -> int:
        if self.bag_run is not None:
            stamp = self.bag_run.stamps[index]
            if self.clock is None:
                self.clock = time.monotonic() - (stamp - self.bag_run.stamps[0]) / 1e9
            time.sleep(max(0.0, self.clock + (stamp - self.bag_run.stamps[0]) / 1e9 - time.monotonic()))
            return stamp
        return self.start_ns + round(index * 1e9 / self.fps)

    def frame(self, index: int, located, pose) -> None:
        """Frame ``index``: its picture with the markers and axes drawn, and its pose.

        Parameters
        ----------
        index : int
            The frame's number in the run.
        located : FramePose
            The frame's own pose and detections.
        pose : Pose or TrackedPose or None
            The pose to show (the tracked one with --track).
        """
        stamp = self._stamp(index)
        image = draw_pose(located.frame.image, located.detections, self.marker_map, located.camera, located.pose)
        self.view.frame(stamp, image, pose)

    def hold(self) -> None:
        """Keep serving until Ctrl-C (or SIGTERM), then close."""
        try:
            print(f"live view: {self.view.frames} frames sent; open at {self.view.url} until Ctrl-C", flush=True)
            while True:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            self.view.close()

    def close(self) -> None:
        """Stop serving."""
        self.view.close()


__all__ = ["LiveRun", "WAIT_S", "add_live_option"]
