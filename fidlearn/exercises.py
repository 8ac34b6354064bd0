"""Classroom exercises with automatic feedback: ``q1.check()``, ``q1.hint()``, ``q1.solution()``.

Each lesson (``"01"`` to ``"09"``) holds questions built from seeded synthetic
data. A question shows its inputs in ``q.inputs``; the learner writes code that
computes the answer from them, assigns ``q.answer = ...`` (or calls
``q.check(value)``) and runs ``q.check()``, which prints one line:

* ``Correct (q1): ...``
* ``Incorrect (q1): what is wrong, and a nudge`` (common mistakes such as a
  transposed K, degrees for radians, the wrong winding order, the extrinsic
  matrix where the camera pose is asked, or feet for mm are recognised and
  named);
* ``Not attempted (q1): ...`` while the answer is still ``...`` or ``None``.

``check()`` never raises in a learner's notebook. Tests and graders switch on
strict mode (``FIDLEARN_STRICT=1`` or ``with exercises.strict():``), in which
every check that is not ``Correct`` raises :class:`AssertionError`;
``strict("blank")`` (``FIDLEARN_STRICT=blank``) instead demands ``Not
attempted`` everywhere, which is how the student copies are tested.

A learner's id seeds a personal variant: ``exercises.lesson("03",
learner="alice")`` gives Alice her own numbers, and the answer key checks
them. The id is hashed with SHA-256, so the variant is the same on every
machine and every Python run. Without an id (``learner=""``) the id comes from
the environment variable ``FIDLEARN_LEARNER``, else the whole class shares one
variant.

Grading: :func:`grade_notebook` (or ``python -m fidlearn.exercises grade
NOTEBOOK... --learner ID --csv FILE``) runs a learner's notebook in a fresh
kernel and checks the answers its lesson holds. The answer-key notebooks are
built from the lesson definitions here (:func:`answer_key_notebook`) and the
student copies from the keys (:func:`student_copy`), by
``tools/make_student_copies.py``; see ``docs/teaching.md``.

Examples
--------
>>> ex = lesson("01", learner="alice")
>>> q1 = ex.q1
>>> q1.check()  # doctest: +ELLIPSIS
Not attempted (q1): ...
>>> w, h = q1.inputs.image_size
>>> f = (w / 2) / math.tan(math.radians(q1.inputs.hfov_deg) / 2)
>>> q1.check([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])  # doctest: +ELLIPSIS
Correct (q1): ...
"""

from __future__ import annotations

import contextvars
import copy
import functools
import hashlib
import json
import math
import os
import re
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from . import _cv, frames
from .camera import Camera
from .detection import Detection
from .markermap import MarkerMap, MarkerPlacement

__all__ = [
    "CORRECT",
    "INCORRECT",
    "NOT_ATTEMPTED",
    "SETUP_CODE",
    "Lesson",
    "Question",
    "Result",
    "lesson",
    "lessons",
    "strict",
    "answer_key_notebook",
    "student_copy",
    "solution_blocks",
    "grade_notebook",
    "Grade",
]

CORRECT = "Correct"
INCORRECT = "Incorrect"
NOT_ATTEMPTED = "Not attempted"
#: Graded mode (fidlearn.grading): an answer of the right form, kept for the instructor's grader.
RECORDED = "Recorded"
_NO_KEY = object()  # a graded question's answer key: never in the learner's kernel

#: The imports every exercise notebook starts with; solution code may use these names.
SETUP_CODE = "import math\nimport numpy as np\nimport cv2\nimport fidlearn\nfrom fidlearn import exercises, frames"

BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"

_MISSING = object()


# ----------------------------------------------------------------------------------
# strict mode
# ----------------------------------------------------------------------------------
_STRICT_WORDS = {
    "": None,
    "0": None,
    "false": None,
    "off": None,
    "no": None,
    "1": "correct",
    "true": "correct",
    "on": "correct",
    "yes": "correct",
    "correct": "correct",
    "blank": "blank",
    "not attempted": "blank",
    "not-attempted": "blank",
    "not_attempted": "blank",
}
_strict_override: list = []  # a stack: the innermost strict() wins


def _parse_strict(value: Any) -> str | None:
    if value is True:
        return "correct"
    if value is False or value is None:
        return None
    key = str(value).strip().lower()
    if key not in _STRICT_WORDS:
        raise ValueError(
            f"strict mode {value!r} is unknown; use True or 'correct' (every check must be Correct), "
            "'blank' (every check must be Not attempted) or False"
        )
    return _STRICT_WORDS[key]


def _strict_mode() -> str | None:
    if _strict_override:
        return _strict_override[-1]
    try:
        return _parse_strict(os.environ.get("FIDLEARN_STRICT", ""))
    except ValueError:
        return "correct"


class strict:
    """Strict mode for tests and graders: a check that is not as expected raises AssertionError.

    ``strict()`` or ``strict(True)`` demands ``Correct``; ``strict("blank")``
    demands ``Not attempted`` (an untouched student copy); ``strict(False)``
    switches strict mode off. Use it as a context manager, or call it once
    (then it stays on until :meth:`restore`). Without either, the environment
    variable ``FIDLEARN_STRICT`` (``1`` or ``blank``) decides.
    """

    def __init__(self, mode: Any = True):
        self.mode = _parse_strict(mode)
        _strict_override.append(self.mode)
        self._active = True

    def restore(self) -> None:
        """Undo this strict() call."""
        if self._active:
            for i in range(len(_strict_override) - 1, -1, -1):  # the latest push of this mode
                if _strict_override[i] == self.mode:
                    del _strict_override[i]
                    break
            self._active = False

    def __enter__(self) -> strict:
        return self

    def __exit__(self, *exc) -> None:
        self.restore()


# ----------------------------------------------------------------------------------
# results, inputs, questions
# ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Result:
    """The outcome of one check: ``status`` is ``Correct``, ``Incorrect`` or ``Not attempted``."""

    question: str
    status: str
    message: str

    @property
    def correct(self) -> bool:
        return self.status == CORRECT

    @property
    def line(self) -> str:
        """The one line that :meth:`Question.check` prints."""
        return (
            f"{self.status} ({self.question}): {self.message}" if self.message else f"{self.status} ({self.question})"
        )

    def __str__(self) -> str:
        return self.line


class _AnswerError(Exception):
    """The learner's answer cannot be read as the kind of value asked for (the message says why)."""


def _short(value: Any) -> str:
    """A readable one-or-few-line view of an input (big arrays by shape only)."""
    if isinstance(value, np.ndarray):
        if value.size > 24:
            return f"array of shape {value.shape}, dtype {value.dtype}"
        return np.array2string(np.round(value, 4), separator=", ", suppress_small=True).replace("\n", "\n    ")
    if isinstance(value, dict) and value and all(isinstance(v, str) and len(v) > 30 for v in value.values()):
        return "{\n" + "\n".join(f"      {k!r}: {v!r}," for k, v in value.items()) + "\n  }"
    if isinstance(value, list) and value and all(isinstance(v, np.ndarray) for v in value) and value[0].size > 24:
        shapes = {v.shape for v in value}
        return (
            f"list of {len(value)} arrays of shape {value[0].shape}"
            if len(shapes) == 1
            else f"list of {len(value)} arrays"
        )
    if (
        isinstance(value, list)
        and 1 < len(value) <= 8
        and all(isinstance(v, (Detection, np.ndarray, dict)) for v in value)
    ):
        return (
            "[\n" + "\n".join(f"      {_short(v) if isinstance(v, np.ndarray) else repr(v)}," for v in value) + "\n  ]"
        )
    if isinstance(value, (list, tuple)) and len(value) > 8 and not isinstance(value[0], (int, float, str)):
        return f"{type(value).__name__} of {len(value)} items, first: {value[0]!r}"
    if isinstance(value, float):
        return f"{value:g}"
    return repr(value)


class Inputs:
    """A question's inputs: read them as attributes (``q.inputs.K``) or keys (``q.inputs["K"]``)."""

    def __init__(self, **values: Any):
        self.__dict__.update(values)

    def __getitem__(self, key: str) -> Any:
        return self.__dict__[key]

    def __iter__(self):
        return iter(self.__dict__)

    def keys(self):
        return self.__dict__.keys()

    def __repr__(self) -> str:
        lines = [f"  {k} = {_short(v)}" for k, v in self.__dict__.items()]
        return "Inputs(\n" + "\n".join(lines) + "\n)"


Detector = Callable[[Any], bool]


class Question:
    """One exercise question: inputs, a hidden answer key, and feedback.

    Attributes
    ----------
    name : str
        ``"q1"``, ``"q2"``...: the variable name the notebook gives it.
    title, task : str
        What to compute, in words (units and frames included).
    inputs : Inputs
        The data to compute from (arrays in mm, pixels, degrees as named).
    answer : object
        The learner's answer; ``...`` or ``None`` means not attempted.
    """

    def __init__(
        self,
        name: str,
        title: str,
        task: str,
        inputs: dict,
        expected: Any,
        parse: Callable[[Any], Any],
        compare: Callable[[Any, Any], str | None],
        wrong: Sequence[tuple[Detector, Any]] = (),
        notes: Sequence[tuple[Detector, Any]] = (),
        hint: str = "",
        solution: str = "",
        level: str = "",
        look: str = "",
    ):
        self.name = name
        self.title = title
        self.task = textwrap.dedent(task).strip()
        self.inputs = Inputs(**inputs)
        self.data = self.inputs
        self._expected = expected
        self._parse = parse
        self._compare = compare
        self._wrong = list(wrong)
        self._notes = list(notes)
        self._hint = textwrap.dedent(hint).strip()
        self.solution_code = textwrap.dedent(solution).strip()
        self.level = level
        #: Code that shows the inputs as a picture in the notebook ("" for none).
        self.look_code = textwrap.dedent(look).strip()
        self.answer: Any = ...

    # -- grading ------------------------------------------------------------------
    def grade(self, answer: Any = _MISSING) -> Result:
        """Judge an answer (default: ``self.answer``) and return a :class:`Result`; prints nothing.

        A learner's answer that cannot be read gives ``Incorrect`` with the
        reason; an error in the grading code itself raises.
        """
        if answer is _MISSING:
            answer = self.answer
        if answer is None or answer is Ellipsis:
            return Result(
                self.name,
                NOT_ATTEMPTED,
                f"replace the ... in {self.name}.answer = ... with code that computes the answer, then run {self.name}.check()",
            )
        try:
            value = self._parse(answer)
        except _AnswerError as exc:
            return Result(self.name, INCORRECT, str(exc))
        if self._expected is _NO_KEY:
            return Result(self.name, RECORDED, "the answer has the right form; your instructor's grader judges it")
        diff = self._compare(value, self._expected)
        if diff is None:
            msg = "well done"
            for detect, note in self._notes:
                if _safe(detect, value):
                    msg = note(value) if callable(note) else note
                    break
            return Result(self.name, CORRECT, msg)
        for detect, message in self._wrong:
            if _safe(detect, value):
                return Result(self.name, INCORRECT, message(value) if callable(message) else message)
        return Result(self.name, INCORRECT, f"{diff}; {self.name}.hint() gives a nudge")

    def check(self, answer: Any = _MISSING) -> None:
        """Print one line: ``Correct``, ``Incorrect`` (what is wrong, and a nudge) or ``Not attempted``.

        ``check(value)`` first sets ``answer = value``. Outside strict mode it
        never raises; in strict mode (see :class:`strict`) an unexpected
        status raises :class:`AssertionError`.
        """
        if answer is not _MISSING:
            self.answer = answer
        mode = _strict_mode()
        try:
            result = self.grade()
        except Exception as exc:  # a bug in the grader must not break a lesson
            if mode:
                raise
            result = Result(
                self.name,
                INCORRECT,
                f"your answer could not be checked ({type(exc).__name__}: {exc}); check its type and shape",
            )
        print(result.line)
        if mode == "correct" and result.status not in (CORRECT, RECORDED):
            raise AssertionError(result.line)
        if mode == "blank" and result.status != NOT_ATTEMPTED:
            raise AssertionError(f"expected a blank answer, got: {result.line}")

    def hint(self) -> None:
        """Print a hint."""
        print(f"Hint ({self.name}): {self._hint}")

    def solution(self) -> None:
        """Print one way to solve it: code that, run in the notebook, makes ``check()`` say Correct."""
        if self._expected is _NO_KEY:
            print(f"Solution ({self.name}): not while the lesson is graded; q.hint() still helps")
            return
        print(f"Solution ({self.name}), one way to do it:\n")
        print(self.solution_code)

    def show(self) -> None:
        """Print the task and the inputs."""
        print(f"{self.name}. {self.title}\n\n{self.task}\n\n{self.name}.inputs = {self.inputs!r}")

    def _fresh(self) -> Question:
        """A copy with its own inputs (a learner may change them) and no answer yet."""
        new = copy.copy(self)
        new.inputs = copy.deepcopy(self.inputs)
        new.data = new.inputs
        new.answer = ...
        return new

    def __repr__(self) -> str:
        status = self.grade().status if self.answer is not ... else NOT_ATTEMPTED
        names = ", ".join(self.inputs.keys())
        return f"<Question {self.name}: {self.title!r}; inputs: {names}; {status}>"


def _safe(detect: Detector, value: Any) -> bool:
    try:
        return bool(detect(value))
    except Exception:
        return False


# ----------------------------------------------------------------------------------
# answer readers and comparisons
# ----------------------------------------------------------------------------------
def _array(shape: tuple, what: str, shape_hints: dict | None = None) -> Callable[[Any], np.ndarray]:
    """A parser: the answer as a float array of ``shape`` (a -1 matches any length)."""

    def parse(answer: Any) -> np.ndarray:
        if isinstance(answer, Camera):
            answer = answer.K
        if isinstance(answer, (str, bytes, dict)):
            raise _AnswerError(
                f"your answer ({what}) should be numbers in an array of shape {_shape_text(shape)}, got a {type(answer).__name__}"
            )
        try:
            a = np.array(answer, dtype=float)
        except (TypeError, ValueError):
            raise _AnswerError(
                f"your answer ({what}) should be numbers in an array of shape {_shape_text(shape)}, got {type(answer).__name__}"
            ) from None
        if not _shape_ok(a.shape, shape):
            sq = a.squeeze()
            if _shape_ok(sq.shape, tuple(s for s in shape if s != 1)) and a.size == sq.size:
                a = sq.reshape(
                    tuple(sq.shape[i] if s == -1 else s for i, s in enumerate(shape)) if -1 in shape else shape
                )
            else:
                extra = (shape_hints or {}).get(a.shape, "")
                raise _AnswerError(
                    f"your answer ({what}) has shape {a.shape}, expected {_shape_text(shape)}"
                    + (f": {extra}" if extra else "")
                )
        if not np.all(np.isfinite(a)):
            raise _AnswerError(
                f"your answer ({what}) contains NaN or infinity; leave out (or fill in) what could not be computed"
            )
        return a

    return parse


def _shape_ok(got: tuple, want: tuple) -> bool:
    return len(got) == len(want) and all(w == -1 or g == w for g, w in zip(got, want))


def _shape_text(shape: tuple) -> str:
    return "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ")"


def _scalar(what: str) -> Callable[[Any], float]:
    def parse(answer: Any) -> float:
        if isinstance(answer, (str, bytes)):
            raise _AnswerError(f"your answer ({what}) should be a number, got the text {answer!r}")
        a = (
            np.asarray(answer, dtype=float)
            if not isinstance(answer, (dict, list, tuple)) or np.size(answer) == 1
            else None
        )
        if a is None or a.size != 1:
            raise _AnswerError(
                f"your answer ({what}) should be one number, got {type(answer).__name__} of {np.size(answer)} values"
            )
        v = float(a.reshape(-1)[0])
        if math.isnan(v):
            raise _AnswerError(
                f"your answer ({what}) is NaN: a NaN in the data spreads through every sum and mean; leave those values out (np.isnan finds them)"
            )
        if not math.isfinite(v):
            raise _AnswerError(f"your answer ({what}) is {v}, expected a finite number")
        return v

    return parse


def _parts(**parsers: Callable[[Any], Any]) -> Callable[[Any], dict]:
    """A parser for a dict answer with named parts (a tuple in the same order is accepted too)."""
    names = list(parsers)

    def parse(answer: Any) -> dict:
        if isinstance(answer, dict):
            missing = [n for n in names if n not in answer]
            if missing:
                raise _AnswerError(f"the answer needs the keys {names}; missing {missing}")
            return {n: parsers[n](answer[n]) for n in names}
        if isinstance(answer, (tuple, list)) and len(answer) == len(names):
            return {n: parsers[n](v) for n, v in zip(names, answer)}
        raise _AnswerError(f"give a dict with keys {names} (or a tuple of {len(names)} values in that order)")

    return parse


def _close(a: Any, b: Any, atol: float = 0.0, rtol: float = 0.0) -> bool:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= atol + rtol * np.abs(b)))


def _cmp_array(atol: float, unit: str = "", rtol: float = 0.0) -> Callable[[np.ndarray, np.ndarray], str | None]:
    def compare(a: np.ndarray, b: np.ndarray) -> str | None:
        if a.shape != b.shape:
            return f"your answer has shape {a.shape}, expected {b.shape}"
        err = np.abs(a - b) - (atol + rtol * np.abs(b))
        if np.all(err <= 0):
            return None
        i = np.unravel_index(int(np.argmax(err)), err.shape)
        where = f" at index {list(map(int, i))}" if a.ndim else ""
        return f"your answer differs from the key by {abs(a[i] - b[i]):.4g}{unit}{where} (tolerance {atol + rtol * abs(b[i]):.3g}{unit})"

    return compare


def _cmp_scalar(atol: float, unit: str = "", rtol: float = 0.0) -> Callable[[float, float], str | None]:
    def compare(a: float, b: float) -> str | None:
        if abs(a - b) <= atol + rtol * abs(b):
            return None
        ratio = f", {a / b:.3g} times the key" if b and a else ""
        return f"your value {a:.6g}{unit} is off by {a - b:+.4g}{unit}{ratio}"

    return compare


