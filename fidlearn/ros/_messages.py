"""ROS 2 messages built from plain dicts (ROS field names), with every field not given at its zero value.

The message classes are ``rosbags``' (a typestore of ROS 2 Humble's definitions), so a message made
here serializes as CDR exactly as a ROS 2 node's would.
"""

from __future__ import annotations

from typing import Any

import numpy as np

_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def typestore():
    """rosbags' typestore of ROS 2 Humble's message definitions (made once).

    Returns
    -------
    rosbags.typesys.store.Typestore
        The typestore.
    """
    global _STORE
    if _STORE is None:
        from rosbags.typesys import Stores, get_typestore

        _STORE = get_typestore(Stores.ROS2_HUMBLE)
    return _STORE


_STORE = None


def _scalar(base: str, value: Any):
    if base == "string":
        return "" if value is None else str(value)
    if base == "bool":
        return bool(value) if value is not None else False
    kind = _DTYPES[base]
    if value is None:
        return 0.0 if np.issubdtype(kind, np.floating) else 0
    return float(value) if np.issubdtype(kind, np.floating) else int(value)


def _field(store, desc, value: Any):
    nodetype, detail = int(desc[0]), desc[1]
    if nodetype == 1:  # a base type
        return _scalar(detail[0], value)
    if nodetype == 2:  # a message
        return build(detail, value or {}, store)
    (item_type, item_detail), length = detail
    if int(item_type) == 1 and item_detail[0] in _DTYPES:
        array: np.ndarray = np.asarray([] if value is None else value, dtype=_DTYPES[item_detail[0]]).reshape(-1)
        if nodetype == 3 and value is None:
            array = np.zeros(length, dtype=_DTYPES[item_detail[0]])
        return array
    items = [] if value is None else list(value)
    if nodetype == 3 and value is None:
        items = [None] * length
    return [_field(store, (item_type, item_detail), v) for v in items]


def build(typename: str, values: dict | None = None, store=None):
    """A ROS 2 message of ``typename`` from a dict of its fields (nested dicts for nested messages).

    Parameters
    ----------
    typename : str
        E.g. ``"geometry_msgs/msg/PoseWithCovarianceStamped"``.
    values : dict, optional
        Field values by ROS name; missing fields are zero, empty text, empty lists (fixed arrays
        zeros of their length).
    store : Typestore, optional
        Default :func:`typestore`.

    Returns
    -------
    object
        The message (a rosbags message class instance).

    Raises
    ------
    KeyError
        A field the message does not have (a mistake in the calling code, not in user data).
    """
    store = store if store is not None else typestore()
    values = dict(values or {})
    _, fields = store.fielddefs[typename]
    names = {name for name, _ in fields}
    unknown = set(values) - names
    if unknown:
        raise KeyError(f"{typename} has no field {sorted(unknown)[0]!r}")
    args = {name: _field(store, desc, values.get(name)) for name, desc in fields}
    return store.types[typename](**args)


def stamp_dict(stamp_ns: int) -> dict:
    """``{"sec", "nanosec"}`` of a time in nanoseconds.

    Parameters
    ----------
    stamp_ns : int
        Nanoseconds since the epoch (>= 0).

    Returns
    -------
    dict
        ``builtin_interfaces/msg/Time``'s fields.
    """
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return {"sec": sec, "nanosec": nanosec}
