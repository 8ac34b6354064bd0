"""``fidlearn survey``: the table, the suspects in words, the outputs, and every user error as exit 2."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from fidlearn import MarkerKey, MarkerMap, data_path
from fidlearn.cli import main

FOLDER = data_path("survey")
CAMERA = FOLDER / "camera.json"
TAPE = FOLDER / "tape_map.json"


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def photos(n=None):
    return sorted(FOLDER.glob("photo_*.jpg"))[:n]


def test_survey_of_the_bundled_photos_names_the_moved_marker(capsys, tmp_path):
    out_path, plot = tmp_path / "surveyed.json", tmp_path / "survey.png"
    code, out, err = run(
        capsys,
        "survey",
        FOLDER,
        "--camera",
        CAMERA,
        "--map",
        TAPE,
        "--map-sigma-mm",
        20,
        "-o",
        out_path,
        "--plot",
        plot,
    )
    assert code == 0, err
    assert "marker 7 is" in out
    assert "mm from where the map says" in out
    assert "measure it again" in out
    assert out.count("SUSPECT") == 1
    assert "tape sigma 20 mm" in out  # --map-sigma-mm overrides the learning
    assert "tape sigma learnt" not in out
    row = next(line for line in out.splitlines() if line.split()[:1] == ["7"])
    assert 80 < float(row.split()[-7]) < 140  # the difference column, mm
    d = json.loads(out_path.read_text())
    assert d["units"] == "cm"
    assert d["surveyed"]["suspects"][0]["id"] == 7
    truth = MarkerMap.load(FOLDER / "true_map.json")
    got = MarkerMap.load(out_path)
    moved = np.linalg.norm(np.subtract(got.placements[7].translation_mm, truth.placements[7].translation_mm))
    assert moved < 40  # back where it is (within the map's overall placement from the tape)
    assert cv2.imread(str(plot)).shape[2] == 3


def test_fixed_marker_is_written_exactly(capsys, tmp_path):
    out_path = tmp_path / "s.json"
    code, out, err = run(capsys, "survey", *photos(8), "--camera", CAMERA, "--map", TAPE, "--fixed", 0, "-o", out_path)
    assert code == 0, err
    tape = json.loads(TAPE.read_text())
    assert json.loads(out_path.read_text())["markers"]["0"] == tape["markers"]["0"]
    assert " fixed" in out
    assert "tape sigma learnt from the tape residuals: " in out  # the default
    assert " mm per coordinate" in out
    assert "print scale (photos against the tape): " in out


def test_marker_in_one_photo_gets_a_warning_saying_what_to_take(capsys, tmp_path):
    record = json.loads((FOLDER / "poses.json").read_text())
    seen = {p["image"]: set(p["visible_ids"]) for p in record["photos"]}
    # a marker left out of the map, and photos among which exactly one shows it
    m = 11
    one = next(name for name, ids in seen.items() if m in ids)
    chosen = [one] + [name for name, ids in seen.items() if m not in ids][:7]
    tape = json.loads(TAPE.read_text())
    del tape["markers"][str(m)]
    (tmp_path / "map.json").write_text(json.dumps(tape))
    code, out, err = run(
        capsys,
        "survey",
        *[FOLDER / c for c in chosen],
        "--camera",
        CAMERA,
        "--map",
        tmp_path / "map.json",
        "-o",
        tmp_path / "s.json",
    )
    assert code == 0, err
    assert f"warning: marker {m} is not in the map and is seen in only one photo ({FOLDER / one})" in err
    assert "take another photo that shows marker 11" in err


def _gray_photos(tmp_path, n=2):
    paths = []
    for k in range(n):
        p = tmp_path / f"blank_{k}.png"
        cv2.imwrite(str(p), np.full((720, 1280), 128, np.uint8))
        paths.append(p)
    return paths


@pytest.mark.parametrize(
    ("case", "match"),
    [
        ("one photo", "a survey needs at least 2 photos"),
        ("no marker", r"only 0 of 2 photos give a camera pose.*shows no marker of the map"),
        ("units", r"look wrong; the distances fit units 'cm'"),
        ("sigma", "--map-sigma-mm 0: give a positive number of mm"),
        ("fixed", "--fixed 99: no such marker in the map"),
        ("suffix", r"-o .*s\.txt: name the file \.json"),
        ("clobber", "is one of the inputs"),
    ],
)
def test_user_errors_exit_2_with_one_line_and_write_nothing(capsys, tmp_path, case, match):
    out_path = tmp_path / "s.json"
    args = ["survey", *photos(4), "--camera", CAMERA, "--map", TAPE, "-o", out_path]
    if case == "one photo":
        args[1:5] = photos(1)
    elif case == "no marker":
        args[1:5] = _gray_photos(tmp_path)
    elif case == "units":
        wrong = json.loads(TAPE.read_text())
        wrong["units"] = "mm"  # the numbers are in cm
        (tmp_path / "mm.json").write_text(json.dumps(wrong))
        args[args.index("--map") + 1] = tmp_path / "mm.json"
    elif case == "sigma":
        args += ["--map-sigma-mm", "0"]
    elif case == "fixed":
        args += ["--fixed", "99"]
    elif case == "suffix":
        args[-1] = out_path = tmp_path / "s.txt"
    elif case == "clobber":
        args[-1] = out_path = TAPE
    before = TAPE.read_bytes()
    code, out, err = run(capsys, *args)
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("error: ")
    assert re.search(match, err), err
    assert TAPE.read_bytes() == before
    assert case == "clobber" or not out_path.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_fixed_reads_a_marker_of_another_dictionary_as_the_map_file_writes_it():
    from fidlearn.cli.survey import _fixed_key
    from fidlearn.synthetic import mixed_survey_room

    room = mixed_survey_room()  # ids 0-3 printed from both ARUCO_ORIGINAL (the map's) and 4X4_50
    assert _fixed_key("1", room) == 1
    assert not isinstance(_fixed_key("1", room), MarkerKey)
    assert _fixed_key("4X4_50:1", room) == MarkerKey(1, "4X4_50")
    assert _fixed_key(" DICT_4X4_50:1", room) == MarkerKey(1, "4X4_50")


def test_the_first_line_counts_the_markers_the_photos_surveyed_not_those_in_no_photo(capsys, tmp_path):
    """Three photos show markers 0-8: 9 surveyed, 9-11 in no photo keep the tape's (it said "12 markers surveyed").
    Photo 1 alone shows markers 4-6, and no solver warning of a singular matrix reaches stderr."""
    code, out, err = run(
        capsys, "survey", *photos(3), "--camera", CAMERA, "--map", TAPE, "-o", tmp_path / "surveyed.json"
    )
    assert code == 0, err
    assert f"{tmp_path / 'surveyed.json'}: 9 markers surveyed from 3 photos, 3 in no photo kept the tape's (" in out
    assert "singular" not in err
    assert err == ""