def _cmp_transform(rot_tol_deg: float, trans_tol_mm: float) -> Callable[[np.ndarray, np.ndarray], str | None]:
    def compare(a: np.ndarray, b: np.ndarray) -> str | None:
        if np.abs(a[3] - [0, 0, 0, 1]).max() > 1e-6:
            return f"the bottom row is {np.round(a[3], 4).tolist()}, a homogeneous transform ends with [0, 0, 0, 1]"
        R = a[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-3 or np.linalg.det(R) < 0:
            return "the top-left 3x3 block is not a rotation matrix (its columns must be orthonormal, determinant +1)"
        ang = frames.rotation_angle_deg(R, b[:3, :3])
        dt = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
        if ang <= rot_tol_deg and dt <= trans_tol_mm:
            return None
        return f"your rotation is {ang:.3g} deg from the key's and your translation {dt:.4g} mm from it"

    return compare


def _corner_order(answer: np.ndarray, expected: np.ndarray, atol: float) -> tuple[str, ...] | None:
    """The corner names in the order the answer lists them, if it is a permutation of the expected corners."""
    if answer.shape != expected.shape or answer.shape[0] != 4:
        return None
    names = ("TL", "TR", "BR", "BL")
    order = []
    for row in answer:
        hits = [i for i in range(4) if np.abs(row - expected[i]).max() <= atol]
        if len(hits) != 1:
            return None
        order.append(names[hits[0]])
    if len(set(order)) != 4:
        return None
    return tuple(order)


def _winding_message(order: tuple[str, ...], what: str = "detection reports") -> str:
    return (
        f"your corners are in the order {', '.join(order)}: {what} TL, TR, BR, BL "
        "(clockwise as seen from the front, starting at the marker's own top-left)"
    )


# ----------------------------------------------------------------------------------
# seeded data
# ----------------------------------------------------------------------------------
#: The seed of graded variants while :func:`build_questions` builds them (see fidlearn.grading).
_SEED: contextvars.ContextVar = contextvars.ContextVar("fidlearn_exercise_seed", default=None)


def _rng(lesson_id: str, learner: str, question: str) -> np.random.Generator:
    """A generator seeded from SHA-256 of the lesson, the learner's id and the question.

    While :func:`build_questions` runs with a ``seed`` function (graded mode), that function
    seeds it instead: HMAC of the class secret, which nobody without the secret can repeat.
    """
    seed_fn = _SEED.get()
    if seed_fn is not None:
        return np.random.default_rng(seed_fn(question))
    digest = hashlib.sha256(f"fidlearn-exercises/{lesson_id}/{learner}/{question}".encode()).digest()
    return np.random.default_rng(int.from_bytes(digest[:8], "little"))


def _look_at(position_mm: Sequence[float], target_mm: Sequence[float], up: Sequence[float] = (0, 0, 1)) -> np.ndarray:
    """``T_world_camera`` (4, 4) of an OpenCV camera at ``position_mm`` looking at ``target_mm`` (x right, y down)."""
    p = np.asarray(position_mm, dtype=float)
    z = np.asarray(target_mm, dtype=float) - p
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, dtype=float))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return frames.make_transform(np.column_stack([x, y, z]), p)


def _round(x: Any, nd: int = 1) -> Any:
    return np.round(np.asarray(x, dtype=float), nd)


_SIZES = [(640, 480), (800, 600), (1280, 720), (1920, 1080)]


# ==================================================================================
# Lesson 01: the pinhole camera and K
# ==================================================================================
def _lesson_01(learner: str) -> list[Question]:
    qs = []

    # q1: K from a field of view -----------------------------------------------------
    rng = _rng("01", learner, "q1")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    hfov = float(np.round(rng.uniform(50, 95) * 2) / 2)
    f = (w / 2) / math.tan(math.radians(hfov) / 2)
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    f_deg_as_rad = (w / 2) / math.tan(hfov / 2)
    f_full = (w / 2) / math.tan(math.radians(hfov))
    f_width = w / math.tan(math.radians(hfov) / 2)
    f_height = (h / 2) / math.tan(math.radians(hfov) / 2)

    def fx_is(value):
        return lambda a: abs(a[0, 0] - value) <= 1e-3 * abs(value) + 0.01

    qs.append(
        Question(
            "q1",
            "K from a field of view",
            """
        A camera with square pixels and its principal point in the middle of the image has a
        horizontal field of view of `hfov_deg` degrees and images of `image_size` = (width, height)
        pixels. Write code that computes its intrinsic matrix K, a (3, 3) array
        `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` in pixels. fidlearn puts pixel centres at integer
        coordinates, so the centre of the image is at ((width - 1) / 2, (height - 1) / 2).
        """,
            {"hfov_deg": hfov, "image_size": (w, h)},
            K,
            _array((3, 3), "K", {(3,): "that is a vector; K is a 3x3 matrix", (4, 4): "K is 3x3, not a 4x4 transform"}),
            lambda a, b: (
                None
                if (
                    abs(a[0, 0] - b[0, 0]) <= 1e-3 * b[0, 0]
                    and abs(a[1, 1] - b[1, 1]) <= 1e-3 * b[1, 1]
                    and abs(a[0, 2] - b[0, 2]) <= 0.51
                    and abs(a[1, 2] - b[1, 2]) <= 0.51
                    and np.abs(a[[0, 1, 2, 2, 2], [1, 0, 0, 1, 2]] - [0, 0, 0, 0, 1]).max() < 1e-9
                )
                else _cmp_array(0.01, " px")(a, b)
            ),
            wrong=[
                (
                    lambda a: _close(a, K.T, 0.51),
                    "your K is transposed: cx and cy belong in the last COLUMN, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], and the bottom row is [0, 0, 1]",
                ),
                (
                    fx_is(f_deg_as_rad),
                    "np.tan and math.tan take radians, and hfov_deg is in degrees: convert with np.radians (or math.radians) first",
                ),
                (
                    fx_is(f_full),
                    "use HALF the field of view: the right triangle has the half-width w/2 opposite the angle hfov/2, so tan(hfov/2) = (w/2) / f",
                ),
                (fx_is(f_width), "use HALF the image width: tan(hfov/2) = (w/2) / f"),
                (
                    fx_is(f_height),
                    "the horizontal field of view goes with the image WIDTH (image_size[0]), not the height",
                ),
                (lambda a: abs(a[0, 0] - f) < 1e-3 * f and abs(a[1, 1] - f) > 1e-3 * f, "square pixels: fy equals fx"),
                (
                    lambda a: (
                        abs(a[0, 0] - f) < 1e-3 * f and (abs(a[0, 2] - (h - 1) / 2) < 0.51 or abs(a[0, 2]) < 1e-9)
                    ),
                    "fx is right; now put cx = (width - 1) / 2 and cy = (height - 1) / 2 (image_size is (width, height))",
                ),
            ],
            notes=[
                (
                    lambda a: abs(a[0, 2] - K[0, 2]) > 0.25 or abs(a[1, 2] - K[1, 2]) > 0.25,
                    "K is right; note that with pixel centres at integer coordinates fidlearn puts cx at (width - 1) / 2, half a pixel left of width / 2",
                )
            ],
            hint="Draw the right triangle from the pinhole to the image's edge: tan(hfov/2) = (width/2) / fx. Angles go to np.tan in radians.",
            solution="""
        w, h = q1.inputs.image_size
        f = (w / 2) / np.tan(np.radians(q1.inputs.hfov_deg) / 2)
        K = np.array([[f, 0, (w - 1) / 2],
                      [0, f, (h - 1) / 2],
                      [0, 0, 1]])
        q1.answer = K
        """,
            level="easy",
        )
    )

    # q2: project points -------------------------------------------------------------
    rng = _rng("01", learner, "q2")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 85))), (w, h))
    K2 = cam.K.copy()
    K2[0, 2] += float(np.round(rng.uniform(-15, 15), 1))
    K2[1, 2] += float(np.round(rng.uniform(-10, 10), 1))
    n = 5
    z = rng.uniform(800, 3000, n)
    u = rng.uniform(0.1 * w, 0.9 * w, n)
    v = rng.uniform(0.1 * h, 0.9 * h, n)
    P = np.column_stack([(u - K2[0, 2]) / K2[0, 0] * z, (v - K2[1, 2]) / K2[1, 1] * z, z])
    P = np.round(P, 1)
    uv = (P @ K2.T)[:, :2] / P[:, 2:]
    no_div = (P @ K2.T)[:, :2]
    kt = (P @ K2)[:, :2] / (P @ K2)[:, 2:]
    no_c = P[:, :2] * [K2[0, 0], K2[1, 1]] / P[:, 2:]
    qs.append(
        Question(
            "q2",
            "Project points with K",
            """
        `points_camera_mm` holds 5 points (N, 3) in the camera frame (OpenCV's: x right, y down,
        z forward), in mm. Write code that projects them with the pinhole model and the intrinsic
        matrix `K` (no distortion) and gives their pixel coordinates, an (N, 2) array of (u, v).
        """,
            {"K": K2, "points_camera_mm": P},
            uv,
            _array(
                (n, 2),
                "the pixels",
                {
                    (n, 3): "drop the third (homogeneous) coordinate after dividing by it",
                    (2, n): "one ROW per point, please: transpose it",
                },
            ),
            _cmp_array(0.05, " px"),
            wrong=[
                (
                    lambda a: _close(a, no_div, 0.05),
                    "divide by the depth: after K @ p, divide u and v by the third coordinate (it is Z)",
                ),
                (
                    lambda a: _close(a, uv[:, ::-1], 0.05),
                    "the columns are swapped: u (the x pixel, to the right) comes first, then v (down)",
                ),
                (
                    lambda a: _close(a, kt, 0.05),
                    "K is used transposed: the pixel is K @ p (with p as a column), i.e. p @ K.T for rows of points",
                ),
                (lambda a: _close(a, no_c, 0.05), "add the principal point: u = fx * X / Z + cx, v = fy * Y / Z + cy"),
            ],
            hint="u = fx * X / Z + cx and v = fy * Y / Z + cy; in matrix form, p_h = K @ [X, Y, Z] and (u, v) = p_h[:2] / p_h[2].",
            solution="""
        P = q2.inputs.points_camera_mm                      # (N, 3) mm, camera frame
        ph = P @ q2.inputs.K.T                              # rows of K @ p
        q2.answer = ph[:, :2] / ph[:, 2:3]                  # divide by the depth
        """,
            level="easy",
        )
    )

    # q3: distance from apparent size ---------------------------------------------------
    rng = _rng("01", learner, "q3")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 85))), (w, h))
    size_in = float(rng.choice([4, 5, 6, 8]))
    dist_mm = float(rng.uniform(700, 4000))
    side_px = float(np.round(cam3.fx * size_in * 25.4 / dist_mm, 1))
    d = cam3.fx * size_in * 25.4 / side_px
    qs.append(
        Question(
            "q3",
            "How far is the marker?",
            """
        A square marker `marker_size_in` inches wide faces the camera squarely, in the middle of the
        image, and appears `side_px` pixels wide. The camera's intrinsics are in `camera`
        (a fidlearn Camera: `camera.fx`, `camera.K`). Write code that computes the distance from
        the camera to the marker along the optical axis, in millimetres.
        """,
            {"camera": cam3, "marker_size_in": size_in, "side_px": side_px},
            d,
            _scalar("the distance"),
            _cmp_scalar(0, " mm", rtol=2e-3),
            wrong=[
                (
                    lambda a: abs(a * 25.4 - d) <= 3e-3 * d,
                    "that is the distance in inches: the answer is asked in mm (1 in = 25.4 mm); convert the marker size first",
                ),
                (
                    lambda a: abs(a * 304.8 - d) <= 3e-3 * d,
                    "that is the distance in feet (304.8x too small): the answer is asked in mm",
                ),
                (lambda a: abs(a * 1000 - d) <= 3e-3 * d, "that is in metres: the answer is asked in mm"),
                (lambda a: abs(a * 10 - d) <= 3e-3 * d, "that is in cm: the answer is asked in mm"),
                (
                    lambda a: abs(a - cam3.fx * size_in / side_px) <= 3e-3 * d,
                    "the marker size is in inches: convert it to mm (x 25.4) before using it",
                ),
                (
                    lambda a: a < 1 or abs(a - side_px / (cam3.fx * size_in * 25.4)) < 1e-6,
                    "the ratio is upside down: similar triangles give Z / size = fx / side_px",
                ),
            ],
            hint="Similar triangles: side_px / fx = size_mm / Z. Convert inches to mm first (25.4 mm per inch).",
            solution="""
        size_mm = q3.inputs.marker_size_in * 25.4
        q3.answer = q3.inputs.camera.fx * size_mm / q3.inputs.side_px
        """,
            level="easy",
        )
    )

    # q4: field of view from K -------------------------------------------------------------
    rng = _rng("01", learner, "q4")
    w, h = _SIZES[rng.integers(len(_SIZES))]
    fx = float(np.round(rng.uniform(0.5, 1.2) * w, 1))
    K4 = np.array([[fx, 0, (w - 1) / 2], [0, fx, (h - 1) / 2], [0, 0, 1]])
    fov = np.degrees([2 * math.atan(w / (2 * fx)), 2 * math.atan(h / (2 * fx))])
    qs.append(
        Question(
            "q4",
            "Field of view from K",
            """
        Given the intrinsic matrix `K` of a camera and its `image_size` (width, height), write code
        that computes its horizontal and vertical fields of view in degrees, as a pair
        (hfov_deg, vfov_deg).
        """,
            {"K": K4, "image_size": (w, h)},
            fov,
            _array((2,), "(hfov_deg, vfov_deg)"),
            _cmp_array(0.05, " deg"),
            wrong=[
                (
                    lambda a: _close(np.degrees(a), fov, 0.05),
                    "those are radians: the answer is asked in degrees (np.degrees)",
                ),
                (
                    lambda a: _close(a, fov[::-1], 0.05),
                    "the order is (horizontal, vertical): the width goes with the horizontal field of view",
                ),
                (
                    lambda a: _close(a, fov / 2, 0.05),
                    "that is the HALF angle: the field of view is 2 * atan((w/2) / fx)",
                ),
                (
                    lambda a: _close(a, np.degrees([2 * math.atan(w / fx), 2 * math.atan(h / fx)]), 0.05),
                    "use half the image size: fov = 2 * atan((w / 2) / fx)",
                ),
            ],
            hint="The inverse of q1: hfov = 2 * atan((width / 2) / fx); vfov uses the height and fy. np.degrees converts.",
            solution="""
        K = q4.inputs.K
        w, h = q4.inputs.image_size
        hfov = np.degrees(2 * np.arctan((w / 2) / K[0, 0]))
        vfov = np.degrees(2 * np.arctan((h / 2) / K[1, 1]))
        q4.answer = (hfov, vfov)
        """,
            level="easy",
        )
    )
    return qs


# ==================================================================================
# Lesson 03: extrinsics and transforms
# ==================================================================================
_EXTRINSIC_MSG = (
    "that is the extrinsic matrix T_camera_world (what solvePnP's rvec, tvec describe), the "
    "inverse of what is asked: the camera's pose is T_world_camera = frames.invert_transform(T_camera_world)"
)


def _T_is(T: np.ndarray, rot_tol_deg: float = 0.05, trans_tol_mm: float = 0.5) -> Detector:
    cmp = _cmp_transform(rot_tol_deg, trans_tol_mm)
    return lambda a: a.shape == (4, 4) and cmp(a, T) is None


_T_HINTS = {
    (3, 3): "that is only the rotation; a pose is the 4x4 [[R, t], [0, 0, 0, 1]] (frames.make_transform(R, t))",
    (
        3,
    ): "that is a 3-vector; if it is an rvec, cv2.Rodrigues(rvec) turns it into a 3x3 rotation matrix, and the pose is the 4x4 [[R, t], [0, 0, 0, 1]]",
    (3, 4): "add the bottom row [0, 0, 0, 1]",
}


