"""The command line under attack: a careless or a hostile user must not lose data or see a traceback.

Every case runs a command in a workspace of real files (the seed map, the bundled camera, rendered
frames, calibration views) and asserts the exact behaviour: exit status 2 with exactly one
``error:`` line naming what is wrong, every input byte for byte unchanged, and no file left
behind (no hidden temporary file, no half-written output). The signal and pipe cases run the
command as a subprocess, as a robot's supervisor or a shell pipeline would.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import ctrl_c_as_a_terminal_gives_it

import fidlearn
from fidlearn import cli

DATA = fidlearn.data_dir()


@pytest.fixture(autouse=True)
def _ctrl_c():
    with ctrl_c_as_a_terminal_gives_it():
        yield


@pytest.fixture
def ws(tmp_path, monkeypatch):
    """A workspace: map.json, camera.json, frames/ (3 scenes), photos/ (4 calibration views)."""
    shutil.copy(DATA / "world_map.json", tmp_path / "map.json")
    shutil.copy(DATA / "scenes" / "camera.json", tmp_path / "camera.json")
    (tmp_path / "frames").mkdir()
    for k in range(3):
        shutil.copy(DATA / "scenes" / f"scene_0{k}.png", tmp_path / "frames" / f"scene_0{k}.png")
    (tmp_path / "photos").mkdir()
    for k in range(4):
        shutil.copy(DATA / "calibration" / f"view_0{k}.png", tmp_path / "photos" / f"view_0{k}.png")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def snapshot(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` (hidden ones too) with the SHA-256 of its bytes."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file() and not p.is_symlink():
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def refused(ws: Path, capsys, argv: list[str], match: str) -> str:
    """Run ``fidlearn ARGV``; assert status 2, one error line containing ``match``, nothing changed."""
    before = snapshot(ws)
    status = cli.main(argv)
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert status == 2, (out, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert match in lines[0], lines[0]
    assert "Traceback" not in err
    assert snapshot(ws) == before  # inputs unchanged, nothing written, no temporary file left
    return lines[0]


LOC = ["--camera", "camera.json", "--map", "map.json"]


def _link(ws: Path, name: str, target: str, hard: bool = False) -> None:
    (os.link if hard else os.symlink)(ws / target, ws / name)


# -- outputs over inputs ------------------------------------------------------------------------
CLOBBER = [
    ("corners -o its own map", ["corners", "map.json", "-o", "map.json"], "is one of the inputs"),
    (
        "corners -o its map spelt another way",
        ["corners", "map.json", "-o", "./frames/../map.json"],
        "is one of the inputs",
    ),
    ("corners -o a symlink to its map", ["corners", "map.json", "-o", "link.json"], "is one of the inputs"),
    ("corners -o a hard link to its map", ["corners", "map.json", "-o", "hard.json"], "is one of the inputs"),
    ("locate --json the camera", ["locate", "frames", *LOC, "--json", "camera.json"], "is one of the inputs"),
    ("locate --json the map", ["locate", "frames", *LOC, "--json", "map.json"], "is one of the inputs"),
    ("locate --json a link to the camera", ["locate", "frames", *LOC, "--json", "link.json"], "is one of the inputs"),
    ("locate --annotate its own folder", ["locate", "frames", *LOC, "--annotate", "frames"], "holds the input"),
    ("locate --annotate its own folder/", ["locate", "frames/", *LOC, "--annotate", "frames/"], "holds the input"),
    (
        "locate --annotate the folder of one image",
        ["locate", "frames/scene_01.png", *LOC, "--annotate", "frames"],
        "holds the input",
    ),
    (
        "locate --annotate through a symlinked folder",
        ["locate", "frames", *LOC, "--annotate", "framelink"],
        "holds the input",
    ),
    (
        "locate --annotate where --json goes",
        ["locate", "frames", *LOC, "--json", "out/poses.jsonl", "--annotate", "out"],
        "is where --json",
    ),
    (
        "calibrate --annotate its photos",
        ["calibrate", "photos", "--pattern", "9x6", "--square-mm", "25", "-o", "cam2.json", "--annotate", "photos"],
        "holds the input",
    ),
    (
        "calibrate --annotate the folder of its photos",
        [
            "calibrate",
            "photos/view_00.png",
            "photos/view_01.png",
            "photos/view_02.png",
            "--pattern",
            "9x6",
            "--square-mm",
            "25",
            "-o",
            "cam2.json",
            "--annotate",
            "photos",
        ],
        "holds the input",
    ),
    (
        "compare-calibrations --report a photo of an input folder",
        [
            "compare-calibrations",
            "photos",
            "photos",
            "--pattern",
            "9x6",
            "--square-mm",
            "25",
            "--report",
            "photos/view_01.png",
        ],
        "is one of the inputs (a file of the folder photos)",
    ),
    (
        "compare-calibrations --tolerance-px 0, refused before any calibration",
        ["compare-calibrations", "photos", "photos", "--pattern", "9x6", "--square-mm", "25", "--tolerance-px", "0"],
        "--tolerance-px must be a positive number of pixels, got 0",
    ),
    (
        "locate --annotate named as its --json file",
        ["locate", "frames", *LOC, "--json", "out/poses.jsonl", "--annotate", "out/poses.jsonl"],
        "is the name --json gives its file",
    ),
    (
        "calibrate --annotate named as its camera file",
        [
            "calibrate",
            "photos",
            "--pattern",
            "9x6",
            "--square-mm",
            "25",
            "-o",
            "out/cam.json",
            "--annotate",
            "out/cam.json",
        ],
        "is the name -o gives its file",
    ),
    (
        "locate --annotate an existing file",
        ["locate", "frames", *LOC, "--annotate", "camera.json"],
        "--annotate camera.json is a file",
    ),
    ("markers -o its own --map", ["markers", "--map", "map.pdf", "-o", "map.pdf"], "is one of the inputs"),
    (
        "render --truth the map",
        ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", "--truth", "map.json"],
        "is one of the inputs",
    ),
    (
        "render --truth the camera",
        ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", "--truth", "camera.json"],
        "is one of the inputs",
    ),
    (
        "render --truth a link to the map",
        ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", "--truth", "link.json"],
        "is one of the inputs",
    ),
]


@pytest.mark.parametrize(("argv", "match"), [c[1:] for c in CLOBBER], ids=[c[0] for c in CLOBBER])
def test_an_output_over_an_input_is_refused_before_any_work(ws, capsys, argv, match):
    target = (
        "camera.json" if "camera" in " ".join(argv[-2:]) or "--json" in argv and "link.json" in argv else "map.json"
    )
    _link(ws, "link.json", target)
    _link(ws, "hard.json", "map.json", hard=True)
    (ws / "out").mkdir()
    os.symlink(ws / "frames", ws / "framelink")
    shutil.copy(ws / "map.json", ws / "map.pdf")  # a map named as the pages would be
    refused(ws, capsys, argv, match)


# -- sizes, numbers and names the user gives ------------------------------------------------------
BOUNDS = [
    ("render --seed -1", ["--seed", "-1"], "--seed -1: give a whole number from 0"),
    ("render --seed 2**40", ["--seed", str(2**40)], "give a whole number from 0"),
    ("render --noise 1000", ["--noise", "1000"], "--noise must be 0 to 255"),
    ("render --noise nan", ["--noise", "nan"], "--noise must be 0 to 255"),
    ("render --blur -1", ["--blur", "-1"], "--blur 0 to 100"),
    ("render --blur inf", ["--blur", "inf"], "--blur 0 to 100"),
    ("render --size 100000x56250", ["--size", "100000x56250"], "at most 2.5 megapixels"),
    ("render --size 20001x11251", ["--size", "20001x11251"], "at most 2.5 megapixels"),
    ("render --size 0x0", ["--size", "0x0"], "needs at least 2"),
]


@pytest.mark.parametrize(("extra", "match"), [c[1:] for c in BOUNDS], ids=[c[0] for c in BOUNDS])
def test_render_options_out_of_range(ws, capsys, extra, match):
    refused(ws, capsys, ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", *extra], match)


POSES = [
    ("--pose 1e308", ["--pose", "1e308,0,0,0,0,0"], "beyond any room"),
    ("--pose -1e12", ["--pose", "-1e12,0,0,0,0,0"], "beyond any room"),
    ("--pose roll 1e9", ["--pose", "1000,190,230,1e9,0,0"], "roll, pitch and yaw are degrees"),
    ("--pose nan", ["--pose", "nan,0,0,0,0,0"], "expected 6 numbers"),
    ("--pose five numbers", ["--pose", "1,2,3,4,5"], "expected 6 numbers"),
    ("--from 1e300", ["--from", "1e300,0,0", "--look-at", "0,0,0"], "beyond any room"),
    ("--look-at -1e300", ["--from", "1000,0,0", "--look-at", "-1e300,0,0"], "beyond any room"),
    ("--roll-deg 1e9", ["--from", "1000,0,0", "--look-at", "0,0,0", "--roll-deg", "1e9"], "--roll-deg is degrees"),
    ("--roll-deg nan", ["--from", "1000,0,0", "--look-at", "0,0,0", "--roll-deg", "nan"], "--roll-deg is degrees"),
    ("--roll-deg with --pose", ["--pose", "1000,0,0,-90,0,90", "--roll-deg", "45"], "--roll-deg goes with --look-at"),
]


@pytest.mark.parametrize(("extra", "match"), [c[1:] for c in POSES], ids=[c[0] for c in POSES])
def test_render_poses_out_of_range(ws, capsys, extra, match):
    refused(ws, capsys, ["render", *LOC, "-o", "r.png", *extra], match)


IDS = [
    ("0-99999", "at most 1024 markers"),
    ("9" * 5000, "at most 1024 markers"),
    ("0-1024", "at most 1024 markers"),
    ("0-3,3", "id 3 is listed twice"),
    ("0-500,250-260", "id 250 is listed twice"),
    ("5-1", "runs backwards"),
    ("a-b", "is not an id or a range"),
    ("-3", "is not an id or a range"),
    ("", "--ids is empty"),
    (",", "is not an id or a range"),
]


@pytest.mark.parametrize(("ids", "match"), IDS)
def test_marker_ids_of_any_range_answer_at_once(ws, capsys, ids, match):
    t0 = time.perf_counter()
    refused(ws, capsys, ["markers", "--ids", ids, "--size-mm", "80", "-o", "m.pdf"], match)
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("index", ["-1", "256", "2147483648", str(2**70)])
def test_camera_indexes_out_of_range(ws, capsys, index):
    refused(ws, capsys, ["locate", *LOC, "--camera-index", index], "cameras are numbered 0 (the first camera) to 255")


@pytest.mark.parametrize("dpi", ["1e9", "0", "-300", "nan", "10"])
def test_print_resolution_out_of_range(ws, capsys, dpi):
    refused(ws, capsys, ["markers", "--ids", "0", "--size-mm", "80", "-o", "m.png", "--dpi", dpi], "--dpi")
    refused(ws, capsys, ["board", "--pattern", "9x6", "--square-mm", "20", "-o", "b.png", "--dpi", dpi], "--dpi")


# -- files that are not what they say --------------------------------------------------------------
def _write(ws: Path, name: str, content) -> None:
    p = ws / name
    p.write_bytes(content if isinstance(content, bytes) else content.encode())


CAMERA_JSON = json.loads((DATA / "scenes" / "camera.json").read_text())


def _camera_with(**changes) -> str:
    d = dict(CAMERA_JSON)
    for k, v in changes.items():
        if v is None:
            d.pop(k)
        else:
            d[k] = v
    return json.dumps(d)


def _yaml(dt: str = "d", fx: str = "628.158") -> str:
    return (
        f"%YAML:1.0\nimage_width: 1280\nimage_height: 720\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
        f"   dt: {dt}\n   data: [ {fx}, 0., 640., 0., 628.156, 360., 0., 0., 1. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n"
    )


def _nested_yaml(depth: int) -> str:
    return "%YAML:1.0\ncamera_matrix: " + "[" * depth + "1" + "]" * depth + "\n"


def _nested_xml(depth: int) -> str:
    return '<?xml version="1.0"?>\n<opencv_storage>\n' + "<a>" * depth + "1" + "</a>" * depth + "\n</opencv_storage>\n"


CAMERAS = [
    (
        "camera.json",
        "misspelt distortion field",
        _camera_with(distortion=[0.1, 0, 0, 0, 0], dist_coeffs=None),
        "unknown field 'distortion': did you mean 'dist_coeffs'?",
    ),
    (
        "camera.json",
        "dist_coefs",
        _camera_with(dist_coefs=[0.1, 0, 0, 0, 0], dist_coeffs=None),
        "unknown field 'dist_coefs': did you mean 'dist_coeffs'?",
    ),
    (
        "camera.json",
        "K for camera_matrix",
        _camera_with(K=CAMERA_JSON["camera_matrix"], camera_matrix=None),
        "unknown field 'K': did you mean 'camera_matrix'?",
    ),
    (
        "camera.json",
        "resolution for image_size",
        _camera_with(resolution=[1280, 720], image_size=None),
        "unknown field 'resolution': did you mean 'image_size'?",
    ),
    ("camera.json", "a typo in source", _camera_with(sourse="x"), "unknown field 'sourse': did you mean 'source'?"),
    (
        "camera.json",
        "skew",
        _camera_with(camera_matrix=[[962.5, 3.0, 641.3], [0, 961.8, 357.9], [0, 0, 1]]),
        "skew term K[0][1] = 3",
    ),
    (
        "camera.json",
        "negative skew",
        _camera_with(camera_matrix=[[962.5, -0.5, 641.3], [0, 961.8, 357.9], [0, 0, 1]]),
        "skew term",
    ),
    ("camera.json", "image size beyond any camera", _camera_with(image_size=[10**6, 720]), "beyond any camera"),
    ("camera.yml", "dt: u clips to 255", _yaml("u"), "dt: u"),
    ("camera.yml", "dt: c", _yaml("c"), "dt: c"),
    ("camera.yml", "dt: i", _yaml("i", "628"), "dt: i"),
    ("camera.yml", "nested 100000 deep (YAML)", _nested_yaml(100_000), "nested 100000 levels deep"),
    ("camera.yml", "nested 40 deep (YAML)", _nested_yaml(40), "nested 40 levels deep"),
    ("camera.xml", "nested 100000 deep (XML)", _nested_xml(100_000), "levels deep"),
    ("camera.yml", "not YAML at all", "fx = 600\n", "not an OpenCV FileStorage file"),
    ("camera.yml", "binary", bytes(range(256)) * 4, "not UTF-8 text"),
    ("camera.json", "11 MB of spaces", b" " * (11 * 1024 * 1024), "MB is more than a camera file can be"),
]


@pytest.mark.parametrize(("name", "content", "match"), [c[:1] + c[2:] for c in CAMERAS], ids=[c[1] for c in CAMERAS])
def test_camera_files_that_say_something_else(ws, capsys, name, content, match):
    _write(ws, name, content)
    refused(ws, capsys, ["locate", "frames", "--camera", name, "--map", "map.json", "--json", "p.jsonl"], match)


SEED = json.loads((DATA / "world_map.json").read_text())


def _map_with(**changes) -> str:
    d = json.loads(json.dumps(SEED))
    for k, v in changes.items():
        d[k] = v
    return json.dumps(d)


MAPS = [
    ("marker_size_mm 1e300", _map_with(marker_size_mm=1e300), "more than 10000 mm"),
    ("marker_size_mm 20000", _map_with(marker_size_mm=20000), "more than 10000 mm"),
    (
        "unit for units",
        json.dumps({"unit": "ft", **{k: v for k, v in SEED.items() if k != "units"}}),
        "unknown field 'unit': did you mean 'units'?",
    ),
    (
        "marker for markers",
        json.dumps({"units": "ft", "marker_size_mm": 80, "marker": SEED["markers"]}),
        "did you mean 'markers'?",
    ),
    (
        "translaton",
        _map_with(markers={"0": {"translaton": [0, 0, 1], "rotation": [0, 0, 0]}}),
        "unknown field 'translaton': did you mean 'translation'?",
    ),
    (
        "rotate",
        _map_with(markers={"0": {"translation": [0, 0, 1], "rotate": [0, 0, 0]}}),
        "unknown field 'rotate': did you mean 'rotation'?",
    ),
    (
        "id beyond the dictionary",
        _map_with(markers={"5000": {"translation": [0, 0, 1]}}),
        "does not exist in dictionary",
    ),
    ("translation 1e12 ft", _map_with(markers={"0": {"translation": [0, 0, 1e12]}}), "far beyond any room"),
    ("11 MB map", " " * (11 * 1024 * 1024) + "{}", "MB is more than a world map file can be"),
]


@pytest.mark.parametrize(("content", "match"), [c[1:] for c in MAPS], ids=[c[0] for c in MAPS])
def test_map_files_that_say_something_else(ws, capsys, content, match):
    _write(ws, "bad_map.json", content)
    refused(ws, capsys, ["corners", "bad_map.json", "-o", "corners.json"], match)
    refused(ws, capsys, ["locate", "frames", "--camera", "camera.json", "--map", "bad_map.json"], match)


def _huge_png() -> bytes:
    import struct
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", 100000, 100000, 8, 0, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(b""))
        + chunk(b"IEND", b"")
    )


IMAGES = [
    ("a 74-byte PNG declaring 100000x100000", "huge.png", _huge_png(), "100000x100000 pixels (1e+04 megapixels)"),
    (
        "a PNG cut in half",
        "cut.png",
        (DATA / "scenes" / "scene_00.png").read_bytes()[:5000],
        "the PNG file is cut short",
    ),
    ("a JPEG without its end", "cut.jpg", b"\xff\xd8\xff\xe0" + bytes(200), "the JPEG file is cut short"),
    ("an empty picture", "empty.png", b"", "the file is empty"),
    ("text named .png", "text.png", b"hello", "not an image OpenCV can read"),
]


@pytest.mark.parametrize(("name", "content", "match"), [c[1:] for c in IMAGES], ids=[c[0] for c in IMAGES])
def test_pictures_that_are_not_what_they_say(ws, capsys, name, content, match):
    _write(ws, name, content)
    refused(ws, capsys, ["locate", name, *LOC, "--json", "p.jsonl"], match)


def test_the_picture_limit_can_be_raised_and_lowered(ws, capsys):
    refused(
        ws,
        capsys,
        ["locate", "frames", *LOC, "--max-megapixels", "0.5"],
        "1280x720 pixels (0.922 megapixels), more than the limit of 0.5 megapixels",
    )
    refused(
        ws, capsys, ["locate", "frames", *LOC, "--max-megapixels", "1e9"], "--max-megapixels 1e+09: give 0.01 to 2000"
    )
    assert cli.main(["locate", "frames", *LOC, "--max-megapixels", "1"]) == 0


@pytest.mark.parametrize("kind", ["fifo map", "fifo camera", "device map", "device camera"])
def test_fifos_and_devices_are_refused_without_blocking(ws, capsys, kind):
    target = "m.json" if "map" in kind else "c.json"
    if kind.startswith("fifo"):
        os.mkfifo(ws / target)
    else:
        os.symlink("/dev/zero", ws / target)
    argv = (
        ["corners", target, "-o", "x.json"]
        if "map" in kind
        else ["locate", "frames", "--camera", target, "--map", "map.json"]
    )
    t0 = time.perf_counter()
    before = {p.name for p in ws.iterdir()}
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "is a FIFO" in err[0] or "is a device" in err[0], err
    assert {p.name for p in ws.iterdir()} == before
    assert time.perf_counter() - t0 < 5


@pytest.mark.parametrize("name", ["ff.png", "ff.mp4"])
def test_a_fifo_given_as_a_picture_or_a_video_is_refused_without_blocking(ws, capsys, name):
    """cv2.VideoCapture blocks on a FIFO named .mp4 and ignores SIGTERM; reading a .png one blocks too."""
    os.mkfifo(ws / name)
    t0 = time.perf_counter()
    refused(ws, capsys, ["locate", name, *LOC], f"{name}: is a FIFO (named pipe); give a picture or a video file")
    assert time.perf_counter() - t0 < 5


@pytest.mark.parametrize(
    "argv",
    [
        ["calibrate", "photos", "photos", "--pattern", "9x6", "--square-mm", "25", "-o", "cam.json"],
        ["survey", "frames/scene_00.png", "./frames/scene_00.png", *LOC, "-o", "surveyed.json"],
    ],
    ids=["calibrate a folder twice", "survey a photo by two names"],
)
def test_a_photo_given_twice_is_refused_as_evidence_counted_twice(ws, capsys, argv):
    """A copy of a photo halves a calibration's stated uncertainty and let a survey of one photo pass its two."""
    refused(ws, capsys, argv, "is given twice")


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_an_output_that_is_a_fifo_or_a_device_is_left_as_it_is(ws, capsys, kind):
    """The output is written whole and renamed into place, which would put a file where a FIFO or a device (a
    symlink to /dev/null here; as root, -o /dev/null itself) was."""
    if kind == "fifo":
        os.mkfifo(ws / "out.json")
    else:
        os.symlink("/dev/null", ws / "out.json")
    refused(
        ws,
        capsys,
        ["corners", "map.json", "-o", "out.json"],
        f"out.json: is a {'FIFO' if kind == 'fifo' else 'device'}, not a file",
    )
    assert (ws / "out.json").is_fifo() if kind == "fifo" else (ws / "out.json").is_symlink()


