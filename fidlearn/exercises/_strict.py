"""Strict mode for tests and graders: a check that is not as expected raises AssertionError."""

from __future__ import annotations

import contextvars
import os
from typing import Any

from ..errors import StrictModeError

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


def _parse_strict(value: Any) -> str | None:
    if value is True:
        return "correct"
    if value is False or value is None:
        return None
    key = str(value).strip().lower()
    if key not in _STRICT_WORDS:
        raise StrictModeError(
            f"strict mode {value!r} is unknown; use True or 'correct' (every check must be Correct), "
            "'blank' (every check must be Not attempted) or False"
        )
    return _STRICT_WORDS[key]


#: The strict modes switched on by :class:`strict` in this context, innermost last (a tuple, so a
#: copied context never shares it). Empty: the environment variable ``FIDLEARN_STRICT`` decides.
STRICT_STACK: contextvars.ContextVar[tuple] = contextvars.ContextVar("fidlearn_exercises_strict", default=())


def strict_mode() -> str | None:
    """The strict mode in force now: ``"correct"``, ``"blank"`` or ``None`` (off).

    Returns
    -------
    str or None
        The innermost :class:`strict` of this context, else what ``FIDLEARN_STRICT`` says
        (an unreadable value counts as ``"correct"``).

    Examples
    --------
    >>> with strict("blank"):
    ...     strict_mode()
    'blank'
    """
    stack = STRICT_STACK.get()
    if stack:
        return stack[-1]
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
    variable ``FIDLEARN_STRICT`` (``1`` or ``blank``) decides. The modes live in the
    context variable :data:`STRICT_STACK`, so a thread or task started elsewhere keeps its own.

    Parameters
    ----------
    mode : bool or str, default True
        ``True``/``"correct"``, ``"blank"``, or ``False``/``None`` (off); the words of
        ``FIDLEARN_STRICT`` (``"1"``, ``"on"``, ``"not attempted"``...) are accepted too.

    Raises
    ------
    ValueError
        For a mode that is none of these.

    Examples
    --------
    >>> with strict():
    ...     strict_mode()
    'correct'
    >>> STRICT_STACK.get()  # left: FIDLEARN_STRICT decides again
    ()
    """

    def __init__(self, mode: Any = True):
        self.mode = _parse_strict(mode)
        STRICT_STACK.set((*STRICT_STACK.get(), self.mode))
        self._active = True

    def restore(self) -> None:
        """Undo this strict() call: remove the latest switch to this mode from the context."""
        if self._active:
            stack = list(STRICT_STACK.get())
            for i in range(len(stack) - 1, -1, -1):  # the latest push of this mode
                if stack[i] == self.mode:
                    del stack[i]
                    break
            STRICT_STACK.set(tuple(stack))
            self._active = False

    def __enter__(self) -> strict:
        return self

    def __exit__(self, *exc) -> None:
        self.restore()
