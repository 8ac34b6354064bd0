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

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fidlearn import Camera, MarkerMap, _cv
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
    ("translation is an object", with_marker('{"translation": {"x": 0, "y": 0, "z": 1}}'), {}, "must be a list of 3 numbers"),
    ("rotation with 4 values", with_marker('{"translation": [0, 0, 1], "rotation": [0, 0, 0, 1]}'), {}, "expected 3 [roll, pitch, yaw] in degrees"),
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
    ("unknown units", full(M0, '"units": "parsec", "marker_size_mm": 80'), {}, "unknown units 'parsec'; use one of mm, cm, m, in, ft"),
    ("units spelled out", full(M0, '"units": "feet", "marker_size_mm": 80'), {}, "use one of mm, cm, m, in, ft"),
    ("units as a number", full(M0, '"units": 1000, "marker_size_mm": 80'), {}, "unknown units 1000"),
    ("no units, full layout", full(M0, '"marker_size_mm": 80'), {}, 'add "units": "ft"'),
    ("no units, bare layout", "{" + M0 + "}", {"marker_size_mm": 80}, "fidlearn never guesses"),
    ("no marker size", full(M0, '"units": "ft"'), {}, 'add "marker_size_mm": 80'),
    ("zero marker size", full(M0, '"units": "ft", "marker_size_mm": 0'), {}, "marker_size_mm is 0; it must be positive"),
    ("negative marker size", full(M0, '"units": "ft", "marker_size_mm": -80'), {}, "it must be positive"),
    ("marker size as text", full(M0, '"units": "ft", "marker_size_mm": "80 mm"'), {}, "marker_size_mm must be a number"),
    ("marker size as text, and given", full(M0, '"units": "ft", "marker_size_mm": "80"'), {"marker_size_mm": 80}, "must be a number"),
    ("huge marker size", full(M0, '"units": "ft", "marker_size_mm": 1' + "0" * 400), {}, "too large for a number"),
    ("unknown dictionary", full(M0, '"units": "ft", "marker_size_mm": 80, "dictionary": "DICT_9X9_100"'), {}, "unknown ArUco dictionary 'DICT_9X9_100'"),
    ("dictionary as a number", full(M0, '"units": "ft", "marker_size_mm": 80, "dictionary": 16'), {}, "try 'ARUCO_ORIGINAL'"),
    ("id beyond 4X4_50", with_marker('{"translation": [0, 0, 1]}', "50").replace('"marker_size_mm": 80', '"marker_size_mm": 80, "dictionary": "4X4_50"'), {}, "marker id 50 does not exist in dictionary 4X4_50, which has ids 0 to 49"),
    ("id beyond ARUCO_ORIGINAL", with_marker('{"translation": [0, 0, 1]}', "1024"), {}, "which has ids 0 to 1023"),
    ("no markers", full(""), {}, "the map has no markers"),
    ("empty bare map", "{}", {"units": "mm", "marker_size_mm": 80}, "add at least one placement"),
    ("a list, not an object", "[1, 2, 3]", {}, "expected a JSON object mapping marker ids to placements, got list"),
    ("a string, not an object", '"map"', {}, "got str"),
    ("placement is a list", full('"0": [0, 0, 1]'), {}, 'must be an object with "translation" and "rotation"'),
    ("placement without translation", with_marker('{"rotation": [0, 0, 0]}'), {}, 'has no "translation"'),
    ("typo in a placement field", with_marker('{"translation": [0, 0, 1], "rotaton": [0, 0, 0]}'), {}, "unknown field 'rotaton'"),
    ("typo in a top-level field", full(M0, '"units": "ft", "marker_size": 80'), {}, "unknown field 'marker_size'"),
    ("markers is a list", '{"units": "ft", "marker_size_mm": 80, "markers": []}', {}, '"markers" must be an object'),
    ("units disagree with the caller", SEED_TEXT, {"units": "mm"}, "the file says units = 'ft' but 'mm' was given; drop one"),
    ("size disagrees with the caller", SEED_TEXT, {"marker_size_mm": 50}, "the file says marker_size_mm = 80 but 50 was given"),
    ("dictionary disagrees with the caller", SEED_TEXT, {"dictionary": "4X4_50"}, "the file says dictionary"),
]