def _lesson_03(learner: str) -> list[Question]:
    qs = []
    # q1: a pose from roll, pitch, yaw ------------------------------------------------
    rng = _rng("03", learner, "q1")
    rpy = np.round(rng.uniform([-20, -20, -180], [20, 20, 180]))
    pos = np.round(rng.uniform([500, -1500, 0], [3000, 1500, 400]))
    R = frames.rotation_from_rpy_deg(*rpy)
    T = frames.make_transform(R, pos)
    R_rad_as_deg = frames.rot_z(rpy[2]) @ frames.rot_y(rpy[1]) @ frames.rot_x(rpy[0])
    R_xyz = frames.rot_x(math.radians(rpy[0])) @ frames.rot_y(math.radians(rpy[1])) @ frames.rot_z(math.radians(rpy[2]))
    qs.append(
        Question(
            "q1",
            "A robot's pose from roll, pitch and yaw",
            """
        A robot stands at `position_mm` (x, y, z in the world, mm) with orientation `rpy_deg` =
        (roll, pitch, yaw) in degrees, rotations about the FIXED world X, Y and Z axes applied in
        that order, so R = Rz(yaw) @ Ry(pitch) @ Rx(roll). Write code that builds its pose
        T_world_robot, a 4x4 homogeneous transform (you may use frames.rot_x / rot_y / rot_z,
        which take radians, or write the matrices yourself).
        """,
            {"rpy_deg": rpy, "position_mm": pos},
            T,
            _array((4, 4), "T_world_robot", _T_HINTS),
            _cmp_transform(0.05, 0.5),
            wrong=[
                (
                    _T_is(frames.invert_transform(T)),
                    "you built the inverse, T_robot_world: the pose of the robot in the world has R in the top-left block and the robot's position as the last column",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], R_rad_as_deg) < 0.05,
                    "the angles are in degrees but rot_x / rot_y / rot_z take radians: convert with np.radians",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], R_xyz) < 0.05,
                    "the order of the rotations is reversed: about fixed axes roll first, then pitch, then yaw, so R = Rz(yaw) @ Ry(pitch) @ Rx(roll)",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], R.T) < 0.05,
                    "the rotation is transposed (inverted): R = Rz(yaw) @ Ry(pitch) @ Rx(roll) goes in as it is",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], R) < 0.05 and not _close(a[:3, 3], pos, 0.5),
                    "the rotation is right; the last column must be the robot's position in mm",
                ),
            ],
            hint="R = frames.rot_z(yaw) @ frames.rot_y(pitch) @ frames.rot_x(roll) with the angles in radians; then frames.make_transform(R, position).",
            solution="""
        roll, pitch, yaw = np.radians(q1.inputs.rpy_deg)
        R = frames.rot_z(yaw) @ frames.rot_y(pitch) @ frames.rot_x(roll)
        T_world_robot = np.eye(4)
        T_world_robot[:3, :3] = R
        T_world_robot[:3, 3] = q1.inputs.position_mm
        q1.answer = T_world_robot
        """,
            level="easy",
        )
    )

    # q2: world points into the camera frame --------------------------------------------
    rng = _rng("03", learner, "q2")
    cpos = np.round(rng.uniform([1500, -800, 900], [3500, 800, 1600]))
    Twc = _look_at(cpos, np.round(rng.uniform([0, -400, 700], [0, 400, 1300])))
    pts = np.round(np.column_stack([np.zeros(4), rng.uniform(-600, 600, 4), rng.uniform(300, 1800, 4)]))
    Tcw = frames.invert_transform(Twc)
    expected = frames.transform_points(Tcw, pts)
    qs.append(
        Question(
            "q2",
            "World points in the camera frame",
            """
        A camera's pose is `T_world_camera` (4x4, mm). `points_world_mm` are 4 points on the wall
        (N, 3) in world coordinates. Write code that expresses them in the camera frame (OpenCV's:
        x right, y down, z forward): an (N, 3) array in mm. Their z (depth) must come out positive:
        the camera sees them.
        """,
            {"T_world_camera": Twc, "points_world_mm": pts},
            expected,
            _array(
                (4, 3),
                "the points",
                {(4, 4): "drop the homogeneous 1 (keep x, y, z)", (3, 4): "one ROW per point: transpose it"},
            ),
            _cmp_array(0.05, " mm"),
            wrong=[
                (
                    lambda a: _close(a, frames.transform_points(Twc, pts), 0.05),
                    "T_world_camera maps camera coordinates INTO the world; you need the other direction, T_camera_world = frames.invert_transform(T_world_camera)",
                ),
                (
                    lambda a: _close(a, pts @ Twc[:3, :3], 0.05),
                    "you rotated but forgot the translation: p_camera = R^T (p_world - t)",
                ),
                (
                    lambda a: _close(a, pts @ Twc[:3, :3] - Twc[:3, 3], 0.05),
                    "subtract the camera position BEFORE rotating: p_camera = R^T (p_world - t), where t is T_world_camera's last column",
                ),
            ],
            hint="p_camera = T_camera_world @ p_world, and T_camera_world is the inverse of T_world_camera (frames.invert_transform). frames.transform_points applies a 4x4 to rows of points.",
            solution="""
        T_camera_world = frames.invert_transform(q2.inputs.T_world_camera)
        q2.answer = frames.transform_points(T_camera_world, q2.inputs.points_world_mm)
        """,
            level="medium",
        )
    )

    # q3: chain a detection and the map -----------------------------------------------
    rng = _rng("03", learner, "q3")
    yaw = float(rng.choice([0, 90, 180, -90]))
    Twm = frames.make_transform(
        frames.rotation_from_rpy_deg(0, 0, yaw) @ np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], dtype=float),
        np.round(rng.uniform([-1000, -1000, 800], [1000, 1000, 1500])),
    )
    normal = Twm[:3, 2]
    cpos = (
        Twm[:3, 3]
        + normal * rng.uniform(1200, 2500)
        + np.cross([0, 0, 1], normal) * rng.uniform(-500, 500)
        + [0, 0, rng.uniform(-300, 300)]
    )
    Twc3 = _look_at(np.round(cpos), Twm[:3, 3])
    Tcm = frames.invert_transform(Twc3) @ Twm
    qs.append(
        Question(
            "q3",
            "Chain the map and a detection",
            """
        The map says where a marker is: `T_world_marker`. A single-marker detection says where the
        marker is seen from the camera: `T_camera_marker`. Write code that computes the camera's
        pose in the world, T_world_camera (4x4, mm). Let the names chain:
        T_world_camera = T_world_marker @ T_marker_camera.
        """,
            {"T_world_marker": Twm, "T_camera_marker": Tcm},
            Twc3,
            _array((4, 4), "T_world_camera", _T_HINTS),
            _cmp_transform(0.05, 0.5),
            wrong=[
                (_T_is(frames.invert_transform(Twc3)), _EXTRINSIC_MSG),
                (
                    _T_is(Twm @ Tcm),
                    "the names do not chain: T_world_marker @ T_camera_marker has 'marker' next to 'camera'; you need T_marker_camera = frames.invert_transform(T_camera_marker)",
                ),
                (
                    _T_is(frames.invert_transform(Tcm) @ Twm),
                    "the order is reversed: matrix products do not commute; T_world_camera = T_world_marker @ T_marker_camera",
                ),
            ],
            hint="Write the frames of each factor under it: T_world_marker @ T_marker_camera -> T_world_camera. The middle names must match.",
            solution="""
        T_marker_camera = frames.invert_transform(q3.inputs.T_camera_marker)
        q3.answer = q3.inputs.T_world_marker @ T_marker_camera
        """,
            level="medium",
        )
    )

    # q4: rvec, tvec to a matrix --------------------------------------------------------
    rng = _rng("03", learner, "q4")
    Twc4 = _look_at(
        np.round(rng.uniform([1500, -900, 900], [3500, 900, 1700])),
        np.round(rng.uniform([0, -300, 800], [0, 300, 1200])),
    )
    Tcw4 = frames.invert_transform(Twc4)
    rvec, tvec = frames.rvec_tvec_from_transform(Tcw4)
    rvec, tvec = np.round(rvec, 6), np.round(tvec, 3)
    Tcw4 = frames.transform_from_rvec_tvec(rvec, tvec)
    R_euler = frames.rot_z(rvec[2]) @ frames.rot_y(rvec[1]) @ frames.rot_x(rvec[0])
    qs.append(
        Question(
            "q4",
            "From rvec, tvec to a 4x4 matrix",
            """
        cv2.solvePnP returned `rvec` and `tvec` (mm). Write code that turns them into the 4x4
        homogeneous transform they describe. Which transform is it, T_camera_world or
        T_world_camera? Give exactly that one.
        """,
            {"rvec": rvec, "tvec": tvec},
            Tcw4,
            _array((4, 4), "the transform", _T_HINTS),
            _cmp_transform(0.05, 0.5),
            wrong=[
                (
                    _T_is(Twc4),
                    "solvePnP's rvec, tvec already ARE T_camera_world (they map world points into the camera frame); you inverted them: give the transform itself",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], R_euler) < 0.05,
                    "rvec is not roll, pitch, yaw: it is a Rodrigues (axis-angle) vector, the axis times the angle; cv2.Rodrigues(rvec) gives the 3x3 rotation matrix",
                ),
                (
                    lambda a: frames.rotation_angle_deg(a[:3, :3], Tcw4[:3, :3].T) < 0.05,
                    "the rotation is transposed: use the matrix cv2.Rodrigues returns as it is",
                ),
            ],
            hint="R, _ = cv2.Rodrigues(rvec) gives the rotation; solvePnP's pair maps world points into the camera frame: p_camera = R @ p_world + tvec.",
            solution="""
        R, _ = cv2.Rodrigues(np.asarray(q4.inputs.rvec, dtype=float))
        T_camera_world = np.eye(4)
        T_camera_world[:3, :3] = R
        T_camera_world[:3, 3] = np.ravel(q4.inputs.tvec)
        q4.answer = T_camera_world
        """,
            level="medium",
        )
    )
    return qs


# ==================================================================================
# Lesson 04: markers, the world map, winding order
# ==================================================================================
_WALL_YAW = {"north": 0, "south": 180, "west": 90, "east": -90}
_ROOM_FT = {
    "north": 0.0,
    "south": 16.0,
    "west": -6.0,
    "east": 6.0,
}  # wall positions: x for north/south, y for west/east


def _wall_translation(
    rng: np.random.Generator, wall: str, step: float, span: tuple, height: tuple, per_ft: float
) -> list:
    """A top-left corner on a wall of the room: along the wall within ``span``, at a height in ``height``.

    ``step`` rounds the values; ``per_ft`` is the unit of the result per foot
    (1 for feet, 304.8 for mm), the room's walls being given in feet.
    """
    along = float(np.round(rng.uniform(*span) / step) * step)
    z = float(np.round(rng.uniform(*height) / step) * step)
    if wall in ("north", "south"):
        return [_ROOM_FT[wall] * per_ft, along, z]
    return [along, _ROOM_FT[wall] * per_ft, z]


def _map_diagnosis(got: MarkerMap, want: MarkerMap) -> str | None:
    """What differs between two maps, in words (None if their corners agree within 0.5 mm)."""
    missing = sorted(set(want.ids) - set(got.ids))
    extra = sorted(set(got.ids) - set(want.ids))
    if missing:
        return f"your map has no marker {missing[0]}; it needs ids {want.ids}"
    if extra:
        return f"your map has marker {extra[0]}, which is not on the walls; it needs ids {want.ids}"
    if abs(got.marker_size_mm - want.marker_size_mm) > 0.01:
        return f"marker_size_mm is {got.marker_size_mm:g}, the markers are {want.marker_size_mm:g} mm (the black square's side, in mm whatever the map's units)"
    for mid in want.ids:
        g, w = got.marker_corners(mid), want.marker_corners(mid)
        if np.abs(g - w).max() <= 0.5:
            continue
        if np.abs(g[0] * 10 - w[0]).max() <= 1:
            return f'marker {mid} is 10x too close to the origin: the positions are in cm, so the map\'s units must be "cm"'
        if np.abs(g[0] / 10 - w[0]).max() <= 1:
            return (
                f'marker {mid} is 10x too far: the positions are in cm; say "units": "cm" (the library converts to mm)'
            )
        if np.abs(g[0] - w[0]).max() <= 0.5:
            n_got, n_want = got.normal(mid), want.normal(mid)
            return (
                f"marker {mid}: its top-left corner is right but it faces {np.round(n_got, 3).tolist()}; on its wall it must face "
                f"{np.round(n_want, 3).tolist()} (into the room): check its yaw"
            )
        return f"marker {mid}: its top-left corner is {np.round(g[0], 1).tolist()} mm, expected {np.round(w[0], 1).tolist()} mm"
    return None


def _lesson_04(learner: str) -> list[Question]:
    qs = []
    # q1: corners of one marker from its placement in feet -------------------------------
    rng = _rng("04", learner, "q1")
    wall = str(rng.choice(list(_WALL_YAW)))
    t_ft = _wall_translation(rng, wall, 0.25, (-4, 4), (2, 6), per_ft=1.0)
    size = float(rng.choice([80, 100, 120, 150]))
    mid = int(rng.integers(0, 50))
    placement = {"translation": t_ft, "rotation": [0, 0, _WALL_YAW[wall]]}
    mm = MarkerMap.from_dict({str(mid): placement}, units="ft", marker_size_mm=size)
    C = mm.marker_corners(mid)
    local = np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]], dtype=float) * size
    C_unconverted = local @ frames.rotation_from_rpy_deg(0, 0, _WALL_YAW[wall]).T + np.asarray(t_ft)
    C_no_yaw = local + np.asarray(t_ft) * 304.8

    def winding(a):
        order = _corner_order(a, C, 0.5)
        return order is not None and order != ("TL", "TR", "BR", "BL")

    qs.append(
        Question(
            "q1",
            "Corners from a placement in feet",
            """
        Marker `marker_id` hangs on the wall named in `wall`. The map gives its `placement`: "translation"
        is the world position of its TOP-LEFT corner in `units` (feet!), "rotation" is
        [roll, pitch, yaw] in degrees, R = Rz(yaw) @ Ry(pitch) @ Rx(roll), applied about that corner.
        With rotation [0, 0, 0] a marker faces +X and TR = TL + s*Y, BL = TL - s*Z (s the side).
        Write code that computes its 4 corners in world mm, a (4, 3) array in the order
        TL, TR, BR, BL (do not use MarkerMap: that is what you are rebuilding).
        """,
            {"marker_id": mid, "wall": wall, "placement": placement, "units": "ft", "marker_size_mm": size},
            C,
            _array(
                (4, 3),
                "the corners",
                {
                    (3, 4): "one ROW per corner: transpose it",
                    (4, 2): "these are world corners: 3 coordinates (x, y, z) each",
                },
            ),
            _cmp_array(0.5, " mm"),
            wrong=[
                (
                    lambda a: _close(a, C_unconverted, 0.5) or _close(a, C / 304.8, 0.01),
                    "the translation is in feet: multiply it by 304.8 to get mm (your values are 304.8x too small)",
                ),
                (winding, lambda a: _winding_message(_corner_order(a, C, 0.5))),
                (
                    lambda a: _close(a, C_no_yaw, 0.5),
                    f"the rotation was left out: on the {wall} wall the marker's right (TL->TR) is R @ [0, 1, 0], not +Y",
                ),
                (
                    lambda a: _close(a[0], C[0], 0.5),
                    "the top-left corner is right; the others are TL + R @ (s * [0, 1, 0]) (TR), TL + R @ (s * [0, 1, -1]) (BR) and TL + R @ (s * [0, 0, -1]) (BL)",
                ),
            ],
            hint="Convert the translation to mm (x 304.8). R = frames.rotation_from_rpy_deg(*rotation). The corners are TL + R @ offset with offsets s*[0,0,0], s*[0,1,0], s*[0,1,-1], s*[0,0,-1].",
            solution="""
        p = q1.inputs.placement
        s = q1.inputs.marker_size_mm
        TL = np.asarray(p["translation"], dtype=float) * 304.8        # feet -> mm
        R = frames.rotation_from_rpy_deg(*p["rotation"])
        offsets = s * np.array([[0, 0, 0], [0, 1, 0], [0, 1, -1], [0, 0, -1]])   # TL, TR, BR, BL
        q1.answer = TL + offsets @ R.T
        """,
            level="easy",
        )
    )

    # q2: write a world map ---------------------------------------------------------------
    rng = _rng("04", learner, "q2")
    size2 = float(rng.choice([80, 100, 150]))
    ids = sorted(int(i) for i in rng.choice(50, size=4, replace=False))
    walls = [str(w) for w in rng.choice(list(_WALL_YAW), size=4)]
    walls[0], walls[1] = "north", "east"
    room_cm = {"north": 0.0, "south": 487.68, "west": -182.88, "east": 182.88}
    measured = []
    for i, w in zip(ids, walls):
        along = float(np.round(rng.uniform(-150, 150)))
        z = float(np.round(rng.uniform(60, 200)))
        tl = [room_cm[w], along, z] if w in ("north", "south") else [along, room_cm[w], z]
        measured.append({"id": i, "wall": w, "top_left_cm": tl})
    want = MarkerMap(
        {
            m["id"]: MarkerPlacement(
                m["id"], tuple(v * 10 for v in m["top_left_cm"]), (0.0, 0.0, float(_WALL_YAW[m["wall"]]))
            )
            for m in measured
        },
        size2,
        "ARUCO_ORIGINAL",
        "cm",
    )

    def parse_map(answer):
        if isinstance(answer, MarkerMap):
            return answer
        if isinstance(answer, dict):
            try:
                return MarkerMap.from_dict(answer, source="your map")
            except Exception as exc:  # the library's message says what to fix
                raise _AnswerError(f"MarkerMap.from_dict cannot read your dict: {exc}") from None
        raise _AnswerError(f"give a dict in the map-file layout (or a MarkerMap), got {type(answer).__name__}")

    qs.append(
        Question(
            "q2",
            "Write the world map",
            """
        You measured 4 markers with a tape in centimetres: `measured` lists each marker's id, its
        wall and the world position of its top-left corner in cm. Markers on a wall face into the
        room; `wall_yaw_deg` gives the yaw that turns a marker (which faces +X at yaw 0) to face
        into the room from each wall. Write code that builds the map as a dict in fidlearn's full
        map-file layout, {"units": ..., "marker_size_mm": ..., "dictionary": ..., "markers":
        {"<id>": {"translation": [x, y, z], "rotation": [roll, pitch, yaw]}}}, which
        fidlearn.MarkerMap.from_dict must load to the right corners.
        """,
            {
                "measured": measured,
                "wall_yaw_deg": dict(_WALL_YAW),
                "marker_size_mm": size2,
                "dictionary": "ARUCO_ORIGINAL",
            },
            want,
            parse_map,
            _map_diagnosis,
            hint='Keep the numbers in cm and say "units": "cm"; the rotation of each marker is [0, 0, wall_yaw_deg[wall]]; the keys of "markers" are the ids as strings.',
            solution="""
        q2.answer = {
            "units": "cm",
            "marker_size_mm": q2.inputs.marker_size_mm,
            "dictionary": q2.inputs.dictionary,
            "markers": {
                str(m["id"]): {"translation": m["top_left_cm"], "rotation": [0, 0, q2.inputs.wall_yaw_deg[m["wall"]]]}
                for m in q2.inputs.measured
            },
        }
        """,
            level="medium",
        )
    )

    # q3: a marker on the floor ---------------------------------------------------------
    rng = _rng("04", learner, "q3")
    dirs = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0)}
    up_name = str(rng.choice(list(dirs)))
    up = np.array(dirs[up_name], dtype=float)
    normal = np.array([0.0, 0.0, 1.0])
    R3 = np.column_stack([normal, np.cross(up, normal), up])

    def R_of(a):
        return frames.rotation_from_rpy_deg(*a)

    def rotated_about_normal(a):
        ang = frames.rotation_angle_deg(R_of(a), R3)
        return R_of(a)[:, 0] @ normal > 0.999 and ang > 1 and abs(ang - 180) > 1

    qs.append(
        Question(
            "q3",
            "A marker on the floor",
            """
        A marker lies flat on the floor, printed face up. Its own "up" direction (from its bottom
        edge to its top edge, BL -> TL) points along the world axis `up_direction` (as a vector:
        `up_vector`).
        Write code that finds its map rotation [roll, pitch, yaw] in degrees (R = Rz(yaw) @ Ry(pitch)
        @ Rx(roll); at [0, 0, 0] a marker faces +X with its up along +Z and its right, TL -> TR,
        along +Y). Hint of a method: build the 3x3 matrix whose columns are the marker's face
        normal, right and up directions in the world, then convert it.
        """,
            {"up_direction": up_name, "up_vector": up},
            R3,
            _array(
                (3,),
                "[roll, pitch, yaw]",
                {
                    (
                        3,
                        3,
                    ): "that is a rotation matrix; the map wants [roll, pitch, yaw] in degrees: frames.rpy_deg_from_rotation(R)"
                },
            ),
            lambda a, b: (
                None
                if frames.rotation_angle_deg(R_of(a), b) <= 0.5
                else f"with your angles the marker faces {np.round(R_of(a)[:, 0], 3).tolist()} with its up along {np.round(R_of(a)[:, 2], 3).tolist()}; "
                f"it should face {normal.tolist()} (up off the floor) with its up along {up.tolist()}"
            ),
            wrong=[
                (
                    lambda a: frames.rotation_angle_deg(R_of(np.degrees(a)), R3) <= 0.5,
                    "those look like radians: map rotations are in degrees (np.degrees)",
                ),
                (
                    lambda a: R_of(a)[:, 0] @ normal < -0.999,
                    "your marker faces DOWN, into the floor: its normal (the first column of R) must be +Z",
                ),
                (
                    lambda a: R_of(a)[:, 0] @ normal > 0.999 and R_of(a)[:, 2] @ up < -0.999,
                    "the marker is upside down: TL and BR swap places; its up (the third column of R) must point along up_direction",
                ),
                (
                    rotated_about_normal,
                    "the face is right but the marker is turned by 90 degrees about its normal: the corners would start at another corner (the winding order shifts); its up (third column of R) must point along up_direction",
                ),
            ],
            hint="Columns of R: R @ [1,0,0] is the face normal (+Z on the floor), R @ [0,1,0] the right (up x normal), R @ [0,0,1] the up direction. frames.rpy_deg_from_rotation(R) gives the angles.",
            solution="""
        up = np.asarray(q3.inputs.up_vector, dtype=float)
        normal = np.array([0.0, 0.0, 1.0])          # face up, off the floor
        right = np.cross(up, normal)                 # at rotation 0: up (Z) x normal (X) = right (Y)
        R = np.column_stack([normal, right, up])
        q3.answer = frames.rpy_deg_from_rotation(R)
        """,
            level="medium",
        )
    )

    # q4: centre and normal -----------------------------------------------------------------
    rng = _rng("04", learner, "q4")
    placements = {}
    for i, w in enumerate(["north", "west", "east", "south"]):
        mid4 = 10 + i
        placements[mid4] = MarkerPlacement(
            mid4,
            tuple(_wall_translation(rng, w, 10.0, (-1200, 1200), (600, 1800), per_ft=304.8)),
            (0.0, 0.0, float(_WALL_YAW[w])),
        )
    m4 = MarkerMap(placements, float(rng.choice([80, 100, 150])), "ARUCO_ORIGINAL", "mm")
    ask = int(rng.choice(m4.ids[1:]))
    centre = m4.marker_corners(ask).mean(axis=0)
    nrm = m4.normal(ask)
    c4 = m4.marker_corners(ask)
    qs.append(
        Question(
            "q4",
            "Centre and facing direction",
            """
        `marker_map` is a fidlearn MarkerMap. For marker `marker_id`, write code that computes its
        centre in world mm (3,) and the unit normal (3,) of its printed face, pointing out of the
        face (towards the room, where a camera can see it). Use only its corners
        (marker_map.marker_corners(id), TL, TR, BR, BL). Answer {"center_mm": ..., "normal": ...}.
        """,
            {"marker_map": m4, "marker_id": ask},
            {"center_mm": centre, "normal": nrm},
            _parts(center_mm=_array((3,), "center_mm"), normal=_array((3,), "normal")),
            lambda a, b: (
                _cmp_array(0.5, " mm")(a["center_mm"], b["center_mm"]) or _cmp_array(0.01)(a["normal"], b["normal"])
            ),
            wrong=[
                (
                    lambda a: _close(a["center_mm"], c4[0], 0.5),
                    "center_mm is the top-left corner: the centre is the mean of the 4 corners",
                ),
                (
                    lambda a: _close(a["normal"], -nrm, 0.01),
                    "your normal points INTO the wall: with corners TL, TR, BR, BL the outward normal is (TR - TL) x (TL - BL), right x up",
                ),
                (
                    lambda a: (
                        abs(np.linalg.norm(a["normal"]) - 1) > 0.01
                        and _close(a["normal"] / np.linalg.norm(a["normal"]), nrm, 0.01)
                    ),
                    "the direction is right; divide by its length to make it a unit vector",
                ),
            ],
            hint="centre = corners.mean(axis=0); right = TR - TL, up = TL - BL, normal = cross(right, up) / its norm.",
            solution="""
        c = q4.inputs.marker_map.marker_corners(q4.inputs.marker_id)
        TL, TR, BR, BL = c
        n = np.cross(TR - TL, TL - BL)
        q4.answer = {"center_mm": c.mean(axis=0), "normal": n / np.linalg.norm(n)}
        """,
            level="medium",
        )
    )
    return qs


