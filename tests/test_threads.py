"""fidlearn from several threads at once: the same answers as one thread, and nobody's stderr lost.

Reading a picture used to point file descriptor 2 at the null device for the whole process while
it decoded; a thread that wrote to stderr meanwhile lost its message, and two threads decoding at
once could leave stderr pointed at the null device for good. Nothing in fidlearn redirects a file
descriptor now.
"""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import fidlearn
from fidlearn import Camera, MarkerMap, detect_markers, estimate_pose, locate
from fidlearn.detection import load_image

SCENES = fidlearn.data_path("scenes")
POSES = json.loads((SCENES / "poses.json").read_text())["images"]


def work(k: int) -> tuple:
    """Load, detect, estimate and locate one bundled scene: everything a robot's threads would do."""
    rec = POSES[k % len(POSES)]
    world = MarkerMap.load(SCENES.parent / rec["map"])
    camera = Camera.load(SCENES / "camera.json")
    image = load_image(SCENES / rec["image"])
    detections = detect_markers(image, world.dictionary, ids=world.ids)
    by_estimate = estimate_pose(detections, world, camera)
    by_locate = locate(image, world, camera)
    return (
        rec["image"],
        sorted(d.id for d in detections),
        np.array([d.corners_px for d in detections]),
        by_estimate.T_world_camera,
        by_locate.T_world_camera,
        by_locate.ambiguous,
    )


def test_eight_threads_give_the_answers_of_one():
    n = 3 * len(POSES)
    alone = [work(k) for k in range(len(POSES))]
    with ThreadPoolExecutor(max_workers=8) as pool:
        together = list(pool.map(work, range(n)))
    for k, got in enumerate(together):
        want = alone[k % len(POSES)]
        assert got[0] == want[0] and got[1] == want[1] and got[5] == want[5]
        np.testing.assert_array_equal(got[2], want[2])
        np.testing.assert_array_equal(got[3], want[3])
        np.testing.assert_array_equal(got[4], want[4])


SCRIPT = r"""
import os, sys, threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from fidlearn.detection import load_image
from fidlearn.errors import ImageError

folder = Path(sys.argv[1])
good = sorted(folder.glob("good*.png"))
bad = sorted(folder.glob("bad*"))
stop = threading.Event()

def talk():
    for i in range(300):
        os.write(2, f"line {i}\n".encode())
    stop.set()

def read(k):
    for _ in range(40):
        path = (good + bad)[k % (len(good) + len(bad))]
        try:
            load_image(path)
        except ImageError:
            pass
        if stop.is_set():
            break
    return k

talker = threading.Thread(target=talk)
with ThreadPoolExecutor(max_workers=8) as pool:
    futures = [pool.submit(read, k) for k in range(16)]
    talker.start()
    [f.result() for f in futures]
talker.join()
print("after", file=sys.stderr, flush=True)
"""


def test_another_threads_stderr_arrives_whole_while_pictures_are_read(tmp_path):
    import cv2

    picture = (np.arange(120 * 160) % 251).astype(np.uint8).reshape(120, 160)
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"good{k}.png"), picture)
    data = (tmp_path / "good0.png").read_bytes()
    (tmp_path / "bad_cut.png").write_bytes(data[: len(data) // 2])
    (tmp_path / "bad_text.png").write_text("not a picture")
    (tmp_path / "bad_garbled.png").write_bytes(data[:40] + bytes(range(256)) * 4 + data[-12:])
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
        env={"PYTHONPATH": str(Path(fidlearn.__file__).parent.parent), "PATH": "/usr/bin:/bin"},
    )
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert [ln for ln in lines if ln.startswith("line ")] == [f"line {i}" for i in range(300)]
    assert lines[-1] == "after"  # stderr still points where it did
