"""Answer readers (parsers) and comparisons against the key, shared by the lessons.

A parser turns a learner's answer into the value the key is compared with, or raises
:class:`~fidlearn.exercises._engine._AnswerError` with a message that says what is wrong with its
form; a comparison returns ``None`` when the answer matches the key, else a sentence.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import frames
from ..camera import Camera
from ._engine import Detector, _AnswerError


def _array(shape: tuple, what: str, shape_hints: dict | None = None) -> Callable[[Any], np.ndarray]:
    """A parser: the answer as a float array of ``shape`` (a -1 matches any length)."""

    def parse(answer: Any) -> np.ndarray:
        if isinstance(answer, Camera):
            answer = answer.K
        if isinstance(answer, (str, bytes, dict)):
            raise _AnswerError(
                f"your answer ({what}) should be numbers in an array of shape {_shape_text(shape)}, got a "
                f"{type(answer).__name__}"
            )
        a = _floats(answer, what, f"numbers in an array of shape {_shape_text(shape)}")
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


def _floats(answer: Any, what: str, expected: str) -> np.ndarray:
    """The answer as a float array, or :class:`_AnswerError` naming what stops it being one.

    A complex answer passes only when its imaginary part is 0 (numpy would drop it without a word); ``None``,
    a ragged list, a set, a generator or a whole number beyond a float's range each get their own sentence.
    """
    try:
        raw = np.asarray(answer)
    except ValueError:  # numpy 2 refuses a ragged list
        raw = None
    if raw is None or (raw.dtype == object and raw.ndim > 0 and _ragged(raw)):
        raise _AnswerError(
            f"your answer ({what}) should be {expected}; its rows have different lengths (a ragged list), "
            "so it is no array: check that every row has as many numbers"
        )
    if raw.dtype == object and any(v is None for v in raw.ravel()):
        raise _AnswerError(f"your answer ({what}) contains None where a number belongs: fill in every value")
    if np.iscomplexobj(raw):
        if np.any(raw.imag != 0):
            raise _AnswerError(
                f"your answer ({what}) is complex (an imaginary part of up to {np.abs(raw.imag).max():.3g}): the "
                "square root or the arc cosine of a negative number, or an eigenvector, gave it; a length or an "
                "angle is a real number: find where the value went below 0"
            )
        raw = raw.real
    try:
        return np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise _AnswerError(f"your answer ({what}) should be {expected}, got {type(answer).__name__}") from None
    except OverflowError:
        raise _AnswerError(f"your answer ({what}) holds a whole number too large for a float") from None


def _ragged(raw: np.ndarray) -> bool:
    """Whether an object array holds sequences of different lengths (what ``np.asarray`` makes of a ragged list)."""
    try:
        shapes = {np.shape(v) if isinstance(v, (list, tuple, np.ndarray)) else () for v in raw.ravel()}
    except ValueError:  # a part that is ragged itself
        return True
    return len(shapes) > 1


def _shape_ok(got: tuple, want: tuple) -> bool:
    return len(got) == len(want) and all(w == -1 or g == w for g, w in zip(got, want))


def _shape_text(shape: tuple) -> str:
    return "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ")"


def _scalar(what: str) -> Callable[[Any], float]:
    def parse(answer: Any) -> float:
        if isinstance(answer, (str, bytes)):
            raise _AnswerError(f"your answer ({what}) should be a number, got the text {answer!r}")
        if isinstance(answer, dict):
            raise _AnswerError(f"your answer ({what}) should be one number, got a dict")
        a = _floats(answer, what, "one number")
        if a.size != 1:
            raise _AnswerError(
                f"your answer ({what}) should be one number, got {type(answer).__name__} of {a.size} values"
            )
        v = float(a.reshape(-1)[0])
        if math.isnan(v):
            raise _AnswerError(
                f"your answer ({what}) is NaN: a NaN in the data spreads through every sum and mean; leave those "
                "values out (np.isnan finds them)"
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
        return (
            f"your answer differs from the key by {abs(a[i] - b[i]):.4g}{unit}{where} (tolerance "
            f"{atol + rtol * abs(b[i]):.3g}{unit})"
        )

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


def _winding_message(order: tuple[str, ...] | None, what: str = "detection reports") -> str:
    assert order is not None, "called for an order that its detector found"
    return (
        f"your corners are in the order {', '.join(order)}: {what} TL, TR, BR, BL "
        "(clockwise as seen from the front, starting at the marker's own top-left)"
    )


_EXTRINSIC_MSG = (
    "that is the extrinsic matrix T_camera_world (what solvePnP's rvec, tvec describe), the "
    "inverse of what is asked: the camera's pose is T_world_camera = frames.invert_transform(T_camera_world)"
)


def _T_is(T: np.ndarray, rot_tol_deg: float = 0.05, trans_tol_mm: float = 0.5) -> Detector:
    cmp = _cmp_transform(rot_tol_deg, trans_tol_mm)
    return lambda a: a.shape == (4, 4) and cmp(a, T) is None


_T_HINTS = {
    (3, 3): "that is only the rotation; a pose is the 4x4 [[R, t], [0, 0, 0, 1]] (frames.make_transform(R, t))",
    (3,): (
        "that is a 3-vector; if it is an rvec, cv2.Rodrigues(rvec) turns it into a 3x3 rotation matrix, "
        "and the pose is the 4x4 [[R, t], [0, 0, 0, 1]]"
    ),
    (3, 4): "add the bottom row [0, 0, 0, 1]",
}


def _marker_map(answer: Any):
    """A parser: a fidlearn MarkerMap, or a dict in the full map-file layout (``MarkerMap.from_dict``)."""
    from ..markermap import MarkerMap

    if isinstance(answer, MarkerMap):
        return answer
    if isinstance(answer, dict):
        try:
            return MarkerMap.from_dict(answer, source="your map")
        except Exception as exc:  # the library's message says what to fix
            raise _AnswerError(f"MarkerMap.from_dict cannot read your dict: {exc}") from None
    raise _AnswerError(
        f"give a fidlearn.MarkerMap or a dict in the full map-file layout (units, marker_size_mm, markers), got "
        f"{type(answer).__name__}"
    )
