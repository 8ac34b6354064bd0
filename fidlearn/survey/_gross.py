"""The gross test: tape placements off by more than the room can explain (a typo, a marker on another wall).

First pass, the photos alone: every marker seen in two photos or more is placed up to the gauge
(where the room is, which way it faces) by an adjustment of the photos alone, with one marker held.
It starts twice: from a chain (from the marker seen in most photos, photos located and markers placed
in turn, as :func:`initial_values` does from the tape map) and from the cameras the tape map places
(every marker then placed from the photos); the start whose adjustment fits the photos is kept (see
:func:`photo_placements`). A chain through small markers far away can take one's mirrored pose and end
in a false minimum (a mixed room's 80 mm markers); a tape start fails when the tape cannot place the
photos (most of it wrong). A similarity (rotation, translation, scale within
``UNITS_FACTOR_LIMIT``) laying these top-left corners on the tape's is fitted robustly: from
triples of taped markers (every triple, or ``MAX_TRIPLES`` drawn with a fixed seed), the one that
most markers agree with (within the threshold), refitted on them. Each taped marker's distance
from its aligned photo placement is its robust residual.

Threshold: ``GROSS_SIGMAS`` times the tape's sigma, or times the residuals' own spread (from
their median) when that is larger (a sigma given too small), and never less than one marker side
(the map's largest: what the photos' own pose ambiguity could move a corner). A taped marker beyond
it is gross: the survey places it from the photos alone. When no more than half of the taped markers agree, the
map cannot be mended by leaving some out: the survey refuses it, naming the markers (or, when a
majority agrees at a scale beyond ``UNITS_FACTOR_LIMIT``, saying the map's units look wrong).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from .. import _stats
from ..errors import MapError, SurveyError
from ..markermap import MarkerMap
from ._geometry import fit_motion, marker_sizes, placement_of
from ._init import UNITS_FACTOR_LIMIT, _place_new, _units_message, initial_values
from ._inputs import _Photo
from ._solve import FIRST_SIGMA_PX, _polish, build_problem
from ._variance import print_scale

#: A taped marker farther than this many tape sigmas (3D distance) from the photos is gross.
GROSS_SIGMAS = 15.0
#: At most this many triples of markers are tried as the alignment's seed.
MAX_TRIPLES = 2000
#: The median distance of a 3D Gaussian with unit sigma per coordinate (sqrt of chi-square(3)'s median).
_MEDIAN_3D = math.sqrt(_stats.chi2_ppf(0.5, 3))  # 1.5382


@dataclass
class GrossTest:
    """What the gross test found: each taped marker's robust residual (mm), the threshold, the gross markers."""

    residual_mm: dict[int, float] = field(default_factory=dict)
    threshold_mm: float = math.nan
    gross: tuple[int, ...] = ()
    spread_mm: float = math.nan  # the residuals' robust spread per coordinate (median / _MEDIAN_3D)
    scale: float = math.nan  # the similarity's scale: the markers' print scale
    scale_se: float = math.nan


def photo_placements(photos: list[_Photo], tape: MarkerMap) -> dict[int, np.ndarray]:
    """Top-left corners (mm) of the markers seen in two photos or more, from the photos alone (any gauge).

    Adjusted from two starts, the photos' own chain and the cameras the tape places (:func:`_chain_start`,
    :func:`_tape_start`). The one that places more markers (then locates more photos) is kept, unless the
    other's corners fit the photos better by more than half (RMS): a start that took a marker's mirrored pose
    ends in a false minimum many times the corner noise.
    """
    counts: dict[int, int] = {}
    for ph in photos:
        for i in ph.corners:
            counts[i] = counts.get(i, 0) + 1
    if not counts:
        return {}
    ref = max(counts, key=lambda i: (counts[i], -i))
    sizes = marker_sizes(tape, [ref, *(i for i in counts if i in tape)])  # the new markers' sides: measured
    tried = []
    for start in (_chain_start, _tape_start):
        placed, cams = start(photos, tape, ref, sizes)
        if ref in placed and len(placed) >= 2 and len(cams) >= 2:
            tried.append((*_adjusted(cams, placed, ref, sizes, tape), len(cams)))
        elif placed:
            tried.append((math.inf, {i: np.asarray(p, float) for i, (_, p) in placed.items()}, len(cams)))
    if not tried:
        return {}
    kept = max(tried, key=lambda t: (len(t[1]), t[2]))
    fits = min(tried, key=lambda t: t[0])
    return fits[1] if fits[0] < 0.5 * kept[0] else kept[1]


