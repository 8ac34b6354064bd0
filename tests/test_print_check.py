"""The print's scale from one photo: rendered markers printed at 98 % and 100 %, with known answers."""

import importlib
import json
import re

import numpy as np
import pytest

from fidlearn import Camera, MarkerMap
from fidlearn.cli import main
from fidlearn.errors import ImageError, SurveyError
from fidlearn.frames import look_at
from fidlearn.images import write_image
from fidlearn.survey import check_print
from fidlearn.synthetic import render_scene

MARKERS = {str(i): {"translation": [0, 250 * (i % 4), 1600 - 250 * (i // 4)]} for i in range(8)}
CAM = Camera([[900, 0, 639.5], [0, 900, 359.5], [0, 0, 1]], [-0.05, 0.02, 0, 0, 0], (1280, 720))


def wall(print_scale=1.0, size=80.0):
    """The map as taped (top-left corners where the map says), its markers printed at ``print_scale``."""
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": size * print_scale, "markers": MARKERS})


def views(n, seed=1):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        eye = [rng.uniform(900, 1600), rng.uniform(0, 750), rng.uniform(1000, 1600)]
        yield look_at(eye, [0, 375, 1350], roll_deg=rng.uniform(-10, 10))


def test_a_print_at_98_percent_is_recovered_within_0_2_percent():
    for k, T in enumerate(views(4)):
        image = render_scene(wall(0.98), CAM, T, seed=k, noise_std_gray=2, blur_px=0.6).image
        r = check_print(image, wall(), CAM)
        assert len(r.marker_ids) == 8
        assert abs(r.scale - 0.98) <= 0.002, (k, r)
        assert 0 < r.scale_std < 0.002
        assert abs(r.scale - 0.98) <= 4 * r.scale_std + 3e-4  # the error it reports covers the truth
        assert r.sizes_mm[0] == pytest.approx(80 * r.scale)
        assert r.advice().startswith(f"your markers print at {100 * r.scale:.2f} % +/- {100 * r.scale_std:.2f} %: ")
        assert f"set size_mm to {80 * r.scale:.2f} or reprint at 100 %" in r.advice()


def test_a_print_at_100_percent_needs_nothing():
    T = next(views(1, seed=5))
    r = check_print(render_scene(wall(), CAM, T, seed=3, noise_std_gray=2).image, wall(), CAM)
    assert abs(r.scale - 1.0) <= 0.002
    assert r.advice().endswith("as the map says, nothing to change")


def test_markers_of_their_own_sizes_share_the_print_scale():
    markers = {**MARKERS, "5": {**MARKERS["5"], "size_mm": 120}, "6": {**MARKERS["6"], "size_mm": 120}}
    taped = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": markers})
    printed = MarkerMap.from_dict(
        {
            "units": "mm",
            "marker_size_mm": 80 * 0.98,
            "markers": {k: {**v, **({"size_mm": 120 * 0.98} if "size_mm" in v else {})} for k, v in markers.items()},
        }
    )
    T = next(views(1, seed=7))
    r = check_print(render_scene(printed, CAM, T, seed=4, noise_std_gray=2).image, taped, CAM)
    assert abs(r.scale - 0.98) <= 0.002
    assert r.sizes_mm[5] == pytest.approx(120 * r.scale)


def test_a_marker_taped_elsewhere_is_left_out_and_said_to_be():
    """Marker 2 taped 300 mm from where the map says: the scale comes from the other 7, and says so (it listed all
    8 among the markers it came from). A photo's path reads as its picture; anything else is an ImageError."""
    moved = json.loads(json.dumps(MARKERS))
    moved["2"]["translation"][1] += 300
    taped = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": moved})
    image = render_scene(wall(0.98), CAM, next(views(1, seed=5)), seed=1, noise_std_gray=2, blur_px=0.6).image
    r = check_print(image, taped, CAM)
    assert r.left_out == (2,)
    assert 2 not in r.marker_ids
    assert 2 not in r.sizes_mm
    assert len(r.marker_ids) == 7
    assert abs(r.scale - 0.98) <= 0.002
    with pytest.raises(ImageError, match="check_print.s image"):
        check_print([1, 2, 3], taped, CAM)


def test_too_few_markers_say_what_to_do():
    few = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": {k: MARKERS[k] for k in "012"}})
    image = render_scene(few, CAM, next(views(1))).image
    with pytest.raises(SurveyError, match="shows 3 markers of the map .*needs at least 4: take a photo"):
        check_print(image, few, CAM)


def test_fidlearn_check_print(tmp_path, capsys):
    T = next(views(1, seed=2))
    photo = write_image(tmp_path / "photo.png", render_scene(wall(0.98), CAM, T, seed=9, noise_std_gray=2).image)
    (tmp_path / "map.json").write_text(json.dumps({"units": "mm", "marker_size_mm": 80, "markers": MARKERS}))
    CAM.save(tmp_path / "camera.json")
    argv = ["check-print", str(photo), "--map", str(tmp_path / "map.json"), "--camera", str(tmp_path / "camera.json")]
    assert main(argv) == 0
    out = capsys.readouterr().out.splitlines()
    pct = float(out[0].split("print at ")[1].split(" %")[0])
    assert abs(pct - 98.0) <= 0.2
    assert re.search(r"set size_mm to 78\.\d\d or reprint at 100 %$", out[0])
    assert out[1].startswith("  from 8 markers of")
    few = {"units": "mm", "marker_size_mm": 80, "markers": {k: MARKERS[k] for k in "01"}}
    (tmp_path / "few.json").write_text(json.dumps(few))
    assert main([*argv[:2], "--map", str(tmp_path / "few.json"), *argv[4:]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("error: the photo shows 2 markers of the map")
    assert main([*argv[:2], "--map", str(tmp_path / "map.json")]) == 2
    assert "--camera" in capsys.readouterr().err


def five_taped(moved_mm: float = 300.0, ids: str = "01245") -> MarkerMap:
    """Markers ``ids`` of the wall as taped, marker 2 ``moved_mm`` along Y from where it is."""
    moved = json.loads(json.dumps(MARKERS))
    moved["2"]["translation"][1] += moved_mm
    return MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": {k: moved[k] for k in ids}})


def test_one_marker_of_five_taped_elsewhere_cannot_drag_the_scale():
    """A least-squares similarity over the five would put the print at 134 % +/- 13 %, marker 2 counted."""
    image = render_scene(wall(0.98), CAM, next(views(1, seed=5)), seed=1, noise_std_gray=2, blur_px=0.6).image
    r = check_print(image, five_taped(), CAM)
    assert r.left_out == (2,)
    assert r.marker_ids == (0, 1, 4, 5)
    assert abs(r.scale - 0.98) <= 0.002
    with pytest.raises(SurveyError, match=r"only 3 of the 4 markers .*\['2'\] is not .*needs 4 that agree"):
        check_print(image, five_taped(ids="0124"), CAM)


def test_a_marker_detected_twice_is_not_counted(monkeypatch):
    """A reflection of marker 3, detected before the marker itself, would put the print at 80 % +/- 11 %."""
    module = importlib.import_module("fidlearn.survey._print_check")
    detect = module.detect_markers

    def with_reflection(image, dictionary):
        found = detect(image, dictionary)
        three = next(d for d in found if d.id == 3)
        return [type(three)(3, three.corners_px * 0.7 + 100, three.dictionary), *found]

    monkeypatch.setattr(module, "detect_markers", with_reflection)
    image = render_scene(wall(0.98), CAM, next(views(1, seed=5)), seed=1, noise_std_gray=2, blur_px=0.6).image
    r = check_print(image, wall(), CAM)
    assert r.repeated == (3,)
    assert 3 not in r.marker_ids
    assert r.left_out == ()
    assert abs(r.scale - 0.98) <= 0.002