# -- writing: the user's path in every error, nothing half-written -------------------------------
def test_a_full_disk_names_the_users_file_not_the_hidden_one(ws, capsys, monkeypatch):
    def full(_src, _dst):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "replace", full)
    line = refused(ws, capsys, ["corners", "map.json", "-o", "corners.json"], "corners.json: cannot write it")
    assert "No space left on device" in line
    assert "/." not in line
    assert ".tmp" not in line


def test_annotate_says_when_it_replaces_earlier_pictures(ws, capsys):
    argv = ["locate", "frames", *LOC, "--annotate", "seen"]
    assert cli.main(argv) == 0
    assert "3 annotated pictures in seen/" in capsys.readouterr().out
    (ws / "seen" / "mine.txt").write_text("keep me")
    assert cli.main(argv) == 0
    assert "replacing 3 earlier ones" in capsys.readouterr().out
    assert (ws / "seen" / "mine.txt").read_text() == "keep me"  # only its own files


def test_calibrate_writes_the_camera_last(ws, capsys, monkeypatch):
    from fidlearn import cli as c

    def broken(*_args, **_kwargs):
        raise fidlearn.FidlearnError("drawing failed")

    monkeypatch.setattr(c.calibrate, "draw_calibration_view", broken)
    before = snapshot(ws)
    status = cli.main(
        ["calibrate", "photos", "--pattern", "9x6", "--square-mm", "25", "-o", "cam.json", "--annotate", "seen"]
    )
    errors = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert status == 2
    assert errors == ["error: drawing failed"]
    assert snapshot(ws) == before  # no camera file: annotation failed before it would have been written