def _chain_start(photos: list[_Photo], tape: MarkerMap, ref: int, sizes: dict) -> tuple[dict, list[_Photo]]:
    """``(placed, located photos)`` from the photos alone: a chain from ``ref``.

    As :func:`initial_values` does from a tape map, from ``ref`` alone: photos located from the markers
    placed, markers placed from the photos located, in turn.
    """
    copies = [_Photo(ph.label, ph.camera, ph.corners) for ph in photos]
    start = MarkerMap(
        {ref: placement_of(ref, np.eye(3), np.zeros(3), sizes[ref])},
        tape.marker_size_mm,
        dictionary=tape.dictionary,
        units="mm",
        source="the photos",
    )
    placed, _ = initial_values(copies, start, sizes)
    return placed, [ph for ph in copies if ph.T_world_camera is not None]


def _tape_start(photos: list[_Photo], tape: MarkerMap, _ref: int, sizes: dict) -> tuple[dict, list[_Photo]]:
    """``(placed, located photos)``: the photos located from the tape map, every marker then placed from them.

    The tape only starts the cameras (:func:`fidlearn.estimate_pose` leaves a marker far off out); each
    marker's placement is the photos' (:func:`_place_new`), so a tape placement metres off moves nothing.
    """
    copies = [_Photo(ph.label, ph.camera, ph.corners) for ph in photos]
    initial_values(copies, tape, sizes)
    located = [ph for ph in copies if ph.T_world_camera is not None]
    placed = {}
    for i in dict.fromkeys(i for ph in located for i in ph.corners):  # in the order first seen
        showing = [ph for ph in located if i in ph.corners]
        cand = _place_new(i, showing, sizes.get(i, tape.marker_size_mm)) if len(showing) >= 2 else None
        if cand is not None:
            placed[i] = cand
    return placed, located


def _adjusted(cams: list[_Photo], placed: dict, ref: int, sizes: dict, tape: MarkerMap) -> tuple[float, dict]:
    """``(reprojection RMS (px), top-left corners)``: the photos alone adjusted, ``ref`` held.

    A photo that shows none of the markers ``placed`` (those it shows are in no other photo) holds nothing and
    is held by nothing: it is left out, or its camera would make every step singular.
    """
    cams = [ph for ph in cams if any(i in placed for i in ph.corners)]
    slots = [i for i in placed if i != ref] + [ref]
    opts = {"marker_size_mm": tape.marker_size_mm, "sizes": sizes, "sigma_px": FIRST_SIGMA_PX, "sigma_mm": math.inf}
    problem = build_problem(cams, slots, len(slots) - 1, placed, {}, {**opts, "sigma_rot_rad": math.inf})
    x = _polish(problem, np.zeros(problem.n_params))  # Gauss-Newton: the start is the photos' own
    _, _, _, p_mark = problem.poses(x)
    rms = float(np.sqrt(np.mean(problem.reprojection_px(x) ** 2)))
    return rms if math.isfinite(rms) else math.inf, {
        i: p_mark[k] for k, i in enumerate(slots) if np.all(np.isfinite(p_mark[k]))
    }


def gross_test(photos: list[_Photo], tape: MarkerMap, sigma_mm: float | None) -> GrossTest:
    """The taped markers that disagree with the photos by more than the room can explain.

    ``sigma_mm`` None (to be learnt): the threshold is the residuals' own spread (and one marker side).

    Raises
    ------
    SurveyError
        No more than half of the taped markers seen agree with the photos (naming them).
    """
    if sigma_mm is not None and not math.isfinite(sigma_mm):
        return GrossTest()
    seen = photo_placements(photos, tape)
    units = _units(seen, tape)
    ids = list(units)
    if len(ids) < 4:  # a majority of three is two markers: too few to align
        return GrossTest()
    src, dst = _points(units, seen, tape)
    floor = max(GROSS_SIGMAS * (sigma_mm or 0.0), max(tape.marker_size(m) for unit in units.values() for m in unit))
    inliers = _consensus(src, dst, floor)
    threshold = floor
    if 2 * int(inliers.sum()) > len(ids):
        r = _residuals(src, dst, inliers)
        threshold = max(floor, GROSS_SIGMAS * float(np.median(r)) / _MEDIAN_3D)
        for _ in range(2):  # refit on the markers within the final threshold
            inliers = r <= threshold
            r = _residuals(src, dst, inliers) if 2 * int(inliers.sum()) > len(ids) else r
        inliers = r <= threshold
    else:
        _refuse_units(src, dst, floor, tape)
        r = _residuals(src, dst, inliers)
    residual = {i: float(v) for i, v in zip(ids, r)}
    if 2 * int(inliers.sum()) <= len(ids):
        raise SurveyError(_no_majority(ids, inliers, residual, threshold, tape))
    gross = tuple(m for i, ok in zip(ids, inliers) if not ok for m in units[i])
    scale, scale_se = print_scale(src, dst, r, _similarity)
    each = {m: residual[i] for i in ids for m in units[i]}
    return GrossTest(each, threshold, gross, float(np.median(r)) / _MEDIAN_3D, scale, scale_se)


