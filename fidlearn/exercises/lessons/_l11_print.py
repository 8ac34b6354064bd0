"""Lesson 11, q5: the size_mm to put in the map for markers a printer scaled.

Kept apart from :mod:`.l11_mapping` (which lists ``_q5`` in its ``build``) for that module's length.
"""

from __future__ import annotations

import numpy as np

from .._engine import Detector, Question, QuestionText
from .._parsers import _array, _close, _cmp_array
from .._scenery import _rng

#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "The size_mm for your printer's scale",
    "task": """
        Your markers came out of the printer at a scale that is not quite 100 % (a "fit to page"
        setting). `ids` (n,) are the map's markers and `size_mm` (n,) the side of each one's black
        square as the map says, the size you asked the printer for (the map mixes sizes). With a ruler
        you measured the black squares of the markers `measured_ids` (all of one size): `measured_mm`.
        Write code that computes the `size_mm` to put in the map for every marker of `ids` (mm, in that
        order), so that `locate` works with the sizes the markers really have.
        """,
    "hint": [
        "A printer's scale multiplies every length on the page by the same factor: a large marker grows or "
        "shrinks by more millimetres than a small one, by the same fraction.",
        "Find that factor from the markers you measured (what the ruler says over what you asked for, averaged), "
        "then apply it to each marker's own size.",
    ],
    "solution": """
        asked = dict(zip(q5.inputs.ids, q5.inputs.size_mm))
        measured_asked = np.array([asked[i] for i in q5.inputs.measured_ids])
        scale = np.mean(np.asarray(q5.inputs.measured_mm) / measured_asked)
        q5.answer = np.asarray(q5.inputs.size_mm) * scale
        """,
    "level": "easy",
}

#: Sides (mm) a map's markers are asked at; each variant uses two or three of them.
_SIZES = (60.0, 80.0, 100.0, 120.0, 150.0, 160.0, 200.0, 250.0)
#: Tolerance of the answer (mm per marker): a size rounded to 0.1 mm passes.
_TOL_MM = 0.06


def _q5_data(rng: np.random.Generator):
    """ids (n,), sizes (n,), the measured ids and their ruler readings (0.5 mm), and the printer's true scale."""
    sizes = np.sort(rng.choice(_SIZES, size=int(rng.integers(2, 4)), replace=False))
    per = [int(rng.integers(3, 6))] + [int(rng.integers(1, 4)) for _ in sizes[1:]]
    size_mm = np.concatenate([np.full(k, s) for k, s in zip(per, sizes)])
    ids = np.sort(rng.choice(50, size=len(size_mm), replace=False)).astype(int)
    order = rng.permutation(len(ids))  # sizes not sorted along the ids
    size_mm = size_mm[order]
    scale = float(rng.choice([-1, 1]) * rng.uniform(0.012, 0.05) + 1.0)
    small = np.flatnonzero(size_mm == sizes[0])  # the smallest fit the ruler: those are measured
    measured = np.round(2 * (size_mm[small] * scale + rng.normal(0, 0.15, len(small)))) / 2
    return ids, size_mm, ids[small], measured, scale


def _q5_mistakes(size_mm: np.ndarray, asked: float, measured: np.ndarray) -> list[tuple[Detector, str]]:
    """The mistakes q5 names, each a detector of the answer it gives and the message."""
    scale = float(np.mean(measured) / asked)
    offset = float(np.mean(measured) - asked)
    return [
        (
            lambda a: _close(a, size_mm + offset, _TOL_MM),
            f"that changes every marker by the same {offset:+.2f} mm; a printer scales: a {size_mm.max():g} mm "
            "marker changes by more millimetres than a small one, by the same fraction",
        ),
        (
            lambda a: _close(a, size_mm / scale, _TOL_MM),
            "that divides by the scale: the printed side is the asked side times the scale (measured over asked)",
        ),
        (
            lambda a: _close(a, np.full_like(size_mm, np.mean(measured)), _TOL_MM),
            "that gives every marker the measured markers' side; the map mixes sizes: scale each marker's own",
        ),
        (
            lambda a: _close(a, size_mm, _TOL_MM),
            "those are the sizes you asked for; the ruler says the printer made them differently",
        ),
        (
            lambda a: _close(a, size_mm * scale * 100, 100 * _TOL_MM) or _close(a, size_mm * 100, 100 * _TOL_MM),
            "size_mm is in millimetres: the scale is a fraction (0.987), not a percentage",
        ),
    ]


def _distinct(key: np.ndarray, size_mm: np.ndarray, asked: float, measured: np.ndarray) -> bool:
    """Whether every named mistake's answer is further than three tolerances from the key."""
    scale = float(np.mean(measured) / asked)
    others = (
        size_mm + (np.mean(measured) - asked),
        size_mm / scale,
        np.full_like(size_mm, np.mean(measured)),
        size_mm,
    )
    return all(np.abs(o - key).max() > 3 * _TOL_MM for o in others)


def _q5(learner: str) -> Question:
    """q5: The size_mm for your printer's scale."""
    rng = _rng("11", learner, "q5")
    while True:
        ids, size_mm, measured_ids, measured, _ = _q5_data(rng)
        asked = float(size_mm[np.isin(ids, measured_ids)][0])
        key = size_mm * float(np.mean(measured / asked))
        if _distinct(key, size_mm, asked, measured):
            break
    return Question(
        "q5",
        inputs={"ids": ids, "size_mm": size_mm, "measured_ids": measured_ids, "measured_mm": measured},
        expected=key,
        parse=_array((len(ids),), "each marker's size_mm, in the order of ids"),
        compare=_cmp_array(_TOL_MM, " mm"),
        wrong=_q5_mistakes(size_mm, asked, measured),
        **_Q5,
    )