# -- signals, pipes and names the terminal cannot print --------------------------------------------
def _locate_process(ws: Path, *extra: str, **kw) -> subprocess.Popen:
    frames = ws / "drive"
    if not frames.exists():
        shutil.copytree(DATA / "trajectory", frames, ignore=shutil.ignore_patterns("*.json"))
        shutil.copy(DATA / "trajectory" / "camera.json", ws / "drive_camera.json")
    env = dict(os.environ, PYTHONPATH=str(Path(fidlearn.__file__).parent.parent))
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "fidlearn",
            "locate",
            "drive",
            "--camera",
            "drive_camera.json",
            "--map",
            "map.json",
            *extra,
        ],
        cwd=ws,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_keeps_every_finished_frame(ws, sig):
    proc = _locate_process(ws, "--json", "poses.jsonl", "--annotate", "seen")
    seen = 0
    while seen < 6:  # the header and five frames printed
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        seen += 1
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    [line] = err.strip().splitlines()
    records = [json.loads(r) for r in (ws / "poses.jsonl").read_text().splitlines()]
    pictures = list((ws / "seen").iterdir())
    assert line.startswith(f"error: interrupted by {signal.Signals(sig).name} after ")
    assert f"poses.jsonl holds {len(records)} whole frame record" in line
    assert f"{len(pictures)} annotated picture" in line
    assert 5 <= len(records) < 40
    assert all(r["located"] for r in records)
    assert records == [json.loads(r) for r in (ws / "poses.jsonl").read_text().splitlines()]
    assert len(records) - 1 <= len(pictures) <= len(records)  # a frame's picture is saved after its record
    assert not [p for p in ws.rglob(".*")], "a hidden temporary file was left behind"


