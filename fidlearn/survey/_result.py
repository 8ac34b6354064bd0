"""The result of a survey: :class:`Survey` and :class:`Suspect`."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .. import _stats
from .._io import write_json_atomic
from .._map_parse import _vector3, key_json
from .._wpilib import layout_format, to_wpilib
from ..errors import MapError, PoseError, SurveyError
from ..markermap import MarkerMap
from ._inputs import _short
from ._layout import TagChange, tag_changes, tag_changes_text

__all__ = ["Survey", "Suspect"]


class Suspect(NamedTuple):
    """A marker whose tape placement disagrees with the photos.

    Attributes
    ----------
    id : int
        The marker.
    distance_mm : float
        How far the photos put its top-left corner from the tape's, mm.
    sigmas : float
        That difference in standard deviations (Mahalanobis, photos' and tape's uncertainty together).
    """

    id: int
    distance_mm: float
    sigmas: float


@dataclass(eq=False)
class Survey:
    """The map from photos, joined with the tape: what :func:`fidlearn.survey` returns.

    Attributes
    ----------
    marker_map : MarkerMap
        The surveyed map: same units, marker size and dictionary as the tape map, usable by
        :func:`fidlearn.locate`; markers the photos never showed keep their tape placement, markers
        the map lacked are added.
    tape_map : MarkerMap
        The map given.
    suspects : list of Suspect
        Markers whose tape placement disagrees with the photos (their tape prior was left out of the
        final adjustment), worst first. A rigid entry is tested as one: each of its markers is named with
        the entry's test (its placement point's distance and sigmas).
    marker_position_std_mm : dict of int to ndarray, shape (3,)
        Standard deviation of each marker's top-left corner along world X, Y, Z, mm (0 for a fixed
        marker; the tape's for a marker no photo showed: inf with ``map_sigma_mm=inf``).
    marker_covariance : dict of int to ndarray, shape (6, 6)
        ``[rotation (rad, 3), top-left corner (mm, 3)]``: the rotation a small rotation vector in
        world axes applied on the left of the placement's; from the Jacobian at the solution.
    camera_poses : dict of str to ndarray, shape (4, 4)
        ``T_world_camera`` (mm) of every photo used, by its label (its path, or ``"photo i"``).
    photo_rms_px, marker_rms_px : dict
        Reprojection RMS (px, corner distance) per photo used and per marker surveyed.
    unused : list of (str, str)
        Photos left out, with the reason and what to do.
    added_ids, unseen_ids, fixed_ids : tuple of int
        Markers added from the photos; markers of the map no photo showed; markers held exactly.
    unplaced : dict of int to str
        Markers seen but not placed, with the reason and what photo to take.
    corner_sigma_px : float
        Corner noise the covariance assumes (px per coordinate): given, or estimated from the residuals.
    map_sigma_mm, map_sigma_deg : float
        The tape's standard deviation on each coordinate of a top-left corner (mm), given or learnt
        (:attr:`map_sigma_learnt`), and on each rotation angle (degrees, derived:
        ``map_sigma_mm / marker_size_mm`` rad).
    photos_per_marker : dict of int to int
        How many photos used show each surveyed marker.
    tests : dict of int to (float, float)
        Every taped marker's suspect test: ``(distance_mm, sigmas)`` of where the photos alone put its
        top-left corner from the tape's (the suspects are those above the chi-square threshold).
    tape_residual_mm : dict of int to float
        Every taped marker's robust residual: the distance (mm) of its tape top-left corner from where
        the photos alone put it, after the similarity that lays the photos' placements on the tape's,
        fitted robustly (by the markers that agree). Markers seen in fewer than two photos are absent.
    gross_ids : tuple of int
        Markers whose robust residual exceeds :attr:`gross_threshold_mm`: their tape placement was
        never used (the photos alone place them); they are also :attr:`suspects`. A rigid entry is tested as
        one (its markers' residual is the entry's), and its tape placement is left out whole.
    gross_threshold_mm : float
        The gross test's threshold (mm): ``GROSS_SIGMAS`` tape sigmas, or residual spreads when those
        are larger, and at least one marker side; NaN when the test was not run (fewer than four
        taped markers in two photos, or ``map_sigma_mm=inf``).
    map_sigma_learnt : bool
        Whether :attr:`map_sigma_mm` was learnt from the tape residuals (``map_sigma_mm=None``): the
        variance component of the taped markers' positions, the suspects left out.
    map_sigma_se_mm : float
        Standard error of a learnt :attr:`map_sigma_mm` (``sigma / sqrt(2 r)``, ``r`` the tape
        residuals' redundancy); NaN when given.
    print_scale, print_scale_se : float
        The markers' print scale and its standard error: the scale of the similarity laying the photos'
        top-left corners on the tape's (0.987: printed at 98.7 %, or a tape that reads long); NaN when
        the gross test did not run.
    added_size_mm : dict of int to float
        The side (mm) of each marker added from the photos whose side, measured from them (its four
        corners triangulated from the photos located by the markers of known size), differs from the
        map's ``marker_size_mm`` by more than 5 %: the surveyed map gives it that ``size_mm``. The other
        added markers (and those whose photos all stand in nearly one place) have the map's size.
    print_scale_applied : bool
        Whether the survey used the marker side ``print_scale * marker_size_mm`` (only when the sigma is
        learnt and the scale is more than 3 standard errors from 1); the surveyed map then has that
        marker size.
    """

    marker_map: MarkerMap
    tape_map: MarkerMap
    suspects: list[Suspect]
    marker_position_std_mm: dict[int, np.ndarray]
    marker_covariance: dict[int, np.ndarray]
    camera_poses: dict[str, np.ndarray]
    photo_rms_px: dict[str, float]
    marker_rms_px: dict[int, float]
    unused: list[tuple[str, str]]
    added_ids: tuple[int, ...]
    unseen_ids: tuple[int, ...]
    fixed_ids: tuple[int, ...]
    unplaced: dict[int, str]
    corner_sigma_px: float
    map_sigma_mm: float
    map_sigma_deg: float
    photos_per_marker: dict[int, int] = field(default_factory=dict)
    tests: dict[int, tuple[float, float]] = field(default_factory=dict)
    tape_residual_mm: dict[int, float] = field(default_factory=dict)
    gross_ids: tuple[int, ...] = ()
    gross_threshold_mm: float = float("nan")
    map_sigma_learnt: bool = False
    map_sigma_se_mm: float = float("nan")
    print_scale: float = float("nan")
    print_scale_se: float = float("nan")
    print_scale_applied: bool = False
    added_size_mm: dict = field(default_factory=dict)

    @property
    def suspect_ids(self) -> list[int]:
        """Ids of :attr:`suspects`."""
        return [s.id for s in self.suspects]

    def position_ellipsoid_contains(self, marker_id: int, point_mm, probability: float = 0.95) -> bool:
        """Whether a point lies in a marker's confidence ellipsoid (top-left corner).

        Parameters
        ----------
        marker_id : int
            A surveyed marker.
        point_mm : array-like, shape (3,)
            World point, mm (e.g. the true top-left corner).
        probability : float
            Confidence level of the ellipsoid, between 0 and 1.

        Returns
        -------
        bool
            True when its squared Mahalanobis distance is at most the chi-square(3) quantile; when the
            tape's sigma was learnt (:attr:`map_sigma_learnt`), at most ``3 F(probability; 3, r)``, ``r`` the
            tape residuals' redundancy (``(map_sigma_mm / map_sigma_se_mm)^2 / 2``): the covariance then
            scales with an estimated sigma, and the region is Student's (as a t interval is wider than a
            normal one).

        Raises
        ------
        SurveyError
            The marker was not surveyed, or the point is not 3 finite numbers.
        PoseError
            ``probability`` is not a number between 0 and 1.
        """
        if isinstance(marker_id, bool) or not _hashable(marker_id) or marker_id not in self.marker_covariance:
            raise SurveyError(
                f"marker {_short(marker_id)} was not surveyed; surveyed markers: {list(self.marker_covariance)}"
            )
        try:
            point = np.asarray(point_mm, dtype=float).reshape(3)
        except (TypeError, ValueError):
            point = np.full(3, np.nan)
        if not np.all(np.isfinite(point)):
            raise SurveyError(f"point_mm must be 3 finite numbers (a world point, mm), got {_short(point_mm)}")
        if isinstance(probability, bool) or not isinstance(probability, (int, float, np.floating, np.integer)):
            raise PoseError(f"probability must be a number between 0 and 1, got {_short(probability)}")
        cov = self.marker_covariance[marker_id][3:, 3:]
        d = point - np.asarray(self.marker_map.placements[marker_id].translation_mm)
        if not np.any(cov):
            return bool(np.allclose(d, 0.0))
        return float(d @ np.linalg.solve(cov, d)) <= self._ellipsoid_limit(probability)

    def _ellipsoid_limit(self, probability: float) -> float:
        """The squared Mahalanobis distance bounding the ``probability`` ellipsoid (3 dimensions)."""
        se = self.map_sigma_se_mm
        if self.map_sigma_learnt and math.isfinite(se) and se > 0 and 0.0 < probability < 1.0:
            return 3.0 * _stats.f_isf(1.0 - probability, 3, 0.5 * (self.map_sigma_mm / se) ** 2)
        return _stats.chi2_ppf(probability, 3)

    def note(self) -> dict:
        """The ``"surveyed"`` note :meth:`save` writes: how the map was made.

        Returns
        -------
        dict
            Photos used and left out, the tape and corner sigmas, fixed, added and suspect markers,
            and each marker's position standard deviation (mm).
        """
        return {
            "method": "bundle adjustment of the photos' marker corners with the tape map as a prior (fidlearn.survey)",
            "photos_used": len(self.camera_poses),
            "photos_unused": len(self.unused),
            # None: map_sigma_mm=inf, the photos alone (JSON has no infinity, and the map reader refuses one)
            "map_sigma_mm": self.map_sigma_mm if math.isfinite(self.map_sigma_mm) else None,
            "map_sigma_learnt": self.map_sigma_learnt,
            "print_scale": self.print_scale if self.print_scale == self.print_scale else None,
            "corner_sigma_px": round(self.corner_sigma_px, 4),
            "fixed_ids": [key_json(k) for k in self.fixed_ids],
            "added_ids": [key_json(k) for k in self.added_ids],
            "added_size_mm": {str(i): round(v, 2) for i, v in self.added_size_mm.items()},
            "unseen_ids": [key_json(k) for k in self.unseen_ids],
            "gross_ids": [key_json(k) for k in self.gross_ids],
            "suspects": [
                {"id": key_json(s.id), "distance_mm": round(s.distance_mm, 2), "sigmas": round(s.sigmas, 2)}
                for s in self.suspects
            ],
            "position_std_mm": {  # None: a marker in no photo, with map_sigma_mm=inf (not known at all)
                str(i): [round(float(v), 3) if math.isfinite(v) else None for v in s]
                for i, s in self.marker_position_std_mm.items()
            },
        }

    def save(self, path: str | os.PathLike, format: str | None = None) -> Path:  # noqa: A002 - the file's format
        """Write the surveyed map (atomically): the full layout with a ``"surveyed"`` note, or a WPILib layout.

        Parameters
        ----------
        path : path-like
            The JSON file to write; :meth:`fidlearn.MarkerMap.load` reads it back.
        format : {None, "fidlearn", "wpilib"}
            None (the default): the format of the map the survey started from, so a survey of a field from
            its official WPILib layout writes the corrected layout (tags' centres and quaternions, metres,
            the official field's size; the file has no room for the note). ``"fidlearn"``: the full layout
            with the note.

        Returns
        -------
        Path
            The file written.

        Raises
        ------
        SurveyError
            A placement lies beyond what :meth:`fidlearn.MarkerMap.load` reads (named), or ``path`` is
            not a path.
        """
        if not isinstance(path, (str, os.PathLike)) or not str(path):
            raise SurveyError(f"save needs a file path (str or pathlib.Path) ending in .json, got {_short(path)}")
        if format not in (None, "fidlearn", "wpilib"):
            raise SurveyError(f"unknown map format {_short(format)}; use 'fidlearn' (the full layout) or 'wpilib'")
        check_readable(self.marker_map)
        if (format or layout_format(self.tape_map)) == "wpilib":
            return write_json_atomic(path, to_wpilib(self.marker_map, getattr(self.tape_map, "field_m", None)))
        return write_json_atomic(path, {**self.marker_map.to_dict(), "surveyed": self.note()})

    def tag_changes(self) -> list[TagChange]:
        """How far each tag of the starting map (an official field layout) is from where the survey puts it.

        Returns
        -------
        list of TagChange
            Per tag: the centres' distance (mm) and the faces' angle (deg), each with the survey's standard
            deviation, the suspect test's sigmas and whether the tag moved beyond the noise (a suspect); see
            :func:`fidlearn.survey._layout.tag_changes`.
        """
        return tag_changes(self)

    def tag_report(self, layout: str = "the official layout") -> list[str]:
        """:meth:`tag_changes` in words, the lines ``fidlearn survey`` prints for a WPILib layout.

        Parameters
        ----------
        layout : str
            What the survey started from, for the lines' wording (e.g. ``"the official layout field.json"``).

        Returns
        -------
        list of str
            A title, a header, one line per tag (distance and angle with the survey's standard deviations, the
            offset, the suspect test's sigmas, a verdict) and a last line naming the moved tags, or saying none moved.
        """
        return tag_changes_text(self.tag_changes(), layout)

    @property
    def layout_format(self) -> str:
        """The starting map's file format, what :meth:`save` writes by default: ``"wpilib"`` or ``"fidlearn"``."""
        return layout_format(self.tape_map)

    def learnt(self) -> list[str]:
        """What the survey learnt of the tape, in words: its sigma (when learnt) and the markers' print scale.

        Returns
        -------
        list of str
            One line for a learnt :attr:`map_sigma_mm` (with its standard error), one for the print
            scale when the gross test measured it (whether it was applied, or is within its error).
        """
        lines = []
        if self.map_sigma_learnt:
            lines.append(
                f"tape sigma learnt from the tape residuals: {self.map_sigma_mm:.1f} +/- {self.map_sigma_se_mm:.1f} mm "
                "per coordinate (give --map-sigma-mm / map_sigma_mm to set it)"
            )
        if self.print_scale == self.print_scale:
            pct, se = 100 * self.print_scale, 100 * self.print_scale_se
            if self.print_scale_applied:
                what = (
                    f"applied: marker side {self.marker_map.marker_size_mm:.1f} mm; check a printed marker with a ruler"
                )
            elif abs(self.print_scale - 1) > 3 * self.print_scale_se:
                what = "more than 3 standard errors from 100 %, not applied (the tape's sigma was given)"
            else:
                what = "within 3 standard errors of 100 %, not applied"
            lines.append(f"print scale (photos against the tape): {pct:.2f} +/- {se:.2f} %, {what}")
        return lines

    def table(self) -> str:
        """The per-marker table ``fidlearn survey`` prints: tape and surveyed corners, their difference.

        One line per marker of the surveyed map: the tape's and the surveyed top-left corner (mm), their
        distance (``diff``), the surveyed position's standard deviation (``std``, the length of its three),
        the robust residual (``resid``: the tape corner's distance from where the photos alone put it,
        :attr:`tape_residual_mm`, ``-`` when not tested), the photos that show the marker and a note
        (a suspect, a marker added from the photos, fixed, in no photo, in one photo only).

        Returns
        -------
        str
            One header line and one line per marker, joined by newlines (no newline at the end).
        """
        head = (
            f"{'id':>4} {'tape x, y, z (mm)':>24} {'surveyed x, y, z (mm)':>24} {'diff':>7} {'std':>6} {'resid':>7} "
            f"{'photos':>6}  note"
        )
        lines = [head]
        suspects = set(self.suspect_ids)
        for i, p in self.marker_map.placements.items():
            got = np.asarray(p.translation_mm)
            if i in self.tape_map:
                tape = np.asarray(self.tape_map.placements[i].translation_mm)
                tape_text, diff = ", ".join(f"{v:.0f}" for v in tape), f"{np.linalg.norm(got - tape):7.1f}"
            else:
                tape_text, diff = "-", f"{'-':>7}"
            std = float(np.linalg.norm(self.marker_position_std_mm[i]))
            resid = f"{self.tape_residual_mm[i]:7.0f}" if i in self.tape_residual_mm else f"{'-':>7}"
            lines.append(
                f"{str(i):>4} {tape_text:>24} {', '.join(f'{v:.0f}' for v in got):>24} {diff} {std:6.1f} {resid} "
                f"{self.photos_per_marker.get(i, 0):>6}  {_table_note(self, i, suspects)}"
            )
        return "\n".join(lines)


def _table_note(s: Survey, i: int, suspects: set) -> str:
    """What the table says of marker ``i`` beside its numbers (empty for a marker well seen)."""
    if i in s.gross_ids:
        return "SUSPECT, far off: placed by the photos; measure again"
    if i in suspects:
        return "SUSPECT: measure again"
    if i in s.added_ids:
        side = f", {s.added_size_mm[i]:.0f} mm" if i in s.added_size_mm else ""
        return f"added from the photos{side}"
    entry = s.tape_map.owner.get(i)
    if i in s.fixed_ids or (entry is not None and any(s.tape_map.owner.get(f) == entry for f in s.fixed_ids)):
        return "fixed" if i in s.fixed_ids else f"fixed with {entry!r}"
    if i in s.unseen_ids:
        return "in no photo: the tape's"
    if entry is not None and s.photos_per_marker.get(i, 0) == 0:
        return f"in no photo: placed with {entry!r}"
    if entry is None and s.photos_per_marker.get(i, 0) < 2:
        return "in one photo only: take another"
    return ""


def _hashable(value) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


def check_readable(marker_map: MarkerMap) -> None:
    """Refuse a surveyed map that :meth:`MarkerMap.load` would not read back (a placement beyond any room).

    Each placement, in the map's units, goes through the map reader's own check of a marker's numbers.
    """
    d = marker_map.to_dict()
    placed = [(f"marker {i}", v) for i, v in d.get("markers", {}).items()]
    placed += [(f"entry {name!r}", v) for kind in ("boards", "bundles") for name, v in d.get(kind, {}).items()]
    for what, entry in placed:
        for key in ("translation", "rotation"):
            try:
                _vector3(entry[key], what, key, "")
            except MapError as exc:
                unit = marker_map.units if key == "translation" else "degrees"
                raise SurveyError(
                    f"the surveyed map cannot be written: {what}'s {key} {entry[key]} ({unit}) is beyond what "
                    f"a map file holds, MarkerMap.load would refuse it ({str(exc).rstrip('; ')}): check {what}'s "
                    "tape placement and ids, and take photos that show it with other markers"
                ) from None
