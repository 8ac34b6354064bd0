"""Every command that writes files, in a workspace of real inputs, with the outputs it must write.

Shared by the full-disk tests (``tests/test_full_disk.py``) and the signal sweep
(``tests/test_signal_sweep.py``): the inputs go in the workspace, every output in ``out/``, so that
"nothing was written" means ``out/`` is empty (hidden files included).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

import fidlearn

DATA = fidlearn.data_dir()
ROOT = Path(fidlearn.__file__).parent.parent

#: command -> (argv after ``fidlearn``, the files it writes below out/)
COMMANDS: dict[str, tuple[list[str], list[str]]] = {
    "survey": (
        ["survey", "sphotos", "--camera", "survey_camera.json", "--map", "tape.json", "--fixed", "0"]
        + ["-o", "out/surveyed.json", "--plot", "out/survey.png"],
        ["surveyed.json", "survey.png"],
    ),
    "calibrate": (
        ["calibrate", "photos", "--pattern", "9x6", "--square-mm", "25", "-o", "out/cam.json"]
        + ["--report", "out/rep.png", "--annotate", "out/seen"],
        ["cam.json", "rep.png"] + [f"seen/view_0{k}.png" for k in range(4)],
    ),
    "render": (
        ["render", "--map", "map.json", "--camera", "camera.json", "--from", "1200,150,250"]
        + ["--look-at", "0,150,250", "-o", "out/scene.png", "--truth", "out/truth.json"],
        ["scene.png", "truth.json"],
    ),
    "plan": (
        ["plan", "map.json", "--camera", "camera.json", "--step-mm", "500", "--headings", "4", "-o", "out/p.png"],
        ["p.png"],
    ),
    "markers": (
        ["markers", "--ids", "0-3", "--size-mm", "80", "--dpi", "60", "-o", "out/m.png"],
        ["m-1.png", "m-2.png"],
    ),
    "board": (["board", "--pattern", "9x6", "--square-mm", "25", "-o", "out/board.pdf"], ["board.pdf"]),
    "corners": (["corners", "map.json", "-o", "out/corners.json"], ["corners.json"]),
    "camera export": (["camera", "export", "camera.json", "--ros", "out/c.yaml"], ["c.yaml"]),
    "camera import": (["camera", "import", "camera_info.yaml", "-o", "out/cam.json"], ["cam.json"]),
    "locate": (
        ["locate", "frames", "--camera", "camera.json", "--map", "map.json"]
        + ["--json", "out/poses.jsonl", "--annotate", "out/seen"],
        ["poses.jsonl"] + [f"seen/scene_0{k}.png" for k in range(3)],
    ),
}


def workspace(ws: Path) -> Path:
    """Fill ``ws`` with every command's inputs and an empty ``out/``; return ``ws``."""
    shutil.copy(DATA / "world_map.json", ws / "map.json")
    shutil.copy(DATA / "scenes" / "camera.json", ws / "camera.json")
    for folder, source, names in (
        ("frames", DATA / "scenes", [f"scene_0{k}.png" for k in range(3)]),
        ("photos", DATA / "calibration", [f"view_0{k}.png" for k in range(4)]),
        ("sphotos", DATA / "survey", [f"photo_0{k}.jpg" for k in range(8)]),
    ):
        (ws / folder).mkdir()
        for name in names:
            shutil.copy(source / name, ws / folder / name)
    shutil.copy(DATA / "survey" / "camera.json", ws / "survey_camera.json")
    shutil.copy(DATA / "survey" / "tape_map.json", ws / "tape.json")
    from fidlearn.ros import save_camera_info

    save_camera_info(fidlearn.Camera.load(ws / "camera.json"), ws / "camera_info.yaml")
    (ws / "out").mkdir()
    return ws


def snapshot(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` (hidden ones too), relative name -> SHA-256 of its bytes."""
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _numbers_close(a, b) -> bool:
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_numbers_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(_numbers_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-7, abs_tol=1e-9)
    return a == b


def same_output(path: Path, reference: Path) -> bool:
    """Is ``path`` the reference file, whole? JSON with the same numbers to 1e-7 (threads may sum in
    another order), a picture that decodes to the same pixels within one gray level, other files
    byte for byte."""
    if path.read_bytes() == reference.read_bytes():
        return True
    if path.suffix == ".json":
        return _numbers_close(json.loads(path.read_text()), json.loads(reference.read_text()))
    if path.suffix == ".png":
        a, b = cv2.imread(str(path)), cv2.imread(str(reference))
        return a is not None and a.shape == b.shape and float(np.abs(a.astype(float) - b).max()) <= 1
    return False


def same_outputs(folder: Path, reference: Path) -> bool:
    """Does ``folder`` hold exactly the reference folder's files, each whole (:func:`same_output`)?"""
    names = snapshot(reference)
    return sorted(snapshot(folder)) == sorted(names) and all(
        same_output(folder / name, reference / name) for name in names
    )


def hidden(folder: Path) -> list[str]:
    """Hidden files and folders below ``folder`` (a temporary file left behind)."""
    return [p.relative_to(folder).as_posix() for p in folder.rglob(".*")]


def environment(**extra: str) -> dict[str, str]:
    """The environment of a ``fidlearn`` subprocess: this worktree's fidlearn, plain stderr."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("FIDLEARN_TEST_")}
    env.update(PYTHONPATH=str(ROOT), MPLBACKEND="Agg", **extra)
    return env


def command(argv: list[str]) -> list[str]:
    """The process's command line for ``fidlearn ARGV``."""
    return [sys.executable, "-m", "fidlearn", *argv]


def run(ws: Path, argv: list[str], **extra: str) -> subprocess.CompletedProcess:
    """Run ``fidlearn ARGV`` in ``ws`` to its end."""
    return subprocess.run(command(argv), cwd=ws, env=environment(**extra), capture_output=True, text=True, timeout=600)


def error_lines(stderr: str) -> list[str]:
    """The ``error:`` lines of a command's stderr."""
    return [line for line in stderr.splitlines() if line.startswith("error:")]