def test_a_closed_stdout_ends_quietly_with_the_files_complete(ws):
    proc = _locate_process(ws, "--json", "poses.jsonl")
    proc.stdout.readline()
    proc.stdout.close()  # what `| head -1` does
    err = proc.stderr.read()
    proc.wait(timeout=120)
    assert proc.returncode == 0, err
    assert err == ""
    assert len((ws / "poses.jsonl").read_text().splitlines()) == 40


def test_names_the_terminal_cannot_encode_are_escaped(ws):
    shutil.copy(ws / "frames" / "scene_00.png", ws / "frames" / "café_ü.png")
    env = dict(os.environ, PYTHONIOENCODING="ascii", PYTHONPATH=str(Path(fidlearn.__file__).parent.parent))
    out = subprocess.run(
        [sys.executable, "-m", "fidlearn", "locate", "frames/café_ü.png", *LOC],
        cwd=ws,
        env=env,
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert "caf\\xe9_\\xfc.png" in out.stdout
    assert "Traceback" not in out.stderr


def test_the_cli_and_library_agree_with_a_misplaced_marker(ws, capsys):
    """A marker measured in the wrong place: a pose with the marker rejected, never a traceback."""
    rng = np.random.default_rng(4)
    bad = json.loads(json.dumps(SEED))
    for _trial in range(12):
        bad["markers"]["1"]["translation"] = [
            float(v) for v in np.array(SEED["markers"]["1"]["translation"]) + rng.normal(0, 0.5, 3)
        ]
        (ws / "moved.json").write_text(json.dumps(bad))
        status = cli.main(["locate", "frames", "--camera", "camera.json", "--map", "moved.json", "--json", "p.jsonl"])
        err = capsys.readouterr().err
        assert status == 0, err
        assert "Traceback" not in err, err


# -- survey: options out of range, too many photos, a tape map with no agreeing majority ---------
SURVEY = fidlearn.data_path("survey")
SURVEY_ARGS = ["--camera", str(SURVEY / "camera.json"), "--map", str(SURVEY / "tape_map.json"), "-o", "s.json"]


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--map-sigma-mm", "1e-300"], "--map-sigma-mm 1e-300: give a positive number of mm from 0.01 to 100000"),
        (["--map-sigma-mm", "nan"], "--map-sigma-mm nan: give a positive number of mm from 0.01 to 100000"),
        (["--map-sigma-mm=-inf"], "--map-sigma-mm -inf: give a positive number of mm"),
        (["--map-sigma-mm", "2e5"], "--map-sigma-mm 200000: give a positive number of mm from 0.01 to 100000"),
        (["--map-sigma-mm", "1e400"], "with map_sigma_mm=inf nothing ties the photos to the world"),
        (["--fixed", str(10**40)], f"--fixed {10**40}: no such marker in the map"),
        (["--fixed", "seven"], "--fixed 'seven': give a marker id such as 3, or a marker of another dictionary"),
        (["--fixed", "NO_SUCH_DICT:3"], "--fixed 'NO_SUCH_DICT:3': give a marker id such as 3"),
        (["--fixed", "4X4_50:3"], "--fixed 4X4_50:3: no such marker in the map"),
    ],
)
def test_survey_options_out_of_range(ws, capsys, extra, match):
    photos = [str(p) for p in sorted(SURVEY.glob("photo_*.jpg"))[:3]]
    refused(ws, capsys, ["survey", *photos, *SURVEY_ARGS, *extra], match)


