"""The bad-input corpus: what users really get wrong, and what a fuzzer finds.

Every user-facing entry point is fed broken input from a table. Each case asserts the
error class *and* a fragment of the message that tells the user what to change: an
error that names the wrong thing is a defect too. Inputs that must still work (16-bit
and 4-channel images, a camera at another resolution with the same aspect ratio) are
checked against their known answer.

Entry points: ``MarkerMap.load`` / ``from_dict`` (map files), ``Camera.load`` (JSON and
OpenCV YAML/XML), ``load_image`` / ``as_gray`` / ``detect_markers`` (images),
``Camera.for_image`` (resolution), and ``python -m fidlearn`` (arguments).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fidlearn import Board, Camera, MarkerMap, _cv
from fidlearn.cli import main as cli_main
from fidlearn.detection import as_gray, detect_markers, load_image
from fidlearn.errors import (
    CameraError,
    DictionaryError,
    FidlearnError,
    FidlearnWarning,
    ImageError,
    MapError,
)
from fidlearn.grading import _selfstudy_cli

SEED = {
    "units": "ft",
    "marker_size_mm": 80,
    "dictionary": "ARUCO_ORIGINAL",
    "markers": {
        "0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]},
        "1": {"translation": [0, 1, 1], "rotation": [0, 0, 0]},
    },
}
SEED_TEXT = json.dumps(SEED, indent=2)
M0 = '"0": {"translation": [0, 0, 1], "rotation": [0, 0, 0]}'


def full(markers: str, head: str = '"units": "ft", "marker_size_mm": 80') -> str:
    """A full-layout map file's text with the given markers object body."""
    return "{" + head + ', "markers": {' + markers + "}}"


def with_marker(placement: str, mid: str = "0") -> str:
    return full(f'"{mid}": {placement}')


