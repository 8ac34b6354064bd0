"""What the survey learns of the tape when not told: its sigma, and the markers' print scale.

The tape's sigma (``map_sigma_mm=None``) is a variance component (Helmert, Foerstner): with the
adjustment solved at a sigma, the tape position residuals ``v`` (mm) of the markers that keep
their tape prior have the redundancy ``r = 3q - sum_k trace(C_k) / sigma^2`` (``C_k`` a marker's
3x3 position covariance: the trace of the prior rows' part of ``I - H``), and
``sigma^2 = sum v^2 / r`` is the new estimate; the two are iterated to a fixed point. It starts
from the gross test's robust spread (the median distance of the tape corners from the photos,
``_MEDIAN_3D``), so a marker moved after it was taped is named a suspect before it can inflate
the estimate, and the suspects' residuals are never in the sum. Its standard error is that of a
variance component with ``r`` degrees of freedom: ``sigma / sqrt(2 r)``.

The print scale: the photos measure the room in printed marker sides, the tape in millimetres;
a printer at 98.7 % makes the photos' room 1/0.987 times the true one. The gross test's
similarity laying the photos' top-left corners on the tape's has that scale; its standard error is
``s_fit / sqrt(sum |a_i - a_mean|^2)`` (``s_fit`` the per-coordinate spread of the fit's residuals).
It is applied (the adjustment's marker side is ``scale * marker_size_mm``, and so is the surveyed
map's) only when the sigma is learnt and the scale is more than ``SCALE_SIGMAS`` standard errors
from 1: a scale the photos see clearly and left out stretches every tape residual with the
distance from the room's middle (1.3 % over 2 m is 26 mm), which the learnt sigma would take for
tape error and the suspect test for moved markers; a scale within its error, applied, would only
add that error to the room's size. A sigma given keeps the survey as it was: the scale is reported.
"""

from __future__ import annotations

import math

import numpy as np

from ._inputs import MAX_MAP_SIGMA_MM, MIN_MAP_SIGMA_MM

#: The learnt sigma's fixed-point iteration stops when a step changes it by less than this fraction.
SIGMA_RTOL = 0.01
#: At most this many fixed-point steps.
SIGMA_STEPS = 12
#: The tape's sigma the learning starts from when the gross test did not run (mm).
START_SIGMA_MM = 10.0
#: The print scale is fitted on the markers within this many robust spreads (3D distance: chi-square(3)
#: at 99.9 % is 4.03 squared), so a marker moved after it was taped is left out.
SCREEN_SIGMAS = 4.0
#: The median distance of a 3D Gaussian with unit sigma per coordinate (sqrt of chi-square(3)'s median).
MEDIAN_3D = 1.5382
#: A marker this close (mm) to where the map puts it is not taken for moved by the print scale's screen, however
#: close the others are: a tape's own error is larger.
NOT_MOVED_MM = 10.0
#: The print scale is applied when it differs from 1 by more than this many standard errors.
SCALE_SIGMAS = 3.0


def tape_variance(problem, x: np.ndarray, C: np.ndarray) -> tuple[float, float]:
    """``(sum of squared tape position residuals (mm^2), their redundancy)`` at the solution ``x``.

    Only the markers that keep their tape prior count (the suspects have none).
    """
    _, _, _, p_mark = problem.poses(x)
    s = problem.prior_slots
    if not len(s):
        return 0.0, 0.0
    v = p_mark[s] - problem.prior_p
    m6 = 6 * problem.n_cams
    used = sum(float(np.trace(C[m6 + 6 * k + 3 : m6 + 6 * k + 6, m6 + 6 * k + 3 : m6 + 6 * k + 6])) for k in s)
    redundancy = 3 * len(s) - used / problem.sigma_mm**2
    return float(np.sum(v**2)), float(redundancy)


def next_sigma(problem, x: np.ndarray, C: np.ndarray) -> tuple[float, float]:
    """``(sigma_mm, redundancy)``: one variance-component step (the current sigma when nothing is redundant)."""
    ss, r = tape_variance(problem, x, C)
    if r <= 0.5 or ss <= 0:
        return float(problem.sigma_mm), max(r, 0.0)
    return float(np.clip(math.sqrt(ss / r), MIN_MAP_SIGMA_MM, MAX_MAP_SIGMA_MM)), r


def sigma_error(sigma_mm: float, redundancy: float) -> float:
    """Standard error (mm) of a sigma learnt with ``redundancy`` degrees of freedom (inf with none)."""
    return sigma_mm / math.sqrt(2 * redundancy) if redundancy > 0 else math.inf


def print_scale_kept(distance: np.ndarray) -> np.ndarray:
    """Which markers :func:`print_scale` counts (bool, per marker): those within ``SCREEN_SIGMAS`` robust spreads,
    or within :data:`NOT_MOVED_MM` of their place (a map measured to a tenth of a millimetre would otherwise
    screen out markers 0.4 mm off beside others 0.15 mm off)."""
    return distance <= max(SCREEN_SIGMAS * float(np.median(distance)) / MEDIAN_3D, NOT_MOVED_MM)


def print_scale(src: np.ndarray, dst: np.ndarray, distance: np.ndarray, similarity) -> tuple[float, float]:
    """``(scale, standard error)`` of the photos' room laid on the tape's (the markers' print scale).

    ``src`` the photos' top-left corners, ``dst`` the tape's, ``distance`` each one's robust
    residual (mm), ``similarity(a, b)`` Umeyama's fit. Only the markers within ``SCREEN_SIGMAS``
    robust spreads count (a marker moved after it was taped would inflate the error); NaN when
    fewer than four remain.
    """
    keep = print_scale_kept(distance)
    if int(keep.sum()) < 4:
        return math.nan, math.nan
    a, b = src[keep], dst[keep]
    sim = similarity(a, b)
    if sim is None:
        return math.nan, math.nan
    s, R, t = sim
    r = b - (s * a @ R.T + t)
    dof = 3 * len(a) - 7
    if dof <= 0:
        return float(s), math.inf
    spread = math.sqrt(float(np.sum(r**2)) / dof)
    return float(s), spread / math.sqrt(float(np.sum((a - a.mean(axis=0)) ** 2)))


def scale_applies(scale: float, error: float) -> bool:
    """Whether a print scale is significant: beyond ``SCALE_SIGMAS`` standard errors from 1."""
    return math.isfinite(scale) and math.isfinite(error) and abs(scale - 1) > SCALE_SIGMAS * error