def test_survey_of_2000_photos_is_refused_up_front(ws, capsys):
    (ws / "many").mkdir()
    for k in range(2000):  # refused before any is read: empty files will do
        (ws / "many" / f"p{k:04d}.jpg").touch()
    t0 = time.perf_counter()
    refused(ws, capsys, ["survey", "many", *SURVEY_ARGS], "2000 photos: a survey takes at most 400")
    assert time.perf_counter() - t0 < 20


def test_survey_of_a_tape_map_with_no_agreeing_majority_names_the_markers(ws, capsys):
    tape = json.loads((SURVEY / "tape_map.json").read_text())  # cm
    for i in range(7):
        tape["markers"][str(i)]["translation"][2] += 200.0 * (i + 1)
    _write(ws, "scrambled.json", json.dumps(tape))
    argv = ["survey", str(SURVEY), *SURVEY_ARGS]
    argv[argv.index(str(SURVEY / "tape_map.json"))] = "scrambled.json"
    line = refused(ws, capsys, argv, "no majority; markers [0, 1, 2, 3, 4, 5, 6] are off")
    assert "[7, 8, 9, 10, 11]" in line


# -- plan and calibrate: numbers beyond reason, work without bound ----------------------------------
PLAN = ["plan", "map.json", "--camera", "camera.json", "--step-mm", "1000", "--headings", "0", "-o", "plan.png"]


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--corner-sigma-px", "1e300"], "--corner-sigma-px 1e+300: give a positive number of pixels up to 100"),
        (["--marker-shift-px", "1e300"], "--marker-shift-px 1e+300: give a number of pixels, 0 or more, up to 100"),
        (["--height-mm", "1e300"], "--height-mm must be a finite number of mm, at most 1e+09"),
        (["--area", "0,0,1e300,1e300"], "area must be a finite number of mm, at most 1e+09"),
        (["--step-mm", "1e-300", "--area", "100,-1000,3000,1000"], "more than 40000: use a larger --step-mm"),
        (["--look-at", "1e400,0,300"], "--look-at"),
    ],
)
def test_plan_numbers_beyond_reason(ws, capsys, extra, match):
    refused(ws, capsys, [*PLAN, *extra], match)