# -- map files -------------------------------------------------------------------------
# (case id, file content (str or bytes), keyword arguments of MarkerMap.load, fragment of the message)
MAP_FILES = [
    ("empty file", b"", {}, "the file is empty"),
    ("only whitespace", "  \n\t\n", {}, "the file is empty"),
    ("truncated json", SEED_TEXT[: len(SEED_TEXT) // 2], {}, "fix the syntax"),
    ("missing comma", SEED_TEXT.replace("],", "]", 1), {}, "a missing comma or bracket"),
    ("trailing comma", full(M0 + ","), {}, "invalid JSON at line 1"),
    ("single quotes", SEED_TEXT.replace('"', "'"), {}, "invalid JSON"),
    ("latin-1 bytes", full(M0).replace("units", "unités").encode("latin-1"), {}, "save the world map as UTF-8"),
    ("utf-16 from notepad", full(M0).encode("utf-16"), {}, "not UTF-8 text"),
    ("a png, not a map", b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", {}, "not UTF-8"),
    ("duplicate id", full(M0 + ", " + M0), {}, 'key "0" appears twice'),
    ("duplicate id spelled 00", full(M0 + ", " + M0.replace('"0"', '"00"')), {}, "appears twice (as '00')"),
    ("NaN literal", with_marker('{"translation": [NaN, 0, 1]}'), {}, "contains NaN, which is not a number"),
    ("Infinity literal", with_marker('{"translation": [Infinity, 0, 1]}'), {}, "write a finite measurement"),
    ("-Infinity literal", with_marker('{"translation": [0, -Infinity, 1]}'), {}, "contains -Infinity"),
    ("1e999 overflows to inf", with_marker('{"translation": [1e999, 0, 1]}'), {}, "expected finite numbers"),
    ("huge number", with_marker('{"translation": [0, 3e12, 1]}'), {}, "far beyond any room; check the units"),
    ("400-digit integer", with_marker('{"translation": [1' + "0" * 400 + ", 0, 1]}"), {}, "too large for a float"),
    ("nested 100000 deep", "[" * 100_000, {}, "nested too deeply"),
    ("translation with 2 values", with_marker('{"translation": [0, 1]}'), {}, "translation has 2 values, expected 3"),
    ("translation is a number", with_marker('{"translation": 5}'), {}, "translation must be a list of 3 numbers"),
    (
        "translation is an object",
        with_marker('{"translation": {"x": 0, "y": 0, "z": 1}}'),
        {},
        "must be a list of 3 numbers",
    ),
    (
        "rotation with 4 values",
        with_marker('{"translation": [0, 0, 1], "rotation": [0, 0, 0, 1]}'),
        {},
        "expected 3 [roll, pitch, yaw] in degrees",
    ),
    ("string for a number", with_marker('{"translation": ["0", 0, 1]}'), {}, "'0', which is not a number"),
    ("number with its unit", with_marker('{"translation": [0, "1 ft", 1]}'), {}, "'1 ft', which is not a number"),
    ("true for a number", with_marker('{"translation": [0, true, 1]}'), {}, "True, which is not a number"),
    ("null for a number", with_marker('{"translation": [0, null, 1]}'), {}, "None, which is not a number"),
    ("nested list", with_marker('{"translation": [[0, 0, 1]]}'), {}, "translation has 1 values, expected 3"),
    ("negative id", with_marker('{"translation": [0, 0, 1]}', "-1"), {}, "marker id -1 is negative; ids start at 0"),
    ("non-integer id", with_marker('{"translation": [0, 0, 1]}', "1.5"), {}, "marker id '1.5' is not a whole number"),
    ("name for an id", with_marker('{"translation": [0, 0, 1]}', "door"), {}, "'door' is not a whole number"),
    ("double minus id", with_marker('{"translation": [0, 0, 1]}', "--5"), {}, "'--5' is not a whole number"),
    ("superscript digit id", with_marker('{"translation": [0, 0, 1]}', "\u00b2"), {}, "is not a whole number"),
    ("empty id", with_marker('{"translation": [0, 0, 1]}', ""), {}, "'' is not a whole number"),
    (
        "unknown units",
        full(M0, '"units": "parsec", "marker_size_mm": 80'),
        {},
        "unknown units 'parsec'; use one of mm, cm, m, in, ft",
    ),
    ("units spelled out", full(M0, '"units": "feet", "marker_size_mm": 80'), {}, "use one of mm, cm, m, in, ft"),
    ("units as a number", full(M0, '"units": 1000, "marker_size_mm": 80'), {}, "unknown units 1000"),
    ("no units, full layout", full(M0, '"marker_size_mm": 80'), {}, 'add "units": "ft"'),
    ("no units, bare layout", "{" + M0 + "}", {"marker_size_mm": 80}, "fidlearn never guesses"),
    ("no marker size", full(M0, '"units": "ft"'), {}, 'add "marker_size_mm": 80'),
    (
        "zero marker size",
        full(M0, '"units": "ft", "marker_size_mm": 0'),
        {},
        "marker_size_mm is 0; it must be positive",
    ),
    ("negative marker size", full(M0, '"units": "ft", "marker_size_mm": -80'), {}, "it must be positive"),
    (
        "marker size as text",
        full(M0, '"units": "ft", "marker_size_mm": "80 mm"'),
        {},
        "marker_size_mm must be a number",
    ),
    (
        "marker size as text, and given",
        full(M0, '"units": "ft", "marker_size_mm": "80"'),
        {"marker_size_mm": 80},
        "must be a number",
    ),
    ("huge marker size", full(M0, '"units": "ft", "marker_size_mm": 1' + "0" * 400), {}, "too large for a number"),
    (
        "unknown dictionary",
        full(M0, '"units": "ft", "marker_size_mm": 80, "dictionary": "DICT_9X9_100"'),
        {},
        "unknown ArUco dictionary 'DICT_9X9_100'",
    ),
    (
        "dictionary as a number",
        full(M0, '"units": "ft", "marker_size_mm": 80, "dictionary": 16'),
        {},
        "try 'ARUCO_ORIGINAL'",
    ),
    (
        "id beyond 4X4_50",
        with_marker('{"translation": [0, 0, 1]}', "50").replace(
            '"marker_size_mm": 80', '"marker_size_mm": 80, "dictionary": "4X4_50"'
        ),
        {},
        "marker id 50 does not exist in dictionary 4X4_50, which has ids 0 to 49",
    ),
    ("id beyond ARUCO_ORIGINAL", with_marker('{"translation": [0, 0, 1]}', "1024"), {}, "which has ids 0 to 1023"),
    ("no markers", full(""), {}, "the map has no markers"),
    ("empty bare map", "{}", {"units": "mm", "marker_size_mm": 80}, "add at least one placement"),
    ("a list, not an object", "[1, 2, 3]", {}, "expected a JSON object mapping marker ids to placements, got list"),
    ("a string, not an object", '"map"', {}, "got str"),
    ("placement is a list", full('"0": [0, 0, 1]'), {}, 'must be an object with "translation" and "rotation"'),
    ("placement without translation", with_marker('{"rotation": [0, 0, 0]}'), {}, 'has no "translation"'),
    (
        "typo in a placement field",
        with_marker('{"translation": [0, 0, 1], "rotaton": [0, 0, 0]}'),
        {},
        "unknown field 'rotaton'",
    ),
    ("typo in a top-level field", full(M0, '"units": "ft", "marker_size": 80'), {}, "unknown field 'marker_size'"),
    ("markers is a list", '{"units": "ft", "marker_size_mm": 80, "markers": []}', {}, '"markers" must be an object'),
    (
        "units disagree with the caller",
        SEED_TEXT,
        {"units": "mm"},
        "the file says units = 'ft' but 'mm' was given; drop one",
    ),
    (
        "size disagrees with the caller",
        SEED_TEXT,
        {"marker_size_mm": 50},
        "the file says marker_size_mm = 80 but 50 was given",
    ),
    ("dictionary disagrees with the caller", SEED_TEXT, {"dictionary": "4X4_50"}, "the file says dictionary"),
]


@pytest.mark.parametrize(("content", "kwargs", "fragment"), [c[1:] for c in MAP_FILES], ids=[c[0] for c in MAP_FILES])
def test_bad_map_file(tmp_path, content, kwargs, fragment):
    path = tmp_path / "map.json"
    if isinstance(content, str):
        path.write_text(content, encoding="utf-8")
    else:
        path.write_bytes(content)
    with pytest.raises(MapError) as info:
        MarkerMap.load(path, **kwargs)
    assert fragment in str(info.value)
    if "nested" not in fragment:  # every message but the syntax-free ones names the file
        assert str(path) in str(info.value)


def test_map_paths_that_are_not_files(tmp_path):
    with pytest.raises(MapError, match="no such file; check the path of the world map"):
        MarkerMap.load(tmp_path / "nope.json")
    with pytest.raises(MapError, match="is a folder, not a file; give the path of a world map file"):
        MarkerMap.load(tmp_path)


def test_the_corpus_base_is_valid(tmp_path):
    """The corpus mutates a valid map: without the mutation it loads, with the seed's answer."""
    path = tmp_path / "map.json"
    path.write_text(SEED_TEXT)
    np.testing.assert_allclose(MarkerMap.load(path).marker_corners(0)[0], [0, 0, 304.8])
    path.write_text(full(M0))
    assert MarkerMap.load(path).ids == [0]


# -- fuzzing the map loader -------------------------------------------------------------
json_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.integers(min_value=10**300),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.sampled_from(["0", "-1", "1.5", "ft", "mm", "ARUCO_ORIGINAL", "4X4_50", "\u00b2", "--5", " 7 ", "1e3"]),
)
json_values = st.recursive(
    json_scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)
numbers = st.one_of(st.integers(-(10**12), 10**12), st.floats(), st.integers(min_value=10**300))
vectors = st.one_of(st.lists(numbers, min_size=0, max_size=4), json_values)
placements = st.fixed_dictionaries(
    {},
    optional={"translation": vectors, "rotation": vectors, "rotaton": json_values},
)
id_keys = st.one_of(
    st.integers(-5, 1100).map(str), st.text(max_size=4), st.sampled_from(["²", "--5", "01", " 3", "1.0"])
)
markers = st.dictionaries(id_keys, st.one_of(placements, json_values), max_size=4)
full_maps = st.fixed_dictionaries(
    {"markers": st.one_of(markers, json_values)},
    optional={
        "units": st.one_of(st.sampled_from(["mm", "cm", "m", "in", "ft", "FT ", "feet"]), json_values),
        "marker_size_mm": st.one_of(numbers, json_values),
        "dictionary": st.one_of(st.sampled_from(["ARUCO_ORIGINAL", "DICT_4X4_50", "6x6_250", "9X9"]), json_values),
        "name": json_values,
        "typo": json_values,
    },
)
map_dicts = st.one_of(full_maps, markers, json_values)
caller_units = st.one_of(st.none(), st.sampled_from(["mm", "ft", "parsec"]))
caller_sizes = st.one_of(st.none(), st.floats(), st.integers(-5, 500))
caller_dictionaries = st.one_of(st.none(), st.sampled_from(["ARUCO_ORIGINAL", "4X4_50", "nope"]))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(d=map_dicts, units=caller_units, size=caller_sizes, dictionary=caller_dictionaries)
def test_map_loader_fuzz_gives_a_map_or_a_map_error(d, units, size, dictionary):
    """Whatever JSON-like value comes in, ``from_dict`` returns a usable map or raises MapError, nothing else."""
    try:
        m = MarkerMap.from_dict(d, units=units, marker_size_mm=size, dictionary=dictionary, source="fuzz.json")
    except MapError as exc:
        assert str(exc).startswith("fuzz.json: ")
        return
    corners = m.corners()
    assert corners
    assert all(c.shape == (4, 3) and np.all(np.isfinite(c)) for c in corners.values())
    assert m.marker_size_mm > 0
    assert math.isfinite(m.marker_size_mm)
    assert all(0 <= i < _cv.dictionary_size(m.dictionary) for i in m.ids)


@settings(max_examples=100, deadline=None)
@given(blob=st.binary(max_size=200))
def test_map_file_fuzz_bytes(tmp_path_factory, blob):
    path = tmp_path_factory.mktemp("fuzz") / "map.json"
    path.write_bytes(blob)
    with contextlib.suppress(MapError):
        MarkerMap.load(path, units="mm", marker_size_mm=80)


# -- camera files ------------------------------------------------------------------------
K_GOOD = [[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]]
CAM = {"camera_matrix": K_GOOD, "dist_coeffs": [0.1, -0.05, 0, 0, 0], "image_size": [640, 480]}


def cam_json(**changes) -> str:
    d = dict(CAM)
    for key, value in changes.items():
        if value is ...:
            d.pop(key)
        else:
            d[key] = value
    return json.dumps(d)


CAMERA_JSON = [
    ("empty file", "", "the file is empty"),
    ("truncated", cam_json()[:40], "invalid JSON"),
    ("a list", "[[600, 0, 319.5]]", "expected a JSON object with camera_matrix"),
    ("no camera_matrix", cam_json(camera_matrix=...), "missing field camera_matrix"),
    ("no image_size", cam_json(image_size=...), "missing field image_size"),
    ("K is 2x2", cam_json(camera_matrix=[[600, 0], [0, 600]]), "camera_matrix has shape (2, 2), expected 3x3"),
    ("K is 3x4", cam_json(camera_matrix=[[600, 0, 319.5, 0], [0, 600, 239.5, 0], [0, 0, 1, 0]]), "has shape (3, 4)"),
    ("K is ragged", cam_json(camera_matrix=[[600, 0, 319.5], [0, 600], [0, 0, 1]]), "camera_matrix is not numeric"),
    (
        "K holds text",
        cam_json(camera_matrix=[["fx", 0, 319.5], [0, 600, 239.5], [0, 0, 1]]),
        "camera_matrix is not numeric",
    ),
    ("K holds a 400-digit number", cam_json()[:-1].replace("600.0", "1" + "0" * 400, 1) + "}", "not numeric"),
    ("zero focal length", cam_json(camera_matrix=[[0, 0, 319.5], [0, 600, 239.5], [0, 0, 1]]), "both must be positive"),
    ("negative focal length", cam_json(camera_matrix=[[600, 0, 319.5], [0, -600, 239.5], [0, 0, 1]]), "fy=-600"),
    ("transposed K", cam_json(camera_matrix=np.array(K_GOOD).T.tolist()), "it looks transposed"),
    (
        "K bottom row not 0 0 1",
        cam_json(camera_matrix=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 0]]),
        "[[fx,0,cx],[0,fy,cy],[0,0,1]]",
    ),
    ("K with NaN", cam_json().replace("319.5", "NaN"), "contains NaN, which is not a number"),
    ("K with 1e999", cam_json().replace("319.5", "1e999"), "camera_matrix contains NaN or infinity"),
    ("dist of length 3", cam_json(dist_coeffs=[0.1, 0, 0]), "dist_coeffs has 3 values; OpenCV takes 4, 5, 8, 12 or 14"),
    ("dist of length 6", cam_json(dist_coeffs=[0.1, 0, 0, 0, 0, 0]), "has 6 values"),
    ("dist with text", cam_json(dist_coeffs=["k1", 0, 0, 0]), "dist_coeffs is not a list of numbers"),
    ("dist with 1e999", cam_json().replace("-0.05", "1e999"), "dist_coeffs contains NaN or infinity"),
    ("image_size with 1 value", cam_json(image_size=[640]), "image_size must be [width, height] in pixels"),
    ("image_size as text", cam_json(image_size="640x480"), "image_size must be [width, height]"),
    ("image_size of 3 values", cam_json(image_size=[640, 480, 3]), "image_size must be [width, height]"),
    ("zero width", cam_json(image_size=[0, 480]), "two positive whole numbers"),
    ("negative height", cam_json(image_size=[640, -480]), "two positive whole numbers"),
    ("fractional width", cam_json(image_size=[640.5, 480]), "two positive whole numbers"),
    ("image_size with null", cam_json(image_size=[640, None]), "image_size must be [width, height]"),
]