@pytest.mark.parametrize("content, kwargs, fragment", [c[1:] for c in MAP_FILES], ids=[c[0] for c in MAP_FILES])
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
    with pytest.raises(MapError, match="is a folder, expected a world map JSON file"):
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
numbers = st.one_of(st.integers(-10**12, 10**12), st.floats(), st.integers(min_value=10**300))
vectors = st.one_of(st.lists(numbers, min_size=0, max_size=4), json_values)
placements = st.fixed_dictionaries(
    {},
    optional={"translation": vectors, "rotation": vectors, "rotaton": json_values},
)
id_keys = st.one_of(st.integers(-5, 1100).map(str), st.text(max_size=4), st.sampled_from(["²", "--5", "01", " 3", "1.0"]))
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
    assert corners and all(c.shape == (4, 3) and np.all(np.isfinite(c)) for c in corners.values())
    assert m.marker_size_mm > 0 and math.isfinite(m.marker_size_mm)
    assert all(0 <= i < _cv.dictionary_size(m.dictionary) for i in m.ids)


@settings(max_examples=100, deadline=None)
@given(blob=st.binary(max_size=200))
def test_map_file_fuzz_bytes(tmp_path_factory, blob):
    path = tmp_path_factory.mktemp("fuzz") / "map.json"
    path.write_bytes(blob)
    try:
        MarkerMap.load(path, units="mm", marker_size_mm=80)
    except MapError:
        pass


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
    ("K holds text", cam_json(camera_matrix=[["fx", 0, 319.5], [0, 600, 239.5], [0, 0, 1]]), "camera_matrix is not numeric"),
    ("K holds a 400-digit number", cam_json()[:-1].replace("600.0", "1" + "0" * 400, 1) + "}", "not numeric"),
    ("zero focal length", cam_json(camera_matrix=[[0, 0, 319.5], [0, 600, 239.5], [0, 0, 1]]), "both must be positive"),
    ("negative focal length", cam_json(camera_matrix=[[600, 0, 319.5], [0, -600, 239.5], [0, 0, 1]]), "fy=-600"),
    ("transposed K", cam_json(camera_matrix=np.array(K_GOOD).T.tolist()), "it looks transposed"),
    ("K bottom row not 0 0 1", cam_json(camera_matrix=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 0]]), "[[fx,s,cx],[0,fy,cy],[0,0,1]]"),
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
    assert cam.K.shape == (3, 3) and np.all(np.isfinite(cam.K)) and cam.fx > 0 and cam.fy > 0
    assert cam.width > 0 and cam.height > 0
    assert np.all(np.isfinite(cam.dist))


