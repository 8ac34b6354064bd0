"""The grading engine: a question, its inputs, the result of a check, and strict mode."""

from __future__ import annotations

import copy
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np

from ..detection import Detection
from ..errors import ExerciseError
from ._dtypes import whole_number_note
from ._strict import strict_mode

CORRECT = "Correct"


INCORRECT = "Incorrect"


NOT_ATTEMPTED = "Not attempted"


#: Graded mode (fidlearn.grading): an answer of the right form, kept for the instructor's grader.
RECORDED = "Recorded"


#: The imports every exercise notebook starts with; solution code may use these names.
SETUP_CODE = "import math\nimport numpy as np\nimport cv2\nimport fidlearn\nfrom fidlearn import exercises, frames"


BEGIN_SOLUTION = "### BEGIN SOLUTION"


END_SOLUTION = "### END SOLUTION"


_MISSING = object()


@dataclass(frozen=True)
class Result:
    """The outcome of one check: ``status`` is ``Correct``, ``Incorrect`` or ``Not attempted``.

    Parameters
    ----------
    question : str
        The question's name, ``"q1"``.
    status : str
        :data:`CORRECT`, :data:`INCORRECT`, :data:`NOT_ATTEMPTED` or (graded mode) :data:`RECORDED`.
    message : str
        What is wrong and a nudge, or a remark on a right answer ("" for none).

    Examples
    --------
    >>> Result("q1", CORRECT, "well done").line
    'Correct (q1): well done'
    """

    question: str
    status: str
    message: str

    @property
    def correct(self) -> bool:
        """Whether the status is ``Correct``.

        Returns
        -------
        bool
        """
        return self.status == CORRECT

    @property
    def line(self) -> str:
        """The one line that :meth:`Question.check` prints.

        Returns
        -------
        str
            ``"<status> (<question>): <message>"``, without the colon part when there is no message.
        """
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
    view = _short_collection(value)
    if view is not None:
        return view
    if isinstance(value, float):
        return f"{value:g}"
    return repr(value)


def _short_collection(value: Any) -> str | None:
    """The view of a dict of long texts or a list of arrays or detections; None for anything else."""
    if isinstance(value, dict) and value and all(isinstance(v, str) and len(v) > 30 for v in value.values()):
        return "{\n" + "\n".join(f"      {k!r}: {v!r}," for k, v in value.items()) + "\n  }"
    if isinstance(value, list) and value and all(isinstance(v, np.ndarray) for v in value) and value[0].size > 24:
        shapes = {v.shape for v in value}
        return (
            f"list of {len(value)} arrays of shape {value[0].shape}"
            if len(shapes) == 1
            else f"list of {len(value)} arrays"
        )
    return _short_sequence(value)


def _short_sequence(value: Any) -> str | None:
    """The view of a short list of detections, arrays or dicts, or of a long sequence; None otherwise."""
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
    return None


class Inputs:
    """A question's inputs: read them as attributes (``q.inputs.K``) or keys (``q.inputs["K"]``).

    Parameters
    ----------
    **values
        The named inputs (arrays in mm, pixels or degrees as their names say).

    Examples
    --------
    >>> inputs = Inputs(hfov_deg=60.0, image_size=(640, 480))
    >>> inputs.hfov_deg, inputs["image_size"], list(inputs.keys())
    (60.0, (640, 480), ['hfov_deg', 'image_size'])
    """

    def __init__(self, **values: Any):
        self.__dict__.update(values)

    def __getitem__(self, key: str) -> Any:
        return self.__dict__[key]

    def __iter__(self):
        return iter(self.__dict__)

    def keys(self):
        """The names of the inputs, in the order the question gives them.

        Returns
        -------
        dict_keys
        """
        return self.__dict__.keys()

    def __repr__(self) -> str:
        lines = [f"  {k} = {_short(v)}" for k, v in self.__dict__.items()]
        return "Inputs(\n" + "\n".join(lines) + "\n)"


Detector = Callable[[Any], bool | np.bool_]


class _QuestionWords(TypedDict):
    title: str
    task: str


