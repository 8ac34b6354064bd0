"""The exercise machinery: checks, hints, solutions, common mistakes, strict mode, personal variants."""

from __future__ import annotations

import math
import subprocess
import sys

import cv2
import numpy as np
import pytest

import fidlearn
from fidlearn import exercises, frames
from fidlearn.exercises import CORRECT, INCORRECT, NOT_ATTEMPTED

LESSONS = list(exercises.lessons())
QUESTIONS = [(n, q.name) for n in LESSONS for q in exercises.lesson(n, learner="")]


@pytest.fixture(autouse=True)
def _no_env(monkeypatch):
    monkeypatch.delenv("FIDLEARN_STRICT", raising=False)
    monkeypatch.delenv("FIDLEARN_LEARNER", raising=False)


def run_solution(q: exercises.Question) -> None:
    """Run the code that q.solution() shows, in the namespace an exercise notebook has."""
    ns: dict = {}
    exec(exercises.SETUP_CODE, ns)
    ns[q.name] = q
    exec(q.solution_code, ns)


def grade(number: str, name: str, answer, learner: str = "") -> exercises.Result:
    return exercises.lesson(number, learner=learner)[name].grade(answer)


# -- the solution each question shows passes its own check, for several learners --------------
@pytest.mark.parametrize("learner", ["", "alice", "Bob Smith <bob@example.org>"])
@pytest.mark.parametrize("number,name", QUESTIONS)
def test_solution_passes_its_own_check(number, name, learner, capsys):
    q = exercises.lesson(number, learner=learner)[name]
    run_solution(q)
    with exercises.strict():
        q.check()
    assert capsys.readouterr().out.startswith(f"Correct ({name})")


@pytest.mark.parametrize("number,name", QUESTIONS)
def test_blank_answers_are_not_attempted(number, name, capsys):
    q = exercises.lesson(number)[name]
    q.check()
    q.check(None)
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and all(line.startswith(f"Not attempted ({name}): ") for line in out)


@pytest.mark.parametrize("number,name", QUESTIONS)
def test_garbage_answers_are_incorrect_and_never_raise(number, name, capsys):
    q = exercises.lesson(number)[name]
    for junk in ("42", 7, [1, 2], np.zeros((5, 5)), {"x": 1}, object()):
        q.check(junk)
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 6
    assert all(line.startswith(f"Incorrect ({name}): ") for line in out), out


@pytest.mark.parametrize("number,name", QUESTIONS)
def test_hint_and_solution_print_text_and_code(number, name, capsys):
    q = exercises.lesson(number)[name]
    q.hint()
    q.solution()
    out = capsys.readouterr().out
    assert out.startswith(f"Hint ({name}): ") and len(out) > 60
    assert q.solution_code in out and f"{name}.answer" in q.solution_code


# -- common wrong answers are named ---------------------------------------------------------------
def key_of(number: str, name: str, learner: str = ""):
    q = exercises.lesson(number, learner=learner)[name]
    run_solution(q)
    return q, q.answer


@pytest.mark.parametrize("learner", ["", "carol"])
def test_transposed_K(learner):
    q, K = key_of("01", "q1", learner)
    r = q.grade(np.asarray(K).T)
    assert r.status == INCORRECT and "transposed" in r.message and "last COLUMN" in r.message