# ==================================================================================
# Lesson 07: inverting the extrinsics
# ==================================================================================
def _room_pose(rng: np.random.Generator) -> np.ndarray:
    """A camera somewhere in the room looking at the north wall (x = 0)."""
    pos = np.round(rng.uniform([1200, -1200, 800], [4000, 1200, 1800]))
    target = np.round(rng.uniform([0, -500, 700], [0, 500, 1400]))
    return _look_at(pos, target)


def _lesson_07(learner: str) -> list[Question]:
    qs = []
    # q1: camera position ------------------------------------------------------------
    rng = _rng("07", learner, "q1")
    Twc = _room_pose(rng)
    rvec, tvec = frames.rvec_tvec_from_transform(frames.invert_transform(Twc))
    rvec, tvec = np.round(rvec, 6), np.round(tvec, 2)
    R, _ = cv2.Rodrigues(rvec)
    pos = -R.T @ tvec
    qs.append(
        Question(
            "q1",
            "Where is the camera?",
            """
        cv2.solvePnP gave `rvec` and `tvec` (mm) for a camera looking at the north wall. Write code
        that computes the camera's position in the world, (3,) in mm.
        """,
            {"rvec": rvec, "tvec": tvec},
            pos,
            _array(
                (3,),
                "the position",
                {(4, 4): "give only the position (3,), the last column of T_world_camera", (3, 1): ""},
            ),
            _cmp_array(0.5, " mm"),
            wrong=[
                (
                    lambda a: _close(a, tvec, 0.5),
                    "tvec is where the world's origin is in the CAMERA frame, not where the camera is: the camera's position is -R^T @ tvec",
                ),
                (
                    lambda a: _close(a, -tvec, 0.5),
                    "-tvec is not enough: tvec is in camera coordinates; rotate it back into the world: -R^T @ tvec",
                ),
                (
                    lambda a: _close(a, -R @ tvec, 0.5),
                    "use the transpose: the inverse of a rotation is R^T, so the position is -R.T @ tvec",
                ),
                (lambda a: _close(a, R.T @ tvec, 0.5), "mind the sign: the position is -R^T @ tvec"),
                (lambda a: _close(a * 304.8, pos, 1), "that is in feet (304.8x too small): the answer is asked in mm"),
                (lambda a: _close(a * 1000, pos, 1), "that is in metres: the answer is asked in mm"),
                (
                    lambda a: _close(a, rvec, 1e-3),
                    "rvec is a rotation (axis times angle), not a position; R, _ = cv2.Rodrigues(rvec), then -R^T @ tvec",
                ),
            ],
            hint="p_camera = R @ p_world + t. The camera's own centre has p_camera = 0; solve for p_world.",
            solution="""
        R, _ = cv2.Rodrigues(np.asarray(q1.inputs.rvec, dtype=float))
        q1.answer = -R.T @ np.ravel(q1.inputs.tvec)
        """,
            level="easy",
        )
    )

    # q2: the camera pose ----------------------------------------------------------------
    rng = _rng("07", learner, "q2")
    Twc2 = _room_pose(rng)
    rvec2, tvec2 = frames.rvec_tvec_from_transform(frames.invert_transform(Twc2))
    rvec2, tvec2 = np.round(rvec2, 6), np.round(tvec2, 2)
    Tcw2 = frames.transform_from_rvec_tvec(rvec2, tvec2)
    Twc2 = frames.invert_transform(Tcw2)
    R2 = Tcw2[:3, :3]
    bad_t = frames.make_transform(R2.T, -tvec2)
    qs.append(
        Question(
            "q2",
            "The camera's pose",
            """
        From solvePnP's `rvec`, `tvec` (mm), write code that builds the camera's pose in the world,
        T_world_camera (4x4, mm): the transform that maps camera coordinates into world
        coordinates. Its last column holds the camera's position.
        """,
            {"rvec": rvec2, "tvec": tvec2},
            Twc2,
            _array((4, 4), "T_world_camera", _T_HINTS),
            _cmp_transform(0.05, 0.5),
            wrong=[
                (_T_is(Tcw2), _EXTRINSIC_MSG),
                (_T_is(bad_t), "the rotation is right (R^T) but the translation is not -tvec: it is -R^T @ tvec"),
                (
                    _T_is(frames.make_transform(R2, -R2.T @ tvec2)),
                    "the translation is right; the rotation of the inverse is R^T, not R",
                ),
            ],
            hint="Invert T_camera_world in closed form: [[R^T, -R^T t], [0, 0, 0, 1]] (frames.invert_transform does it).",
            solution="""
        R, _ = cv2.Rodrigues(np.asarray(q2.inputs.rvec, dtype=float))
        t = np.ravel(q2.inputs.tvec)
        T_world_camera = np.eye(4)
        T_world_camera[:3, :3] = R.T
        T_world_camera[:3, 3] = -R.T @ t
        q2.answer = T_world_camera
        """,
            level="easy",
        )
    )

    # q3: where does it look? ---------------------------------------------------------------
    rng = _rng("07", learner, "q3")
    pos3 = np.round(rng.uniform([1200, -1500, 1000], [4000, 1500, 2200]))
    target3 = np.round(rng.uniform([0, -900, 200], [0, 900, 1200]))
    Twc3 = _look_at(pos3, target3)
    rvec3, tvec3 = frames.rvec_tvec_from_transform(frames.invert_transform(Twc3))
    rvec3, tvec3 = np.round(rvec3, 6), np.round(tvec3, 2)
    Twc3 = frames.invert_transform(frames.transform_from_rvec_tvec(rvec3, tvec3))
    axis = Twc3[:3, 2]
    heading = math.degrees(math.atan2(axis[1], axis[0]))
    tilt = math.degrees(math.asin(-axis[2]))
    expected3 = np.array([heading, tilt])
    row = Twc3[:3, :3][2, :]  # solvePnP's R[:, 2], the mistaken 'optical axis'
    wrong_heading = np.array(
        [math.degrees(math.atan2(row[1], row[0])), math.degrees(math.asin(float(np.clip(-row[2], -1, 1))))]
    )

    def heading_diff(a, b):
        d = (a[0] - b[0] + 180) % 360 - 180
        if abs(d) <= 0.2 and abs(a[1] - b[1]) <= 0.2:
            return None
        return f"your heading is {d:+.3g} deg and your tilt {a[1] - b[1]:+.3g} deg away from the key's"

    qs.append(
        Question(
            "q3",
            "Which way does the camera look?",
            """
        From solvePnP's `rvec`, `tvec`, write code that finds where the camera's optical axis
        (its +z) points in the world: its heading in degrees (the angle in the XY plane from +X
        towards +Y, atan2(dy, dx)) and its tilt in degrees below the horizon (positive when
        looking down). Answer (heading_deg, tilt_down_deg).
        """,
            {"rvec": rvec3, "tvec": tvec3},
            expected3,
            _array((2,), "(heading_deg, tilt_down_deg)"),
            heading_diff,
            wrong=[
                (
                    lambda a: heading_diff(np.degrees(a), expected3) is None,
                    "those are radians: the answer is asked in degrees",
                ),
                (
                    lambda a: heading_diff(a, wrong_heading) is None,
                    "R[:, 2] of solvePnP's R is the world's Z axis seen from the camera; the camera's z axis in the world is the third column of R^T (the third ROW of R)",
                ),
                (
                    lambda a: heading_diff(a, np.array([heading + 180, -tilt])) is None,
                    "that is the direction behind the camera: the optical axis is +z of the camera frame",
                ),
                (
                    lambda a: abs(a[0] - heading) <= 0.2 and abs(a[1] + tilt) <= 0.2,
                    "the heading is right; the tilt has the wrong sign: looking down means the axis has a negative world z, tilt = asin(-z)",
                ),
            ],
            hint="R_world_camera = R^T (R from cv2.Rodrigues(rvec)); its third column is the optical axis d in the world. heading = atan2(d_y, d_x), tilt down = asin(-d_z).",
            solution="""
        R, _ = cv2.Rodrigues(np.asarray(q3.inputs.rvec, dtype=float))
        d = R.T[:, 2]                                    # camera +z in world coordinates
        heading = np.degrees(np.arctan2(d[1], d[0]))
        tilt_down = np.degrees(np.arcsin(-d[2]))
        q3.answer = (heading, tilt_down)
        """,
            level="medium",
        )
    )

    # q4: from one marker's pose to the camera's position in the world -------------------------
    rng = _rng("07", learner, "q4")
    wall = str(rng.choice(["north", "west", "east"]))
    yaw = _WALL_YAW[wall]
    t = _wall_translation(rng, wall, 10.0, (-1000, 1000), (700, 1600), per_ft=304.8)
    mmap = MarkerMap({5: MarkerPlacement(5, tuple(t), (0.0, 0.0, float(yaw)))}, 150.0, "ARUCO_ORIGINAL", "mm")
    Twm = mmap.T_world_marker(5)
    n = Twm[:3, 2]
    cpos = (
        Twm[:3, 3]
        + n * rng.uniform(1000, 2500)
        + np.cross([0, 0, 1], n) * rng.uniform(-600, 600)
        + [0, 0, rng.uniform(-200, 400)]
    )
    Twc4 = _look_at(np.round(cpos), Twm[:3, 3])
    Tcm = frames.invert_transform(Twc4) @ Twm
    rvec4, tvec4 = frames.rvec_tvec_from_transform(Tcm)
    rvec4, tvec4 = np.round(rvec4, 6), np.round(tvec4, 2)
    Tcm = frames.transform_from_rvec_tvec(rvec4, tvec4)
    pos4 = (Twm @ frames.invert_transform(Tcm))[:3, 3]
    pos_in_marker = frames.invert_transform(Tcm)[:3, 3]
    qs.append(
        Question(
            "q4",
            "Camera position from a single marker",
            """
        solvePnP on the 4 corners of one marker, with the corners given in the MARKER's own frame
        (centre origin, x to the right, y up, z out of the face), gave `rvec`, `tvec` (mm): they
        describe T_camera_marker. The marker's pose in the world is `T_world_marker`. Write code that
        computes the camera's position in the WORLD, (3,) mm.
        """,
            {"rvec": rvec4, "tvec": tvec4, "T_world_marker": Twm},
            pos4,
            _array((3,), "the position"),
            _cmp_array(0.5, " mm"),
            wrong=[
                (
                    lambda a: _close(a, pos_in_marker, 0.5),
                    "that is the camera's position in the MARKER's frame; chain it into the world: T_world_camera = T_world_marker @ T_marker_camera",
                ),
                (
                    lambda a: _close(a, (Twm @ Tcm)[:3, 3], 0.5),
                    "T_camera_marker must be inverted before chaining: T_marker_camera = invert(T_camera_marker)",
                ),
                (
                    lambda a: _close(a, Twm[:3, :3] @ tvec4 + Twm[:3, 3], 0.5) or _close(a, tvec4, 0.5),
                    "tvec is the marker's position seen from the camera, not the camera's position; invert T_camera_marker first",
                ),
                (lambda a: _close(a * 304.8, pos4, 1), "that is in feet: the answer is asked in mm"),
            ],
            hint="T_camera_marker = frames.transform_from_rvec_tvec(rvec, tvec); T_world_camera = T_world_marker @ invert_transform(T_camera_marker); its last column is the position.",
            solution="""
        T_camera_marker = frames.transform_from_rvec_tvec(q4.inputs.rvec, q4.inputs.tvec)
        T_world_camera = q4.inputs.T_world_marker @ frames.invert_transform(T_camera_marker)
        q4.answer = T_world_camera[:3, 3]
        """,
            level="hard",
        )
    )
    return qs


# ==================================================================================
# lessons, registry and notebooks
# ==================================================================================
@dataclass(frozen=True)
class _LessonInfo:
    number: str
    topic: str
    title: str
    intro: str
    build: Callable[[str], list]


_LESSONS: dict[str, _LessonInfo] = {}


def _register(number: str, topic: str, title: str, intro: str, build: Callable[[str], list]) -> None:
    _LESSONS[number] = _LessonInfo(number, topic, title, textwrap.dedent(intro).strip(), build)


class Lesson:
    """The questions of one lesson for one learner: ``ex.q1``, ``ex.q2``... and :meth:`summary`."""

    def __init__(self, info: _LessonInfo, learner: str):
        self.number = info.number
        self.topic = info.topic
        self.title = info.title
        self.intro = info.intro
        self.learner = learner
        self.questions: list[Question] = [q._fresh() for q in _built(info.number, learner)]
        for q in self.questions:
            setattr(self, q.name, q)

    def __iter__(self):
        return iter(self.questions)

    def __len__(self) -> int:
        return len(self.questions)

    def __getitem__(self, name: str) -> Question:
        for q in self.questions:
            if q.name == name:
                return q
        raise KeyError(f"lesson {self.number} has no question {name!r}; it has {[q.name for q in self.questions]}")

    def results(self) -> list[Result]:
        """The current result of every question (prints nothing)."""
        return [q.grade() for q in self.questions]

    def summary(self) -> None:
        """Print a score and one line per question."""
        res = self.results()
        n_ok = sum(r.correct for r in res)
        who = f" for learner {self.learner!r}" if self.learner else ""
        print(f"Lesson {self.number}{who}: {n_ok} of {len(res)} correct")
        for q, r in zip(self.questions, res):
            print(f"  {q.name} [{r.status}] {q.title}")

    def __repr__(self) -> str:
        who = f", learner {self.learner!r}" if self.learner else ", the class's shared variant"
        qs = "\n".join(f"  {q.name}: {q.title} ({q.level})" for q in self.questions)
        return f"Lesson {self.number}: {self.title}{who}\n{qs}"


@functools.lru_cache(maxsize=64)
def _built(number: str, learner: str) -> tuple:
    """The questions of a lesson for a learner, built once (rendering takes a moment); Lesson hands out copies."""
    return tuple(_LESSONS[number].build(learner))


def lessons() -> dict[str, str]:
    """The available lessons: ``{"01": "pinhole", ...}`` (number to topic)."""
    return {k: v.topic for k, v in sorted(_LESSONS.items())}


def lesson(number: str | int, learner: str | None = None) -> Lesson:
    """The exercises of lesson ``number`` (``"01"`` ... ``"09"``) for a learner.

    Parameters
    ----------
    number : str or int
        The lesson, ``"03"`` or ``3``.
    learner : str, optional
        Any id (a name, an e-mail, a student number): it seeds the learner's
        own numbers. ``None`` or ``""`` takes ``$FIDLEARN_LEARNER``, else the
        variant the whole class shares.
    """
    key = lesson_number(number)
    graded = Path(INPUTS_FILE)
    if graded.is_file():
        return _graded_lesson(key, graded)
    if not learner:
        learner = os.environ.get("FIDLEARN_LEARNER", "")
    return Lesson(_LESSONS[key], str(learner).strip())


