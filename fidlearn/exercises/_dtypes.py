"""Why an answer made of whole numbers misses a key with fractions: the array's type, named."""

from __future__ import annotations

from typing import Any

import numpy as np


def _arrays(value: Any, depth: int = 0) -> list[np.ndarray]:
    """The numpy arrays in an answer: itself, or the parts of a tuple, list or dict (two levels deep)."""
    if isinstance(value, np.ndarray):
        return [value]
    if depth < 2 and isinstance(value, (tuple, list)):
        return [a for v in value for a in _arrays(v, depth + 1)]
    if depth < 2 and isinstance(value, dict):
        return [a for v in value.values() for a in _arrays(v, depth + 1)]
    return []


def _has_fractions(value: Any) -> bool:
    """Whether a key holds a number that is not whole (in any of its arrays or plain numbers)."""
    parts = _arrays(value) or [value]
    for part in parts:
        try:
            a = np.asarray(part, dtype=float)
        except (TypeError, ValueError, OverflowError):
            continue
        finite = a[np.isfinite(a)]
        if finite.size and np.any(finite != np.round(finite)):
            return True
    return False


def whole_number_note(answer: Any, expected: Any) -> str | None:
    """A sentence for an incorrect answer held in an integer or boolean array when the key has fractions.

    Parameters
    ----------
    answer : object
        The learner's answer, as given (before it was read as floats).
    expected : object
        The key the answer was compared with.

    Returns
    -------
    str or None
        What the array's type did to the numbers and how to keep them; None when no array of the
        answer is of a whole-number type, or the key has no fractions.

    Examples
    --------
    >>> whole_number_note(np.array([1, 2], dtype=np.uint8), np.array([1.5, 2.0])) is not None
    True
    >>> whole_number_note(np.array([1.0, 2.0]), np.array([1.5, 2.0])) is None
    True
    """
    kinds = [a.dtype for a in _arrays(answer) if a.dtype.kind in "uib"]
    if not kinds or not _has_fractions(expected):
        return None
    dtype = kinds[0]
    wraps = ""
    if dtype.kind in "ui" and dtype.itemsize <= 2:
        info = np.iinfo(dtype)
        wraps = f", and {dtype} keeps only {info.min} to {info.max} (a value beyond wraps around)"
    return (
        f"your answer is an array of {dtype}, which holds whole numbers only: every fraction was cut off{wraps}; "
        "make the array float (np.zeros(shape) or np.asarray(x, dtype=float), not zeros_like of an image or of "
        "ids)"
    )
