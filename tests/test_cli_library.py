"""``fidlearn locate`` gives the library's answers: fidlearn.locate on pictures, MarkerTracker on a video."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn.cli import main
from fidlearn.errors import NoMarkersError, PoseError

DATA = Path(fidlearn.data_path("scenes")).parent
SCENES = json.loads((DATA / "scenes" / "poses.json").read_text())["images"]


def _records(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]


def _same_pose(record: dict, pose) -> None:
    """The JSON record holds the pose exactly (JSON writes Python floats in full)."""
    assert record["located"] is True, record
    np.testing.assert_allclose(record["position_mm"], pose.position_mm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(record["rpy_deg"], pose.rpy_deg, rtol=0, atol=1e-9)
    np.testing.assert_allclose(record["T_world_camera"], pose.T_world_camera, rtol=0, atol=1e-9)
    assert record["marker_ids"] == list(pose.marker_ids)
    assert record["reprojection_rms_px"] == pytest.approx(pose.reprojection_rms_px, rel=0, abs=1e-9)
    assert record["ambiguous"] is bool(pose.ambiguous)
    assert record["rejected_ids"] == list(pose.rejected_ids)
    assert record["method"] == pose.method


@pytest.mark.parametrize("map_name", sorted({s["map"] for s in SCENES}))
def test_locate_json_is_fidlearn_locate_on_every_bundled_scene(tmp_path, capsys, map_name):
    images = [DATA / "scenes" / s["image"] for s in SCENES if s["map"] == map_name]
    camera_path, map_path = DATA / "scenes" / "camera.json", DATA / map_name
    out = tmp_path / "poses.jsonl"
    argv = ["locate", *map(str, images), "--camera", str(camera_path), "--map", str(map_path), "--json", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    records = _records(out)
    assert [r["frame"] for r in records] == [p.name for p in images]
    marker_map, camera = fidlearn.MarkerMap.load(map_path), fidlearn.Camera.load(camera_path)
    for record, path in zip(records, images):
        _same_pose(record, fidlearn.locate(fidlearn.detection.load_image(path), marker_map, camera))


def _write_video(path: Path, frames: list[np.ndarray]) -> None:
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w, h))
    assert writer.isOpened(), "OpenCV cannot write MJPG here"
    for frame in frames:
        writer.write(frame if frame.ndim == 3 else cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
    writer.release()


def _read_video(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    return frames


def _tracked(tracker, frame):
    """The tracker's pose, None when it has none (returned as None, or raised)."""
    try:
        return tracker.locate(frame)
    except (NoMarkersError, PoseError):
        return None


def test_locate_json_is_marker_tracker_on_a_video(tmp_path, capsys):
    folder = DATA / "trajectory"
    pictures = [cv2.imread(str(folder / f"frame_{k:03d}.png"), cv2.IMREAD_UNCHANGED) for k in range(0, 40, 3)]
    blank = np.full_like(pictures[0], 200)  # a frame without markers: the tracker starts afresh after it
    video = tmp_path / "drive.avi"
    _write_video(video, [*pictures[:6], blank, *pictures[6:]])
    out = tmp_path / "drive.jsonl"
    camera_path, map_path = folder / "camera.json", DATA / "world_map.json"
    argv = ["locate", str(video), "--camera", str(camera_path), "--map", str(map_path), "--json", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    records = _records(out)
    frames = _read_video(video)  # the same decoded pixels the command line read
    assert [r["frame"] for r in records] == [f"drive.avi#{k}" for k in range(len(frames))]
    tracker = fidlearn.MarkerTracker(fidlearn.MarkerMap.load(map_path), fidlearn.Camera.load(camera_path))
    located = 0
    for record, frame in zip(records, frames):
        pose = _tracked(tracker, frame)
        if pose is None:
            assert record["located"] is False, record
            assert record["reason"] == "no known marker", record
        else:
            _same_pose(record, pose)
            located += 1
    assert located == len(frames) - 1
    assert tracker.full_detections < len(frames)  # the windows did part of the work, as in the command line