@pytest.mark.parametrize("learner", ["", "carol"])
def test_degrees_for_radians_in_tan(learner):
    q = exercises.lesson("01", learner=learner).q1
    w, h = q.inputs.image_size
    f = (w / 2) / np.tan(q.inputs.hfov_deg / 2)  # forgot np.radians
    r = q.grade([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    assert r.status == INCORRECT and "radians" in r.message


def test_half_angle_and_half_width_mistakes():
    q = exercises.lesson("01").q1
    w, h = q.inputs.image_size
    for f, words in (((w / 2) / math.tan(math.radians(q.inputs.hfov_deg)), "HALF the field of view"),
                     (w / math.tan(math.radians(q.inputs.hfov_deg) / 2), "HALF the image width")):
        r = q.grade([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
        assert r.status == INCORRECT and words in r.message


def test_cx_at_half_width_is_correct_with_a_note():
    q = exercises.lesson("01").q1
    w, h = q.inputs.image_size
    f = (w / 2) / math.tan(math.radians(q.inputs.hfov_deg) / 2)
    r = q.grade([[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]])
    assert r.status == CORRECT and "(width - 1) / 2" in r.message


def test_projection_mistakes():
    q, uv = key_of("01", "q2")
    P, K = q.inputs.points_camera_mm, q.inputs.K
    assert "divide by the depth" in q.grade((P @ K.T)[:, :2]).message
    assert "swapped" in q.grade(uv[:, ::-1]).message
    assert "principal point" in q.grade(P[:, :2] * [K[0, 0], K[1, 1]] / P[:, 2:]).message
    assert "drop the third" in q.grade(np.column_stack([uv, np.ones(len(uv))])).message
    assert q.grade(cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, None)[0]).status == CORRECT  # (N, 1, 2) accepted


@pytest.mark.parametrize("factor,unit", [(25.4, "inches"), (304.8, "feet"), (1000, "metres")])
def test_distance_in_the_wrong_unit(factor, unit):
    q, d = key_of("01", "q3")
    r = q.grade(d / factor)
    assert r.status == INCORRECT and unit in r.message and "mm" in r.message


def test_fov_in_radians():
    q, fov = key_of("01", "q4")
    r = q.grade(np.radians(fov))
    assert r.status == INCORRECT and "radians" in r.message and "degrees" in r.message


def test_rpy_degrees_fed_to_radian_functions_and_wrong_order():
    q, T = key_of("03", "q1")
    roll, pitch, yaw = q.inputs.rpy_deg
    R_deg = frames.rot_z(yaw) @ frames.rot_y(pitch) @ frames.rot_x(roll)
    r = q.grade(frames.make_transform(R_deg, q.inputs.position_mm))
    assert r.status == INCORRECT and "np.radians" in r.message
    r, p, y = np.radians(q.inputs.rpy_deg)
    res = q.grade(frames.make_transform(frames.rot_x(r) @ frames.rot_y(p) @ frames.rot_z(y), q.inputs.position_mm))
    assert res.status == INCORRECT and "Rz(yaw) @ Ry(pitch) @ Rx(roll)" in res.message
    assert "T_robot_world" in q.grade(frames.invert_transform(T)).message


def test_forgot_to_invert_the_camera_pose():
    q, _ = key_of("03", "q2")
    wrong = frames.transform_points(q.inputs.T_world_camera, q.inputs.points_world_mm)
    r = q.grade(wrong)
    assert r.status == INCORRECT and "invert_transform" in r.message


@pytest.mark.parametrize("number,name", [("03", "q3"), ("07", "q2")])
def test_extrinsic_matrix_where_the_camera_pose_is_asked(number, name):
    q, T_world_camera = key_of(number, name)
    r = q.grade(frames.invert_transform(T_world_camera))
    assert r.status == INCORRECT and "extrinsic matrix T_camera_world" in r.message
    assert "T_world_camera = frames.invert_transform(T_camera_world)" in r.message


def test_names_that_do_not_chain():
    q, _ = key_of("03", "q3")
    r = q.grade(q.inputs.T_world_marker @ q.inputs.T_camera_marker)
    assert r.status == INCORRECT and "do not chain" in r.message


def test_rvec_versus_rotation_matrix():
    q, T = key_of("03", "q4")
    rvec = q.inputs.rvec
    r = q.grade(frames.make_transform(frames.rot_z(rvec[2]) @ frames.rot_y(rvec[1]) @ frames.rot_x(rvec[0]), q.inputs.tvec))
    assert r.status == INCORRECT and "Rodrigues" in r.message and "not roll, pitch, yaw" in r.message
    r = q.grade(rvec)  # the bare rvec where a 4x4 matrix is asked
    assert r.status == INCORRECT and "cv2.Rodrigues(rvec)" in r.message
    r = q.grade(T[:3, :3])
    assert r.status == INCORRECT and "4x4" in r.message
    assert "inverted" in q.grade(frames.invert_transform(T)).message


def test_feet_for_mm_in_a_placement():
    q, C = key_of("04", "q1")
    r = q.grade(C / 304.8)
    assert r.status == INCORRECT and "feet" in r.message and "304.8" in r.message
    p = q.inputs.placement
    R = frames.rotation_from_rpy_deg(*p["rotation"])
    s = q.inputs.marker_size_mm
    unconverted = np.asarray(p["translation"]) + s * np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]]) @ R.T
    assert "304.8" in q.grade(unconverted).message