#: The file a graded lesson's inputs come in (written by ``fidlearn release``).
INPUTS_FILE = "fidlearn_inputs.json"


def lesson_number(number: str | int) -> str:
    """``3``, ``"3"`` or ``"03"`` -> ``"03"``; a KeyError naming the lessons for anything else."""
    key = f"{int(number):02d}" if str(number).strip().isdigit() and len(str(number).strip()) < 4 else str(number)
    if key not in _LESSONS:
        raise KeyError(f"no exercises for lesson {number!r}; available: {', '.join(sorted(_LESSONS))}")
    return key


def build_questions(number: str, learner: str, seed: Callable[[str], int] | None = None) -> list:
    """The questions of a lesson built afresh, seeded by ``seed(question_name)`` when given (graded mode)."""
    token = _SEED.set(seed)
    try:
        return list(_LESSONS[lesson_number(number)].build(learner))
    finally:
        _SEED.reset(token)


def _graded_lesson(key: str, path: Path) -> Lesson:
    """A lesson whose inputs come from the grader's file and whose answers stay with the grader."""
    from .grading import from_plain

    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        questions = {
            name: {k: from_plain(v) for k, v in inputs.items()} for name, inputs in record["questions"].items()
        }
        lesson_of_file, learner = str(record["lesson"]), str(record["learner"])
    except Exception as exc:  # noqa: BLE001 - a damaged inputs file: say so in one line
        raise KeyError(
            f"{path} is damaged ({type(exc).__name__}); ask your instructor for your lesson's files again"
        ) from None
    if lesson_of_file != key:
        raise KeyError(
            f"this folder holds the inputs of lesson {lesson_of_file}, not {key}: "
            f"use exercises.lesson({lesson_of_file!r})"
        )
    shell = Lesson(_LESSONS[key], "graded")
    shell.learner = learner
    for q in shell.questions:
        q.inputs = Inputs(**questions.get(q.name, {}))
        q.data = q.inputs
        q._expected = _NO_KEY
    return shell


def notebook_name(number: str) -> str:
    """The file name of a lesson's exercise notebook, ``"03_extrinsics.ipynb"``."""
    info = _LESSONS[number]
    return f"{info.number}_{info.topic}.ipynb"


_HOW_TO = """\
**How to work.** Each question gives its data in `qN.inputs`. Write code that computes the
answer from them, assign it to `qN.answer` and run `qN.check()`: it says `Correct`,
`Incorrect` (with what looks wrong) or `Not attempted`. Stuck? `qN.hint()`. Given up?
`qN.solution()` shows one way to do it. Put your name (or the id your teacher gave you) in
`LEARNER` to get your own numbers; the checks know the answers for everyone."""


def answer_key_notebook(number: str):
    """The answer-key notebook of a lesson (an ``nbformat`` notebook, not executed).

    Each question has a markdown cell (the task), a cell showing its inputs,
    and a cell whose solution sits between ``### BEGIN SOLUTION`` and
    ``### END SOLUTION``, followed by ``qN.check()``.
    """
    import nbformat

    info = _LESSONS[number]
    ex = Lesson(info, "")
    v4 = nbformat.v4
    cells = [
        v4.new_markdown_cell(f"# Exercises {info.number}: {info.title}\n\n{info.intro}\n\n{_HOW_TO}"),
        v4.new_code_cell(
            f'{SETUP_CODE}\n\nLEARNER = ""  # your name or id, e.g. "alice": it gives you your own numbers\nex = exercises.lesson("{info.number}", learner=LEARNER)\nex'
        ),
    ]
    for q in ex:
        level = f" ({q.level})" if q.level else ""
        cells.append(v4.new_markdown_cell(f"## {q.name}. {q.title}{level}\n\n{q.task}"))
        look = f"{q.look_code}\n" if q.look_code else ""
        cells.append(v4.new_code_cell(f"{q.name} = ex.{q.name}\n{look}{q.name}.inputs"))
        cells.append(v4.new_code_cell(f"{BEGIN_SOLUTION}\n{q.solution_code}\n{END_SOLUTION}\n{q.name}.check()"))
    cells.append(v4.new_markdown_cell("## Your score"))
    cells.append(v4.new_code_cell("ex.summary()"))
    for i, c in enumerate(cells):
        c["id"] = f"ex{info.number}-{i:02d}"
    nb = v4.new_notebook(cells=cells)
    nb.metadata = {
        "kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"},
        "language_info": {"name": "python"},
    }
    return nb


_BLOCK_RE = re.compile(re.escape(BEGIN_SOLUTION) + r"\n(.*?)\n?" + re.escape(END_SOLUTION) + r"\n?", re.S)
_ANSWER_RE = re.compile(r"^(\w+)\.answer\s*=", re.M)


def solution_blocks(nb) -> dict[str, str]:
    """The solution code of each question in an answer-key notebook: ``{"q1": code, ...}``."""
    out = {}
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        for m in _BLOCK_RE.finditer(cell.source):
            names = _ANSWER_RE.findall(m.group(1))
            if not names:
                raise ValueError(
                    f"a solution block assigns no answer (expected a line 'qN.answer = ...'):\n{m.group(1)}"
                )
            out[names[-1]] = m.group(1).strip()
    return out


def student_copy(nb):
    """The student copy of an answer-key notebook: solutions replaced by stubs, outputs cleared.

    A block between ``### BEGIN SOLUTION`` and ``### END SOLUTION`` that
    assigns ``qN.answer`` becomes ``# your code here ...`` and
    ``qN.answer = ...``, so the check that follows says ``Not attempted``.
    """
    nb = copy.deepcopy(nb)

    def stub(m: re.Match) -> str:
        names = _ANSWER_RE.findall(m.group(1))
        if not names:
            raise ValueError(f"a solution block assigns no answer (expected a line 'qN.answer = ...'):\n{m.group(1)}")
        q = names[-1]
        return f"# Your code here: compute the answer from {q}.inputs. Stuck? {q}.hint()\n{q}.answer = ...\n"

    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.source = _BLOCK_RE.sub(stub, cell.source)
            cell.outputs = []
            cell.execution_count = None
        cell.get("metadata", {}).pop("execution", None)
    return nb


_register(
    "01",
    "pinhole",
    "The pinhole camera and K",
    """
    The pinhole model in code: build the intrinsic matrix K from a field of view, project points
    with it, and use similar triangles to measure distance from a marker's apparent size.
    """,
    _lesson_01,
)
_register(
    "03",
    "extrinsics",
    "Extrinsics and transforms",
    """
    Poses as 4x4 homogeneous transforms: build one from roll, pitch and yaw, move points between
    frames, chain transforms so that their names match, and read solvePnP's rvec, tvec.
    """,
    _lesson_03,
)
_register(
    "04",
    "world_map",
    "Markers and the world map",
    """
    From a tape measure to corners: placements in feet, a map file in centimetres, a marker on the
    floor, and the winding order TL, TR, BR, BL that detection and the map must share.
    """,
    _lesson_04,
)
_register(
    "07",
    "inversion",
    "Inverting the extrinsics: where is the camera?",
    """
    solvePnP answers with the world seen from the camera (T_camera_world). Turn it around: the
    camera's position -R^T t, its pose T_world_camera, the direction it looks, and a pose from a
    single marker chained through the map.
    """,
    _lesson_07,
)


# ==================================================================================
# Lesson 02: calibration
# ==================================================================================
def _board_points(pattern: tuple[int, int], square_mm: float) -> np.ndarray:
    """Checkerboard inner corners (N, 3), mm, in the order cv2.findChessboardCorners reports them (rows of x)."""
    cols, rows = pattern
    jj, ii = np.mgrid[0:rows, 0:cols]
    return np.column_stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)]) * float(square_mm)


def _calibration_views(
    rng: np.random.Generator, camera: Camera, obj: np.ndarray, n_views: int, noise_px: float
) -> list:
    """Pixel corners (N, 2) of a board seen from n_views varied poses, with Gaussian noise."""
    centre = obj.mean(axis=0)
    extent = float(np.ptp(obj[:, 0]))
    views = []
    while len(views) < n_views:
        dist = extent * rng.uniform(1.6, 3.0)
        direction = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), -1.0])
        eye = centre + dist * direction / np.linalg.norm(direction)
        T = _look_at(eye, centre + [rng.uniform(-0.3, 0.3) * extent, rng.uniform(-0.2, 0.2) * extent, 0], up=(0, -1, 0))
        T = T @ frames.make_transform(frames.rot_z(math.radians(rng.uniform(-20, 20))))
        px = camera.project(obj, T)
        if np.all(camera.points_in_front(obj, T)) and np.all((px > 5) & (px < np.array(camera.image_size) - 6)):
            views.append(np.round(px + rng.normal(0, noise_px, px.shape), 3))
    return views


