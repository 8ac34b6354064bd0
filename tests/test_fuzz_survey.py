"""The survey's public functions under wrong input: only FidlearnError comes out, quickly.

``fidlearn.survey`` (each argument in turn, each photo, each corner), ``Survey.save`` and
``Survey.position_ellipsoid_contains`` are called from a valid baseline (a synthetic room, five
photos of exact corners) with one item replaced by a wrong type or value (None, text, bytes, NaN,
infinity, -1, 10^40, 1e300, True, an empty, ragged or wrongly shaped list, an object, a dict),
and with sizes past the limits (2,000 photos, a placement at 8e20 mm). Whatever happens, the only
exception allowed out is a FidlearnError; an accepted value gives a finite survey whose map
``MarkerMap.load`` reads back.
"""

from __future__ import annotations

import contextlib
import math
import time
import warnings

import numpy as np
import pytest

import fidlearn
from fidlearn import Detection, FidlearnError, MarkerMap, MarkerPlacement
from fidlearn.errors import ImageError, SurveyError
from fidlearn.survey._inputs import MAX_PHOTOS, MAX_SIGHTINGS
from fidlearn.synthetic import survey_room, survey_walk, tape_measured, visible_markers

CAM = fidlearn.Camera.from_fov(70, (1280, 720), dist=[-0.1, 0.02, 0.001, -0.001, 0.0])
ROOM = survey_room()
POSES = survey_walk(ROOM, CAM, n_photos=5, seed=2)
TAPE = tape_measured(ROOM, sigma_mm=10.0, sigma_deg=0.5, seed=3)
PHOTOS = [[Detection(i, c) for i, c in visible_markers(ROOM, CAM, T).items()] for T in POSES]

BAD = {
    "None": None,
    "text": "abc",
    "empty text": "",
    "bytes": b"\x00\x01",
    "nan": float("nan"),
    "inf": float("inf"),
    "-1": -1,
    "huge int": 10**40,
    "huge float": 1e300,
    "True": True,
    "empty list": [],
    "nested list": [[1, 2], [3]],
    "wrong shape": np.zeros((2, 5)),
    "object": object(),
    "dict": {"a": 1},
}
ARGS = ["images", "marker_map", "camera", "map_sigma_mm", "fixed_ids", "corner_sigma_px", "progress"]
#: A wrong value the survey may accept (running then to the end): None where None means "not given".
ACCEPTED = {
    ("map_sigma_mm", "None"),
    ("fixed_ids", "None"),
    ("corner_sigma_px", "None"),
    ("progress", "None"),
    ("fixed_ids", "empty list"),
}


def run_survey(**changes):
    kw = {"images": PHOTOS, "marker_map": TAPE, "camera": CAM, "map_sigma_mm": 10.0, **changes}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fidlearn.survey(kw.pop("images"), kw.pop("marker_map"), kw.pop("camera"), **kw)


def assert_sound(s, tmp_path) -> None:
    for i, p in s.marker_map.placements.items():
        assert np.all(np.isfinite(p.translation_mm)), i
        assert np.all(np.isfinite(p.rotation_deg)), i
    back = MarkerMap.load(s.save(tmp_path / "s.json"))
    assert back.ids == s.marker_map.ids


@pytest.fixture(scope="module")
def baseline():
    return run_survey()


@pytest.mark.parametrize("arg", ARGS)
@pytest.mark.parametrize("bad", list(BAD))
def test_each_argument_wrong(arg, bad, tmp_path):
    t0 = time.perf_counter()
    try:
        s = run_survey(**{arg: BAD[bad]})
    except FidlearnError as exc:
        assert str(exc)
        assert "\n" not in str(exc)
    else:
        assert (arg, bad) in ACCEPTED, f"{arg}={bad!r} was accepted"
        assert_sound(s, tmp_path)
    assert time.perf_counter() - t0 < 30


@pytest.mark.parametrize("bad", list(BAD))
def test_each_photo_wrong(bad):
    if bad == "empty list":  # a photo in which nothing was detected: left out, with the reason
        s = run_survey(images=[BAD[bad], *PHOTOS[1:]])
        assert s.unused[0][0] == "photo 0"
        assert "shows no marker" in s.unused[0][1]
        return
    with pytest.raises(FidlearnError):
        run_survey(images=[BAD[bad], *PHOTOS[1:]])


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e7])
def test_a_corner_not_a_pixel_is_refused_naming_the_photo(value):
    corners = PHOTOS[2][0].corners_px.copy()
    corners[1, 0] = value
    bad = [Detection(PHOTOS[2][0].id, corners), *PHOTOS[2][1:]]
    with pytest.raises(ImageError, match=rf"images\[2\]: marker {PHOTOS[2][0].id}'s corners"):
        run_survey(images=[*PHOTOS[:2], bad, *PHOTOS[3:]])


@pytest.mark.parametrize("sigma", [1e-300, 1e-5, 0.0, -0.0, 2e5, 1e300, math.nan, -math.inf])
def test_map_sigma_out_of_its_range_names_the_range(sigma):
    with pytest.raises(SurveyError, match=r"from 0.01 to 100000 mm"):
        run_survey(map_sigma_mm=sigma)