@pytest.mark.parametrize("order", [(0, 3, 2, 1), (1, 2, 3, 0), (3, 2, 1, 0), (0, 1, 3, 2)])
def test_wrong_winding_order_is_named(order):
    q, C = key_of("04", "q1")
    names = ("TL", "TR", "BR", "BL")
    r = q.grade(np.asarray(C)[list(order)])
    assert r.status == INCORRECT
    assert r.message.startswith(f"your corners are in the order {', '.join(names[i] for i in order)}: detection reports TL, TR, BR, BL")


def test_map_in_cm_declared_as_mm():
    q, d = key_of("04", "q2")
    d = dict(d, units="mm")
    r = q.grade(d)
    assert r.status == INCORRECT and "\"cm\"" in r.message
    no_units = {k: v for k, v in d.items() if k != "units"}
    r = q.grade(no_units)
    assert r.status == INCORRECT and "no units" in r.message


def test_map_marker_facing_the_wall():
    q, d = key_of("04", "q2")
    first = next(iter(d["markers"]))
    bad = dict(d, markers=dict(d["markers"]))
    bad["markers"][first] = dict(bad["markers"][first], rotation=[0, 0, 180 + bad["markers"][first]["rotation"][2]])
    r = q.grade(bad)
    assert r.status == INCORRECT and f"marker {first}" in r.message and "into the room" in r.message


def test_floor_marker_radians_and_upside_down():
    q, rpy = key_of("04", "q3")
    assert "radians" in q.grade(np.radians(rpy)).message
    R = frames.rotation_from_rpy_deg(*rpy)
    flipped = R @ np.diag([1.0, -1.0, -1.0])  # turned 180 degrees about the normal
    assert "upside down" in q.grade(frames.rpy_deg_from_rotation(flipped)).message
    facing_down = R @ np.diag([-1.0, -1.0, 1.0])
    assert "DOWN" in q.grade(frames.rpy_deg_from_rotation(facing_down)).message


def test_normal_into_the_wall():
    q, ans = key_of("04", "q4")
    r = q.grade({"center_mm": ans["center_mm"], "normal": -np.asarray(ans["normal"])})
    assert r.status == INCORRECT and "INTO the wall" in r.message


def test_camera_position_mistakes():
    q, pos = key_of("07", "q1")
    assert "-R^T @ tvec" in q.grade(q.inputs.tvec).message
    assert "feet" in q.grade(np.asarray(pos) / 304.8).message
    R, _ = cv2.Rodrigues(q.inputs.rvec)
    assert "transpose" in q.grade(-R @ q.inputs.tvec).message


def test_heading_from_a_row_instead_of_a_column():
    q, ans = key_of("07", "q3")
    R, _ = cv2.Rodrigues(q.inputs.rvec)
    d = R[:, 2]
    r = q.grade((np.degrees(np.arctan2(d[1], d[0])), np.degrees(np.arcsin(-d[2]))))
    assert r.status == INCORRECT and "third ROW of R" in r.message
    assert "radians" in q.grade(np.radians(ans)).message