@pytest.mark.parametrize("far", ["1e300,0,300", "-1e300,1e300,0", "1e200,0,0"])
def test_plan_looking_at_a_far_point_works_without_a_warning(ws, capsys, far):
    """A far look-at point is a direction: the plan is made, and nothing but its figures is said."""
    assert cli.main([*PLAN, "--look-at", far]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "places, 1000 mm apart, camera at 300 mm" in out
    assert (ws / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("board", "match"),
    [
        (["--pattern", "200x100"], "--pattern 200x100: 20000 inner corners, more than 2500"),
        (["--pattern", "99999999x99999999"], "inner corners, more than 2500"),
        (
            ["--squares", "60x60", "--charuco", "--marker-mm", "10"],
            "--squares 60x60: 3481 inner corners, more than 2500",
        ),
    ],
)
def test_calibrate_refuses_a_board_too_large_up_front(ws, capsys, board, match):
    start = time.monotonic()
    refused(ws, capsys, ["calibrate", "photos", *board, "--square-mm", "25", "-o", "cam.json"], match)
    assert time.monotonic() - start < 5  # before any photo is searched


# -- camera import, the track's frames, the mount file, render's size --------------------------------
CAMERA_INFO = """image_width: 640
image_height: 480
camera_name: camera
camera_matrix:
  rows: 3
  cols: 3
  data: [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.1, 0.01, 0, 0, 0]
"""
CAMERA_INFO_CASES = [
    ("width 1e999", ("image_width: 640", "image_width: 1e999"), "image_width must be a whole number of pixels > 0"),
    ("width 9x400", ("image_width: 640", "image_width: 9x400"), "image_width must be a whole number of pixels > 0"),
    ("height -1e999", ("image_height: 480", "image_height: -1e999"), "image_height must be a whole number"),
    ("rows 4.5", ("  rows: 1\n  cols: 5", "  rows: 4.5\n  cols: 2"), "distortion_coefficients.rows must be a whole"),
    ("rows -1 cols -5", ("  rows: 1\n  cols: 5", "  rows: -1\n  cols: -5"), "rows must be a whole number >= 0"),
    ("a model that is a list", ("model: plumb_bob", "model: [plumb_bob]"), "distortion_model must be a name"),
    ("a model that is a mapping", ("model: plumb_bob", "model: {a: 1}"), "distortion_model must be a name"),
]


@pytest.mark.parametrize(("change", "match"), [c[1:] for c in CAMERA_INFO_CASES], ids=[c[0] for c in CAMERA_INFO_CASES])
def test_camera_import_of_a_hostile_camera_info(ws, capsys, change, match):
    assert change[0] in CAMERA_INFO
    (ws / "info.yaml").write_text(CAMERA_INFO.replace(*change))
    refused(ws, capsys, ["camera", "import", "info.yaml", "-o", "imported.json"], match)


def test_camera_import_of_the_unchanged_camera_info_works(ws):
    (ws / "info.yaml").write_text(CAMERA_INFO)
    assert cli.main(["camera", "import", "info.yaml", "-o", "imported.json"]) == 0
    cam = fidlearn.Camera.load(ws / "imported.json")
    assert cam.image_size == (640, 480)
    assert cam.fx == 600.0
    assert cam.dist[0] == -0.1


def _frames_of_two_aspects(ws: Path) -> None:
    """frames/ with a 4:3 picture after the 16:9 scenes (the camera is 16:9)."""
    import cv2

    cv2.imwrite(str(ws / "frames" / "scene_09.png"), np.full((480, 640), 128, np.uint8))


@pytest.mark.parametrize(
    "track", [["--track"], ["--track", "-o", "track.jsonl"], []], ids=["track", "track -o", "locate"]
)
def test_frames_of_another_aspect_ratio_give_one_error_line_before_any_work(ws, capsys, track):
    _frames_of_two_aspects(ws)
    line = refused(ws, capsys, ["locate", "frames", *LOC, *track], "scene_09.png: camera calibrated at 1280x720")
    assert "aspect" in line
    assert capsys.readouterr().out == ""  # not even the table's header


MOUNT = {"units": "mm", "camera_in_base": {"translation": [200, 0, 300], "rpy_deg": [0, 0, 0]}}
MOUNT_CASES = [
    ("axes for camera_axes", {**MOUNT, "axes": "optical"}, "unknown key 'axes': did you mean 'camera_axes'?"),
    ("unit for units", {"unit": "mm", "camera_in_base": MOUNT["camera_in_base"]}, "did you mean 'units'?"),
    ("a key of nothing", {**MOUNT, "colour": "red"}, "a mount file has units, camera_in_base, camera_axes"),
    (
        "rpy for rpy_deg",
        {"units": "mm", "camera_in_base": {"translation": [0, 0, 0], "rpy": [0, 0, 0]}},
        "unknown key 'rpy': did you mean 'rpy_deg'?",
    ),
    ("both poses", {**MOUNT, "T_camera_base": np.eye(4).tolist()}, "not both"),
    ("units a list", {**MOUNT, "units": ["mm"]}, 'needs "units"'),
    ("camera_axes a list", {**MOUNT, "camera_axes": ["link"]}, "camera_axes must be"),
    ("1e300 m away", {**MOUNT, "camera_in_base": {"translation": [1e300, 0, 0], "rpy_deg": [0, 0, 0]}}, "check"),
]


@pytest.mark.parametrize(("mount", "match"), [c[1:] for c in MOUNT_CASES], ids=[c[0] for c in MOUNT_CASES])
def test_a_mount_file_with_an_unknown_or_wrong_key_is_refused(ws, capsys, mount, match):
    (ws / "mount.json").write_text(json.dumps(mount))
    refused(ws, capsys, ["locate", "frames", *LOC, "--track", "--mount", "mount.json", "-o", "t.jsonl"], match)


def test_render_refuses_a_size_that_takes_minutes_naming_the_limit(ws, capsys):
    refused(
        ws,
        capsys,
        ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", "--size", "2560x1440"],
        "at most 2.5 megapixels (1920x1080 fits)",
    )


@pytest.mark.slow
def test_render_at_the_largest_size_allowed_finishes_in_seconds(ws, capsys):
    """2.5 megapixels at the camera's 16:9 (2100x1181 is 2.48): seconds, where 40 megapixels took minutes."""
    start = time.monotonic()
    argv = ["render", *LOC, "--pose", "1000,190,230,-90,0,90", "-o", "r.png", "--size", "2100x1181"]
    assert cli.main(argv) == 0, capsys.readouterr().err
    assert time.monotonic() - start < 30
    import cv2

    assert cv2.imread(str(ws / "r.png"), cv2.IMREAD_GRAYSCALE).shape == (1181, 2100)


def test_a_jpeg_whose_size_comes_after_its_first_4_kb_is_checked_too(ws, capsys):
    """OpenCV's ArUco photo (640x480) gives its size after 4 KB of other blocks; the 16:9 camera does not fit it."""
    shutil.copy(DATA / "real" / "opencv_aruco_photo" / "singlemarkersoriginal.jpg", ws / "frames" / "z.jpg")
    refused(ws, capsys, ["locate", "frames", *LOC, "--track"], "z.jpg: camera calibrated at 1280x720 (aspect 1.778)")


# -- interrupted or out of disk: every output of a command, or none, and a line that says which ---------
def _signal_at(monkeypatch, step: str) -> None:
    """The command sends itself a signal at an exact step of its outputs' commit (see fidlearn._staged)."""
    from fidlearn import _staged

    monkeypatch.setattr(_staged, "_points", {})
    monkeypatch.setenv(_staged.SIGNAL_AT_VARIABLE, step)


RENDER = ["render", *LOC, "--from", "1200,150,250", "--look-at", "0,150,250", "-o", "s.png", "--truth", "t.json"]


def test_render_interrupted_with_its_picture_staged_writes_neither(ws, capsys, monkeypatch):
    before = snapshot(ws)
    _signal_at(monkeypatch, "staged:1:SIGTERM")
    assert cli.main(RENDER) == 128 + signal.SIGTERM
    assert capsys.readouterr().err.strip() == "error: interrupted by SIGTERM; nothing was written"
    assert snapshot(ws) == before


def test_render_interrupted_in_its_commit_writes_both_and_says_so(ws, capsys, monkeypatch):
    _signal_at(monkeypatch, "renamed:1:SIGTERM")
    assert cli.main(RENDER) == 128 + signal.SIGTERM
    assert capsys.readouterr().err.strip() == "error: interrupted by SIGTERM; written: s.png, t.json"
    assert cv2_shape(ws / "s.png") == (720, 1280, 3)
    assert json.loads((ws / "t.json").read_text())["image"] == "s.png"
    assert not [p for p in ws.rglob(".*")]


def cv2_shape(path: Path) -> tuple:
    import cv2

    return cv2.imread(str(path)).shape


def test_plan_interrupted_by_ctrl_c_with_its_picture_drawn_writes_nothing(ws, capsys, monkeypatch):
    before = snapshot(ws)
    _signal_at(monkeypatch, "staged:1:SIGINT")
    argv = ["plan", "map.json", "--camera", "camera.json", "--step-mm", "1000", "--headings", "0", "-o", "p.png"]
    assert cli.main(argv) == 128 + signal.SIGINT
    assert capsys.readouterr().err.strip() == "error: interrupted by SIGINT; nothing was written"
    assert snapshot(ws) == before


def test_a_full_disk_at_the_camera_takes_back_the_report_and_the_annotations(ws, capsys, monkeypatch):
    from fidlearn import _staged

    real = _staged.file_mode_for

    def full_at_the_camera(path):
        if Path(path).name == "cam.json":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path)

    monkeypatch.setattr(_staged, "file_mode_for", full_at_the_camera)
    before = snapshot(ws)
    argv = ["calibrate", "photos", "--pattern", "9x6", "--square-mm", "25", "-o", "cam.json"]
    assert cli.main([*argv, "--report", "rep.png", "--annotate", "seen"]) == 2
    err = capsys.readouterr().err  # the search's counter and the coach's warnings, then the error, last
    assert [ln for ln in err.splitlines() if ln.startswith("error:")] == [err.splitlines()[-1]]
    assert err.splitlines()[-1] == (
        "error: cam.json: cannot write it (No space left on device); check the free disk space and the "
        "folder's permissions; nothing was written"
    )
    assert snapshot(ws) == before  # neither the report nor the annotations, nor a hidden file


