"""``fidlearn locate BAG --track -o OUT.mcap`` on a 60-frame 640x480 ROS 2 bag, against plain OpenCV on the same frames.

    python benchmarks/bench_rosbag.py            # 7 interleaved pairs
    python benchmarks/bench_rosbag.py --quick    # 3 pairs

The bag: 60 frames of a rendered drive past the course's three markers (``render_trajectory``,
640x480, 60 deg), recorded at 30 frames per second (2.0 s of real time) as ``sensor_msgs/msg/Image``
bgr8 with a CameraInfo beside each (``fidlearn.ros.write_image_bag``, one .mcap file).

fidlearn: the whole command in-process (``fidlearn.cli.main``, its table sent to a buffer): open
the bag, read and decode each image, locate (one MarkerTracker), track (PoseTracker on the header
stamps), write the output bag (pose, odometry, TF, markers) and rename it. Plain OpenCV: the same
frames read from the same bag with rosbags (``AnyReader``, the image's bytes reshaped), then
``cv2.aruco.ArucoDetector.detectMarkers`` and ``cv2.solvePnP`` (SQPNP) on the map's markers seen,
for each frame: what a program of a few lines does, with no tracking and no output. The two runs
alternate (fidlearn, OpenCV, fidlearn, ...); the ratio is the median of the per-pair ratios, in
wall-clock time and in CPU time (``time.process_time``). The real-time factor is the bag's
duration (60 frames at 30 fps) over fidlearn's median time, and the position error of the last
tracked pose against the truth is given beside it.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

import fidlearn
from fidlearn import _cv
from fidlearn.cli import main
from fidlearn.ros import write_image_bag
from fidlearn.ros._messages import typestore

N_FRAMES, FPS = 60, 30.0
T0 = 1_700_000_000_000_000_000


def make_bag(folder: Path):
    marker_map = fidlearn.MarkerMap.load(fidlearn.data_path("world_map.json"))
    camera = fidlearn.Camera.from_fov(60, (640, 480))
    drive = fidlearn.render_trajectory(marker_map, camera, n_frames=N_FRAMES)
    stamps = [T0 + round(k * 1e9 / FPS) for k in range(N_FRAMES)]
    return write_image_bag(folder / "drive.mcap", drive.images, camera, stamps), marker_map, camera, drive


def run_fidlearn(bag: Path, out: Path) -> None:
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["locate", str(bag), "--map", str(fidlearn.data_path("world_map.json")), "--track", "-o", str(out)])
    assert code == 0


def run_plain(bag: Path, marker_map, camera) -> int:
    from rosbags.highlevel import AnyReader

    detector = cv2.aruco.ArucoDetector(_cv.get_dictionary(marker_map.dictionary), cv2.aruco.DetectorParameters())
    corners_3d = marker_map.corners()
    located = 0
    with AnyReader([bag], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/camera/image_raw"]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            image = np.asarray(msg.data).reshape(msg.height, msg.step)[:, : msg.width * 3].reshape(msg.height, -1, 3)
            corners, ids, _ = detector.detectMarkers(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
            if ids is None:
                continue
            seen = [
                (c.reshape(4, 2), corners_3d[int(i)]) for c, i in zip(corners, ids.reshape(-1)) if int(i) in corners_3d
            ]
            if not seen:
                continue
            img = np.concatenate([s[0] for s in seen]).astype(np.float64)
            obj = np.concatenate([s[1] for s in seen]).astype(np.float64)
            ok, _, _ = cv2.solvePnP(obj, img, camera.K, camera.dist, flags=cv2.SOLVEPNP_SQPNP)
            located += bool(ok)
    return located


def last_error_mm(out: Path, drive) -> float:
    from rosbags.highlevel import AnyReader

    with AnyReader([out], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic == "/fidlearn/pose"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    p = msgs[-1].pose.pose.position
    return float(np.linalg.norm(np.array([p.x, p.y, p.z]) * 1000.0 - drive.T_world_camera[-1][:3, 3]))


def timed(fn, *args):
    w, c = time.perf_counter(), time.process_time()
    fn(*args)
    return time.perf_counter() - w, time.process_time() - c


def main_bench(pairs: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bag, marker_map, camera, drive = make_bag(folder)
        assert run_plain(bag, marker_map, camera) == N_FRAMES
        run_fidlearn(bag, folder / "warm.mcap")  # imports and OpenCV's first calls, outside the timing
        fid, plain = [], []
        for k in range(pairs):
            fid.append(timed(run_fidlearn, bag, folder / f"out{k}.mcap"))
            plain.append(timed(run_plain, bag, marker_map, camera))
        err = last_error_mm(folder / "out0.mcap", drive)
        size_mb = bag.stat().st_size / 1e6
    real_s = N_FRAMES / FPS
    wall = statistics.median(f[0] for f in fid)
    cpu = statistics.median(f[1] for f in fid)
    r_wall = statistics.median(f[0] / p[0] for f, p in zip(fid, plain))
    r_cpu = statistics.median(f[1] / p[1] for f, p in zip(fid, plain))
    print(f"Bag: {N_FRAMES} frames 640x480 bgr8 at {FPS:g} fps ({real_s:.1f} s), {size_mb:.1f} MB, one .mcap file.")
    print()
    print("| run | wall s (median) | CPU s (median) | x real time (wall) | x real time (CPU) |")
    print("| --- | ---: | ---: | ---: | ---: |")
    factors = f"{real_s / wall:.1f} | {real_s / cpu:.1f}"
    print(f"| fidlearn locate BAG --track -o OUT.mcap | {wall:.3f} | {cpu:.3f} | {factors} |")
    pw = statistics.median(p[0] for p in plain)
    pc = statistics.median(p[1] for p in plain)
    factors = f"{real_s / pw:.1f} | {real_s / pc:.1f}"
    print(f"| plain OpenCV (rosbags + detectMarkers + solvePnP) | {pw:.3f} | {pc:.3f} | {factors} |")
    print()
    print(
        f"Ratio fidlearn / plain OpenCV (median of {pairs} interleaved pairs): {r_wall:.2f} x wall, {r_cpu:.2f} x CPU."
    )
    print(f"Last tracked pose against the truth: {err:.1f} mm.")
    met = "yes" if real_s / wall >= 10 else "no"
    print()
    print(
        f"<!-- target: ROS 2 bag: 60 frames 640x480 at 30 fps through locate --track -o OUT.mcap >= 10 x real time | "
        f"{real_s / wall:.1f} x wall ({real_s / cpu:.1f} x CPU), {r_wall:.2f} x plain OpenCV | {met} -->"
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 pairs instead of 7")
    main_bench(3 if ap.parse_args().quick else 7)