# -- strict mode ----------------------------------------------------------------------------------
def test_strict_mode_raises_on_incorrect_and_not_attempted(capsys):
    q, K = key_of("01", "q1")
    with exercises.strict():
        with pytest.raises(AssertionError, match=r"Incorrect \(q1\): your K is transposed"):
            q.check(np.asarray(K).T)
        with pytest.raises(AssertionError, match=r"Not attempted \(q1\)"):
            q.check(...)
        q.check(K)
    q.check(np.asarray(K).T)  # strict mode is over: prints, does not raise
    assert capsys.readouterr().out.splitlines()[-1].startswith("Incorrect (q1)")


def test_strict_blank_mode_demands_not_attempted():
    q, K = key_of("01", "q1")
    with exercises.strict("blank"):
        with pytest.raises(AssertionError, match="expected a blank answer"):
            q.check(K)
        q.check(...)


def test_strict_mode_from_the_environment(monkeypatch):
    q, K = key_of("01", "q1")
    monkeypatch.setenv("FIDLEARN_STRICT", "1")
    with pytest.raises(AssertionError):
        q.check(np.asarray(K).T)
    monkeypatch.setenv("FIDLEARN_STRICT", "blank")
    q.check(None)
    with exercises.strict(False):
        q.check(np.asarray(K).T)


def test_unknown_strict_mode_is_refused():
    with pytest.raises(ValueError, match="'correct'"):
        exercises.strict("sometimes")


# -- personal variants -----------------------------------------------------------------------------
def _inputs_equal(a, b) -> bool:
    for k in a.keys():
        va, vb = a[k], b[k]
        if isinstance(va, (np.ndarray, list, tuple, float, int)) and not isinstance(va, bool):
            try:
                if not np.array_equal(np.asarray(va, dtype=float), np.asarray(vb, dtype=float)):
                    return False
            except (TypeError, ValueError):
                if repr(va) != repr(vb):
                    return False
        elif repr(va) != repr(vb):
            return False
    return True


@pytest.mark.parametrize("number", LESSONS)
def test_two_learners_get_different_data_and_are_each_checked(number):
    alice = exercises.lesson(number, learner="alice")
    bob = exercises.lesson(number, learner="bob")
    differ = [qa.name for qa, qb in zip(alice, bob) if not _inputs_equal(qa.inputs, qb.inputs)]
    assert len(differ) >= len(alice) - 1, f"only {differ} differ between alice and bob"
    for qa, qb in zip(alice, bob):
        run_solution(qa)
        run_solution(qb)
        assert qa.grade().correct and qb.grade().correct
        if qa.name in differ and not isinstance(qa.answer, dict):
            assert qb.grade(qa.answer).status == INCORRECT, f"{number} {qa.name}: alice's answer passes bob's check"


def test_the_variant_does_not_depend_on_the_python_hash_seed():
    code = "from fidlearn import exercises; q = exercises.lesson('01', learner='alice').q1; print(q.inputs.hfov_deg, q.inputs.image_size)"
    outs = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={"PYTHONHASHSEED": seed, "PATH": ""}).stdout for seed in ("1", "2")}
    here = exercises.lesson("01", learner="alice").q1
    assert outs == {f"{here.inputs.hfov_deg} {here.inputs.image_size}\n"}


def test_learner_from_the_environment(monkeypatch):
    monkeypatch.setenv("FIDLEARN_LEARNER", "dora")
    ex = exercises.lesson(1)
    assert ex.learner == "dora"
    assert _inputs_equal(ex.q2.inputs, exercises.lesson("01", learner="dora").q2.inputs)


def test_unknown_lesson():
    with pytest.raises(KeyError, match="available: 01"):
        exercises.lesson("42")


def test_summary_counts(capsys):
    ex = exercises.lesson("07")
    run_solution(ex.q1)
    ex.summary()
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"Lesson 07: 1 of {len(ex)} correct"
    assert out[1].startswith("  q1 [Correct]") and out[2].startswith("  q2 [Not attempted]")


def test_exercises_is_importable_from_fidlearn():
    assert fidlearn.exercises is exercises