class QuestionText(_QuestionWords, total=False):
    """A :class:`Question`'s words, kept apart from its code: ``Question(..., **text)``.

    Attributes
    ----------
    title, task : str
        Required.
    hint : str or sequence of str
    solution, level, look : str
    """

    hint: str | Sequence[str]
    solution: str
    level: str
    look: str


class _Asked:
    """What every question shows a learner: its task and inputs (:meth:`show`) and tiered hints (:meth:`hint`)."""

    name: str
    title: str
    task: str
    inputs: Inputs
    _hints: list
    _hints_shown: int
    #: The tail of the last of several hints.
    _LAST_HINT = " [that was the last hint: the rest is yours to work out]"

    def hint(self) -> None:
        """Print a hint: ``Hint (q1): ...``; tiered hints one more per call (``Hint (q1, 1 of 2): ...``)."""
        n = len(self._hints)
        k = min(self._hints_shown, n - 1)
        self._hints_shown += 1
        if n == 1:
            print(f"Hint ({self.name}): {self._hints[0]}")
            return
        more = f" [{self.name}.hint() again gives the next hint]" if k < n - 1 else self._LAST_HINT
        print(f"Hint ({self.name}, {k + 1} of {n}): {self._hints[k]}{more}")

    def show(self) -> None:
        """Print the task and the inputs."""
        print(f"{self.name}. {self.title}\n\n{self.task}\n\n{self.name}.inputs = {self.inputs!r}")

    def _describe(self, status: str) -> str:
        """The question's ``repr`` with its status."""
        names = ", ".join(self.inputs.keys())
        return f"<Question {self.name}: {self.title!r}; inputs: {names}; {status}>"


class _Questions:
    """A lesson's questions for one learner: iteration, ``len``, ``lesson["q1"]`` and the per-question lines."""

    number: str
    questions: list

    def __iter__(self):
        return iter(self.questions)

    def __len__(self) -> int:
        return len(self.questions)

    def __getitem__(self, name: str):
        """The question called ``name`` (``ex["q1"]``).

        Raises
        ------
        ExerciseError
            When the lesson has no such question (it is a KeyError too).
        """
        for q in self.questions:
            if q.name == name:
                return q
        raise ExerciseError(f"lesson {self.number} has no question {name!r}; it has {[q.name for q in self.questions]}")

    def _print_rows(self, results: list[Result]) -> None:
        """Print one line per question: its name, status and title."""
        for q, r in zip(self.questions, results):
            print(f"  {q.name} [{r.status}] {q.title}")

    def _listing(self) -> str:
        """One line per question: its name, title and level."""
        return "\n".join(f"  {q.name}: {q.title} ({q.level})" for q in self.questions)


def _say(result: Result, accepted: tuple[str, ...]) -> None:
    """Print the result's line; in strict mode, raise for a status the mode does not expect."""
    print(result.line)
    mode = strict_mode()
    if mode == "correct" and result.status not in accepted:
        raise AssertionError(result.line)
    if mode == "blank" and result.status != NOT_ATTEMPTED:
        raise AssertionError(f"expected a blank answer, got: {result.line}")