def test_a_signal_during_a_c_extensions_import_is_an_interruption(ws, capsys, monkeypatch):
    """A SIGTERM while matplotlib's Agg module initialises comes out as ``ImportError: initialization failed``."""
    from fidlearn.cli import _common, corners

    def importing(_args):
        try:
            raise _common._Interrupted(signal.SIGTERM)
        except KeyboardInterrupt as exc:
            raise ImportError("initialization failed") from exc

    monkeypatch.setattr(corners, "run", importing)
    before = snapshot(ws)
    status = cli.main(["corners", "map.json", "-o", "c.json"])
    assert status == 128 + signal.SIGTERM
    assert capsys.readouterr().err.strip() == "error: interrupted by SIGTERM; nothing was written"
    assert snapshot(ws) == before


# -- the odometry file's numbers -------------------------------------------------------------------


@pytest.mark.parametrize("x_m", ["1e308", "-1e300", "2e6"])
def test_odometry_positions_beyond_reason_are_one_line(ws, capsys, x_m):
    (ws / "odom.csv").write_text(f"t_s,x_m,y_m,z_m,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,{x_m},0,0,0,0,0,1\n")
    argv = ["locate", "frames", *LOC, "--track", "--odometry", "odom.csv", "-o", "t.jsonl"]
    line = refused(ws, capsys, argv, "odom.csv: row 3: a position of")
    assert "within 1000 km of its origin" in line