@pytest.mark.parametrize("content, fragment", [c[1:] for c in CAMERA_JSON], ids=[c[0] for c in CAMERA_JSON])
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
    ("plain text", "fx = 600\n", {}, "not a readable OpenCV FileStorage file"),
    ("binary garbage", b"\x89PNG\r\n\x1a\n" + bytes(range(256)), {}, "not a readable OpenCV FileStorage"),
    ("header only", "%YAML:1.0\n", {}, "no camera_matrix field"),
    ("K under another name", GOOD_YAML.replace("camera_matrix", "K"), {}, "no camera_matrix field"),
    ("K is a number", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: 600\n", {}, "camera_matrix is not an !!opencv-matrix"),
    ("K is a plain list", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]\n", {}, "not an !!opencv-matrix"),
    ("K rows x cols != data", GOOD_YAML.replace("rows: 3\n   cols: 3", "rows: 3\n   cols: 4"), {}, "rows x cols must equal the number of values in data"),
    ("K is 2x2", GOOD_YAML.replace("rows: 3\n   cols: 3", "rows: 2\n   cols: 2").replace(K_DATA, "data: [ 600., 0., 0., 600. ]"), {}, "camera_matrix has shape (2, 2)"),
    ("zero focal", GOOD_YAML.replace("600., 0., 319.5", "0., 0., 319.5"), {}, "both must be positive"),
    ("transposed K", GOOD_YAML.replace(K_DATA, "data: [ 600., 0., 0., 0., 600., 0., 319.5, 239.5, 1. ]"), {}, "it looks transposed"),
    ("dist of length 3", GOOD_YAML.replace(DIST5, DIST3), {}, "dist_coeffs has 3 values"),
    ("dist rows x cols != data", GOOD_YAML.replace("cols: 5", "cols: 6"), {}, "distortion_coefficients is a malformed !!opencv-matrix"),
    ("dist with .nan", GOOD_YAML.replace("-0.05", ".nan"), {}, "dist_coeffs contains NaN or infinity"),
    ("width written as text", GOOD_YAML.replace("image_width: 640", "image_width: wide"), {}, "image_width must be a whole number of pixels"),
    ("fractional width", GOOD_YAML.replace("image_width: 640", "image_width: 640.7"), {}, "image_width must be a whole number"),
    ("zero height", GOOD_YAML.replace("image_height: 480", "image_height: 0"), {}, "two positive whole numbers"),
    ("no size, none given", GOOD_YAML.replace("image_width: 640\nimage_height: 480\n", ""), {}, "pass image_size=(width, height)"),
    ("only the width", GOOD_YAML.replace("image_height: 480\n", ""), {}, "no image_width/image_height"),
    ("size disagrees with the caller", GOOD_YAML, {"image_size": (1280, 720)}, "the caller says 1280x720; use Camera.scaled()"),
]


@pytest.mark.parametrize("content, kwargs, fragment", [c[1:] for c in CAMERA_YAML], ids=[c[0] for c in CAMERA_YAML])
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
    "dtype, channels",
    [(np.uint8, 1), (np.uint8, 3), (np.uint8, 4), (np.uint16, 1), (np.uint16, 3), (np.uint16, 4), (np.float32, 1), (np.float64, 3)],
    ids=["gray8", "bgr8", "bgra8", "gray16", "bgr16", "bgra16", "float32 gray", "float64 bgr"],
)
def test_every_image_type_users_have_is_detected(tmp_path, dtype, channels):
    img, truth = marker_scene(dtype, channels)
    images = [img]
    if dtype != np.float32 and dtype != np.float64:  # PNG holds 8 and 16 bits, gray, BGR and BGRA
        path = tmp_path / "scene.png"
        assert cv2.imwrite(str(path), img)
        loaded = load_image(path)
        assert loaded.dtype == dtype and loaded.shape == img.shape
        images.append(loaded)
    for image in images:
        found = detect_markers(image, "ARUCO_ORIGINAL")
        assert [d.id for d in found] == [7]
        np.testing.assert_allclose(found[0].corners, truth, atol=0.5)


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
    ("png header only", lambda p: p.write_bytes(write_png(p)[:40]), "is it truncated"),
    ("png cut in half", lambda p: p.write_bytes(write_png(p)[: len(write_png(p)) // 2]), "is it truncated"),
    ("png without its end", lambda p: p.write_bytes(write_png(p)[:-12]), "is it truncated"),
    ("jpeg cut in half", lambda p: p.write_bytes(write_jpeg(p)[: len(write_jpeg(p)) // 3]), "is it truncated"),
]


@pytest.mark.parametrize("make, fragment", [c[1:] for c in IMAGE_FILES], ids=[c[0] for c in IMAGE_FILES])
def test_bad_image_file(tmp_path, make, fragment):
    path = tmp_path / "photo.png"
    make(path)
    with pytest.raises(ImageError) as info:
        load_image(path)
    assert fragment in str(info.value)
    assert str(path) in str(info.value)


def test_image_paths_that_are_not_files(tmp_path):
    with pytest.raises(ImageError, match="no such file; check the image path"):
        load_image(tmp_path / "photo.png")
    with pytest.raises(ImageError, match="is a folder, expected an image file"):
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
    ("a nested list", [[0] * 64] * 64, "expected a numpy array (use fidlearn.detection.load_image for a file), got list"),
    ("a path instead of pixels", "photo.png", "got str"),
    ("None", None, "got NoneType"),
]


@pytest.mark.parametrize("image, fragment", [c[1:] for c in IMAGE_ARRAYS], ids=[c[0] for c in IMAGE_ARRAYS])
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
    ("unknown detector parameter", {"params": {"adaptiveTreshWinSizeMin": 3}}, FidlearnError, "no field 'adaptiveTreshWinSizeMin'"),
]


@pytest.mark.parametrize("kwargs, error, fragment", [c[1:] for c in DETECT_ARGUMENTS], ids=[c[0] for c in DETECT_ARGUMENTS])
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
    ("no arguments to corners", ["corners"], "the following arguments are required: map, -o/--output"),
    ("no output", ["corners", "map.json"], "required: -o/--output"),
    ("map does not exist", ["corners", "nope.json", "-o", "out.json"], "nope.json: no such file"),
    ("map is a folder", ["corners", "outdir", "-o", "out.json"], "is a folder, expected a world map JSON file"),
    ("map is a photo", ["corners", "photo.png", "-o", "out.json"], "not UTF-8 text"),
    ("map nested too deeply", ["corners", "deep.json", "-o", "out.json"], "nested too deeply"),
    ("bare map without units", ["corners", "bare.json", "--marker-size-mm", "80", "-o", "out.json"], "pass units= (command line: --units)"),
    ("bare map without size", ["corners", "bare.json", "--units", "ft", "-o", "out.json"], "--marker-size-mm"),
    ("unknown units", ["corners", "bare.json", "--units", "parsec", "-o", "out.json"], "invalid choice: 'parsec'"),
    ("size not a number", ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "big", "-o", "out.json"], "invalid float value: 'big'"),
    ("negative size", ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "-80", "-o", "out.json"], "it must be positive"),
    ("nan size", ["corners", "bare.json", "--units", "ft", "--marker-size-mm", "nan", "-o", "out.json"], "it must be positive"),
    ("size disagrees with the file", ["corners", "map.json", "--marker-size-mm", "50", "-o", "out.json"], "drop one of them"),
    ("unknown dictionary", ["corners", "map.json", "--dictionary", "7x7", "-o", "out.json"], "unknown ArUco dictionary '7x7'"),
    ("output folder missing", ["corners", "map.json", "-o", "nodir/out.json"], "the folder nodir does not exist; create it first"),
    ("output is a folder", ["corners", "map.json", "-o", "outdir"], "outdir: is a folder"),
    ("unknown option", ["corners", "map.json", "-o", "out.json", "--bogus"], "unrecognized arguments: --bogus"),
    ("unknown command", ["frobnicate"], "invalid choice: 'frobnicate'"),
]