matrices = st.one_of(
    st.lists(st.lists(numbers, min_size=3, max_size=3), min_size=3, max_size=3),
    st.lists(numbers, min_size=0, max_size=10),
    json_values,
)
camera_dicts = st.one_of(
    st.fixed_dictionaries(
        {},
        optional={
            "camera_matrix": st.one_of(matrices, st.just(K_GOOD)),
            "dist_coeffs": st.one_of(st.lists(numbers, max_size=15), json_values),
            "image_size": st.one_of(st.lists(st.one_of(st.integers(-2, 5000), numbers), max_size=3), json_values),
            "source": json_values,
        },
    ),
    json_values,
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(d=camera_dicts)
def test_camera_loader_fuzz_gives_a_camera_or_a_camera_error(d):
    try:
        cam = Camera.from_dict(d, source="fuzz.json")
    except CameraError:
        return
    assert cam.K.shape == (3, 3)
    assert np.all(np.isfinite(cam.K))
    assert cam.fx > 0
    assert cam.fy > 0
    assert cam.width > 0
    assert cam.height > 0
    assert np.all(np.isfinite(cam.dist))


@pytest.mark.parametrize(("content", "fragment"), [c[1:] for c in CAMERA_JSON], ids=[c[0] for c in CAMERA_JSON])
def test_bad_camera_json(tmp_path, content, fragment):
    path = tmp_path / "camera.json"
    path.write_text(content)
    with pytest.raises(CameraError) as info:
        Camera.load(path)
    assert fragment in str(info.value)
    assert str(path) in str(info.value)


GOOD_YAML = """%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0.1, -0.05, 0., 0., 0. ]
"""
DIST3 = "rows: 1\n   cols: 3\n   dt: d\n   data: [ 0.1, -0.05, 0. ]"
DIST5 = "rows: 1\n   cols: 5\n   dt: d\n   data: [ 0.1, -0.05, 0., 0., 0. ]"
K_DATA = "data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]"

CAMERA_YAML = [
    ("empty file", "", {}, "the file is empty"),
    ("only blank lines", "\n\n   \n", {}, "the file is empty"),
    ("truncated", GOOD_YAML[: len(GOOD_YAML) // 2], {}, "not a readable OpenCV FileStorage file"),
    ("truncated in the last matrix", GOOD_YAML[:-25], {}, "should start with %YAML:1.0 or <?xml"),
    ("plain text", "fx = 600\n", {}, "not an OpenCV FileStorage file; it should start with %YAML:1.0 or <?xml"),
    ("binary garbage", b"\x89PNG\r\n\x1a\n" + bytes(range(256)), {}, "not UTF-8 text"),
    ("header only", "%YAML:1.0\n", {}, "no camera_matrix field"),
    ("K under another name", GOOD_YAML.replace("camera_matrix", "K"), {}, "no camera_matrix field, but 'K': did you"),
    (
        "the distortion under fidlearn's JSON name",
        GOOD_YAML.replace("distortion_coefficients", "dist_coeffs"),
        {},
        "no distortion_coefficients field, but 'dist_coeffs': did you mean 'distortion_coefficients'?",
    ),
    (
        "K is a number",
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: 600\n",
        {},
        "camera_matrix is not an !!opencv-matrix",
    ),
    (
        "K is a plain list",
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]\n",
        {},
        "not an !!opencv-matrix",
    ),
    (
        "K rows x cols != data",
        GOOD_YAML.replace("rows: 3\n   cols: 3", "rows: 3\n   cols: 4"),
        {},
        "rows x cols must equal the number of values in data",
    ),
    (
        "K is 2x2",
        GOOD_YAML.replace("rows: 3\n   cols: 3", "rows: 2\n   cols: 2").replace(K_DATA, "data: [ 600., 0., 0., 600. ]"),
        {},
        "camera_matrix has shape (2, 2)",
    ),
    ("zero focal", GOOD_YAML.replace("600., 0., 319.5", "0., 0., 319.5"), {}, "both must be positive"),
    (
        "transposed K",
        GOOD_YAML.replace(K_DATA, "data: [ 600., 0., 0., 0., 600., 0., 319.5, 239.5, 1. ]"),
        {},
        "it looks transposed",
    ),
    ("dist of length 3", GOOD_YAML.replace(DIST5, DIST3), {}, "dist_coeffs has 3 values"),
    (
        "dist rows x cols != data",
        GOOD_YAML.replace("cols: 5", "cols: 6"),
        {},
        "distortion_coefficients is a malformed !!opencv-matrix",
    ),
    ("dist with .nan", GOOD_YAML.replace("-0.05", ".nan"), {}, "dist_coeffs contains NaN or infinity"),
    (
        "width written as text",
        GOOD_YAML.replace("image_width: 640", "image_width: wide"),
        {},
        "image_width must be a whole number of pixels",
    ),
    (
        "fractional width",
        GOOD_YAML.replace("image_width: 640", "image_width: 640.7"),
        {},
        "image_width must be a whole number",
    ),
    ("zero height", GOOD_YAML.replace("image_height: 480", "image_height: 0"), {}, "two positive whole numbers"),
    (
        "no size, none given",
        GOOD_YAML.replace("image_width: 640\nimage_height: 480\n", ""),
        {},
        "pass image_size=(width, height)",
    ),
    ("only the width", GOOD_YAML.replace("image_height: 480\n", ""), {}, "no image_width/image_height"),
    (
        "size disagrees with the caller",
        GOOD_YAML,
        {"image_size": (1280, 720)},
        "the caller says 1280x720; use Camera.scaled()",
    ),
]


@pytest.mark.parametrize(
    ("content", "kwargs", "fragment"), [c[1:] for c in CAMERA_YAML], ids=[c[0] for c in CAMERA_YAML]
)
def test_bad_camera_yaml(tmp_path, content, kwargs, fragment):
    path = tmp_path / "camera.yml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    with pytest.raises(CameraError) as info:
        Camera.load(path, **kwargs)
    assert fragment in str(info.value)
    assert str(path) in str(info.value)


def test_camera_corpus_base_is_valid(tmp_path):
    (tmp_path / "c.yml").write_text(GOOD_YAML)
    (tmp_path / "c.json").write_text(cam_json())
    for name in ("c.yml", "c.json"):
        cam = Camera.load(tmp_path / name)
        np.testing.assert_array_equal(cam.K, K_GOOD)
        np.testing.assert_array_equal(cam.dist, [0.1, -0.05, 0, 0, 0])
        assert cam.image_size == (640, 480)


@pytest.mark.parametrize("suffix", [".xml", ".yml"])
def test_truncated_filestorage_written_by_fidlearn(tmp_path, suffix):
    path = tmp_path / f"camera{suffix}"
    Camera(K_GOOD, [0.1, 0, 0, 0, 0], (640, 480)).save(path)
    text = path.read_text()
    path.write_text(text[: text.rindex("0.")])  # cut inside the last matrix's data
    with pytest.raises(CameraError, match="not a readable OpenCV FileStorage file"):
        Camera.load(path)


def test_camera_paths_that_are_not_files(tmp_path):
    with pytest.raises(CameraError, match="no such file; check the path of the camera"):
        Camera.load(tmp_path / "camera.json")
    with pytest.raises(CameraError, match="no such file; check the path of the camera"):
        Camera.load(tmp_path / "camera.yml")
    with pytest.raises(CameraError, match="is a folder"):
        Camera.load(tmp_path)


# -- a camera used at another resolution ----------------------------------------------------
def test_camera_at_half_resolution_warns_and_scales():
    cam = Camera(K_GOOD, None, (640, 480))
    with pytest.warns(FidlearnWarning, match="rescaled to 320x240"):
        half = cam.for_image(np.zeros((240, 320), np.uint8))
    # Pixel-centre convention: c' = (c + 0.5) * s - 0.5.
    np.testing.assert_allclose(half.K, [[300, 0, 159.5], [0, 300, 119.5], [0, 0, 1]])
    assert half.image_size == (320, 240)


@pytest.mark.parametrize("size", [(640, 360), (480, 640), (1920, 1080)])
def test_camera_at_another_aspect_ratio_is_refused(size):
    cam = Camera(K_GOOD, None, (640, 480))
    with pytest.raises(CameraError, match="calibrate at the resolution you run at"):
        cam.for_image(np.zeros((size[1], size[0]), np.uint8))


# -- images -------------------------------------------------------------------------------
def marker_scene(dtype=np.uint8, channels: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """ARUCO_ORIGINAL marker 7, 100 px with its border, at (50, 40): the image and its true corners.

    The marker's outer corners are pixel edges, so in OpenCV's pixel-centre convention
    the TL corner sits at (49.5, 39.5) and the side is 100 px.
    """
    marker = _cv.generate_marker("ARUCO_ORIGINAL", 7, 100)
    gray = np.full((200, 220), 255, np.uint8)
    gray[40:140, 50:150] = marker
    truth = np.array([[49.5, 39.5], [149.5, 39.5], [149.5, 139.5], [49.5, 139.5]])
    img = gray.astype(np.float64) / 255.0
    if dtype == np.uint16:
        img = (img * 65535).round().astype(np.uint16)
    elif dtype == np.uint8:
        img = gray
    else:
        img = img.astype(dtype)
    if channels == 3:
        img = np.dstack([img] * 3)
    elif channels == 4:
        alpha = np.full(img.shape, np.iinfo(img.dtype).max if img.dtype.kind == "u" else 1, img.dtype)
        img = np.dstack([img] * 3 + [alpha])
    return img, truth


@pytest.mark.parametrize(
    ("dtype", "channels"),
    [
        (np.uint8, 1),
        (np.uint8, 3),
        (np.uint8, 4),
        (np.uint16, 1),
        (np.uint16, 3),
        (np.uint16, 4),
        (np.float32, 1),
        (np.float64, 3),
    ],
    ids=["gray8", "bgr8", "bgra8", "gray16", "bgr16", "bgra16", "float32 gray", "float64 bgr"],
)
def test_every_image_type_users_have_is_detected(tmp_path, dtype, channels):
    img, truth = marker_scene(dtype, channels)
    images = [img]
    if dtype != np.float32 and dtype != np.float64:  # PNG holds 8 and 16 bits, gray, BGR and BGRA
        path = tmp_path / "scene.png"
        assert cv2.imwrite(str(path), img)
        loaded = load_image(path)
        assert loaded.dtype == dtype
        assert loaded.shape == img.shape
        images.append(loaded)
    for image in images:
        found = detect_markers(image, "ARUCO_ORIGINAL")
        assert [d.id for d in found] == [7]
        np.testing.assert_allclose(found[0].corners_px, truth, atol=0.5)


def write_png(path: Path) -> bytes:
    img, _ = marker_scene()
    ok, buf = cv2.imencode(".png", img)
    assert ok
    path.write_bytes(buf.tobytes())
    return buf.tobytes()


def write_jpeg(path: Path) -> bytes:
    img, _ = marker_scene()
    ok, buf = cv2.imencode(".jpg", img + np.random.default_rng(0).integers(0, 9, img.shape, dtype=np.uint8))
    assert ok
    path.write_bytes(buf.tobytes())
    return buf.tobytes()


IMAGE_FILES = [
    ("empty file", lambda p: p.write_bytes(b""), "the file is empty; expected a PNG or JPEG"),
    ("text file", lambda p: p.write_text("not an image\n"), "not an image OpenCV can read"),
    ("json map named .png", lambda p: p.write_text(SEED_TEXT), "is it truncated or another file type?"),
    ("png header only", lambda p: p.write_bytes(write_png(p)[:40]), "is cut short"),
    ("png cut in half", lambda p: p.write_bytes(write_png(p)[: len(write_png(p)) // 2]), "is cut short"),
    ("png without its end", lambda p: p.write_bytes(write_png(p)[:-12]), "is cut short"),
    ("jpeg cut in half", lambda p: p.write_bytes(write_jpeg(p)[: len(write_jpeg(p)) // 3]), "is cut short"),
    ("only the PNG signature", lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n"), "is cut short"),
]


@pytest.mark.parametrize(("make", "fragment"), [c[1:] for c in IMAGE_FILES], ids=[c[0] for c in IMAGE_FILES])
def test_bad_image_file(tmp_path, make, fragment):
    path = tmp_path / "photo.png"
    make(path)
    with pytest.raises(ImageError) as info:
        load_image(path)
    assert fragment in str(info.value)
    assert str(path) in str(info.value)


def test_bad_image_files_leave_opencv_silent(tmp_path):
    """OpenCV's own log lines go straight to file descriptor 2, past Python: a real process must show none.

    Otherwise the command line's one ``error:`` line comes with ``[ERROR:0@0.1] global grfmt_png.cpp
    ... IHDR chunk shall be first`` or ``[ WARN:0@0.1] ... PNG input buffer is incomplete`` around it.
    """
    paths = []
    for k, (_, make, _) in enumerate(IMAGE_FILES):
        path = tmp_path / f"bad_{k}.png"
        make(path)
        paths.append(str(path))
    code = (
        "import sys\n"
        "from fidlearn.detection import load_image\n"
        "from fidlearn.errors import ImageError\n"
        "for p in sys.argv[1:]:\n"
        "    try:\n"
        "        load_image(p)\n"
        "    except ImageError:\n"
        "        print('refused', p)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, *paths], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.count("refused") == len(paths)
    assert proc.stderr == ""


def test_image_paths_that_are_not_files(tmp_path):
    with pytest.raises(ImageError, match="no such file; check the path of the picture"):
        load_image(tmp_path / "photo.png")
    with pytest.raises(ImageError, match="is a folder, not a file"):
        load_image(tmp_path)


IMAGE_ARRAYS = [
    ("1x1 image", np.full((1, 1), 200, np.uint8), "1x1 pixels is too small to hold a marker"),
    ("one row", np.zeros((1, 640), np.uint8), "too small to hold a marker"),
    ("empty array", np.zeros((0, 0), np.uint8), "the image is empty"),
    ("float beyond [0, 1]", np.full((64, 64), 255.0), "a float image must hold values in [0, 1], got 255..255"),
    ("float with NaN", np.full((64, 64), np.nan, np.float32), "contains NaN or infinity"),
    ("int32 pixels", np.zeros((64, 64), np.int32), "pixel type int32 is not supported; use uint8"),
    ("bool pixels", np.zeros((64, 64), bool), "pixel type bool is not supported"),
    ("float16 pixels", np.zeros((64, 64), np.float16), "pixel type float16 is not supported"),
    ("2 channels", np.zeros((64, 64, 2), np.uint8), "expected (H, W) gray or (H, W, 3) BGR"),
    ("5 channels", np.zeros((64, 64, 5), np.uint8), "shape (64, 64, 5) is not an image"),
    ("a batch of images", np.zeros((2, 64, 64, 3), np.uint8), "shape (2, 64, 64, 3) is not an image"),
    ("a 1-D array", np.zeros(4096, np.uint8), "is not an image"),
    (
        "a nested list",
        [[0] * 64] * 64,
        "expected a numpy array (use fidlearn.detection.load_image for a file), got list",
    ),
    ("a path instead of pixels", "photo.png", "got str"),
    ("None", None, "got NoneType"),
]


@pytest.mark.parametrize(("image", "fragment"), [c[1:] for c in IMAGE_ARRAYS], ids=[c[0] for c in IMAGE_ARRAYS])
@pytest.mark.parametrize("entry", [as_gray, detect_markers], ids=["as_gray", "detect_markers"])
def test_bad_image_array(entry, image, fragment):
    with pytest.raises(ImageError) as info:
        entry(image)
    assert fragment in str(info.value)


def test_an_image_of_one_colour_has_no_markers():
    assert detect_markers(np.full((480, 640), 128, np.uint8)) == []


DETECT_ARGUMENTS = [
    ("unknown dictionary", {"dictionary": "DICT_9X9_100"}, DictionaryError, "unknown ArUco dictionary"),
    ("dictionary without its size", {"dictionary": "6x6"}, DictionaryError, "did you mean 6X6_100"),
    ("dictionary with a dash", {"dictionary": "6x6-250"}, DictionaryError, "known: 4X4_100"),
    ("dictionary not a string", {"dictionary": 10}, DictionaryError, "try 'ARUCO_ORIGINAL'"),
    ("unknown refinement", {"refine": "sharp"}, FidlearnError, "unknown corner refinement 'sharp'"),
    ("refinement not a string", {"refine": True}, FidlearnError, "unknown corner refinement True"),
    (
        "unknown detector parameter",
        {"detector_params": {"adaptiveTreshWinSizeMin": 3}},
        FidlearnError,
        "no field 'adaptiveTreshWinSizeMin'",
    ),
]


@pytest.mark.parametrize(
    ("kwargs", "error", "fragment"), [c[1:] for c in DETECT_ARGUMENTS], ids=[c[0] for c in DETECT_ARGUMENTS]
)
def test_bad_detect_arguments(kwargs, error, fragment):
    img, _ = marker_scene()
    with pytest.raises(error) as info:
        detect_markers(img, **kwargs)
    assert fragment in str(info.value)


# -- the command line ---------------------------------------------------------------------
def cli_setup(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "map.json").write_text(SEED_TEXT)
    (tmp_path / "bare.json").write_text("{" + M0 + "}")
    (tmp_path / "deep.json").write_text("[" * 100_000)
    write_png(tmp_path / "photo.png")
    (tmp_path / "outdir").mkdir()
    return {}


CLI_CASES = [
    ("no arguments to corners", ["corners"], "the following arguments are required: MAP.json, -o/--output"),
    ("no output", ["corners", "map.json"], "required: -o/--output"),
    ("map does not exist", ["corners", "nope.json", "-o", "out.json"], "nope.json: no such file"),
    (
        "map is a folder",
        ["corners", "outdir", "-o", "out.json"],
        "is a folder, not a file; give the path of a world map file",
    ),
    ("map is a photo", ["corners", "photo.png", "-o", "out.json"], "not UTF-8 text"),
    ("map nested too deeply", ["corners", "deep.json", "-o", "out.json"], "nested too deeply"),
    (
        "bare map without units",
        ["corners", "bare.json", "--marker-size-mm", "80", "-o", "out.json"],
        "pass units= (command line: --units)",
    ),
    ("bare map without size", ["corners", "bare.json", "--units", "ft", "-o", "out.json"], "--marker-size-mm"),
    ("unknown units", ["corners", "bare.json", "--units", "parsec", "-o", "out.json"], "invalid choice: 'parsec'"),
    (
        "size not a number",
        ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "big", "-o", "out.json"],
        "invalid float value: 'big'",
    ),
    (
        "negative size",
        ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "-80", "-o", "out.json"],
        "it must be positive",
    ),
    (
        "nan size",
        ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "nan", "-o", "out.json"],
        "it must be positive",
    ),
    (
        "size disagrees with the file",
        ["corners", "map.json", "--marker-size-mm", "50", "-o", "out.json"],
        "drop one of them",
    ),
    (
        "unknown dictionary",
        ["corners", "map.json", "--dictionary", "7x7", "-o", "out.json"],
        "unknown ArUco dictionary '7x7'",
    ),
    (
        "output folder missing",
        ["corners", "map.json", "-o", "nodir/out.json"],
        "the folder nodir does not exist; create it first",
    ),
    ("output is a folder", ["corners", "map.json", "-o", "outdir"], "outdir: is a folder"),
    ("unknown option", ["corners", "map.json", "-o", "out.json", "--bogus"], "unrecognized arguments: --bogus"),
    ("unknown command", ["frobnicate"], "invalid choice: 'frobnicate'"),
]


@pytest.mark.parametrize(("argv", "fragment"), [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_bad_command_line(tmp_path, monkeypatch, capsys, argv, fragment):
    cli_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    status = cli_main(argv)
    out, err = capsys.readouterr()
    assert status == 2
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert fragment in lines[0]
    assert "Traceback" not in out + err
    # No output file, and no temporary file left behind.
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["corners", "map.json", "-o", "outdir"], "is a folder"),
        (["corners", "deep.json", "-o", "out.json"], "nested too deeply"),
        (["corners", "--units", "ft", "-o", "out.json"], "required: MAP.json"),
    ],
    ids=["output is a folder", "map nested too deeply", "map missing"],
)
def test_bad_command_line_in_a_real_process(tmp_path, argv, fragment):
    """``python -m fidlearn`` itself: status 2, one ``error:`` line, no traceback, no output file."""
    cli_setup(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    proc = subprocess.run(
        [sys.executable, "-m", "fidlearn", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: "), proc.stderr
    assert fragment in lines[0], proc.stderr
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_good_command_line_for_comparison(tmp_path, monkeypatch, capsys):
    """The same set-up with a correct command writes the corner file: the failures above are the inputs' fault."""
    cli_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert cli_main(["corners", "bare.json", "--units", "ft", "--marker-size-mm", "80", "-o", "outdir/c.json"]) == 0
    assert json.loads((tmp_path / "outdir" / "c.json").read_text())["0"][0] == [0.0, 0.0, 304.8]
    assert capsys.readouterr().err == ""


# -- pose: estimate_pose and locate --------------------------------------------------------
from fidlearn.calibration import calibrate_checkerboard  # noqa: E402
from fidlearn.data import data_path  # noqa: E402
from fidlearn.detection import Detection  # noqa: E402
from fidlearn.errors import CalibrationError, NoMarkersError, PoseError  # noqa: E402
from fidlearn.frames import look_at  # noqa: E402
from fidlearn.pose import estimate_pose, locate  # noqa: E402
from fidlearn.synthetic import render_scene  # noqa: E402

SQUARE_PX = [[100.0, 100.0], [200.0, 100.0], [200.0, 200.0], [100.0, 200.0]]


def seed_map() -> MarkerMap:
    return MarkerMap.from_dict(SEED)


def camera_640() -> Camera:
    return Camera.from_fov(60, (640, 480))


ESTIMATE_POSE = [
    (
        "NaN corner",
        lambda: ([Detection(0, [[np.nan, 100.0]] + SQUARE_PX[1:])], seed_map(), camera_640()),
        {},
        PoseError,
        "detections[0] (marker 0) has NaN or infinite corners",
    ),
    (
        "infinite corner",
        lambda: ([Detection(1, SQUARE_PX[:3] + [[100.0, np.inf]])], seed_map(), camera_640()),
        {},
        PoseError,
        "(marker 1) has NaN or infinite corners",
    ),
    (
        "corners from a picture twice the size",  # a pose with no residual, in the wrong place
        lambda: ([Detection(0, np.array(SQUARE_PX) * 4.5)], seed_map(), camera_640()),
        {},
        PoseError,
        "far outside the camera's 640x480 picture: were they detected in a picture of another size?",
    ),
    (
        "a corner far to the left of the picture",  # the message names that corner, not the largest coordinates
        lambda: ([Detection(0, np.array(SQUARE_PX) - [2000.0, 0.0])], seed_map(), camera_640()),
        {},
        PoseError,
        "a detected corner lies at (-",
    ),
    ("no detections", lambda: ([], seed_map(), camera_640()), {}, NoMarkersError, "no marker was detected"),
    (
        "only ids the map lacks",
        lambda: ([Detection(77, SQUARE_PX)], seed_map(), camera_640()),
        {},
        NoMarkersError,
        "the image shows markers [77], none of which is in the map",
    ),
    (
        "all corners at one point",
        lambda: ([Detection(0, [[100.0, 100.0]] * 4)], seed_map(), camera_640()),
        {},
        PoseError,
        "enclose no area",
    ),
    (
        "mirrored winding TL, BL, BR, TR",
        lambda: ([Detection(0, np.array(SQUARE_PX)[[0, 3, 2, 1]])], seed_map(), camera_640()),
        {},
        PoseError,
        "marker 0: its image corners "
        "[[100.0, 100.0], [100.0, 200.0], [200.0, 200.0], [200.0, 100.0]] run anticlockwise",
    ),
    (
        "shuffled corners",
        lambda: ([Detection(0, np.array(SQUARE_PX)[[0, 2, 1, 3]])], seed_map(), camera_640()),
        {},
        PoseError,
        "do not form a convex quadrilateral",
    ),
    (
        "unknown method",
        lambda: ([Detection(0, SQUARE_PX)], seed_map(), camera_640()),
        {"method": "magic"},
        PoseError,
        "unknown method 'magic'; use 'auto'",
    ),
    (
        "corners as an array",
        lambda: (np.array([SQUARE_PX]), seed_map(), camera_640()),
        {},
        PoseError,
        "detections must be a list of fidlearn Detection (from detect_markers), got ndarray",
    ),
    (
        "a dict of corners",
        lambda: ({0: np.array(SQUARE_PX)}, seed_map(), camera_640()),
        {},
        PoseError,
        "detections[0] is a int, expected a Detection(id, corners (4, 2))",
    ),
    (
        "a list of arrays",
        lambda: ([np.array(SQUARE_PX)], seed_map(), camera_640()),
        {},
        PoseError,
        "detections[0] is a ndarray",
    ),
    ("None for detections", lambda: (None, seed_map(), camera_640()), {}, PoseError, "got NoneType"),
    (
        "a map file that is not there",
        lambda: ([Detection(0, SQUARE_PX)], "no_map.json", camera_640()),
        {},
        MapError,
        "no_map.json: no such file; check the path of the world map",
    ),
    (
        "a camera file that is not there",
        lambda: ([Detection(0, SQUARE_PX)], seed_map(), "no_camera.json"),
        {},
        CameraError,
        "no_camera.json: no such file",
    ),
    (
        "K instead of a camera",
        lambda: ([Detection(0, SQUARE_PX)], seed_map(), camera_640().K),
        {},
        PoseError,
        "camera must be a fidlearn.Camera or the path of a camera file, got ndarray",
    ),
    ("a list instead of a map", lambda: ([Detection(0, SQUARE_PX)], [SEED], camera_640()), {}, PoseError, "got list"),
]


@pytest.mark.parametrize(
    ("make", "kwargs", "error", "fragment"), [c[1:] for c in ESTIMATE_POSE], ids=[c[0] for c in ESTIMATE_POSE]
)
def test_bad_estimate_pose_input(make, kwargs, error, fragment):
    detections, marker_map, camera = make()
    with pytest.raises(error) as info:
        estimate_pose(detections, marker_map, camera, **kwargs)
    assert fragment in str(info.value)


@pytest.fixture(scope="module")
def seed_scene():
    """The seed wall from 1.5 m at 1280x960, with its true pose."""
    camera = Camera.from_fov(60, (1280, 960))
    T_world_camera = look_at([1500, 150, 250], [0, 150, 250])
    image = render_scene(seed_map(), camera, T_world_camera).image
    return camera, image, T_world_camera


LOCATE = [
    ("a file name for the image", lambda _img: "scene.png", ImageError, "use fidlearn.detection.load_image"),
    ("a blank picture", lambda img: np.full_like(img, 255), NoMarkersError, "no marker was detected"),
    ("another aspect ratio", lambda img: img[:720], CameraError, "calibrate at the resolution you run at"),
    ("int32 pixels", lambda img: img.astype(np.int32), ImageError, "pixel type int32 is not supported"),
]


@pytest.mark.parametrize(("change", "error", "fragment"), [c[1:] for c in LOCATE], ids=[c[0] for c in LOCATE])
def test_bad_locate_input(seed_scene, change, error, fragment):
    camera, image, _ = seed_scene
    with pytest.raises(error) as info:
        locate(change(image), seed_map(), camera)
    assert fragment in str(info.value)


def test_locate_at_half_resolution_warns_and_finds_the_true_pose(seed_scene):
    camera, image, T_world_camera = seed_scene
    half = cv2.resize(image, (640, 480), interpolation=cv2.INTER_AREA)
    with pytest.warns(FidlearnWarning, match="rescaled to 640x480"):
        pose = locate(half, seed_map(), camera)
    # The same answer as with the camera scaled by hand, and the truth within its 3-sigma box.
    by_hand = locate(half, seed_map(), camera.scaled((640, 480)))
    np.testing.assert_allclose(pose.T_world_camera, by_hand.T_world_camera, atol=1e-9)
    assert np.all(np.abs(pose.position_mm - T_world_camera[:3, 3]) <= 3 * pose.position_std_mm)
    assert list(pose.marker_ids) == [0, 1]


# -- calibration ---------------------------------------------------------------------------
def calib_setup(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "a.txt").write_text("board photos go here\n")
    for name in ("text.png", "text2.png", "text3.png"):
        (tmp_path / name).write_text("not a picture\n")
    for name in ("marker.png", "marker2.png", "marker3.png"):  # each photo counts once: three files
        write_png(tmp_path / name)


BLANK = np.full((480, 640), 255, np.uint8)
CALIBRATE = [
    ("empty folder", "{tmp}/empty", (9, 6), 25, "no images (.png, .jpg, .jpeg"),
    ("folder without pictures", "{tmp}/notes", (9, 6), 25, "no images ("),
    ("a folder inside the list", ["{tmp}/notes"], (9, 6), 25, "is a folder, not a file"),
    ("glob that matches nothing", "{tmp}/*.jpeg", (9, 6), 25, "no file matches this pattern"),
    ("no images at all", [], (9, 6), 25, "calibration needs at least 3 views of the board"),
    ("pattern as words", [BLANK] * 3, "9 by 6", 25, "must be two whole numbers (columns, rows) of inner corners"),
    ("pattern 1x1", [BLANK] * 3, (1, 1), 25, "needs at least 3 each way"),
    ("pattern of squares, not corners", [BLANK] * 3, (0, 6), 25, "a board of 10x7 squares has 9x6 inner corners"),
    ("negative square", [BLANK] * 3, (9, 6), -25, "square_size_mm must be positive"),
    ("NaN square", [BLANK] * 3, (9, 6), float("nan"), "square_size_mm must be positive, got nan"),
    (
        "text file named .png",
        ["{tmp}/text.png", "{tmp}/text2.png", "{tmp}/text3.png"],
        (9, 6),
        25,
        "not an image OpenCV can read",
    ),
    ("missing files", ["{tmp}/a.png", "{tmp}/b.png", "{tmp}/c.png"], (9, 6), 25, "no such file"),
    (
        "a photo given twice",
        ["{tmp}/marker.png", "{tmp}/./marker.png", "{tmp}/marker2.png"],
        (9, 6),
        25,
        "is given twice (also as",
    ),
    ("no board in the pictures", [BLANK] * 3, (9, 6), 25, "board not found (9x6 inner corners)"),
    (
        "pictures of a marker",
        ["{tmp}/marker.png", "{tmp}/marker2.png", "{tmp}/marker3.png"],
        (9, 6),
        25,
        "board not found",
    ),
    (
        "pictures of two sizes",
        [BLANK, BLANK[:240, :320], BLANK],
        (9, 6),
        25,
        "image is 320x240 but the others are 640x480",
    ),
]


@pytest.mark.parametrize(
    ("images", "pattern", "square", "fragment"), [c[1:] for c in CALIBRATE], ids=[c[0] for c in CALIBRATE]
)
def test_bad_calibration_input(tmp_path, images, pattern, square, fragment):
    calib_setup(tmp_path)
    if isinstance(images, str):
        images = images.format(tmp=tmp_path)
    else:
        images = [im.format(tmp=tmp_path) if isinstance(im, str) else im for im in images]
    with pytest.raises(CalibrationError) as info:
        calibrate_checkerboard(images, pattern, square)
    assert fragment in str(info.value)


# -- the other commands ---------------------------------------------------------------------
def write_video(path: Path, frames: int = 6) -> int:
    """An MJPG .avi of the bundled scene_00.png (OpenCV writes MJPG on every platform); its byte size."""
    image = load_image(data_path("scenes", "scene_00.png"))
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    h, w = image.shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 5, (w, h))
    assert writer.isOpened()
    for _ in range(frames):
        writer.write(image)
    writer.release()
    return path.stat().st_size


def commands_setup(tmp_path: Path) -> None:
    cli_setup(tmp_path)
    calib_setup(tmp_path)
    shutil.copy(data_path("scenes", "camera.json"), tmp_path / "camera.json")
    size = write_video(tmp_path / "clip.avi")
    (tmp_path / "head.avi").write_bytes((tmp_path / "clip.avi").read_bytes()[: min(300, size // 4)])
    (tmp_path / "notes.avi").write_text("a video of the wall\n")


LOCATE_ARGS = ["--camera", "camera.json", "--map", "map.json"]
COMMANDS = [
    (
        "locate: negative camera index",
        ["locate", *LOCATE_ARGS, "--camera-index", "-1"],
        "cameras are numbered 0 (the first camera) to 255",
    ),
    (
        "locate: map given as the camera",
        ["locate", "clip.avi", "--camera", "map.json", "--map", "map.json"],
        "missing field camera_matrix",
    ),
    (
        "locate: camera given as the map",
        ["locate", "clip.avi", "--camera", "camera.json", "--map", "camera.json"],
        "the map does not say its units",
    ),
    ("camera without export or import", ["camera"], "fidlearn camera: give export or import"),
    ("locate: annotate into a file", ["locate", "clip.avi", *LOCATE_ARGS, "--annotate", "map.json"], "give a folder"),
    ("locate: text file named .png", ["locate", "text.png", *LOCATE_ARGS], "not an image OpenCV can read"),
    ("locate: not a video", ["locate", "notes.avi", *LOCATE_ARGS, "--json", "p.jsonl"], "cannot open this video"),
    (
        "locate: video cut after its header",
        ["locate", "head.avi", *LOCATE_ARGS, "--json", "p.jsonl"],
        "cannot open this video",
    ),
    ("locate: folder without pictures", ["locate", "empty", *LOCATE_ARGS], "no images (.png, .jpg"),
    (
        "calibrate: a video",
        ["calibrate", "clip.avi", "--pattern", "9x6", "--square-mm", "25", "-o", "c.json"],
        "not an image by its name",
    ),
    (
        "calibrate: unreadable pictures",
        ["calibrate", "text.png", "text2.png", "text3.png", "--pattern", "9x6", "--square-mm", "25", "-o", "c.json"],
        "unreadable: 3",
    ),
    (
        "calibrate: output of unknown type",
        ["calibrate", "empty", "--pattern", "9x6", "--square-mm", "25", "-o", "c.txt"],
        "name the file .json or .yml",
    ),
    (
        "markers: backwards range",
        ["markers", "--ids", "5-3", "--size-mm", "50", "-o", "m.pdf"],
        "runs backwards; write 3-5",
    ),
    ("markers: id twice", ["markers", "--ids", "0,0", "--size-mm", "50", "-o", "m.pdf"], "id 0 is listed twice"),
    ("markers: negative id", ["markers", "--ids", "-1", "--size-mm", "50", "-o", "m.pdf"], "give ids like 0-9"),
    ("markers: 20-digit id", ["markers", "--ids", "9" * 20, "--size-mm", "50", "-o", "m.pdf"], "ids 0 to 1023"),
    (
        "markers: infinite size",
        ["markers", "--ids", "0", "--size-mm", "inf", "-o", "m.pdf"],
        "must be a positive length in mm",
    ),
    (
        "markers: larger than the paper",
        ["markers", "--ids", "0", "--size-mm", "1e9", "-o", "m.pdf"],
        "does not fit on a4 paper",
    ),
    (
        "markers: zero dpi",
        ["markers", "--ids", "0", "--size-mm", "50", "--dpi", "0", "-o", "m.png"],
        "--dpi 0: give 50 to 1200 dots per inch",
    ),
    (
        "board: marker larger than its square",
        ["board", "--squares", "5x7", "--charuco", "--square-mm", "20", "--marker-mm", "30", "-o", "b.pdf"],
        "must be smaller than square_size_mm (20) (command line: --marker-mm, --square-mm)",
    ),
    (
        "board: NaN square",
        ["board", "--pattern", "9x6", "--square-mm", "nan", "-o", "b.pdf"],
        "square_size_mm must be positive, at most 100 m, got nan; measure one printed square in millimetres "
        "(command line: --square-mm)",
    ),
    (
        "render: negative noise",
        [
            "render",
            "--map",
            "map.json",
            "--camera",
            "camera.json",
            "--pose",
            "1000,190,230,-90,0,90",
            "--noise",
            "-1",
            "-o",
            "r.png",
        ],
        "--noise must be 0 to 255 gray levels",
    ),
    (
        "render: size in words",
        [
            "render",
            "--map",
            "map.json",
            "--camera",
            "camera.json",
            "--pose",
            "1000,190,230,-90,0,90",
            "--size",
            "big",
            "-o",
            "r.png",
        ],
        "is not COLUMNSxROWS",
    ),
    (
        "survey: one photo",
        ["survey", "text.png", *LOCATE_ARGS, "-o", "s.json"],
        "a survey needs at least 2 photos",
    ),
    (
        "survey: output of unknown type",
        ["survey", "text.png", "text.png", *LOCATE_ARGS, "-o", "s.txt"],
        "name the file .json",
    ),
    (
        "survey: negative tape sigma",
        ["survey", "text.png", "text2.png", *LOCATE_ARGS, "--map-sigma-mm", "-5", "-o", "s.json"],
        "--map-sigma-mm -5: give a positive number of mm",
    ),
    (
        "render: missing camera file",
        ["render", "--map", "map.json", "--camera", "nope.yml", "--pose", "1000,190,230,-90,0,90", "-o", "r.png"],
        "nope.yml: no such file",
    ),
]


@pytest.mark.parametrize(("argv", "fragment"), [c[1:] for c in COMMANDS], ids=[c[0] for c in COMMANDS])
def test_bad_command(tmp_path, monkeypatch, capsys, argv, fragment):
    commands_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    status = cli_main(argv)
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert fragment in lines[0]
    assert "Traceback" not in out + err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_negative_camera_index_in_a_real_process(tmp_path):
    """cv2.VideoCapture(-1) kills the interpreter with a segmentation fault when no camera is attached."""
    commands_setup(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "fidlearn", "locate", *LOCATE_ARGS, "--camera-index", "-1"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert proc.stderr.startswith("error: --camera-index -1")
    assert len(proc.stderr.splitlines()) == 1


def test_video_that_ends_early_gives_the_frames_before_the_cut(tmp_path, monkeypatch, capsys):
    """A video cut in the middle: the frames before the cut are located at their true pose, the run succeeds."""
    commands_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    data = (tmp_path / "clip.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: len(data) // 2])
    assert cli_main(["locate", "cut.avi", *LOCATE_ARGS, "--json", "p.jsonl"]) == 0
    lines = [json.loads(line) for line in (tmp_path / "p.jsonl").read_text().splitlines()]
    assert 1 <= len(lines) < 6
    err = capsys.readouterr().err
    assert f"warning: cut.avi: the video ended after {len(lines)} of the 6 frames its header announces" in err
    truth = np.array(json.loads(data_path("scenes", "poses.json").read_text())["images"][0]["T_world_camera"])
    for line in lines:
        assert line["located"]
        np.testing.assert_allclose(line["position_mm"], truth[:3, 3], atol=20)


# -- printables and ChArUco calibration (Python API) ------------------------------------------
from fidlearn.calibration import calibrate_charuco  # noqa: E402
from fidlearn.printables import PrintError, board_pdf, markers_pdf  # noqa: E402

PRINTABLES = [
    ("no ids", lambda out: markers_pdf(out / "m.pdf", [], 50), PrintError, "no marker ids to print"),
    (
        "negative id",
        lambda out: markers_pdf(out / "m.pdf", [-1], 50),
        DictionaryError,
        "marker id -1 does not exist in ARUCO_ORIGINAL",
    ),
    (
        "id beyond the dictionary",
        lambda out: markers_pdf(out / "m.pdf", [50], 50, dictionary="4X4_50"),
        DictionaryError,
        "which has ids 0 to 49",
    ),
    ("zero size", lambda out: markers_pdf(out / "m.pdf", [1], 0), PrintError, "must be a positive length in mm, got 0"),
    ("NaN size", lambda out: markers_pdf(out / "m.pdf", [1], float("nan")), PrintError, "got nan"),
    (
        "paper size A3",
        lambda out: markers_pdf(out / "m.pdf", [1], 50, paper="a3"),
        PrintError,
        "unknown paper 'a3'; use a4 or letter",
    ),
    (
        "unknown dictionary",
        lambda out: markers_pdf(out / "m.pdf", [1], 50, dictionary="nope"),
        DictionaryError,
        "unknown ArUco dictionary 'nope'",
    ),
    ("a folder for the file", lambda out: markers_pdf(out, [1], 50), PrintError, "expected a .pdf file name"),
    (
        "a .png name for the pdf",
        lambda out: markers_pdf(out / "m.png", [1], 50),
        PrintError,
        "expected a .pdf file name",
    ),
    (
        "missing folder",
        lambda out: markers_pdf(out / "no" / "m.pdf", [1], 50),
        FidlearnError,
        "does not exist; create it first",
    ),
    (
        "fractional id",
        lambda out: markers_pdf(out / "m.pdf", [1.5], 50),
        PrintError,
        "marker id 1.5 is not a whole number",
    ),
    (
        "True for an id",
        lambda out: markers_pdf(out / "m.pdf", [True, 2], 50),
        PrintError,
        "marker id True is not a whole number",
    ),
    ("bytes for ids", lambda out: markers_pdf(out / "m.pdf", b"12", 50), PrintError, "b'12' is not a whole number"),
    (
        "backwards range as text",
        lambda out: markers_pdf(out / "m.pdf", "5-3", 50),
        PrintError,
        "runs backwards; write 3-5",
    ),
    (
        "board pattern in words",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard("9 by 6", 25)),
        PrintError,
        "write it like 9x6",
    ),
    (
        "board pattern of 3 numbers",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((9, 6, 1), 25)),
        PrintError,
        "two whole numbers (columns, rows), e.g. (9, 6)",
    ),
    (
        "board pattern of floats",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((9.5, 6), 25)),
        PrintError,
        "must be two whole numbers",
    ),
    (
        "board of 1x1 corners",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((1, 1), 25)),
        PrintError,
        "at least 2x2 inner corners, got 1x1",
    ),
    (
        "board of negative size",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((-9, 6), 25)),
        PrintError,
        "at least 2x2 inner corners",
    ),
    (
        "board with zero squares",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((9, 6), 0)),
        PrintError,
        "square_size_mm must be positive",
    ),
    (
        "board larger than the paper",
        lambda out: board_pdf(out / "b.pdf", Board.checkerboard((9, 6), 1000)),
        PrintError,
        "the largest square that fits is",
    ),
    (
        "ChArUco marker larger than its square",
        lambda out: board_pdf(out / "b.pdf", Board.charuco((5, 7), 20, 30)),
        PrintError,
        "must be smaller than square_size_mm (20) (command line: --marker-mm, --square-mm)",
    ),
    (
        "ChArUco board larger than its dictionary",
        lambda out: board_pdf(out / "b.pdf", Board.charuco((15, 20), 10, 7, "4X4_50")),
        PrintError,
        "needs 150 markers but 4X4_50 has only 50",
    ),
]


@pytest.mark.parametrize(("make", "error", "fragment"), [c[1:] for c in PRINTABLES], ids=[c[0] for c in PRINTABLES])
def test_bad_printable(tmp_path, make, error, fragment):
    with pytest.raises(error) as info:
        make(tmp_path)
    assert fragment in str(info.value)
    assert list(tmp_path.iterdir()) == []  # nothing written, not even a temporary file


CHARUCO = [
    ("no images", [], {}, "no images given"),
    ("a checkerboard", [BLANK] * 3, {"board": Board.checkerboard((9, 6), 25)}, "a checkerboard goes to calibrate_"),
    ("a board's counts", [BLANK] * 3, {"board": (5, 7)}, "board must be a fidlearn.Board.charuco(squares, "),
    ("unknown legacy value", [BLANK] * 3, {"legacy": "maybe"}, "legacy must be True, False or 'auto'"),
    ("too few corners asked for", [BLANK] * 3, {"min_corners": 0}, "min_corners must be a whole number, at least 4"),
    ("corners asked for in words", [BLANK] * 3, {"min_corners": "six"}, "at least 4, got 'six'"),
    ("a fraction of a corner", [BLANK] * 3, {"min_corners": 4.7}, "at least 4, got 4.7"),
    ("no board in the pictures", [BLANK] * 3, {}, "no 6X6_250 marker in the picture; check the dictionary"),
]


@pytest.mark.parametrize(("images", "kwargs", "fragment"), [c[1:] for c in CHARUCO], ids=[c[0] for c in CHARUCO])
def test_bad_charuco_calibration_input(images, kwargs, fragment):
    with pytest.raises(CalibrationError) as info:
        calibrate_charuco(images, **({"board": Board.charuco((5, 7), 40, 20)} | kwargs))
    assert fragment in str(info.value)


def test_printables_take_ids_and_patterns_as_the_command_line_writes_them(tmp_path):
    sheet = markers_pdf(tmp_path / "m.pdf", "0-3,8", 50)
    assert [i for page in sheet.pages for i, _, _ in page] == [0, 1, 2, 3, 8]
    assert board_pdf(tmp_path / "b.pdf", Board.checkerboard("9x6", 20)).board.squares == (10, 7)


def test_charuco_calibration_with_an_unknown_dictionary():
    with pytest.raises(DictionaryError, match="unknown ArUco dictionary 'nope'"):
        calibrate_charuco([BLANK] * 3, Board.charuco((5, 7), 40, 20, "nope"))


# -- the tracker ----------------------------------------------------------------------------
from fidlearn.tracking import MarkerTracker  # noqa: E402

TRACKER_OPTIONS = [
    ("a map file name", lambda _m, c: MarkerTracker("map.json", c), "use MarkerMap.load('map.json')"),
    ("K instead of a camera", lambda m, c: MarkerTracker(m, c.K), "use Camera.load('camera.json')"),
    (
        "full_every 0",
        lambda m, c: MarkerTracker(m, c, full_every=0),
        "full_every must be a whole number of frames >= 1",
    ),
    ("full_every True", lambda m, c: MarkerTracker(m, c, full_every=True), "got True"),
    (
        "NaN search margin",
        lambda m, c: MarkerTracker(m, c, search_px=float("nan")),
        "search_px must be a number of pixels >= 0",
    ),
    (
        "misspelt pose option",
        lambda m, c: MarkerTracker(m, c, metod="auto"),
        "MarkerTracker() got unknown option 'metod'; it takes refine, detector_params, full_every, search_px and "
        "estimate_pose's corner_sigma_px, method",
    ),
    ("unknown method", lambda m, c: MarkerTracker(m, c, method="magic"), "unknown method 'magic'"),
    ("unknown refinement", lambda m, c: MarkerTracker(m, c, refine="sharp"), "unknown corner refinement 'sharp'"),
    (
        "unknown detector parameter",
        lambda m, c: MarkerTracker(m, c, detector_params={"nope": 1}),
        "has no field 'nope'",
    ),
]


@pytest.mark.parametrize(("make", "fragment"), [c[1:] for c in TRACKER_OPTIONS], ids=[c[0] for c in TRACKER_OPTIONS])
def test_bad_tracker_options(make, fragment):
    with pytest.raises(FidlearnError) as info:
        make(seed_map(), camera_640())
    assert fragment in str(info.value)


TRACKER_FRAMES = [
    ("a file name", lambda _img: "frame.png", ImageError, "use fidlearn.detection.load_image"),
    ("float with NaN", lambda img: np.full(img.shape, np.nan), ImageError, "contains NaN or infinity"),
    ("int32 pixels", lambda img: img.astype(np.int32), ImageError, "pixel type int32"),
    ("another aspect ratio", lambda img: img[:100], CameraError, "calibrate at the resolution you run at"),
]


def test_tracker_refuses_bad_frames_and_carries_on(seed_scene):
    """Each bad frame raises its error; the next good frame is located exactly as before."""
    camera, image, T_world_camera = seed_scene
    tracker = MarkerTracker(seed_map(), camera)
    first = tracker.locate(image)
    for _, change, error, fragment in TRACKER_FRAMES:
        with pytest.raises(error, match=re.escape(fragment)):
            tracker.locate(change(image))
    again = tracker.locate(image)
    np.testing.assert_allclose(again.T_world_camera, first.T_world_camera, atol=1e-6)
    assert np.all(np.abs(again.position_mm - T_world_camera[:3, 3]) <= 3 * again.position_std_mm)


# -- grading learners' notebooks ----------------------------------------------------------

GRADE = [
    ("missing notebook", "nope.ipynb", "nope.ipynb: no such notebook; check the path"),
    ("a folder", "empty", "is a folder; give the notebooks in it (folder/*.ipynb)"),
    ("a JSON map", "map.json", "not a Jupyter notebook (ValidationError)"),
    ("a picture", "photo.png", "not a Jupyter notebook (UnicodeDecodeError)"),
    ("a truncated notebook", "cut.ipynb", "not a Jupyter notebook"),
]


@pytest.mark.parametrize(("name", "fragment"), [c[1:] for c in GRADE], ids=[c[0] for c in GRADE])
def test_bad_notebook_to_grade(tmp_path, monkeypatch, capsys, name, fragment):
    """``python -m fidlearn.exercises grade``: one ``error:`` line and status 2, as every fidlearn command."""
    commands_setup(tmp_path)
    (tmp_path / "cut.ipynb").write_text('{"cells": [{"cell_type": "code", "source": "x = ')
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    status = _selfstudy_cli._main(["grade", name, "--csv", "grades.csv"])
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert status == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert fragment in lines[0], err
    assert out == ""
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


# -- fuzzing the command line ---------------------------------------------------------------
ARG_WORDS = [
    "corners",
    "markers",
    "board",
    "map.json",
    "bare.json",
    "deep.json",
    "photo.png",
    "outdir",
    "nope.json",
    "-o",
    "out.json",
    "out.pdf",
    "out.png",
    "out.svg",
    "outdir/c.json",
    "--units",
    "ft",
    "mm",
    "parsec",
    "--marker-size-mm",
    "--size-mm",
    "--square-mm",
    "--marker-mm",
    "80",
    "-5",
    "0",
    "nan",
    "1e9",
    "--dictionary",
    "6X6_250",
    "4X4_50",
    "--ids",
    "0-3",
    "3-0",
    "0,0",
    "--pattern",
    "9x6",
    "1x1",
    "--charuco",
    "--squares",
    "5x7",
    "--paper",
    "a4",
    "a3",
    "--dpi",
    "30",
    "--bogus",
    "",
]


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture]
)
@given(argv=st.lists(st.sampled_from(ARG_WORDS), min_size=1, max_size=9))
def test_command_line_fuzz_succeeds_or_says_one_error_line(tmp_path_factory, capsys, argv):
    """Random arguments: status 0 with the output written, or status 2 with one ``error:`` line and nothing written."""
    folder = tmp_path_factory.mktemp("cli")
    cli_setup(folder)
    before = sorted(p.name for p in folder.rglob("*"))
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        capsys.readouterr()
        status = cli_main(argv)
    except SystemExit as exc:  # argparse's own --help / --version
        status = exc.code
    finally:
        os.chdir(cwd)
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    if status == 2:
        lines = err.splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith("error: "), err
        assert sorted(p.name for p in folder.rglob("*")) == before
    else:
        assert status == 0, (status, err)
        assert all(line.startswith("warning: ") for line in err.splitlines()), err