def _lesson_02(learner: str) -> list[Question]:
    qs = []
    # q1: the board's object points ---------------------------------------------------
    rng = _rng("02", learner, "q1")
    pattern = (int(rng.integers(6, 10)), int(rng.integers(4, 7)))
    square_in = float(rng.choice([0.75, 1.0, 1.25, 1.5]))
    obj = _board_points(pattern, square_in * 25.4)
    cols, rows = pattern
    col_major = np.array([[i, j, 0] for i in range(cols) for j in range(rows)], dtype=float) * square_in * 25.4
    qs.append(
        Question(
            "q1",
            "The board's object points",
            """
        Your checkerboard has `pattern_size` = (columns, rows) INNER corners and squares of
        `square_size_in` inches. Write code that builds its object points for cv2.calibrateCamera:
        an (N, 3) float array in mm, z = 0, the first corner at the origin, in the order
        cv2.findChessboardCorners reports corners: along a row first (x grows fastest), then the
        next row (y grows).
        """,
            {"pattern_size": pattern, "square_size_in": square_in},
            obj,
            _array(
                (cols * rows, 3),
                "the object points",
                {
                    (
                        (cols + 1) * (rows + 1),
                        3,
                    ): "that counts the squares' corners on the outer border too: pattern_size counts the INNER corners",
                    (cols * rows, 2): "add z = 0: object points are 3D",
                },
            ),
            _cmp_array(0.01, " mm"),
            wrong=[
                (
                    lambda a: _close(a * 25.4, obj, 0.01),
                    "the square size is in inches: multiply by 25.4 to get mm (your values are 25.4x too small)",
                ),
                (
                    lambda a: _close(a, col_major, 0.01),
                    "the order is column by column; findChessboardCorners goes along a row first: point k is at (k % columns, k // columns) * square",
                ),
                (
                    lambda a: _close(np.sort(a, axis=0), np.sort(obj, axis=0), 0.01),
                    "the points are right but in another order: along a row first (x fastest), then the next row",
                ),
            ],
            hint="np.mgrid[0:rows, 0:cols] gives row and column indices; x = column * square_mm, y = row * square_mm, z = 0.",
            solution="""
        cols, rows = q1.inputs.pattern_size
        square_mm = q1.inputs.square_size_in * 25.4
        obj = np.zeros((cols * rows, 3))
        obj[:, 0] = np.tile(np.arange(cols), rows) * square_mm     # x: along a row
        obj[:, 1] = np.repeat(np.arange(rows), cols) * square_mm   # y: row after row
        q1.answer = obj
        """,
            level="easy",
        )
    )

    # q2: calibrate ----------------------------------------------------------------------
    rng = _rng("02", learner, "q2")
    size = _SIZES[int(rng.integers(1, 3))]
    true_cam = Camera.from_fov(
        float(np.round(rng.uniform(55, 75))), size, dist=[float(np.round(rng.uniform(-0.15, 0.05), 3)), 0, 0, 0, 0]
    )
    K_true = true_cam.K.copy()
    K_true[0, 2] += float(np.round(rng.uniform(-12, 12), 1))
    K_true[1, 2] += float(np.round(rng.uniform(-8, 8), 1))
    true_cam = Camera(K_true, true_cam.dist, size)
    obj2 = _board_points((9, 6), 25.0)
    views = _calibration_views(rng, true_cam, obj2, 10, 0.15)
    _, K_key, _, _, _ = cv2.calibrateCamera(
        [obj2.astype(np.float32)] * len(views), [v.astype(np.float32) for v in views], size, None, None
    )
    # judged against the true camera, with what calibration on these corners can reach
    f_tol2 = max(0.01 * K_true[0, 0], 3 * abs(K_key[0, 0] - K_true[0, 0]))
    c_tol2 = max(3.0, 3 * float(np.abs(K_key[:2, 2] - K_true[:2, 2]).max()))

    def cmp_K(a, b):
        if (
            abs(a[0, 0] - b[0, 0]) <= f_tol2
            and abs(a[1, 1] - b[1, 1]) <= f_tol2
            and np.abs(a[:2, 2] - b[:2, 2]).max() <= c_tol2
            and abs(a[2, 2] - 1) < 1e-6
        ):
            return None
        return (
            f"your fx = {a[0, 0]:.1f}, cx = {a[0, 2]:.1f}, cy = {a[1, 2]:.1f} px are farther from the true camera than calibration "
            f"on these corners gets (fx within {f_tol2:.1f} px, cx, cy within {c_tol2:.1f} px)"
        )

    qs.append(
        Question(
            "q2",
            "Calibrate from corner detections",
            """
        A 9 x 6 checkerboard with 25 mm squares (its object points are in `object_points`, (54, 3)
        mm) was detected in 10 pictures of `image_size` (width, height); `image_points` holds the
        10 arrays of (54, 2) pixel corners. Write code that calibrates the camera with
        cv2.calibrateCamera and gives its intrinsic matrix K (3, 3).
        """,
            {"object_points": obj2, "image_points": views, "image_size": size},
            K_true,
            _array(
                (3, 3),
                "K",
                {
                    (5,): "that is the distortion vector; K is the 3x3 matrix calibrateCamera returns second",
                    (1, 5): "that is the distortion vector; K is the 3x3 matrix calibrateCamera returns second",
                    (): "that is the RMS error; K is the 3x3 matrix calibrateCamera returns second",
                },
            ),
            cmp_K,
            wrong=[
                (lambda a: cmp_K(a.T, K_true) is None, "your K is transposed: cx and cy belong in the last column"),
            ],
            hint="cv2.calibrateCamera wants a list of object-point arrays (one per view, float32) and a list of image-point arrays; it returns rms, K, dist, rvecs, tvecs.",
            solution="""
        obj = q2.inputs.object_points.astype(np.float32)
        imgs = [p.astype(np.float32) for p in q2.inputs.image_points]
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(imgs), imgs, q2.inputs.image_size, None, None)
        q2.answer = K
        """,
            level="medium",
        )
    )

    # q3: the view from another resolution --------------------------------------------------
    rng = _rng("02", learner, "q3")
    size3 = (1280, 720)
    cam3 = Camera.from_fov(float(np.round(rng.uniform(60, 75))), size3)
    obj3 = _board_points((9, 6), 25.0)
    views3 = _calibration_views(rng, cam3, obj3, 9, 0.15)
    small = cam3.scaled((640, 360))
    odd = int(rng.integers(1, 9))
    objs3 = [obj3.astype(np.float32)] * len(views3)
    for _ in range(30):
        # a board seen squarely at half resolution looks like one twice as far away: draw the odd
        # view again until the per-view errors single it out clearly (3x the next worst view)
        views3[odd] = np.round(_calibration_views(rng, small, obj3, 1, 0.1)[0], 3)
        _, K3, d3, rv3, tv3 = cv2.calibrateCamera(objs3, [v.astype(np.float32) for v in views3], size3, None, None)
        per_view = [
            float(
                np.sqrt(np.mean(np.sum((cv2.projectPoints(objs3[0], r, t, K3, d3)[0].reshape(-1, 2) - v) ** 2, axis=1)))
            )
            for v, r, t in zip(views3, rv3, tv3)
        ]
        if int(np.argmax(per_view)) == odd and per_view[odd] >= 3 * sorted(per_view)[-2]:
            break
    qs.append(
        Question(
            "q3",
            "Find the picture that does not belong",
            """
        Your class pooled its checkerboard pictures; one of the 9 views in
        `image_points` was taken at another resolution (the phone's video mode), so its corners do
        not fit the same K. Write code that calibrates on all views and finds the bad one from
        the per-view reprojection RMS (the view whose reprojected corners are farthest from its
        detected corners). Answer the view's index in the list (0-based).
        """,
            {"object_points": obj3, "image_points": views3, "image_size": size3},
            odd,
            lambda a: int(_scalar("the index")(a)),
            lambda a, b: None if a == b else f"view {a} is not the one that stands out",
            wrong=[
                (lambda a: a == odd + 1, "Python counts from 0: the first view has index 0"),
            ],
            hint="cv2.calibrateCamera returns rvecs and tvecs per view; cv2.projectPoints(object_points, rvecs[i], tvecs[i], K, dist) reprojects view i; compare with image_points[i] (RMS of the distances). cv2.calibrateCameraExtended also returns perViewErrors.",
            solution="""
        obj = q3.inputs.object_points.astype(np.float32)
        imgs = [p.astype(np.float32) for p in q3.inputs.image_points]
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(imgs), imgs, q3.inputs.image_size, None, None)
        per_view = []
        for img, rvec, tvec in zip(imgs, rvecs, tvecs):
            proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
            per_view.append(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
        q3.answer = int(np.argmax(per_view))
        """,
            level="medium",
        )
    )

    # q4: K at another resolution --------------------------------------------------------------
    rng = _rng("02", learner, "q4")
    big = _SIZES[int(rng.integers(2, 4))]
    new = [
        (w, h)
        for w, h in (
            (big[0] // 2, big[1] // 2),
            (big[0] // 4, big[1] // 4),
            (1280, 720),
            (640, 360),
            (big[0] * 2, big[1] * 2),
        )
        if (w, h) != big
    ]
    new = new[int(rng.integers(len(new)))]
    cam4 = Camera.from_fov(float(np.round(rng.uniform(55, 80))), big)
    K4 = cam4.K.copy()
    K4[0, 2] += float(np.round(rng.uniform(-20, 20), 1))
    K4[1, 2] += float(np.round(rng.uniform(-15, 15), 1))
    K4new = Camera(K4, None, big).scaled(new).K
    s = new[0] / big[0]
    qs.append(
        Question(
            "q4",
            "K at another resolution",
            """
        The camera was calibrated at `calibrated_size` (width, height) with intrinsic matrix `K`;
        you now run it at `new_size` (same aspect ratio, the whole sensor resized). Write code that
        computes K at the new size. With pixel centres at integer coordinates a position scales as
        c' = (c + 0.5) * s - 0.5.
        """,
            {"K": K4, "calibrated_size": big, "new_size": new},
            K4new,
            _array((3, 3), "K"),
            lambda a, b: (
                None
                if (
                    np.abs(a[[0, 1], [0, 1]] - b[[0, 1], [0, 1]]).max() <= 0.01
                    and np.abs(a[:2, 2] - b[:2, 2]).max() <= 0.51
                    and np.abs(a[2] - [0, 0, 1]).max() < 1e-9
                )
                else _cmp_array(0.01, " px")(a, b)
            ),
            wrong=[
                (
                    lambda a: abs(a[0, 0] - K4[0, 0]) < 0.01,
                    "the focal length is in pixels, so it scales with the image: fx' = fx * new_width / old_width",
                ),
                (
                    lambda a: abs(a[0, 0] - K4[0, 0] / s) < 0.01,
                    "the scale is upside down: s = new_width / old_width (a smaller image has a smaller fx, in pixels)",
                ),
                (
                    lambda a: abs(a[0, 0] - K4new[0, 0]) < 0.01 and abs(a[0, 2] - K4[0, 2]) < 0.01,
                    "the principal point moves too: cx and cy scale like fx (in pixels)",
                ),
                (lambda a: _close(a, K4new.T, 0.51), "your K is transposed: cx and cy belong in the last column"),
            ],
            notes=[
                (
                    lambda a: np.abs(a[:2, 2] - K4new[:2, 2]).max() > 0.1,
                    "K is right to within half a pixel; with pixel centres at integer coordinates c' = (c + 0.5) * s - 0.5 is exact",
                )
            ],
            hint="Every entry measured in pixels scales by s = new_width / old_width: fx, fy, cx, cy (cx, cy with the half-pixel shift).",
            solution="""
        sx = q4.inputs.new_size[0] / q4.inputs.calibrated_size[0]
        sy = q4.inputs.new_size[1] / q4.inputs.calibrated_size[1]
        K = np.array(q4.inputs.K, dtype=float)
        K_new = K.copy()
        K_new[0, 0] = K[0, 0] * sx
        K_new[1, 1] = K[1, 1] * sy
        K_new[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K_new[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        q4.answer = K_new
        """,
            level="easy",
        )
    )

    # q5: calibrate from pictures ----------------------------------------------------------------
    from . import synthetic
    from .calibration import calibrate_checkerboard

    rng = _rng("02", learner, "q5")
    f5 = float(np.round(rng.uniform(260, 340)))
    cam5 = Camera(
        [
            [f5, 0, 159.5 + float(np.round(rng.uniform(-4, 4), 1))],
            [0, f5, 119.5 + float(np.round(rng.uniform(-3, 3), 1))],
            [0, 0, 1],
        ],
        [float(np.round(rng.uniform(-0.15, 0.0), 3)), 0, 0, 0, 0],
        (320, 240),
    )
    square5 = float(rng.choice([20, 25, 30]))
    views5 = synthetic.render_calibration_views(
        cam5, n_views=6, pattern_size=(7, 5), square_size_mm=square5, seed=int(rng.integers(1 << 20)), supersample=2
    )
    key5 = calibrate_checkerboard(views5.images, (7, 5), square5).camera.K
    f_tol = max(0.015 * f5, 3 * abs(key5[0, 0] - f5))
    c_tol = max(4.0, 3 * float(np.abs(key5[:2, 2] - cam5.K[:2, 2]).max()))

    def cmp5(a, b):
        if (
            abs(a[0, 0] - b[0, 0]) <= f_tol
            and abs(a[1, 1] - b[1, 1]) <= f_tol
            and np.abs(a[:2, 2] - b[:2, 2]).max() <= c_tol
            and abs(a[2, 2] - 1) < 1e-6
        ):
            return None
        return f"your fx = {a[0, 0]:.1f} px, cx = {a[0, 2]:.1f}, cy = {a[1, 2]:.1f} are farther from the true camera than calibration on these pictures gets (fx within {f_tol:.1f} px, cx, cy within {c_tol:.1f} px)"

    qs.append(
        Question(
            "q5",
            "Calibrate from pictures",
            """
        `images` are 6 gray photos (320 x 240) of a printed checkerboard with `pattern_size` =
        (columns, rows) INNER corners and squares of `square_size_mm`. Write code that calibrates the
        camera from the pictures (fidlearn.calibration.calibrate_checkerboard, or
        cv2.findChessboardCorners + cv2.calibrateCamera) and gives K (3, 3).
        """,
            {"images": [im.copy() for im in views5.images], "pattern_size": (7, 5), "square_size_mm": square5},
            cam5.K,
            _array(
                (3, 3),
                "K",
                {(5,): "that is the distortion vector; give K", (1, 5): "that is the distortion vector; give K"},
            ),
            cmp5,
            wrong=[
                (lambda a: cmp5(a.T, cam5.K) is None, "your K is transposed: cx and cy belong in the last column"),
            ],
            hint="calibration = fidlearn.calibration.calibrate_checkerboard(images, pattern_size, square_size_mm); calibration.camera.K. pattern_size counts INNER corners: a board of 8 x 6 squares has 7 x 5.",
            solution="""
        from fidlearn.calibration import calibrate_checkerboard
        calibration = calibrate_checkerboard(q5.inputs.images, q5.inputs.pattern_size, q5.inputs.square_size_mm)
        print(f"RMS {calibration.rms_px:.3f} px over {len(calibration.used)} views")
        q5.answer = calibration.camera.K
        """,
            level="medium",
        )
    )
    return qs


_register(
    "02",
    "calibration",
    "Calibration",
    """
    From checkerboard corners to K: build the board's object points, run cv2.calibrateCamera, find
    the picture that does not belong, and carry K to another resolution.
    """,
    _lesson_02,
)


# ==================================================================================
# Lesson 06: PnP over several markers
# ==================================================================================
def _wall_map(
    rng: np.random.Generator, n: int, size_mm: float, first_id: int = 0, spread_mm: float = 900.0
) -> MarkerMap:
    """n markers on the north wall (x = 0, facing +X), top-left corners on a loose grid, mm."""
    ids = first_id + np.sort(rng.choice(40, size=n, replace=False))
    placements = {}
    k = 0
    while len(placements) < n:
        y = float(np.round(rng.uniform(-spread_mm, spread_mm), -1))
        z = float(np.round(rng.uniform(700, 1700), -1))
        tl = np.array([0.0, y, z])
        if all(np.abs(np.asarray(p.translation_mm) - tl)[1:].max() > 2 * size_mm for p in placements.values()):
            mid = int(ids[k])
            placements[mid] = MarkerPlacement(mid, (0.0, y, z), (0.0, 0.0, 0.0))
            k += 1
    return MarkerMap(placements, size_mm, "ARUCO_ORIGINAL", "mm")


def _noisy_detections(
    rng: np.random.Generator, camera: Camera, marker_map: MarkerMap, T_world_camera: np.ndarray, noise_px: float
) -> list:
    dets = []
    for mid in marker_map.ids:
        px = camera.project(marker_map.marker_corners(mid), T_world_camera)
        dets.append(Detection(mid, np.round(px + rng.normal(0, noise_px, px.shape), 3)))
    return dets


def _same_rows(a: np.ndarray, b: np.ndarray, tol: float = 0.01) -> bool:
    """Whether the rows of a and b are the same set (any order, each within tol), float32 answers included."""
    if a.shape != b.shape:
        return False
    free = list(range(len(b)))
    for row in a:
        hit = next((k for k in free if np.abs(b[k] - row).max() <= tol), None)
        if hit is None:
            return False
        free.remove(hit)
    return True


def _lesson_06(learner: str) -> list[Question]:
    qs = []
    # q1: correspondences ---------------------------------------------------------------
    rng = _rng("06", learner, "q1")
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    m = _wall_map(rng, 4, float(rng.choice([100, 120, 150])))
    T = _look_at(np.round(rng.uniform([1800, -500, 1000], [3000, 500, 1500])), [0, 0, 1200])
    dets = _noisy_detections(rng, cam, m, T, 0.2)
    stray_id = int(max(m.ids) + 1 + rng.integers(0, 5))
    stray = Detection(stray_id, np.round(dets[0].corners + [[-300, 150]], 3))
    detections = sorted(dets + [stray], key=lambda d: d.corners[0, 0])
    obj = np.concatenate([m.marker_corners(d.id) for d in detections if d.id in m])
    img = np.concatenate([d.corners for d in detections if d.id in m])
    key_pairs = np.column_stack([obj, img])

    def parse_pairs(answer):
        if not isinstance(answer, (tuple, list)) or len(answer) != 2:
            raise _AnswerError("give a pair (object_points (N, 3), image_points (N, 2))")
        o = _array((-1, 3), "object_points", {(len(obj), 2): "object points are 3D world corners (x, y, z), mm"})(
            answer[0]
        )
        i = _array((-1, 2), "image_points")(answer[1])
        if len(o) != len(i):
            raise _AnswerError(f"{len(o)} object points but {len(i)} image points: every world corner needs its pixel")
        return o, i

    def cmp_pairs(a, _):
        o, i = a
        if _same_rows(np.column_stack([o, i]), key_pairs):
            return None
        if len(o) == len(obj) + 4:
            return f"you have {len(o) // 4} markers; marker {stray_id} was detected but is not in the map: skip ids the map does not know"
        if len(o) != len(obj):
            return f"you have {len(o)} correspondences; the {len(obj) // 4} mapped markers give {len(obj)} (4 corners each)"
        if _same_rows(o, obj):
            return "each world corner must sit next to ITS pixel: detection i's corners (TL, TR, BR, BL) go with marker_corners(detection i's id), in the same order"
        return "these are not the map's corners of the detected markers"

    qs.append(
        Question(
            "q1",
            "2D-3D correspondences",
            """
        `detections` lists detected markers (fidlearn Detection: `.id`, `.corners` (4, 2) px,
        TL, TR, BR, BL); one of them is not in the map. `marker_map` gives world corners
        (marker_map.marker_corners(id), (4, 3) mm, same order). Write code that builds the
        arrays solvePnP needs: object_points (N, 3) mm and image_points (N, 2) px, row k of one
        matching row k of the other. Answer (object_points, image_points).
        """,
            {"detections": detections, "marker_map": m, "camera": cam},
            (obj, img),
            parse_pairs,
            cmp_pairs,
            hint="Loop over the detections, skip an id that is not in marker_map (`d.id in marker_map`), and stack marker_map.marker_corners(d.id) and d.corners.",
            solution="""
        m = q1.inputs.marker_map
        known = [d for d in q1.inputs.detections if d.id in m]
        object_points = np.concatenate([m.marker_corners(d.id) for d in known])
        image_points = np.concatenate([d.corners for d in known])
        q1.answer = (object_points, image_points)
        """,
            level="easy",
        )
    )

    # q2: solvePnP ------------------------------------------------------------------------
    rng = _rng("06", learner, "q2")
    cam2 = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    m2 = _wall_map(rng, 5, 150.0)
    T2 = _look_at(
        np.round(rng.uniform([1500, -700, 900], [3000, 700, 1600])), [0, float(np.round(rng.uniform(-200, 200))), 1200]
    )
    dets2 = _noisy_detections(rng, cam2, m2, T2, 0.3)
    obj2 = np.concatenate([m2.marker_corners(d.id) for d in dets2])
    img2 = np.concatenate([d.corners for d in dets2])
    ok, rv, tv = cv2.solvePnP(obj2, img2, cam2.K, cam2.dist, flags=_cv.solvepnp_flag("ITERATIVE"))
    Tcw_key = frames.transform_from_rvec_tvec(rv.ravel(), tv.ravel())
    ok, rv_e, tv_e = cv2.solvePnP(obj2, img2, cam2.K, cam2.dist, flags=_cv.solvepnp_flag("EPNP"))
    Tcw_epnp = frames.transform_from_rvec_tvec(rv_e.ravel(), tv_e.ravel())

    def parse_rt(answer):
        if isinstance(answer, np.ndarray) and answer.shape == (4, 4):
            raise _AnswerError("give (rvec, tvec) as solvePnP returns them, not a 4x4 matrix")
        if not isinstance(answer, (tuple, list)) or len(answer) not in (2, 3):
            raise _AnswerError("give the pair (rvec, tvec) that cv2.solvePnP returns")
        if len(answer) == 3:
            answer = answer[1:]  # (ok, rvec, tvec) straight from solvePnP
        r = _array(
            (3,), "rvec", {(3, 3): "that is a rotation matrix: give the Rodrigues vector (cv2.Rodrigues(R)[0])"}
        )(answer[0])
        t = _array((3,), "tvec")(answer[1])
        return frames.transform_from_rvec_tvec(r, t)

    qs.append(
        Question(
            "q2",
            "solvePnP over every marker",
            """
        The camera `camera` (K, dist) saw the 5 markers of `marker_map`; their detections are in
        `detections`. Write code that estimates the camera's extrinsics with cv2.solvePnP using
        the corners of ALL markers at once. Answer (rvec, tvec) as solvePnP returns them.
        """,
            {"detections": dets2, "marker_map": m2, "camera": cam2},
            Tcw_key,
            parse_rt,
            _cmp_transform(0.5, 15.0),
            wrong=[
                (
                    _T_is(frames.invert_transform(Tcw_key), 0.5, 15),
                    "that is the camera's pose (T_world_camera); solvePnP's rvec, tvec are T_camera_world: give them as they are",
                ),
                (
                    _T_is(Tcw_epnp, 0.05, 1.0),
                    "EPnP is unreliable when all the points lie on one plane (the markers are all on one wall): use the default SOLVEPNP_ITERATIVE, IPPE or SQPNP",
                ),
                (
                    lambda a: (
                        frames.rotation_angle_deg(a[:3, :3], Tcw_key[:3, :3]) < 3
                        and np.linalg.norm(a[:3, 3] - Tcw_key[:3, 3]) < 150
                    ),
                    "close, but not the least-squares pose: use all 5 markers (20 corners) and the camera's distortion, and if you chose SOLVEPNP_IPPE, refine with cv2.solvePnPRefineLM (the default SOLVEPNP_ITERATIVE does)",
                ),
            ],
            hint="Build object_points and image_points over all detections (as in q1), then ok, rvec, tvec = cv2.solvePnP(object_points, image_points, camera.K, camera.dist).",
            solution="""
        m, cam = q2.inputs.marker_map, q2.inputs.camera
        known = [d for d in q2.inputs.detections if d.id in m]
        object_points = np.concatenate([m.marker_corners(d.id) for d in known])
        image_points = np.concatenate([d.corners for d in known])
        ok, rvec, tvec = cv2.solvePnP(object_points, image_points, cam.K, cam.dist)
        q2.answer = (rvec, tvec)
        """,
            level="medium",
        )
    )

    # q3: reprojection RMS ----------------------------------------------------------------
    rng = _rng("06", learner, "q3")
    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    m3 = _wall_map(rng, 4, 120.0)
    T3 = _look_at(np.round(rng.uniform([1500, -700, 900], [3000, 700, 1600])), [0, 0, 1200])
    dets3 = _noisy_detections(rng, cam3, m3, T3, float(np.round(rng.uniform(0.3, 1.0), 2)))
    obj3 = np.concatenate([m3.marker_corners(d.id) for d in dets3])
    img3 = np.concatenate([d.corners for d in dets3])
    ok, rv3, tv3 = cv2.solvePnP(obj3, img3, cam3.K, cam3.dist)
    rv3, tv3 = np.round(rv3.ravel(), 6), np.round(tv3.ravel(), 3)
    proj = cv2.projectPoints(obj3, rv3, tv3, cam3.K, cam3.dist)[0].reshape(-1, 2)
    d = np.linalg.norm(proj - img3, axis=1)
    rms = float(np.sqrt(np.mean(d**2)))
    qs.append(
        Question(
            "q3",
            "Reprojection error",
            """
        solvePnP on `object_points` (N, 3) mm and `image_points` (N, 2) px gave `rvec`, `tvec`.
        Write code that reprojects the object points with that pose and the camera (K, dist) and
        computes the RMS reprojection error in pixels: the square root of the mean of the SQUARED
        distances between reprojected and detected corners.
        """,
            {"object_points": obj3, "image_points": img3, "rvec": rv3, "tvec": tv3, "camera": cam3},
            rms,
            _scalar("the RMS error"),
            _cmp_scalar(1e-3, " px", rtol=1e-3),
            wrong=[
                (
                    lambda a: abs(a - d.mean()) < 1e-3,
                    "that is the mean distance; RMS is the square ROOT of the MEAN of the SQUARED distances",
                ),
                (
                    lambda a: abs(a - rms / math.sqrt(2)) < 1e-3,
                    "that averages over the 2N coordinates; average the squared DISTANCES over the N points (dx^2 + dy^2 per point)",
                ),
                (lambda a: abs(a - rms**2) < 1e-3, "that is the mean squared error; take its square root"),
                (
                    lambda a: abs(a - float(np.sqrt(np.sum(d**2)))) < 1e-3,
                    "divide by the number of points before the square root (the MEAN of the squares)",
                ),
                (
                    lambda a: a > 20,
                    "that is far too large: did you project with the right pose (rvec, tvec are T_camera_world, as cv2.projectPoints wants) and the camera's K and dist?",
                ),
            ],
            hint="proj, _ = cv2.projectPoints(object_points, rvec, tvec, K, dist); proj.reshape(-1, 2) - image_points gives the residuals; RMS = sqrt(mean(dx^2 + dy^2)).",
            solution="""
        cam = q3.inputs.camera
        proj, _ = cv2.projectPoints(q3.inputs.object_points, q3.inputs.rvec, q3.inputs.tvec, cam.K, cam.dist)
        residuals = proj.reshape(-1, 2) - q3.inputs.image_points
        q3.answer = np.sqrt(np.mean(np.sum(residuals ** 2, axis=1)))
        """,
            level="easy",
        )
    )
    return qs


_register(
    "06",
    "pnp",
    "PnP: the pose from several markers",
    """
    Solve for the camera's extrinsics with every marker at once: pair world corners with pixels,
    run cv2.solvePnP, and measure how well the pose explains the corners (reprojection error).
    """,
    _lesson_06,
)


# ==================================================================================
# Lesson 05: detection
# ==================================================================================
def _scene(lesson_id: str, learner: str, question: str, n_markers: int, rotated: bool, dictionaries: Sequence[str]):
    """A seeded scene: (camera, marker_map, T_world_camera, image, truth, rotated_id, dictionary)."""
    from . import synthetic

    rng = _rng(lesson_id, learner, question)
    dictionary = str(rng.choice(list(dictionaries)))
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 70))), (800, 600))
    size = 120.0
    ids = [int(i) for i in np.sort(rng.choice(40, size=n_markers, replace=False))]
    ys = np.linspace(-600, 600, n_markers) + rng.uniform(-60, 60, n_markers)
    placements = {}
    rotated_id = int(rng.choice(ids)) if rotated else None
    for k, (mid, y) in enumerate(zip(ids, ys)):
        z = 1150.0 + (180.0 if k % 2 else -120.0) + float(rng.uniform(-40, 40))
        roll = float(rng.choice([90, 180, -90])) if mid == rotated_id else 0.0
        # a marker rotated about its top-left corner: shift it so that it stays where it was meant to be
        tl = np.array([0.0, np.round(y), np.round(z)])
        R = frames.rotation_from_rpy_deg(roll, 0, 0)
        centre_offset = R @ np.array([0.0, size / 2, -size / 2]) - np.array([0.0, size / 2, -size / 2])
        tl = tl - centre_offset
        placements[mid] = MarkerPlacement(mid, tuple(float(v) for v in tl), (roll, 0.0, 0.0))
    m = MarkerMap(placements, size, dictionary, "mm")
    eye = np.round(rng.uniform([1700, -300, 1000], [2300, 300, 1400]))
    T = synthetic.look_at(eye, [0.0, float(np.round(rng.uniform(-100, 100))), 1150.0])
    image, truth = synthetic.render_scene(
        cam, m, T, seed=int(rng.integers(1 << 30)), blur_px=0.6, noise_std=2.0, gradient=0.15
    )
    return cam, m, T, image, truth, rotated_id, dictionary