def test_odometry_poses_beyond_reason_are_refused_in_the_library():
    far = np.eye(4)
    far[0, 3] = 2e12  # mm: 2e6 km
    with pytest.raises(fidlearn.FidlearnError, match=r"odometry pose 1 is 2e\+09 m from its origin"):
        fidlearn.ros.Odometry([0.0, 1.0], [np.eye(4), far])


# -- grade's notebooks: a folder, or a link to the class secret ------------------------------------


def test_grade_names_a_folder_and_a_link_to_the_secret(ws, capsys):
    (ws / "class.secret").write_bytes(b"s" * 32)
    (ws / "sub").mkdir()
    (ws / "sub" / "eve.ipynb").symlink_to(ws / "class.secret")
    grade = ["grade", "--lesson", "03", "--secret-file", "class.secret", "-o", "g.csv"]
    refused(ws, capsys, [*grade[:1], "sub", *grade[1:]], "sub is a folder; give the notebooks in it (sub/*.ipynb)")
    refused(ws, capsys, [*grade[:1], "sub/eve.ipynb", *grade[1:]], "is the class secret (class.secret), not a notebook")


# -- warnings on stderr: fidlearn's own, never a library's deprecation notice ----------------------


def test_a_librarys_deprecation_notice_is_not_a_line_for_the_user(ws, capsys, monkeypatch):
    import warnings

    from fidlearn.cli import corners

    real = corners.run

    def run(args):
        warnings.warn("'parseString' deprecated - use 'parse_string'", DeprecationWarning, stacklevel=1)
        warnings.warn("'resetCache' will go", PendingDeprecationWarning, stacklevel=1)
        return real(args)

    monkeypatch.setattr(corners, "run", run)
    assert cli.main(["corners", "map.json", "-o", "c.json"]) == 0
    assert capsys.readouterr().err == ""
    assert (ws / "c.json").is_file()


def test_an_output_name_of_250_characters_is_written(ws, capsys):
    """A name may have 255 bytes; the hidden file it is staged in is kept within them too."""
    name = "a" * 245 + ".json"
    assert cli.main(["corners", "map.json", "-o", name]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in ws.iterdir() if p.name.startswith(("a", ".a"))) == [name]
