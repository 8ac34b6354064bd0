"""Which of the markers large enough for the detector it finds, and so which poses a camera may get.

:func:`~fidlearn.planning.predict.predict_accuracy` counts a marker as seen when it is whole in the
picture, facing the camera and larger than the detector's limits
(:func:`~fidlearn.planning.noise.min_perimeter_px`). That limit is where half of the face-on markers
at the picture's centre are found; a marker on a wall seen from a few metres, upright and a little
oblique, needs more: its cells fall between the pixels. Measured on fidlearn's renders (the rooms of
``benchmarks/bench_planning.py``, seed 11: walls of 1 to 12 markers seen from 0.5 to 4 m, up to 45 deg
off their axis, 640x480 to 1920x1080; 1105 markers with sides under 25 px at 640x480), the chance that
such a marker is found rises from a quarter at 10.5 px sides through a half at 11.6 px to 0.98 at
15-18 px; a logistic curve in the mean side fits it (held out: seed 12 gives 11.8 px and the same
slope). Larger markers are missed once in a hundred (52 of 5170 over 25 px, seeds 11 and 12): a few
touch the picture's border, the others are lost by the detector for no reason of size.

A pose from fewer markers than predicted is worse, and one marker left alone may flip to its other
planar solution: ``predict_accuracy`` mixes the errors of the subsets of markers that may be found
(:func:`found_subsets`), each with its chance, and says how likely no marker at all is found.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import PoseError
from ._checks import check_number

__all__ = ["HALF_FOUND_SIDE_PX", "FOUND_SCALE_PX", "MISSED", "found_probability", "found_subsets"]

#: Mean apparent side (px) at which half of the markers are found in the rendered rooms ...
HALF_FOUND_SIDE_PX = 11.6
#: ... and the scale (px) of the logistic curve about it.
FOUND_SCALE_PX = 1.23
#: Chance that a marker of any size is not found (its border too near the picture's edge, or lost
#: by the detector).
MISSED = 0.01
#: A marker found with at least this chance counts as always found when subsets are formed.
SURE = 0.97
#: At most this many subsets are mixed: all of them while there are few uncertain markers, else
#: this many drawn at random (a fixed seed, so a prediction is the same every time).
MAX_SUBSETS = 16
#: Subsets less likely than this (relative to the chance of a pose) are left out.
MIN_WEIGHT = 0.002


def found_probability(side_px: float) -> float:
    """Chance that the detector finds a marker of mean apparent side ``side_px`` in a room.

    The marker must already pass the detector's size limits
    (:func:`~fidlearn.planning.noise.min_perimeter_px`); this is the chance it is then found.

    Parameters
    ----------
    side_px : float
        Mean apparent side (px).

    Returns
    -------
    float
        ``(1 - MISSED) / (1 + exp(-(side_px - HALF_FOUND_SIDE_PX) / FOUND_SCALE_PX))``.

    Raises
    ------
    PoseError
        If ``side_px`` is not a positive number of pixels.

    Examples
    --------
    >>> round(found_probability(11.6), 3)
    0.495
    >>> round(found_probability(40.0), 2)
    0.99
    """
    z = (check_number(side_px, "side_px", 0.0, 1e7, PoseError, " px") - HALF_FOUND_SIDE_PX) / FOUND_SCALE_PX
    return (1.0 - MISSED) / (1.0 + math.exp(-max(z, -700.0)))


def found_subsets(found: dict[int, float]) -> tuple[list[tuple[float, list[int]]], float]:
    """The subsets of markers that may be found, each with its chance given that some marker is.

    Parameters
    ----------
    found : dict of int to float
        Each marker's chance of being found (:func:`found_probability`).

    Returns
    -------
    subsets : list of (float, list of int)
        ``(weight, sorted ids)``; the weights sum to 1. Markers found with a chance of at least
        :data:`SURE` are in every subset; the others in or out as their chances say, every
        combination while they make at most :data:`MAX_SUBSETS`, else that many drawn at random.
    pose_probability : float
        The chance that at least one marker is found.
    """
    sure = sorted(i for i, p in found.items() if p >= SURE)
    unsure = sorted(i for i, p in found.items() if p < SURE)
    pose_probability = 1.0 - math.prod(1.0 - p for p in found.values())
    weights, picks = _picks([found[i] for i in unsure], bool(sure))
    out = [(w, sorted(sure + [i for i, k in zip(unsure, c) if k])) for w, c in zip(weights, picks)]
    out = [(w, ids) for w, ids in out if ids]
    total = sum(w for w, _ in out)
    out = [(w, ids) for w, ids in out if w >= MIN_WEIGHT * total]
    total = sum(w for w, _ in out)
    return [(w / total, ids) for w, ids in out], pose_probability


def _picks(chances: list[float], any_sure: bool) -> tuple[list[float], list[np.ndarray]]:
    """Weights and in-or-out masks of the uncertain markers: every combination, or draws that find some marker."""
    if 2 ** len(chances) <= MAX_SUBSETS:
        picks = [np.array(c, dtype=bool) for c in itertools.product([False, True], repeat=len(chances))]
        return [math.prod(p if k else 1.0 - p for p, k in zip(chances, c)) for c in picks], picks
    q = np.array(chances)
    draws = np.random.default_rng(20261128).random((64 * MAX_SUBSETS, len(q))) < q
    picks = [c for c in draws if any_sure or c.any()][:MAX_SUBSETS] or [q == q.max()]
    return [1.0] * len(picks), picks
