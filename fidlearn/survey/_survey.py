"""survey(): the marker map from photos, joined with the tape."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .. import frames
from ..errors import FidlearnWarning, SurveyError
from ..markermap import MarkerMap
from ._entries import (
    adjustment_slots,
    entry_frame,
    entry_groups,
    member_covariance,
    refuse_untied,
    scaled_entry,
    slot_of,
    slot_order,
    start_from_photos,
    surveyed_entry,
)
from ._geometry import marker_sizes, placement_of
from ._gross import GrossTest, gross_test
from ._init import _locate, check_units, initial_values, remeasured_sides
from ._inputs import MAX_MAP_SIGMA_MM, MIN_MAP_SIGMA_MM, MIN_PHOTOS, STAGES, _check_options, _read_photos, _report
from ._result import Survey, Suspect, check_readable
from ._solve import (
    FIRST_SIGMA_PX,
    build_problem,
    corner_sigma,
    covariance,
    fit,
    marker_block,
    suspect_threshold,
    tape_test,
)
from ._variance import SIGMA_RTOL, SIGMA_STEPS, START_SIGMA_MM, next_sigma, scale_applies, sigma_error

__all__ = ["survey"]

#: At most this many markers are named suspects (and let go of their tape placement) in one survey.
MAX_SUSPECTS = 4


def survey(
    images, marker_map, camera, *, map_sigma_mm=None, fixed_ids=None, corner_sigma_px=None, progress=None
) -> Survey:
    """The marker map from photos, joined with the tape map: a bundle adjustment.

    Unknowns: every photo's camera pose and every marker's placement (6 each). Residuals: each
    detected corner's reprojection through the camera's lens model (OpenCV's pinhole with its
    distortion, or the Kannala-Brandt fisheye: ``Camera.model``), in the picture's own pixels, over
    the corner noise, and each taped marker's placement minus the tape's over ``map_sigma_mm``
    (position, per coordinate) and
    ``map_sigma_mm / marker_size_mm`` radians (rotation: as if two corners one side apart were
    each off by the tape's sigma). ``scipy.optimize.least_squares`` solves it with a sparse
    analytic Jacobian, first with a soft-L1 loss on the tape residuals (so a marker taped 100 mm
    off cannot drag the others), then plainly; a marker seen in two photos or more whose tape
    placement disagrees with the photos (a chi-square test at 1 %, see :mod:`fidlearn.survey._solve`)
    is named a suspect and its tape prior dropped, so the photos alone place it. The corner noise
    is estimated from the residuals unless given; the covariances assume it, and the tape's sigma
    (given, or learnt from the tape residuals when ``map_sigma_mm`` is None).

    A photo the tape map cannot locate (most of what it shows taped wrong: a moved board) is located again
    with the map the adjustment made, and when that places it the adjustment runs again with its corners.

    A rigid entry of the map (a ChArUco or grid board, a bundle: :mod:`fidlearn.markermap_entries`) is one
    placement in the adjustment, its markers' corners fixed in it by the entry's geometry
    (:mod:`fidlearn.survey._entries`): its tape prior, its suspect test, the gross test's vote and a fixed id
    among its markers are the entry's, and the surveyed map writes it back as the entry, moved.

    Before all this, a gross test (:mod:`fidlearn.survey._gross`): the photos alone place every
    marker seen in two photos up to the gauge, a similarity laying them on the tape map is fitted
    robustly (by the markers that agree), and a taped marker farther from the photos than the room
    can explain (``GROSS_SIGMAS`` tape sigmas or residual spreads, at least one marker side: a
    typo, metres off) is a suspect whose tape placement is never used, so it cannot drag the
    others; the survey is then the one it would be without that marker's tape entry. Each taped
    marker's distance in that alignment is :attr:`Survey.tape_residual_mm`.

    Parameters
    ----------
    images : sequence
        The photos: paths, image arrays (gray or BGR), or lists of :class:`fidlearn.Detection`
        (already detected; corners in px, TL, TR, BR, BL). Markers are detected with
        :func:`fidlearn.detect_markers` (edge refinement) in each of the map's dictionaries.
    marker_map : MarkerMap or path
        The tape map: each marker's top-left corner and rotation, as measured.
    camera : Camera or path
        The calibrated camera, pinhole or fisheye (fitted to each image's size as :func:`fidlearn.locate`
        does). A fisheye's corners are projected through its own model, markers near the picture's
        edge included; a ray 90 degrees or more off the axis has no place in the adjustment.
    map_sigma_mm : float or None
        Standard deviation of the tape's top-left corners, mm per coordinate; ``math.inf`` to let
        the photos alone decide (then ``fixed_ids`` hold the map in the world). None (the default):
        learnt from the tape residuals, a variance component (Helmert, Foerstner: the sum of the
        squared tape position residuals over their redundancy, iterated to a fixed point from the
        gross test's robust spread, the suspects left out; :mod:`fidlearn.survey._variance`), with
        its standard error (:attr:`Survey.map_sigma_se_mm`); the markers' print scale is then
        applied when it is more than 3 standard errors from 1 (:attr:`Survey.print_scale`). A
        number given is used as it is, and the print scale only reported.
    fixed_ids : int or sequence of int, optional
        Markers whose tape placement is exact: held, not adjusted (a marker of a rigid entry holds its entry). A
        marker of another dictionary than the map's is given by its key, ``marker_map.key(id, dictionary)``.
    corner_sigma_px : float, optional
        Corner noise, px per coordinate; estimated from the residuals when None.
    progress : callable, optional
        ``progress(i, n, label)`` after each photo is read, then ``progress(n, n, stage)`` as each stage of the
        adjustment starts (``"checking the tape"``, ``"adjusting"``, ``"adjusting with more photos"``). Whatever
        it raises stops the survey as a :class:`~fidlearn.errors.SurveyError` naming it, with the original as
        ``__cause__``.

    Returns
    -------
    Survey
        The surveyed map (same units as the tape map), the suspects, each marker's covariance, the
        camera poses (``T_world_camera``, mm) and what could not be used.

    Raises
    ------
    SurveyError
        Fewer than 2 photos give a camera pose (the message says why and what photo to take),
        bad options (each with its range), more than ``MAX_PHOTOS`` photos (400, before reading any)
        or ``MAX_SIGHTINGS`` markers detected in them (1,200), a ``progress`` function that raises
        (its exception is the SurveyError's ``__cause__``), nothing ties the photos to the world,
        no majority of the taped markers agrees with the photos (the message names them), or a fixed
        marker is off by more than the room can explain.
    MapError
        The map cannot be read, or its distances disagree with the photos' by a factor (units).
    ImageError
        A photo cannot be read.
    CameraError
        The camera does not fit a photo.

    Warns
    -----
    FidlearnWarning
        For each marker seen but not placed (not in the map and in only one photo), saying what to take.
    """
    tape, camera, sigma_mm, fixed = _check_options(marker_map, camera, map_sigma_mm, fixed_ids, corner_sigma_px)
    photos = _read_photos(images, tape, camera, progress)
    _one_size(photos)

    def stage(k: int) -> None:  # the adjustment's stages (STAGES), on the photos' finished bar
        if progress is not None:
            _report(progress, len(photos), len(photos), STAGES[k])

    stage(0)
    gross = gross_test(photos, tape, sigma_mm)
    bad = {slot_of(i, tape.owner) for i in gross.gross}  # a gross marker's entry is gross as a whole
    if bad & {slot_of(i, tape.owner) for i in fixed}:
        raise SurveyError(_fixed_gross(gross, fixed, tape))
    clean = {i: p for i, p in tape.placements.items() if slot_of(i, tape.owner) not in bad}
    clean_map = MarkerMap(clean, tape.marker_size_mm, dictionary=tape.dictionary, units=tape.units, source=tape.source)
    check_units(photos, clean_map)
    sizes = marker_sizes(tape, tape.ids)  # and the markers the map lacks: measured from the photos
    placed, unplaced = initial_values(photos, clean_map, sizes)
    cams = _usable(photos)
    learn = sigma_mm is None
    sigma_mm, scale = _start(sigma_mm, gross)
    groups = entry_groups(tape, scale)
    placed.update(_entry_starts(tape, groups, cams, placed, bad))
    for i, reason in unplaced.items():
        if tape.owner.get(i) not in placed:  # a gross entry's marker in one photo is placed with its entry
            warnings.warn(reason, FidlearnWarning, stacklevel=2)
    free, slots = adjustment_slots(cams, placed, tape.owner, fixed)
    if math.isinf(sigma_mm):
        refuse_untied(cams, slots, len(free), tape.owner, fixed)
    opts = {**_options(tape, sizes, placed, scale, sigma_mm, corner_sigma_px), "groups": groups}
    taped = {i: (p.R_world_marker, np.asarray(p.translation_mm, float)) for i, p in tape.placements.items()}
    taped.update({name: entry_frame(e) for name, e in tape.entries.items()})
    priors = {} if math.isinf(sigma_mm) else {i: taped[i] for i in free if i in taped}
    stage(1)
    fitted = _adjust(cams, slots, len(free), placed, priors, opts, corner_sigma_px is None, bad, learn)
    learnt = {"learnt": learn, "scale": scale, "size": tape.marker_size_mm, "sides": sizes, "groups": groups}
    if _located_again(photos, tape, fitted, slots, learnt):  # then adjusted again, with them, from the first
        _, _, R_mark, p_mark = fitted[0].poses(fitted[1])
        placed.update({i: (R_mark[k], p_mark[k]) for k, i in enumerate(slots)})
        cams = _usable(photos)
        stage(2)
        fitted = _adjust(cams, slots, len(free), placed, priors, opts, corner_sigma_px is None, bad, learn)
    return _result(tape, photos, cams, slots, fitted, unplaced, fixed, gross, learnt)


def _located_again(photos: list, tape: MarkerMap, fitted: tuple, slots: list, learnt: dict) -> bool:
    """Locate again, with the map the adjustment made, the photos the tape map could not; True if any is located.

    A photo whose markers the tape puts wrong (most of what it shows is a moved board) has no pose from the tape
    map; from the adjusted map it has one, and its corners join the adjustment.
    """
    lost = [ph for ph in photos if ph.T_world_camera is None and ph.reason.startswith("no camera pose from the map")]
    if not lost:
        return False
    problem, x = fitted[:2]
    _, _, R_mark, p_mark = problem.poses(x)
    current = _surveyed_map(tape, problem, R_mark, p_mark, slots, learnt)
    for ph in lost:
        _locate(ph, current)
    return any(ph.T_world_camera is not None for ph in lost)


def _entry_starts(tape: MarkerMap, groups: dict, cams: list, placed: dict, bad: set) -> dict:
    """Each entry's starting placement: the tape's, or where the photos put its markers when the tape's is gross."""
    starts = {}
    for name, g in groups.items():
        start = start_from_photos(g, cams, placed) if name in bad else entry_frame(tape.entries[name])
        if start is not None:
            starts[name] = start
    return starts


def _options(tape: MarkerMap, sizes: dict, placed: dict, scale: float, sigma_mm: float, corner_sigma_px) -> dict:
    """The adjustment's options: marker sides (the map's times the print ``scale``), the measured ones, sigmas."""
    return {
        "marker_size_mm": tape.marker_size_mm * scale,
        "sizes": {i: v * (scale if i in tape else 1.0) for i, v in sizes.items()},
        "measured": [i for i in placed if i not in tape and i in sizes],
        "sigma_px": corner_sigma_px or FIRST_SIGMA_PX,
        "sigma_mm": sigma_mm,
        "sigma_rot_rad": sigma_mm / tape.marker_size_mm,
    }


def _start(sigma_mm: float | None, gross: GrossTest) -> tuple[float, float]:
    """``(sigma_mm, print scale)`` the adjustment starts from: as given (scale 1), or to be learnt.

    To be learnt (None): the gross test's robust spread (or ``START_SIGMA_MM``), and its print scale
    when it is significant (:func:`fidlearn.survey._variance.scale_applies`).
    """
    if sigma_mm is not None:
        return sigma_mm, 1.0
    start = gross.spread_mm if math.isfinite(gross.spread_mm) else START_SIGMA_MM
    scale = gross.scale if scale_applies(gross.scale, gross.scale_se) else 1.0
    return min(max(start, MIN_MAP_SIGMA_MM), MAX_MAP_SIGMA_MM), scale


def _fixed_gross(gross: GrossTest, fixed, tape: MarkerMap) -> str:
    held = {slot_of(i, tape.owner) for i in fixed}
    bad = [i for i in gross.gross if slot_of(i, tape.owner) in held]
    what = f"fixed marker {bad[0]}"
    if bad[0] in tape.owner:
        name = tape.owner[bad[0]]
        what = f"entry {name!r}, held by fixed marker {next(f for f in fixed if tape.owner.get(f) == name)},"
    return (
        f"{what} is {gross.residual_mm[bad[0]]:.0f} mm from where the photos put it (more than the "
        f"{gross.threshold_mm:.0f} mm the room can explain): a fixed placement must be exact; measure it again or "
        "fix another marker"
    )


def _one_size(photos: list) -> None:
    """SurveyError for photos of several sizes: before the gross test, which would blame the tape for them."""
    sizes_px = sorted({ph.camera.image_size for ph in photos if getattr(ph, "camera", None) is not None})
    if len(sizes_px) > 1:
        raise SurveyError(
            f"the photos have different sizes ({', '.join(f'{w}x{h}' for w, h in sizes_px)}); survey with photos "
            "from one camera at one resolution"
        )


def _usable(photos: list) -> list:
    cams = [ph for ph in photos if ph.T_world_camera is not None]
    if len(cams) < MIN_PHOTOS:
        why = "; ".join(f"{ph.label}: {ph.reason}" for ph in photos if ph.T_world_camera is None)
        raise SurveyError(
            f"only {len(cams)} of {len(photos)} photos give a camera pose, a survey needs {MIN_PHOTOS}: {why}"
        )
    if any(not np.array_equal(ph.camera.K, cams[0].camera.K) for ph in cams):
        raise SurveyError("the photos have different sizes; survey with photos from one camera at one resolution")
    return cams


def _adjust(cams, slots, n_free, placed, priors, opts, estimate_sigma: bool, gross: set[int], learn: bool):
    """Robust pass, corner noise, then the suspect passes; with ``learn``, the tape's sigma to its fixed point.

    The gross markers' tape placements are left out from the start (they are suspects already).
    The tape's sigma is learnt as :mod:`fidlearn.survey._variance` says: each step re-solves (and
    re-tests the suspects) at the sigma the last solution's tape residuals give.
    """
    problem = build_problem(cams, slots, n_free, placed, {i: v for i, v in priors.items() if i not in gross}, opts)
    seen_twice = {i for k, i in enumerate(slots) if len(set(problem.obs_cam[problem.obs_marker == k])) >= 2}
    x = fit(problem, np.zeros(problem.n_params), robust=True)
    if estimate_sigma:
        opts = {**opts, "sigma_px": corner_sigma(problem, x, gauge_free=False)}
    if opts.get("measured"):  # the added markers' sides again, from the cameras the known markers now place
        opts = {**opts, "sizes": {**opts["sizes"], **remeasured_sides(cams, problem, x, opts["measured"])}}
    fitted = _suspect_passes(cams, slots, n_free, placed, priors, opts, x, seen_twice, gross)
    redundancy = math.nan
    for _ in range(SIGMA_STEPS if learn and priors else 0):
        problem, x, C = fitted[:3]
        sigma, redundancy = next_sigma(problem, x, C)
        done = abs(sigma / opts["sigma_mm"] - 1) < SIGMA_RTOL
        ratio = opts["sigma_rot_rad"] / opts["sigma_mm"]
        opts = {**opts, "sigma_mm": sigma, "sigma_rot_rad": sigma * ratio}
        fitted = _suspect_passes(cams, slots, n_free, placed, priors, opts, x, seen_twice, gross)
        if done:
            break
    return (*fitted, redundancy)


def _suspect_passes(cams, slots, n_free, placed, priors, opts, x, seen_twice: set[int], gross: set[int]):
    """Plain passes from ``x`` until the suspect test names no new marker.

    Suspects are named one at a time, the worst first (a marker far off can make its neighbours
    look wrong until it is let go), and only among markers seen in two photos or more: one photo
    cannot dispute the tape (a lone marker's pose may flip), it asks for another photo.
    """
    dropped: set[int] = set(gross)
    threshold = suspect_threshold()
    for _ in range(MAX_SUSPECTS + 1):
        keep = {i: v for i, v in priors.items() if i not in dropped}
        problem = build_problem(cams, slots, n_free, placed, keep, opts)
        x = fit(problem, x, robust=False)
        C = covariance(problem, x)
        tests = {
            i: tape_test(problem, x, C, k, priors[i], i in keep) for k, i in enumerate(slots[:n_free]) if i in priors
        }
        new = {i: s for i, (_, s) in tests.items() if s**2 > threshold and i in seen_twice and i not in dropped}
        if not new or len(dropped - gross) == MAX_SUSPECTS:
            break
        dropped.add(max(new, key=new.__getitem__))
    return problem, x, C, tests, dropped


def _result(tape, photos, cams, slots, fitted, unplaced, fixed, gross: GrossTest, learnt: dict) -> Survey:
    problem, x, C, tests, dropped, redundancy = fitted
    R_cam, t_cam, R_mark, p_mark = problem.poses(x)
    groups = learnt["groups"]
    surveyed = _surveyed_map(tape, problem, R_mark, p_mark, slots, learnt)
    s_mm, s_rot = problem.sigma_mm, problem.sigma_rot_rad
    seen = _members(slots, groups)
    unseen = tuple(i for i in tape.ids if i not in seen)
    cov, std = _covariances(problem, C, R_mark, slots, unseen, groups)
    r = np.linalg.norm(problem.reprojection_px(x), axis=1)
    poses = {}
    for c, ph in enumerate(cams):
        poses[ph.label] = frames.invert_transform(frames.make_transform(R_cam[c], t_cam[c]))
    member_tests, suspects = _member_tests(seen, tests, dropped)
    return Survey(
        marker_map=surveyed,
        tape_map=tape,
        suspects=suspects,
        marker_position_std_mm=dict(sorted(std.items(), key=lambda kv: slot_order(kv[0]))),
        marker_covariance=dict(sorted(cov.items(), key=lambda kv: slot_order(kv[0]))),
        camera_poses=poses,
        photo_rms_px={ph.label: _rms(r[problem.obs_cam == c]) for c, ph in enumerate(cams)},
        marker_rms_px=_marker_rms(problem, r),
        unused=[(ph.label, ph.reason) for ph in photos if ph.T_world_camera is None],
        added_ids=tuple(i for i in slots if i not in tape and i not in groups),
        unseen_ids=unseen,
        fixed_ids=fixed,
        unplaced=unplaced,
        corner_sigma_px=float(problem.sigma_px),
        map_sigma_mm=float(s_mm),
        map_sigma_deg=float(np.degrees(s_rot)),
        photos_per_marker={i: sum(i in ph.corners for ph in cams) for i in seen},
        tests=member_tests,
        tape_residual_mm=gross.residual_mm,
        gross_ids=gross.gross,
        gross_threshold_mm=gross.threshold_mm,
        map_sigma_learnt=learnt["learnt"],
        map_sigma_se_mm=sigma_error(float(s_mm), redundancy) if learnt["learnt"] else math.nan,
        print_scale=gross.scale,
        print_scale_se=gross.scale_se,
        print_scale_applied=learnt["scale"] != 1.0,
        added_size_mm={
            i: side for i, side in _sides(problem, slots, groups).items() if i not in tape and i in learnt["sides"]
        },
    )


def _surveyed_map(tape: MarkerMap, problem, R_mark, p_mark, slots: list, learnt: dict) -> MarkerMap:
    """The surveyed map: the single markers and the entries the adjustment placed, the others the tape's."""
    groups, scale = learnt["groups"], learnt["scale"]
    free = {i: k for k, i in enumerate(slots[: problem.n_free])}
    singles = [i for i in free if i not in groups]
    ks = [free[i] for i in singles]
    placements = _placements(tape, singles, R_mark[ks], p_mark[ks], {**learnt, "sides": _sides(problem, slots, groups)})
    entries = [
        surveyed_entry(e, R_mark[free[n]], p_mark[free[n]], scale) if n in free else scaled_entry(e, scale)
        for n, e in tape.entries.items()
    ]
    surveyed = MarkerMap(
        placements,
        learnt["size"] * scale,
        dictionary=tape.dictionary,
        units=tape.units,
        source=f"survey of {tape.source}",
        entries=entries,
    )
    check_readable(surveyed)
    return surveyed


def _member_tests(seen: dict, tests: dict, dropped: set) -> tuple[dict, list]:
    """Each marker's suspect test (an entry's markers: their entry's) and the suspects, worst first."""
    member_tests = {i: tests[slot] for i, slot in seen.items() if slot in tests}
    suspects = [Suspect(i, *member_tests[i]) for i, slot in seen.items() if slot in dropped and slot in tests]
    return member_tests, sorted(suspects, key=lambda s: -s.sigmas)


def _marker_rms(problem, r: np.ndarray) -> dict:
    """Reprojection RMS (px) of each marker seen, from the residual distances ``r`` (one per corner)."""
    index = {k: n for n, k in enumerate(dict.fromkeys(problem.sightings))}
    sighted = np.repeat(np.array([index[k] for k in problem.sightings], int), 4)
    return {i: _rms(r[sighted == index[i]]) for i in sorted(index, key=slot_order)}


def _members(slots: list, groups: dict) -> dict:
    """``{marker key: its slot}`` for every marker the adjustment placed (an entry's: all of its markers)."""
    out = {}
    for i in slots:
        out.update({m: i for m in groups[i].members} if i in groups else {i: i})
    return out


def _covariances(problem, C: np.ndarray, R_mark, slots: list, unseen: tuple, groups: dict) -> tuple[dict, dict]:
    """Each marker's 6x6 covariance and position standard deviations: surveyed, fixed (0), unseen (the tape's, inf
    with ``map_sigma_mm=inf``).

    An entry's markers have their entry's covariance carried to each one's placement (:func:`member_covariance`).
    """
    cov = {}
    for k, i in enumerate(slots):
        block = marker_block(problem, C, k) if k < problem.n_free else np.zeros((6, 6))  # fixed: the tape's, exactly
        if i in groups:
            cov.update({m: member_covariance(block, R_mark[k], groups[i], n) for n, m in enumerate(groups[i].members)})
        else:
            cov[i] = block
    s_mm, s_rot = problem.sigma_mm, problem.sigma_rot_rad
    for i in unseen:  # with map_sigma_mm=inf the tape's placement is not known at all: inf, not 0 (a fixed marker's)
        cov[i] = np.diag([s_rot**2] * 3 + [s_mm**2] * 3)
    std = {i: np.sqrt(np.maximum(np.diag(c)[3:], 0.0)) for i, c in cov.items()}
    return cov, std


def _sides(problem, slots: list, groups: dict) -> dict:
    """Each single marker's side (mm) in the adjustment."""
    return {
        i: float(np.linalg.norm(problem.local[k, 1] - problem.local[k, 0]))
        for k, i in enumerate(slots)
        if i not in groups
    }


def _placements(tape: MarkerMap, free: list, R_mark: np.ndarray, p_mark: np.ndarray, learnt: dict) -> dict:
    """The surveyed map's single placements: the tape's, the ``free`` markers' surveyed (entries' markers apart).

    A marker's own side (``size_mm``) is kept, times the print scale applied, as is its dictionary; a
    marker added from the photos has the side measured from them (``learnt["sides"]``).
    """
    scale = learnt["scale"]

    def scaled(p):
        return p if p.size_mm is None or scale == 1.0 else dataclasses.replace(p, size_mm=p.size_mm * scale)

    placements = {i: scaled(p) for i, p in tape.placements.items() if i not in tape.owner}
    for k, i in enumerate(free):
        own = (tape.placements[i].size_mm and tape.placements[i].size_mm * scale) if i in tape else None
        placements[i] = placement_of(i, R_mark[k], p_mark[k], own if i in tape else learnt["sides"].get(i))
    return placements


def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")