@pytest.mark.parametrize("sigma", [1e-300, 1e-4, 101.0, math.inf, math.nan])
def test_corner_sigma_out_of_its_range_names_the_range(sigma):
    with pytest.raises(SurveyError, match=r"from 0.001 to 100"):
        run_survey(corner_sigma_px=sigma)


@pytest.mark.parametrize("fixed", [[math.inf], [math.nan], [1.5], [10**40], ["0"], [True], [None]])
def test_fixed_ids_not_marker_ids(fixed):
    with pytest.raises(SurveyError, match="fixed_ids"):
        run_survey(fixed_ids=fixed)


class Mine(Exception):
    pass


@pytest.mark.parametrize("error", [ZeroDivisionError, Mine, KeyError, TypeError])
def test_a_progress_function_that_raises_stops_the_survey_as_a_survey_error(error):
    def progress(i, _n, _label):
        if i == 3:
            raise error("boom")

    with pytest.raises(SurveyError, match=rf"progress function raised {error.__name__} .* after photo 3 of 5") as info:
        run_survey(progress=progress)
    assert isinstance(info.value.__cause__, error)  # the user's own exception, kept as the cause


def test_progress_is_called_for_every_photo_then_each_stage():
    calls = []
    run_survey(progress=lambda i, n, label: calls.append((i, n, label)))
    assert calls == [(k + 1, 5, f"photo {k}") for k in range(5)] + [(5, 5, "checking the tape"), (5, 5, "adjusting")]


def test_a_progress_function_that_raises_at_a_stage_names_the_stage():
    def progress(_i, _n, label):
        if label == "adjusting":
            raise RuntimeError("stop")

    with pytest.raises(SurveyError, match=r"progress function raised RuntimeError \(stop\) at 'adjusting'"):
        run_survey(progress=progress)


def test_too_many_photos_are_refused_up_front_with_the_limit():
    calls = []
    t0 = time.perf_counter()
    with pytest.raises(SurveyError, match=rf"at most {MAX_PHOTOS} photos, got 2000"):
        run_survey(images=[PHOTOS[k % 5] for k in range(2000)], progress=lambda *a: calls.append(a))
    assert time.perf_counter() - t0 < 2.0
    assert calls == []


def test_too_many_sightings_are_refused_after_reading_before_the_adjustment():
    images = [PHOTOS[k % 5] for k in range(MAX_PHOTOS)]
    sightings = sum(len(ph) for ph in images)
    assert sightings > MAX_SIGHTINGS
    t0 = time.perf_counter()
    with pytest.raises(SurveyError, match=rf"show markers {sightings} times, a survey takes at most {MAX_SIGHTINGS}"):
        run_survey(images=images)
    assert time.perf_counter() - t0 < 5.0


def test_a_placement_no_map_file_holds_is_never_written(baseline, tmp_path):
    far = dict(TAPE.placements)
    far[40] = MarkerPlacement(40, (8e20, 0.0, 0.0), (0.0, 0.0, 0.0))  # a marker no photo shows, far away
    far_map = MarkerMap(far, TAPE.marker_size_mm, dictionary=TAPE.dictionary, units=TAPE.units, source="far.json")
    with pytest.raises(SurveyError, match=r"marker 40's translation \[8e\+20, 0\.0, 0\.0\] \(mm\) is beyond"):
        run_survey(marker_map=far_map)
    import dataclasses

    forged = dataclasses.replace(baseline, marker_map=far_map)
    with pytest.raises(SurveyError, match="marker 40"):
        forged.save(tmp_path / "far.json")
    assert list(tmp_path.iterdir()) == []


def test_the_baseline_is_sound(baseline, tmp_path):
    assert_sound(baseline, tmp_path)
    assert baseline.gross_ids == ()
    assert len(baseline.tape_residual_mm) >= 4
    assert all(baseline.photos_per_marker[i] >= 2 for i in baseline.tape_residual_mm)
    assert max(baseline.tape_residual_mm.values()) < baseline.gross_threshold_mm


@pytest.mark.parametrize("bad", list(BAD))
def test_ellipsoid_and_save_with_wrong_arguments(baseline, bad):
    for call in (
        lambda: baseline.position_ellipsoid_contains(BAD[bad], [0, 0, 0]),
        lambda: baseline.position_ellipsoid_contains(0, BAD[bad]),
        lambda: baseline.position_ellipsoid_contains(0, [0, 0, 0], BAD[bad]),
    ):
        with contextlib.suppress(FidlearnError):
            assert call() in (True, False)
    if bad != "text":  # a file name, written in the working folder
        with pytest.raises(FidlearnError):
            baseline.save(BAD[bad])


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_random_corner_noise_and_tape_errors_give_a_sound_survey_or_an_error(seed, tmp_path):
    rng = np.random.default_rng(seed)
    noise = [1e-3, 0.5, 5.0, 50.0][seed % 4]
    images = [[Detection(d.id, d.corners_px + rng.normal(0, noise, (4, 2))) for d in ph] for ph in PHOTOS]
    tape = tape_measured(ROOM, sigma_mm=float(rng.choice([1.0, 50.0, 3000.0])), sigma_deg=5.0, seed=seed)
    try:
        s = run_survey(images=images, marker_map=tape, map_sigma_mm=float(rng.choice([0.01, 20.0, 1e5])))
    except FidlearnError as exc:
        assert "\n" not in str(exc)
    else:
        assert_sound(s, tmp_path)