@pytest.mark.parametrize("argv, fragment", [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_bad_command_line(tmp_path, monkeypatch, capsys, argv, fragment):
    cli_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    status = cli_main(argv)
    out, err = capsys.readouterr()
    assert status == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert fragment in lines[0]
    assert "Traceback" not in out + err
    # No output file, and no temporary file left behind.
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["corners", "map.json", "-o", "outdir"], "is a folder"),
        (["corners", "deep.json", "-o", "out.json"], "nested too deeply"),
        (["corners", "--units", "ft", "-o", "out.json"], "required: map"),
    ],
    ids=["output is a folder", "map nested too deeply", "map missing"],
)
def test_bad_command_line_in_a_real_process(tmp_path, argv, fragment):
    """``python -m fidlearn`` itself: status 2, one ``error:`` line, no traceback, no output file."""
    cli_setup(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    proc = subprocess.run([sys.executable, "-m", "fidlearn", *argv], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and fragment in lines[0], proc.stderr
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_good_command_line_for_comparison(tmp_path, monkeypatch, capsys):
    """The same set-up with a correct command writes the corner file: the failures above are the inputs' fault."""
    cli_setup(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert cli_main(["corners", "bare.json", "--units", "ft", "--marker-size-mm", "80", "-o", "outdir/c.json"]) == 0
    assert json.loads((tmp_path / "outdir" / "c.json").read_text())["0"][0] == [0.0, 0.0, 304.8]
    assert capsys.readouterr().err == ""