def _lesson_05(learner: str) -> list[Question]:
    qs = []
    cam, m, T, image, truth, rot_id, dictionary = _scene(
        "05", learner, "scene", 5, True, ["ARUCO_ORIGINAL", "4X4_50", "6X6_250"]
    )
    ids = sorted(truth)

    def parse_ids(answer):
        if isinstance(answer, (str, bytes)) or not hasattr(answer, "__iter__"):
            raise _AnswerError("give a list of marker ids (integers)")
        out = []
        for v in answer:
            v = getattr(v, "id", v)  # Detection objects are fine too
            try:
                out.append(int(np.asarray(v).reshape(-1)[0]))
            except (TypeError, ValueError, IndexError):
                raise _AnswerError(f"{v!r} is not a marker id") from None
        return sorted(out)

    def cmp_ids(a, b):
        if sorted(set(a)) == b:
            return None if len(a) == len(b) else "each id once, please"
        if not a:
            return None if not b else "no ids"
        missing = sorted(set(b) - set(a))
        extra = sorted(set(a) - set(b))
        if extra:
            return f"ids {extra} are not in the picture"
        return f"you found {len(b) - len(missing)} of the {len(b)} markers; look again (the whole image, the right dictionary)"

    qs.append(
        Question(
            "q1",
            "Which markers are in the picture?",
            """
        `image` is a gray picture (H, W) of a wall with markers from the dictionary `dictionary`.
        Write code that detects them (fidlearn.detection.detect_markers, or OpenCV's
        cv2.aruco.ArucoDetector) and gives the sorted list of their ids.
        """,
            {"image": image.copy(), "dictionary": dictionary},
            ids,
            parse_ids,
            cmp_ids,
            wrong=[
                (
                    lambda a: len(a) == 0,
                    f"nothing was found: a detector only sees markers of its own dictionary; this picture uses {dictionary!r} (pass dictionary=q1.inputs.dictionary)",
                ),
            ],
            hint="from fidlearn.detection import detect_markers; detections = detect_markers(image, dictionary=...); each has .id and .corners.",
            look='from fidlearn import plotting\nplotting.show_image(None, q1.inputs.image, title="q1.inputs.image");',
            solution="""
        from fidlearn.detection import detect_markers
        detections = detect_markers(q1.inputs.image, dictionary=q1.inputs.dictionary)
        q1.answer = sorted(d.id for d in detections)
        """,
            level="easy",
        )
    )

    C = truth[rot_id]

    def winding(a):
        order = _corner_order(a, C, 1.5)
        return order is not None and order != ("TL", "TR", "BR", "BL")

    image_sorted = C[np.lexsort((C[:, 0], C[:, 1]))]
    qs.append(
        Question(
            "q2",
            "The corners of a turned marker, in order",
            """
        Marker `marker_id` hangs turned on the wall, so its own top-left corner is not the
        top-left of the picture. Write code that finds its four corners in `image` (dictionary
        `dictionary`) and gives them as a (4, 2) array of (x, y) pixels in the marker's own order
        TL, TR, BR, BL: the order the map uses and detection reports.
        """,
            {"image": image.copy(), "dictionary": dictionary, "marker_id": rot_id},
            C,
            _array((4, 2), "the corners", {(2, 4): "one ROW per corner: transpose it", (1, 4, 2): ""}),
            _cmp_array(1.5, " px"),  # OpenCV's unrefined corners are within about a pixel
            wrong=[
                (winding, lambda a: _winding_message(_corner_order(a, C, 1.5))),
                (lambda a: _close(a[:, ::-1], C, 1.0), "x and y are swapped: a pixel is (x, y) = (column, row)"),
                (
                    lambda a: _close(a, image_sorted, 1.0),
                    "you sorted the corners by their place in the picture; keep the order detection gives: the marker's own TL, TR, BR, BL",
                ),
            ],
            hint="Keep the corners exactly as the detector returns them for that id: d.corners for the Detection with d.id == marker_id.",
            solution="""
        from fidlearn.detection import detect_markers
        detections = detect_markers(q2.inputs.image, dictionary=q2.inputs.dictionary)
        q2.answer = next(d.corners for d in detections if d.id == q2.inputs.marker_id)
        """,
            level="medium",
        )
    )

    angle = math.degrees(math.atan2(C[1, 1] - C[0, 1], C[1, 0] - C[0, 0]))

    def ang_diff(a, b):
        d = (a - b + 180) % 360 - 180
        return None if abs(d) <= 3 else f"your angle is {d:+.3g} deg from the key's"

    qs.append(
        Question(
            "q3",
            "How is the marker turned?",
            """
        From the detected corners of marker `marker_id`, write code that computes the direction of
        its top edge (from its TL to its TR) in the picture, in degrees, as atan2(dy, dx) with the
        image's axes (x right, y DOWN): 0 means upright, 90 means turned a quarter turn clockwise
        as you look at the picture.
        """,
            {"image": image.copy(), "dictionary": dictionary, "marker_id": rot_id},
            angle,
            _scalar("the angle"),
            ang_diff,
            wrong=[
                (lambda a: ang_diff(math.degrees(a), angle) is None, "that is in radians: give degrees (np.degrees)"),
                (
                    lambda a: ang_diff(-a, angle) is None,
                    "the sign is flipped: image y grows DOWNward, so use atan2(y_TR - y_TL, x_TR - x_TL) as it is",
                ),
                (
                    lambda a: ang_diff(a, math.degrees(math.atan2(C[1, 0] - C[0, 0], C[1, 1] - C[0, 1]))) is None,
                    "atan2 takes (dy, dx): y first",
                ),
                (
                    lambda a: (
                        ang_diff(a + 90, angle) is None
                        or ang_diff(a - 90, angle) is None
                        or ang_diff(a + 180, angle) is None
                    ),
                    "that is the direction of another edge: use the TOP edge, TL (corner 0) to TR (corner 1)",
                ),
            ],
            hint="c = the detection's corners; dx, dy = c[1] - c[0]; np.degrees(np.arctan2(dy, dx)).",
            solution="""
        from fidlearn.detection import detect_markers
        detections = detect_markers(q3.inputs.image, dictionary=q3.inputs.dictionary)
        c = next(d.corners for d in detections if d.id == q3.inputs.marker_id)
        dx, dy = c[1] - c[0]
        q3.answer = np.degrees(np.arctan2(dy, dx))
        """,
            level="medium",
        )
    )
    return qs


_register(
    "05",
    "detection",
    "Detecting markers",
    """
    Find markers in a rendered picture: the right dictionary, the ids, the corners in the marker's
    own winding order TL, TR, BR, BL, and how a turned marker shows in the image.
    """,
    _lesson_05,
)


# ==================================================================================
# Lesson 08: accuracy and pitfalls
# ==================================================================================
_AMBIGUITY_CHOICES = [
    (
        "flip",
        "A small flat marker seen nearly face-on from far away: two mirror-image tilts project its "
        "corners to almost the same pixels, and the corner noise cannot tell them apart.",
    ),
    ("id", "The marker's id was decoded wrongly, so the map gave the corners of another marker."),
    ("distortion", "The lens distortion was not calibrated, so the corners are in the wrong places."),
    ("too_few", "solvePnP needs at least 6 points; the 4 corners of one marker are too few for a pose."),
]
_AMBIGUITY_WRONG = {
    "id": "a wrong id would give one bad pose with a large reprojection error, not two poses that both fit the corners",
    "distortion": "the corners here are projected with the camera's own model; both candidates fit them to a fraction of a pixel",
    "too_few": "4 coplanar points are enough: IPPE (SOLVEPNP_IPPE_SQUARE) solves a square marker from its 4 corners; the trouble is that it finds TWO solutions",
}


def _lesson_08(learner: str) -> list[Question]:
    from . import pose as _pose
    from . import synthetic
    from .detection import detect_markers

    qs = []
    # q1: depth error versus distance -----------------------------------------------------
    rng = _rng("08", learner, "q1")
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 75))), (1280, 720))
    size = float(np.round(rng.uniform(60, 200), -1) + 5 * rng.integers(0, 2))
    dists = np.array([500.0, 1000.0, 2000.0, 4000.0, 8000.0])
    err_px = float(rng.choice([0.2, 0.25, 0.3, 0.4, 0.5, 0.75, 1.0]))
    dZ = dists**2 * err_px / (cam.fx * size)
    qs.append(
        Question(
            "q1",
            "Error grows with distance",
            """
        A marker of side `marker_size_mm` faces the camera squarely at each distance in
        `distances_mm`; the camera's focal length is `camera.fx` px. Distance from apparent size is
        Z = fx * s / w (w the side in pixels). If w is measured `side_error_px` pixels too large,
        how far off is Z? Write code that gives the size of the depth error (mm, positive) at
        each distance, an array like `distances_mm`, to first order (dZ = |dZ/dw| * side_error_px).
        How does it grow when the distance doubles?
        """,
            {"camera": cam, "marker_size_mm": size, "distances_mm": dists, "side_error_px": err_px},
            dZ,
            _array((len(dists),), "the depth errors"),
            _cmp_array(0.0, " mm", rtol=0.01),
            wrong=[
                (
                    lambda a: _close(a, dists * err_px / cam.fx, 0, 0.01),
                    "that is the SIDEWAYS error of one pixel (Z / fx per px); the depth error from the apparent size grows with Z squared: |dZ/dw| = fx * s / w^2 = Z^2 / (fx * s)",
                ),
                (
                    lambda a: _close(a, dists * err_px / size, 0, 0.01),
                    "your error grows linearly with distance; differentiate Z = fx * s / w with respect to w: |dZ/dw| = Z^2 / (fx * s)",
                ),
                (lambda a: _close(a * 1000, dZ, 0, 0.01), "that is in metres: the answer is asked in mm"),
                (lambda a: _close(-a, dZ, 0, 0.01), "give the size of the error (positive)"),
            ],
            hint="w = fx * s / Z, so dZ/dw = -fx * s / w^2 = -Z^2 / (fx * s). Multiply by side_error_px.",
            solution="""
        Z = np.asarray(q1.inputs.distances_mm, dtype=float)
        q1.answer = Z ** 2 / (q1.inputs.camera.fx * q1.inputs.marker_size_mm) * q1.inputs.side_error_px
        """,
            level="easy",
        )
    )

    # q2: a misplaced marker ---------------------------------------------------------------
    rng = _rng("08", learner, "q2")
    cam2 = Camera.from_fov(float(np.round(rng.uniform(55, 65))), (960, 720))
    true_map = _wall_map(rng, 5, 150.0, spread_mm=700.0)
    eye = np.round(rng.uniform([1800, -400, 1000], [2600, 400, 1400]))
    T2 = synthetic.look_at(eye, [0.0, 0.0, 1250.0])
    image, truth = synthetic.render_scene(
        cam2, true_map, T2, seed=int(rng.integers(1 << 30)), blur_px=0.5, noise_std=1.5
    )
    bad = int(rng.choice(sorted(truth)))
    shift = rng.choice([-1, 1]) * float(rng.uniform(80, 140))
    placements = dict(true_map.placements)
    p = placements[bad]
    placements[bad] = MarkerPlacement(
        bad, (p.translation_mm[0], p.translation_mm[1] + round(shift), p.translation_mm[2]), p.rotation_deg
    )
    wrong_map = MarkerMap(placements, true_map.marker_size_mm, true_map.dictionary, "mm")
    dets = detect_markers(image, true_map.dictionary)
    all_pos = _pose.estimate_pose(dets, wrong_map, cam2, reject_outliers=False).position_mm
    good_pos = _pose.estimate_pose([d for d in dets if d.id != bad], wrong_map, cam2).position_mm
    tol = max(25.0, 2 * float(np.linalg.norm(good_pos - T2[:3, 3])))
    true_pos = T2[:3, 3]

    def cmp2(a, _):
        if a["misplaced_id"] != bad:
            return f"marker {a['misplaced_id']} agrees with the others; leave each marker out in turn and see which one the others do not explain"
        err = float(np.linalg.norm(a["position_mm"] - true_pos))
        if err > tol:
            return f"the right marker, but your position is {err:.0f} mm from the truth (tolerance {tol:.0f} mm)"
        return None

    qs.append(
        Question(
            "q2",
            "Localize despite a misplaced marker",
            """
        Someone moved one marker after the map was measured: `marker_map` still has the old
        position. Write code that detects the markers in `image` (the map's dictionary), finds the
        marker the others disagree with (leave each marker out in turn: without the misplaced one
        the rest fit each other to a fraction of a pixel; fidlearn.pose.estimate_pose can also do
        it for you, read its result), and
        localizes the camera without it. Answer {"misplaced_id": id, "position_mm": (3,) world mm}.
        """,
            {"image": image.copy(), "marker_map": wrong_map, "camera": cam2},
            {"misplaced_id": bad, "position_mm": true_pos},
            _parts(misplaced_id=lambda v: int(_scalar("misplaced_id")(v)), position_mm=_array((3,), "position_mm")),
            cmp2,
            wrong=[
                (
                    lambda a: (
                        a["misplaced_id"] == bad
                        and np.linalg.norm(a["position_mm"] - all_pos) < 3
                        and np.linalg.norm(all_pos - true_pos) > tol
                    ),
                    "the right marker, but your position still uses it: leave it out of the pose (estimate_pose on the other detections, or read Pose.rejected_ids)",
                ),
                (
                    lambda a: a["misplaced_id"] == bad and np.linalg.norm(a["position_mm"] * 304.8 - true_pos) < tol,
                    "that position is in feet: give mm",
                ),
            ],
            look='from fidlearn import plotting\nplotting.show_image(None, q2.inputs.image, title="q2.inputs.image");',
            hint="estimate_pose(detections, marker_map, camera) leaves out a marker that disagrees and lists it in pose.rejected_ids; or do it yourself: for each id, solve with the others only (reject_outliers=False) and look at Pose.reprojection_rms_px: it drops when the misplaced marker is the one left out.",
            solution="""
        from fidlearn.detection import detect_markers
        from fidlearn.pose import estimate_pose
        m, cam = q2.inputs.marker_map, q2.inputs.camera
        dets = [d for d in detect_markers(q2.inputs.image, m.dictionary) if d.id in m]
        rms_without = {}                              # leave one out: do the others agree?
        for left_out in dets:
            others = [d for d in dets if d.id != left_out.id]
            rms_without[left_out.id] = estimate_pose(others, m, cam, reject_outliers=False).reprojection_rms_px
        worst_id = min(rms_without, key=rms_without.get)  # without it, the rest fit best
        best = estimate_pose([d for d in dets if d.id != worst_id], m, cam, reject_outliers=False)
        q2.answer = {"misplaced_id": worst_id, "position_mm": best.position_mm}
        """,
            level="hard",
        )
    )

    # q3: an ambiguous pose ------------------------------------------------------------------
    rng = _rng("08", learner, "q3")
    cam3 = Camera.from_fov(float(np.round(rng.uniform(55, 70))), (1280, 720))
    mid = int(rng.integers(0, 40))
    m3 = MarkerMap(
        {
            mid: MarkerPlacement(
                mid,
                (0.0, float(np.round(rng.uniform(-300, 300))), float(np.round(rng.uniform(1000, 1400)))),
                (0.0, 0.0, 0.0),
            )
        },
        float(rng.choice([80, 100])),
        "ARUCO_ORIGINAL",
        "mm",
    )
    centre = m3.marker_corners(mid).mean(axis=0)
    for _ in range(50):
        T3 = synthetic.look_at(
            centre + [float(rng.uniform(2800, 3600)), float(rng.uniform(-150, 150)), float(rng.uniform(-100, 100))],
            centre,
        )
        det3 = _noisy_detections(rng, cam3, m3, T3, 0.3)
        p3 = _pose.estimate_pose(det3, m3, cam3)
        if (
            p3.ambiguous
            and p3.alternative is not None
            and np.linalg.norm(p3.position_mm - p3.alternative.position_mm) > 250
        ):
            break
    sep = float(np.linalg.norm(p3.position_mm - p3.alternative.position_mm))
    # the two raw IPPE solutions (no refinement) are a fair answer too
    s3 = m3.marker_size_mm / 2
    local = np.array([[-s3, s3, 0], [s3, s3, 0], [s3, -s3, 0], [-s3, -s3, 0]])
    _, rvs, tvs, _ = cv2.solvePnPGeneric(
        local, det3[0].corners, cam3.K, cam3.dist, flags=_cv.solvepnp_flag("IPPE_SQUARE")
    )
    raw = [
        frames.invert_transform(frames.transform_from_rvec_tvec(np.ravel(r), np.ravel(t)))[:3, 3]
        for r, t in zip(rvs, tvs)
    ]
    seps = [sep] + ([float(np.linalg.norm(raw[0] - raw[1]))] if len(raw) == 2 else [])
    order = list(rng.permutation(len(_AMBIGUITY_CHOICES)))
    letters = "ABCD"
    choices = {letters[k]: _AMBIGUITY_CHOICES[i][1] for k, i in enumerate(order)}
    right = letters[order.index(0)]
    wrong_letters = {letters[k]: _AMBIGUITY_CHOICES[i][0] for k, i in enumerate(order) if i != 0}

    def parse3(answer):
        d = _parts(choice=lambda v: str(v).strip().upper()[:1], separation_mm=_scalar("separation_mm"))(answer)
        if d["choice"] not in choices:
            raise _AnswerError(f"choice must be one of {', '.join(choices)}, got {d['choice']!r}")
        return d

    def cmp3(a, _):
        if a["choice"] != right:
            return f"choice {a['choice']} does not explain it: {_AMBIGUITY_WRONG[wrong_letters[a['choice']]]}"
        if all(abs(a["separation_mm"] - x) > 0.15 * x + 5 for x in seps):
            return f"the explanation is right; the separation {a['separation_mm']:.0f} mm is not what the two candidate poses give (within 15 %)"
        return None

    qs.append(
        Question(
            "q3",
            "Two poses that both fit",
            """
        One marker, seen from about 3 m, was detected (`detections`); `marker_map` and `camera`
        are as usual. fidlearn.pose.estimate_pose reports the pose as ambiguous, and the camera
        position jumps from frame to frame. Write code that computes both candidate camera poses
        (estimate_pose returns the second one as Pose.alternative; cv2.solvePnPGeneric with
        SOLVEPNP_IPPE_SQUARE gives both too) and the distance in mm between the two candidate
        camera positions. Then choose the explanation from `choices`. Answer
        {"choice": letter, "separation_mm": distance}.
        """,
            {"detections": det3, "marker_map": m3, "camera": cam3, "choices": choices},
            {"choice": right, "separation_mm": sep},
            parse3,
            cmp3,
            wrong=[
                (
                    lambda a: a["choice"] == right and abs(a["separation_mm"] * 1000 - sep) <= 0.15 * sep + 5,
                    "that separation is in metres: give mm",
                ),
                (
                    lambda a: a["choice"] == right and a["separation_mm"] < 1,
                    "the two candidates are far apart (the camera seems to swing to the other side): compare pose.position_mm with pose.alternative.position_mm",
                ),
            ],
            hint="pose = estimate_pose(detections, marker_map, camera); np.linalg.norm(pose.position_mm - pose.alternative.position_mm). Both fit the corners to a fraction of a pixel: which explanation allows that?",
            solution="""
        from fidlearn.pose import estimate_pose
        pose = estimate_pose(q3.inputs.detections, q3.inputs.marker_map, q3.inputs.camera)
        separation = np.linalg.norm(pose.position_mm - pose.alternative.position_mm)
        flip = next(k for k, text in q3.inputs.choices.items() if "face-on" in text)
        q3.answer = {"choice": flip, "separation_mm": separation}
        """,
            level="hard",
        )
    )
    return qs


