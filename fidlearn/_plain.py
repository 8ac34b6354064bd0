"""Plain data: what crosses between the grader and a learner's kernel (see :mod:`fidlearn.grading`).

Answers and inputs travel as JSON: numbers, text, lists, and tagged objects for what JSON lacks
(tuples, dicts with any keys, arrays with their dtype and shape, NaN, fidlearn's Camera, MarkerMap
and Detection). Nothing else is read back: an unknown tag raises ``ValueError``.
"""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Deepest nesting of an answer.
MAX_DEPTH = 32
#: Most items of an array read back.
MAX_ARRAY_ITEMS = 50_000_000


def to_plain(value: Any, depth: int = 0) -> Any:
    """``value`` as JSON-ready plain data, fidlearn's own types and arrays tagged.

    Parameters
    ----------
    value : object
        Numbers, text, None, arrays of numbers, tuples, lists, dicts, Camera, MarkerMap,
        Detection, nested up to ``MAX_DEPTH`` deep.
    depth : int
        How deep ``value`` sits in the whole (the caller leaves it at 0).

    Returns
    -------
    object
        JSON-ready data; an array keeps its dtype and shape, a NaN or infinity is tagged, and a
        value of any other type becomes ``{"__unsupported__": type name}``.

    Raises
    ------
    ValueError
        When ``value`` is nested more than ``MAX_DEPTH`` deep.

    Examples
    --------
    >>> to_plain((1, float("nan")))
    {'__tuple__': [1, {'__float__': 'nan'}]}
    """
    from .camera import Camera
    from .detection import Detection
    from .markermap import MarkerMap

    if depth > MAX_DEPTH:
        raise ValueError("nested too deeply")
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else {"__float__": repr(v)}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            return {"__unsupported__": f"array of {value.dtype}"}
        raw = np.ascontiguousarray(value)
        return {
            "__array__": base64.b64encode(raw.tobytes()).decode("ascii"),
            "dtype": raw.dtype.str,
            "shape": list(raw.shape),
        }
    if isinstance(value, tuple):
        return {"__tuple__": [to_plain(v, depth + 1) for v in value]}
    if isinstance(value, list):
        return [to_plain(v, depth + 1) for v in value]
    if isinstance(value, dict):
        return {"__dict__": [[to_plain(k, depth + 1), to_plain(v, depth + 1)] for k, v in value.items()]}
    if isinstance(value, Camera):
        return {"__camera__": value.to_dict()}
    if isinstance(value, MarkerMap):
        return {"__map__": value.to_dict()}
    if isinstance(value, Detection):
        body = [int(value.id), to_plain(np.asarray(value.corners_px, dtype=float))]
        return {"__detection__": body if value.dictionary is None else [*body, value.dictionary]}
    return {"__unsupported__": type(value).__name__}


_ARRAY_KINDS = {"b", "i", "u", "f"}


def from_plain(value: Any, depth: int = 0) -> Any:
    """The inverse of :func:`to_plain`.

    Parameters
    ----------
    value : object
        Plain data as :func:`to_plain` makes it (read from JSON).
    depth : int
        How deep ``value`` sits in the whole (the caller leaves it at 0).

    Returns
    -------
    object
        The value: arrays, tuples, dicts, Camera, MarkerMap, Detection as they were sent; an
        object that could not be sent comes back as a placeholder the grader marks Incorrect.

    Raises
    ------
    ValueError
        For anything :func:`to_plain` does not make (an unknown tag, a damaged array, too deep).

    Examples
    --------
    >>> from_plain(to_plain((1, [2.5, "a"])))
    (1, [2.5, 'a'])
    """
    if depth > MAX_DEPTH:
        raise ValueError("nested too deeply")
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [from_plain(v, depth + 1) for v in value]
    if not isinstance(value, dict) or len(value) not in (1, 3):
        raise ValueError("not plain data")
    if "__array__" in value:
        return _array_from_plain(value)
    ((tag, body),) = value.items()
    return _tagged_from_plain(tag, body, depth)


def _array_from_plain(value: dict) -> np.ndarray:
    """A tagged array (base64 of its bytes, dtype, shape) back as an array of its own."""
    shape, text = value.get("shape"), value.get("__array__")
    if not isinstance(value.get("dtype"), str) or not isinstance(shape, list) or not isinstance(text, str):
        raise ValueError("not an array fidlearn reads")
    if len(shape) > 8 or not all(type(n) is int and 0 <= n <= MAX_ARRAY_ITEMS for n in shape):
        raise ValueError("an array's shape is up to 8 whole numbers, each 0 or more")
    dtype = np.dtype(value["dtype"])
    if dtype.kind not in _ARRAY_KINDS or math.prod(shape) > MAX_ARRAY_ITEMS:
        raise ValueError("not an array fidlearn reads")
    raw = base64.b64decode(text, validate=True)
    if len(raw) != math.prod(shape) * dtype.itemsize:
        raise ValueError("array size does not match its shape")
    return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()


def _tagged_from_plain(tag: str, body: Any, depth: int) -> Any:
    """One tagged value (``{"__tuple__": ...}`` and the like) back as the value it stands for."""
    from .camera import Camera
    from .detection import Detection
    from .markermap import MarkerMap

    if tag == "__float__":
        return float(body) if body in ("nan", "inf", "-inf") else _bad(tag)
    if tag in ("__tuple__", "__dict__", "__detection__") and not isinstance(body, list):
        raise ValueError(f"{tag} holds a list")
    if tag == "__tuple__":
        return tuple(from_plain(v, depth + 1) for v in body)
    if tag == "__dict__":
        out = {}
        for item in body:
            if not isinstance(item, list) or len(item) != 2:
                raise ValueError("a __dict__ item is a [key, value] pair")
            k = from_plain(item[0], depth + 1)
            out[k if not isinstance(k, list) else tuple(k)] = from_plain(item[1], depth + 1)
        return out
    if tag == "__camera__":
        return Camera.from_dict(body, source="an answer")
    if tag == "__map__":
        return MarkerMap.from_dict(body, source="an answer")
    if tag == "__detection__":
        if len(body) not in (2, 3) or type(body[0]) is not int or (len(body) == 3 and type(body[2]) is not str):
            raise ValueError("a __detection__ is [id, corners] or [id, corners, dictionary]")
        return Detection(body[0], from_plain(body[1], depth + 1), *body[2:])
    if tag == "__unsupported__":
        return _Unsupported(str(body)[:80])
    return _bad(tag)


def _bad(tag: str):
    raise ValueError(f"unknown tag {tag[:40]!r}")


@dataclass(frozen=True)
class _Unsupported:
    """An answer of a type that cannot be sent as plain data (a function, an open file...)."""

    type_name: str