def _points(units: dict, seen: dict, tape: MarkerMap) -> tuple[np.ndarray, np.ndarray]:
    """Each unit's point (mm) from the photos and from the tape: its markers' mean top-left corner."""
    src = np.array([np.mean([seen[m] for m in unit], axis=0) for unit in units.values()])
    dst = np.array([np.mean([tape.placements[m].translation_mm for m in unit], axis=0) for unit in units.values()])
    return src, dst.astype(float)


def _units(seen: dict, tape: MarkerMap) -> dict[object, list]:
    """What the test aligns and judges: each taped single marker the photos place, and each rigid entry as one.

    ``{single marker's key: [it]}`` first (by id), then ``{entry name: [its markers the photos place]}``: an
    entry's point is its markers' mean top-left corner (the photos' and the tape's of the same markers), so a
    moved board counts once, as the one object that moved, however many markers it carries.
    """
    units: dict[object, list] = {i: [i] for i in sorted(i for i in seen if i in tape and i not in tape.owner)}
    for i in seen:
        if i in tape.owner:
            units.setdefault(tape.owner[i], []).append(i)
    return units


def _refuse_units(src: np.ndarray, dst: np.ndarray, threshold: float, tape: MarkerMap) -> None:
    """Raise MapError when a majority agrees at a scale the units check refuses (the map's units are wrong)."""
    inliers = _consensus(src, dst, threshold, limit=math.inf)
    if 2 * int(inliers.sum()) > len(src):
        sim = _similarity(src[inliers], dst[inliers], limit=math.inf)
        if sim is not None:
            raise MapError(_units_message(sim[0], tape))


def _consensus(src: np.ndarray, dst: np.ndarray, threshold: float, limit: float = UNITS_FACTOR_LIMIT) -> np.ndarray:
    """The inliers (bool, one per marker) of the best similarity seeded by a triple of markers.

    The similarity's scale must lie within ``limit`` of 1; ``threshold`` is in the tape's mm.
    """
    n = len(src)
    triples = list(combinations(range(n), 3)) if math.comb(n, 3) <= MAX_TRIPLES else None
    if triples is None:
        rng = np.random.default_rng(0)
        triples = [tuple(rng.choice(n, 3, replace=False)) for _ in range(MAX_TRIPLES)]
    best = np.zeros(n, bool)
    best_key = (-1, math.inf)
    for t in triples:
        sim = _similarity(src[list(t)], dst[list(t)], limit)
        if sim is None:
            continue
        d = np.linalg.norm(_apply(sim, src) - dst, axis=1)
        ok = d <= threshold
        key = (int(ok.sum()), float(np.sum(np.minimum(d, threshold))))
        if key[0] > best_key[0] or (key[0] == best_key[0] and key[1] < best_key[1]):
            best, best_key = ok, key
    return best


def _residuals(src: np.ndarray, dst: np.ndarray, inliers: np.ndarray) -> np.ndarray:
    """Distances (mm) of the aligned photo placements from the tape's, the similarity fitted on ``inliers``."""
    sim = _similarity(src[inliers], dst[inliers]) if inliers.sum() >= 3 else None
    if sim is None:
        return np.full(len(src), math.inf)
    return np.linalg.norm(_apply(sim, src) - dst, axis=1)


def _similarity(a: np.ndarray, b: np.ndarray, limit: float = UNITS_FACTOR_LIMIT):
    """``(s, R, t)`` with ``s R a + t`` closest to ``b``; None when degenerate or the scale is off."""
    return fit_motion(a, b, scaled=True, limit=limit)


def _apply(sim, p: np.ndarray) -> np.ndarray:
    s, R, t = sim
    return s * p @ R.T + t


def _no_majority(ids, inliers, residual, threshold: float, tape: MarkerMap) -> str:
    agree = [i for i, ok in zip(ids, inliers) if ok]
    off = [i for i, ok in zip(ids, inliers) if not ok]
    worst = ", ".join(f"{i} ({residual[i] / 1000:.2g} m)" for i in off[:8] if math.isfinite(residual[i]))
    return (
        f"{tape.source}: the tape placements cannot agree with the photos: at most {len(agree)} of the "
        f"{len(ids)} taped markers the photos place ({agree}) fit them within {threshold:.0f} mm, no majority; "
        f"markers {off} are off{' by ' + worst if worst else ''}: check the map's ids and positions and measure "
        "them again"
    )