_register(
    "08",
    "accuracy",
    "Accuracy and pitfalls",
    """
    What limits a pose: depth error that grows with the square of the distance, a marker that
    moved after the map was measured, and the two-fold ambiguity of a small marker seen from afar.
    """,
    _lesson_08,
)


# ==================================================================================
# Lesson 09: localizing a robot
# ==================================================================================
def _lesson_09(learner: str) -> list[Question]:
    from . import pose as _pose
    from . import synthetic
    from .data import data_path
    from .detection import detect_markers

    qs = []
    # q1: every frame of a drive -------------------------------------------------------------
    rng = _rng("09", learner, "q1")
    m = MarkerMap.load(data_path("world_map.json"))
    cam = Camera.from_fov(float(np.round(rng.uniform(55, 65))), (960, 720))
    n = 6
    drive = synthetic.render_trajectory(
        cam,
        m,
        n_frames=n,
        seed=int(rng.integers(1 << 20)),
        start_lateral_mm=float(rng.uniform(-700, -300)),
        end_lateral_mm=float(rng.uniform(200, 600)),
    )
    truth_pos = drive.positions_mm
    est, tvecs = [], []
    for image in drive.images:
        p = _pose.estimate_pose(detect_markers(image, m.dictionary), m, cam)
        est.append(p.position_mm)
        tvecs.append(p.tvec)
    est = np.array(est)
    tvecs = np.array(tvecs)
    centre = np.mean([m.marker_corners(i).mean(axis=0) for i in m.ids], axis=0)
    distance = np.linalg.norm(truth_pos - centre, axis=1)
    # what corner noise allows: 6 % of the distance, or 3x what fidlearn's own pipeline misses by
    tol = np.maximum.reduce([np.full(n, 50.0), 0.06 * distance, 3.0 * np.linalg.norm(est - truth_pos, axis=1)])

    def cmp1(a, b):
        err = np.linalg.norm(a - b, axis=1)
        bad = np.flatnonzero(err > tol)
        if bad.size == 0:
            return None
        k = int(bad[0])
        return (
            f"frame {k} is {err[k]:.0f} mm from the truth (tolerance {tol[k]:.0f} mm at {distance[k] / 1000:.1f} m); {bad.size} of {len(a)} "
            "frames are off. Far away the markers are small and a corner error of half a pixel moves the camera by centimetres: "
            "refine the corners (fidlearn.detection.detect_markers does by default; OpenCV's detector does not) and use every marker"
        )

    qs.append(
        Question(
            "q1",
            "Localize every frame of a drive",
            """
        A camera on a robot drove toward the seed wall (`marker_map`, the course's world_map.json)
        and took the frames in `images` (a list of gray pictures); `camera` is calibrated. Write
        code that localizes every frame: detect, estimate the pose, and collect the camera's
        position in the world. Answer an (N, 3) array, mm, one row per frame in order.
        """,
            {"images": [im.copy() for im in drive.images], "marker_map": m, "camera": cam},
            truth_pos,
            _array(
                (n, 3),
                "the positions",
                {
                    (3, n): "one ROW per frame: transpose it",
                    (n, 4, 4): "give the positions (the last column of each T_world_camera), not the 4x4 poses",
                },
            ),
            cmp1,
            wrong=[
                (
                    lambda a: _close(a, tvecs, 1.0),
                    "those are the tvecs, the world's origin seen from the camera (T_camera_world); the camera's position is Pose.position_mm (= -R^T t)",
                ),
                (lambda a: np.all(np.linalg.norm(a * 1000 - truth_pos, axis=1) <= tol), "those are metres: give mm"),
                (
                    lambda a: np.all(np.linalg.norm(a * 304.8 - truth_pos, axis=1) <= tol),
                    "those are feet (304.8x too small): give mm",
                ),
            ],
            hint="for image in images: pose = estimate_pose(detect_markers(image, marker_map.dictionary), marker_map, camera); keep pose.position_mm.",
            look='from fidlearn import plotting\nfirst_middle_last = [0, len(q1.inputs.images) // 2, len(q1.inputs.images) - 1]\nplotting.show_images([q1.inputs.images[i] for i in first_middle_last], titles=[f"frame {i}" for i in first_middle_last], ncols=3);',
            solution="""
        from fidlearn.detection import detect_markers
        from fidlearn.pose import estimate_pose
        m, cam = q1.inputs.marker_map, q1.inputs.camera
        positions = []
        for image in q1.inputs.images:
            pose = estimate_pose(detect_markers(image, m.dictionary), m, cam)
            positions.append(pose.position_mm)
        q1.answer = np.array(positions)
        """,
            level="medium",
        )
    )

    # q2: the robot's pose from the camera's --------------------------------------------------
    rng = _rng("09", learner, "q2")
    cam_yaw = float(np.round(rng.uniform(10, 35)) * rng.choice([-1, 1]))
    R_robot_camera = frames.rot_z(math.radians(cam_yaw)) @ np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    T_robot_camera = frames.make_transform(
        R_robot_camera,
        [
            float(np.round(rng.uniform(80, 250))),
            float(np.round(rng.uniform(-60, 60))),
            float(np.round(rng.uniform(250, 450))),
        ],
    )
    robot_xy = np.round(rng.uniform([800, -800], [2500, 800]))
    robot_yaw = float(np.round(rng.uniform(120, 240)))
    T_world_robot = frames.make_transform(frames.rot_z(math.radians(robot_yaw)), [robot_xy[0], robot_xy[1], 0.0])
    Twc = T_world_robot @ T_robot_camera
    Twc = np.round(Twc, 9)
    T_wr = Twc @ frames.invert_transform(T_robot_camera)
    key2 = np.array([T_wr[0, 3], T_wr[1, 3], math.degrees(math.atan2(T_wr[1, 0], T_wr[0, 0]))])

    def cmp2(a, b):
        d = (a[2] - b[2] + 180) % 360 - 180
        if np.linalg.norm(a[:2] - b[:2]) <= 1.0 and abs(d) <= 0.1:
            return None
        return f"your (x, y) is {np.linalg.norm(a[:2] - b[:2]):.0f} mm and your heading {d:+.3g} deg from the key's"

    def pose_xyh(T):
        return np.array([T[0, 3], T[1, 3], math.degrees(math.atan2(T[1, 0], T[0, 0]))])

    cam_axis = Twc[:3, 2]
    cam_heading = math.degrees(math.atan2(cam_axis[1], cam_axis[0]))
    qs.append(
        Question(
            "q2",
            "From the camera's pose to the robot's",
            """
        The camera is bolted to the robot, turned a little to one side: `T_robot_camera` (4x4, mm)
        is its pose in the robot's frame (x forward, y left, z up, origin on the floor between the
        wheels). Localization gave `T_world_camera`. Write code that computes where the ROBOT is:
        (x_mm, y_mm, heading_deg), its origin's world x and y and the direction of its x axis in
        the world, atan2(dy, dx) in degrees.
        """,
            {"T_world_camera": Twc, "T_robot_camera": T_robot_camera},
            key2,
            _array((3,), "(x_mm, y_mm, heading_deg)"),
            cmp2,
            wrong=[
                (
                    lambda a: np.linalg.norm(a[:2] - Twc[:2, 3]) <= 1.0,
                    "that is where the CAMERA is; the robot's origin is elsewhere: T_world_robot = T_world_camera @ T_camera_robot, with T_camera_robot = invert(T_robot_camera)",
                ),
                (
                    lambda a: cmp2(a, pose_xyh(Twc @ T_robot_camera)) is None,
                    "the names do not chain: T_world_camera @ T_robot_camera; invert T_robot_camera first (T_camera_robot)",
                ),
                (
                    lambda a: (
                        np.linalg.norm(a[:2] - key2[:2]) <= 1.0 and abs((a[2] - cam_heading + 180) % 360 - 180) <= 0.1
                    ),
                    "the position is right, but that heading is the CAMERA's optical axis; the camera is turned on the robot: take the robot's x axis from T_world_robot",
                ),
                (
                    lambda a: (
                        np.linalg.norm(a[:2] - key2[:2]) <= 1.0
                        and abs((math.degrees(a[2]) - key2[2] + 180) % 360 - 180) <= 0.1
                    ),
                    "the heading is in radians: give degrees",
                ),
                (
                    lambda a: np.linalg.norm(a[:2] - key2[:2]) <= 1.0,
                    "the position is right; the heading is the direction of the robot's x axis, the first column of T_world_robot's rotation: atan2(R[1, 0], R[0, 0]) in degrees",
                ),
            ],
            hint="T_world_robot = T_world_camera @ frames.invert_transform(T_robot_camera); x, y = its last column; heading = degrees(atan2(R[1, 0], R[0, 0])).",
            solution="""
        T_world_robot = q2.inputs.T_world_camera @ frames.invert_transform(q2.inputs.T_robot_camera)
        heading = np.degrees(np.arctan2(T_world_robot[1, 0], T_world_robot[0, 0]))
        q2.answer = (T_world_robot[0, 3], T_world_robot[1, 3], heading)
        """,
            level="medium",
        )
    )

    # q3: distance driven ----------------------------------------------------------------------
    rng = _rng("09", learner, "q3")
    k = 12
    s = np.linspace(0, 1, k)
    start = np.round(rng.uniform([2000, -900], [2600, -400]))
    end = np.round(rng.uniform([700, 200], [1100, 800]))
    bend = float(rng.uniform(150, 400))
    xy = start + np.outer(s, end - start) + np.outer(np.sin(np.pi * s) * bend, [0.6, 0.8])
    xy = xy + rng.normal(0, 4, xy.shape)
    z = 300 + rng.normal(0, 2, k)
    pts = np.round(np.column_stack([xy, z]), 1)
    lost = sorted(int(i) for i in rng.choice(np.arange(2, k - 2), size=2, replace=False))
    pts[lost] = np.nan
    ok = ~np.isnan(pts[:, 0])
    good = pts[ok]
    length = float(np.sum(np.linalg.norm(np.diff(good[:, :2], axis=0), axis=1)))
    length3 = float(np.sum(np.linalg.norm(np.diff(good, axis=0), axis=1)))
    straight = float(np.linalg.norm(good[-1, :2] - good[0, :2]))
    qs.append(
        Question(
            "q3",
            "How far did the robot drive?",
            """
        `positions_mm` (N, 3) are the camera positions of a drive, one per frame; in the frames
        where no marker was seen the row is NaN. Write code that computes the distance driven on
        the floor: the length of the path through the valid positions in order, using x and y
        only, in mm.
        """,
            {"positions_mm": pts},
            length,
            _scalar("the distance"),
            _cmp_scalar(0.05, " mm"),
            wrong=[
                (
                    lambda a: abs(a - straight) < 0.5,
                    "that is the straight line from start to finish; add up the steps between consecutive valid frames",
                ),
                (
                    lambda a: abs(a - length3) < 0.05,
                    "use x and y only: the camera's z wobbles a little but the robot drives on the floor",
                ),
                (lambda a: abs(a * 1000 - length) < 0.5, "that is in metres: give mm"),
                (
                    lambda a: a < length * 0.9,
                    "too short: did you drop more than the NaN rows, or skip the steps around a lost frame? Join each valid position to the next valid one",
                ),
            ],
            hint="Keep the rows without NaN (~np.isnan(p).any(axis=1)), take np.diff of their x, y and sum the step lengths (np.linalg.norm along axis 1).",
            solution="""
        p = np.asarray(q3.inputs.positions_mm, dtype=float)
        valid = p[~np.isnan(p).any(axis=1)]
        steps = np.diff(valid[:, :2], axis=0)
        q3.answer = np.sum(np.linalg.norm(steps, axis=1))
        """,
            level="easy",
        )
    )
    return qs


_register(
    "09",
    "robot",
    "Localizing a robot",
    """
    Put it together on a moving robot: localize every frame of a drive, carry the camera's pose to
    the robot's through the mounting transform, and measure the path it drove.
    """,
    _lesson_09,
)


# ==================================================================================
# grading a learner's notebook
# ==================================================================================
@dataclass
class Grade:
    """The outcome of checking one notebook: the lesson, the learner id it used, a Result per question."""

    path: str
    lesson: str | None
    learner: str | None
    results: list
    errors: list

    @property
    def n_correct(self) -> int:
        return sum(r.correct for r in self.results)

    def __str__(self) -> str:
        head = f"{self.path}: lesson {self.lesson}, learner {self.learner!r}: {self.n_correct} of {len(self.results)} correct"
        lines = [head] + [f"  {r.line}" for r in self.results] + [f"  problem: {e}" for e in self.errors]
        return "\n".join(lines)


_LESSON_CALL = re.compile(r"exercises\.lesson\(\s*[\"']?(\d{1,2})[\"']?")


def grade_notebook(path: str | os.PathLike, learner: str | None = None, timeout: int = 300) -> Grade:
    """Check a learner's self-study notebook: run it in a sandbox, judge its answers outside it.

    The notebook runs in a process of its own (see :mod:`fidlearn.grading`); its answers are
    collected as plain data and judged here against the self-study variant of ``learner``.
    This is a practice check: a self-study kernel holds its own answer key. For marks, release
    the lesson with a class secret and grade with ``fidlearn grade``.

    Parameters
    ----------
    path : path
        The notebook (``.ipynb``).
    learner : str, optional
        The id the learner was told to use (a notebook whose ``LEARNER`` is empty runs with it).
    timeout : int
        Seconds the notebook may run.
    """
    import nbformat

    from . import grading
    from .errors import FidlearnError

    path = os.fspath(path)
    if not os.path.isfile(path):
        what = (
            "is a folder; give the notebooks in it (folder/*.ipynb)"
            if os.path.isdir(path)
            else "no such notebook; check the path"
        )
        raise FidlearnError(f"{path}: {what}")
    try:
        nb = nbformat.read(path, as_version=4)
    except Exception as exc:  # nbformat raises NotJSONError, UnicodeDecodeError, KeyError, validation errors...
        raise FidlearnError(
            f"{path}: not a Jupyter notebook ({type(exc).__name__}); give the learner's .ipynb file"
        ) from None
    found = {m.group(1) for c in nb.cells if c.cell_type == "code" for m in _LESSON_CALL.finditer(c.source)}
    if len(found) != 1:
        return Grade(path, None, learner, [], ["no exercises found: the notebook never ran ex = exercises.lesson(...)"])
    number = lesson_number(found.pop())
    g = grading.grade_one(path, number, learner or "", None, timeout_s=timeout, run_as="")
    results = [Result(q, status, message) for q, status, message in g.results]
    errors = list(g.cell_errors) + ([g.problem] if g.problem else [])
    return Grade(path, number, learner or "", results, errors)


def _main(argv: Sequence[str] | None = None) -> int:
    """``python -m fidlearn.exercises grade NOTEBOOK... [--learner ID] [--csv FILE]``."""
    import argparse
    import csv
    import io
    import sys

    from ._io import write_text_atomic

    parser = argparse.ArgumentParser(
        prog="python -m fidlearn.exercises",
        description="Check learners' self-study notebooks (for marks: fidlearn grade).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("grade", help="run notebooks in sandboxes and check every question (self-study variants)")
    g.add_argument("notebooks", nargs="+")
    g.add_argument("--learner", help="the id the learner was told to use (one notebook, or all of one learner)")
    g.add_argument("--csv", help="also write one row per question to this CSV file")
    args = parser.parse_args(argv)
    from .errors import FidlearnError

    grades = []
    for path in args.notebooks:
        try:
            grade = grade_notebook(path, learner=args.learner)
        except FidlearnError as exc:  # one line and status 2, as every fidlearn command
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        print(grade)
        grades.append(grade)
    if args.csv:
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(["notebook", "lesson", "learner", "question", "status", "message"])
        for grade in grades:
            for r in grade.results:
                w.writerow([grade.path, grade.lesson, grade.learner, r.question, r.status, r.message])
            for e in grade.errors:
                w.writerow([grade.path, grade.lesson, grade.learner, "", "problem", e])
        write_text_atomic(args.csv, buf.getvalue())
    return 0


if __name__ == "__main__":
    raise SystemExit(_main())