class Question(_Asked):
    """One exercise question: inputs, a hidden answer key, and feedback.

    Parameters
    ----------
    name : str
        ``"q1"``, ``"q2"``...: the variable name the notebook gives it.
    title : str
        The question's heading.
    task : str
        What to compute, in words (units and frames included); dedented.
    inputs : dict
        The data to compute from, shown as :class:`Inputs`.
    expected : object
        The answer key, in the form ``parse`` gives.
    parse : callable
        Reads a learner's answer into that form, or raises ``_AnswerError`` saying why not.
    compare : callable
        ``compare(value, expected)``: None when they agree, else what differs, in words.
    wrong : sequence of (callable, str or callable)
        Recognised mistakes: the first detector that is true for a wrong answer gives the message.
    notes : sequence of (callable, str or callable)
        Remarks on a right answer, the same way.
    hint : str or sequence of str
        A nudge; a sequence gives tiered hints, shown one more per :meth:`hint` call: first a
        nudge, then the idea, never the answer.
    solution : str
        Code that solves it in the notebook (dedented).
    level : str
        ``"easy"``, ``"medium"`` or ``"hard"``.
    look : str
        Code that shows the inputs as a picture in the notebook ("" for none).

    Attributes
    ----------
    inputs : Inputs
        The data to compute from (arrays in mm, pixels, degrees as named); also ``data``.
    answer : object
        The learner's answer; ``...`` or ``None`` means not attempted.
    solution_code, look_code : str
        The dedented ``solution`` and ``look``.
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
        *,
        wrong: Sequence[tuple[Detector, Any]] = (),
        notes: Sequence[tuple[Detector, Any]] = (),
        hint: str | Sequence[str] = "",
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
        self._parse: Callable[[Any], Any] | None = parse  # None in a learner's copy (see _fresh)
        self._compare: Callable[[Any, Any], str | None] | None = compare
        self._wrong = list(wrong)
        self._notes = list(notes)
        self._hints = [textwrap.dedent(h).strip() for h in ([hint] if isinstance(hint, str) else hint)]
        self._hints_shown = 0
        self.solution_code = textwrap.dedent(solution).strip()
        self.level = level
        #: Code that shows the inputs as a picture in the notebook ("" for none).
        self.look_code = textwrap.dedent(look).strip()
        self.answer: Any = ...
        #: In a learner's copy: rebuilds the question with its key for each check (see :meth:`_fresh`).
        self._judge: Callable[[], Question] | None = None

    # -- grading ------------------------------------------------------------------
    def grade(self, answer: Any = _MISSING) -> Result:
        """Judge an answer (default: ``self.answer``) and return a :class:`Result`; prints nothing.

        A learner's answer that cannot be read gives ``Incorrect`` with the
        reason; an error in the grading code itself raises.

        Parameters
        ----------
        answer : object, optional
            The answer to judge; without it, ``self.answer``.

        Returns
        -------
        Result
            ``Not attempted`` for ``...`` or None, else ``Correct`` or ``Incorrect`` with the message.
        """
        if answer is _MISSING:
            answer = self.answer
        if self._judge is not None:  # a learner's copy: the key is built here, for this check only
            return self._judge().grade(answer)
        if answer is None or answer is Ellipsis:
            return Result(
                self.name,
                NOT_ATTEMPTED,
                (
                    f"replace the ... in {self.name}.answer = ... with code that computes the answer, then run "
                    f"{self.name}.check()"
                ),
            )
        assert self._parse is not None  # only a learner's copy, judged above, has none
        assert self._compare is not None
        try:
            value = self._parse(answer)
        except _AnswerError as exc:
            return Result(self.name, INCORRECT, str(exc))
        diff = self._compare(value, self._expected)
        note = whole_number_note(answer, self._expected) if diff is not None else None
        if note is not None:
            return Result(self.name, INCORRECT, f"{note}; {self.name}.hint() gives a nudge")
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

        Parameters
        ----------
        answer : object, optional
            When given, it becomes ``self.answer`` first.

        Raises
        ------
        AssertionError
            Only in strict mode, for a status the mode does not expect.
        """
        if answer is not _MISSING:
            self.answer = answer
        mode = strict_mode()
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
        _say(result, (CORRECT, RECORDED))

    def solution(self) -> None:
        """Print one way to solve it: code that, run in the notebook, makes ``check()`` say Correct."""
        print(f"Solution ({self.name}), one way to do it:\n")
        print(self.solution_code)

    def _fresh(self, judge: Callable[[], Question] | None = None) -> Question:
        """A copy with its own inputs (a learner may change them) and no answer yet.

        With ``judge`` (a function that builds this question again, key included), the copy keeps
        no answer key, no comparison and no list of mistakes (they hold the key): each check asks
        ``judge`` for them, so the key is never an attribute of the learner's question.
        """
        new = copy.copy(self)
        new.inputs = copy.deepcopy(self.inputs)
        new.data = new.inputs
        new.answer = ...
        new._hints_shown = 0
        if judge is not None:
            new._judge = judge
            new._expected = new._parse = new._compare = None
            new._wrong, new._notes = [], []
        return new

    def __repr__(self) -> str:
        return self._describe(self.grade().status if self.answer is not ... else NOT_ATTEMPTED)


def _safe(detect: Detector, value: Any) -> bool:
    try:
        return bool(detect(value))
    except Exception:
        return False
