"""The motion noise, learnt from the innovations while the track runs.

A Kalman filter is optimal when its innovations (each frame's pose minus the prediction, whitened by
their covariance ``S``) are white: no correlation from one frame to the next. A process noise too small
makes the track lag behind the motion and the innovations of consecutive frames point the same way
(positive correlation); one too large makes the track follow each frame's noise, and the next
prediction carries that noise with the opposite sign (negative correlation). Scaling both the process
noise and the poses' covariance by one factor leaves the gain, hence the correlation, unchanged: the
correlation fixes the process noise against the poses' covariance as given, whatever its scale (the
track's covariance is then as honest as the poses'; the NIS, :meth:`PoseTracker.consistency`, says
how honest).

The poses' covariance holds two kinds of error: one that varies from frame to frame (corner noise), which
the track averages away, and one the frames around it share (a marker's shift, the calibration, a bias of
the corners that changes only as the view does), which no number of frames removes and the innovations do
not show. So the NIS (with the poses' covariance as given) tells only the first: its mean over 6 is the
*share* of the covariance that varies (``learn_share``: the mean over the frames so far, then a moving mean
forgetting at ``SHARE_RATE``), and the rest is taken as shared (:mod:`fidlearn.filtering._track`). The
track's own gains never change with it (the scale of the poses' covariance and of the process noise
together does not change a gain): the share only says how the track's covariance and its NIS are read.
A scale learnt from the NIS alone and put on the whole covariance (the shared part dropped) came out 0.32
on the tracking benchmark's drive, and the track's 95 % ellipsoid then held the truth in 71 % of the frames.

So, frame after frame (separately for the position, which sets ``q_lin``, and the rotation, which sets
``q_ang``): ``log q^2 += ADAPT_RATE * c``, with ``c`` the mean cosine between the new whitened innovation
and the last ``LAGS`` ones (lag 1 alone is fooled by poses whose errors alternate from frame to frame;
a lagging track makes every lag positive). Only well-determined poses (several markers, not ambiguous)
teach: a single marker's pose, or an ambiguous one, has heavy tails and errors that persist from frame
to frame. ``q`` stays within ``[PROCESS_NOISE_FLOOR, PROCESS_NOISE_CEILING]``: at the floor a parked
robot's track is still smooth (the way down is slow, the lower ``q`` the weaker the correlation that
tells it: on a parked camera's rendered frames the track's jitter is about half the frames' after 2 s,
a fifth after 10 s). A sudden manoeuvre (a well-determined frame further than ``MANOEUVRE_CHI2`` from a
prediction made with the learnt noise) is followed at once: that step's process noise is raised, up to
the ceiling, until the frame's distance is ``MANOEUVRE_CHI2``, and half of that raise (in log) is kept;
a frame the ceiling cannot explain is rejected by the gate as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import _stats
from ._so3 import chi2_6_quantile

#: The process noise a learning track starts from: (mm/s^2, rad/s^2) per sqrt(Hz).
PROCESS_NOISE_START = (100.0, 0.2)
#: The least process noise learnt: a parked robot's track is as smooth as this allows.
PROCESS_NOISE_FLOOR = (2.0, 0.004)
#: The most, for one manoeuvre's step: a velocity change ``dv`` within one frame needs ``q = dv / sqrt(dt)``;
#: at 30 fps 5000 mm/s^2 per sqrt(Hz) is 0.9 m/s, and 20 rad/s^2 a turn of 3.6 rad/s started within a frame.
PROCESS_NOISE_CEILING = (5000.0, 20.0)
#: The innovations each new one is compared with: the last ``LAGS``.
LAGS = 2
#: The step of ``log q^2`` per frame and unit cosine.
ADAPT_RATE = 0.4
#: A frame further than this from the prediction (6 degrees of freedom, probability 0.99) is a manoeuvre.
MANOEUVRE_CHI2 = chi2_6_quantile(0.99)
#: The share of the poses' covariance that varies from frame to frame is the mean of ``d2 / 6`` (``d2`` with the
#: poses' covariance as given): the mean over the frames so far, then a moving mean that forgets at this rate
#: (about the last 20 frames) ...
SHARE_RATE = 0.1
#: ... within these bounds (above 1: the frames vary more than their covariance says, which is widened).
SHARE_RANGE = (0.01, 10.0)


@dataclass
class _Block:
    """The learning state of one block (rotation or position): ``log q^2`` and the last whitened innovations."""

    log_q2: float
    floor: float
    ceiling: float
    prev: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def q(self) -> float:
        return math.exp(0.5 * self.log_q2)

    def learn(self, e) -> None:
        """Take one whitened innovation block ``e`` (3 numbers)."""
        norm = math.sqrt(sum(x * x for x in e))
        if norm == 0:
            return
        u = (e[0] / norm, e[1] / norm, e[2] / norm)
        cosines = [u[0] * p[0] + u[1] * p[1] + u[2] * p[2] for p in self.prev]
        if cosines:
            step = ADAPT_RATE * sum(cosines) / len(cosines)
            self.log_q2 = min(max(self.log_q2 + step, 2 * math.log(self.floor)), 2 * math.log(self.ceiling))
        self.prev = ([u] + self.prev)[:LAGS]


class NoiseLearner:
    """The learnt process noise ``(q_lin, q_ang)`` of one track."""

    def __init__(self, start: tuple[float, float] = PROCESS_NOISE_START, frozen: bool = False) -> None:
        self.rot = _Block(2 * math.log(start[1]), PROCESS_NOISE_FLOOR[1], PROCESS_NOISE_CEILING[1])
        self.pos = _Block(2 * math.log(start[0]), PROCESS_NOISE_FLOOR[0], PROCESS_NOISE_CEILING[0])
        self.frozen = frozen  # learnt already (the smoother's second pass): the manoeuvres alone remain
        # the share of the poses' covariance that varies from frame to frame, and the frames that taught it
        self.share, self.taught = 1.0, 0

    @property
    def q(self) -> tuple[float, float]:
        """``(q_lin, q_ang)`` now."""
        return self.pos.q, self.rot.q

    def headroom(self) -> float:
        """How much the process noise may be multiplied by for one step (both blocks stay under the ceiling)."""
        return min(self.pos.ceiling / self.pos.q, self.rot.ceiling / self.rot.q) ** 2

    def learn(self, r: np.ndarray, S: np.ndarray) -> None:
        """Take one frame's innovation ``r`` (6,) ``[rotation, position]`` and its covariance ``S``."""
        if self.frozen:
            return
        S_rows, r_list = S.tolist(), r.tolist()
        for block, i in ((self.rot, 0), (self.pos, 3)):
            e = whiten3([row[i : i + 3] for row in S_rows[i : i + 3]], r_list[i : i + 3])
            if e is not None:
                block.learn(e)

    def nis(self, d2: float) -> float:
        """The NIS of a frame whose squared Mahalanobis distance, with the poses' covariance as given, is ``d2``:
        ``d2 / share``, times ``1 - 2 / k`` (``k`` the degrees of freedom the share was learnt from, 6 per
        frame, fewer as the moving mean forgets) so that it averages 6 however few frames taught the share
        (``E[1 / chi2(k)] = 1 / (k - 2)``)."""
        if self.taught == 0:
            return d2 / self.share
        frames = min(self.taught, (2.0 - SHARE_RATE) / SHARE_RATE)
        return d2 / self.share * (1.0 - 2.0 / (6.0 * frames))

    def learn_share(self, d2: float) -> None:
        """Take one measured frame's squared Mahalanobis distance ``d2`` from the prediction, made with the
        poses' covariance as given (the NIS is ``d2 / share``)."""
        if self.frozen:
            return
        self.taught += 1
        rate = max(1.0 / self.taught, SHARE_RATE)
        self.share = min(max((1.0 - rate) * self.share + rate * d2 / 6.0, SHARE_RANGE[0]), SHARE_RANGE[1])

    def manoeuvre(self, inflation: float) -> None:
        """A frame needed the process noise multiplied by ``inflation`` for one step: keep half of it (in log)."""
        if self.frozen or inflation <= 1.0:
            return
        for block in (self.rot, self.pos):
            block.log_q2 = min(block.log_q2 + 0.5 * math.log(inflation), 2 * math.log(block.ceiling))

    def forget_lag(self) -> None:
        """The track (re)starts: the next innovation has no predecessor to be compared with."""
        self.rot.prev, self.pos.prev = [], []


def whiten3(S: list[list[float]], r: list[float]) -> tuple[float, float, float] | None:
    """``L^-1 r`` with ``L`` the lower Cholesky factor of the 3x3 ``S`` (nested lists), in closed form on plain
    floats (``np.linalg.solve(np.linalg.cholesky(S), r)`` costs ten times more); None when ``S`` is not
    positive definite."""
    a = S[0][0]
    if not a > 0:
        return None
    l00 = math.sqrt(a)
    l10, l20 = S[1][0] / l00, S[2][0] / l00
    b = S[1][1] - l10 * l10
    if not b > 0:
        return None
    l11 = math.sqrt(b)
    l21 = (S[2][1] - l20 * l10) / l11
    c = S[2][2] - l20 * l20 - l21 * l21
    if not c > 0:
        return None
    l22 = math.sqrt(c)
    e0 = r[0] / l00
    e1 = (r[1] - l10 * e0) / l11
    return e0, e1, (r[2] - l20 * e0 - l21 * e1) / l22


def manoeuvre_inflation(P_pred: np.ndarray, Q: np.ndarray, r: np.ndarray, R: np.ndarray, most: float) -> float:
    """The least ``lam`` in ``[1, most]`` with ``r^T (P_pred + (lam - 1) Q + R)^-1 r <= MANOEUVRE_CHI2``
    (``most`` when none: the caller's gate then decides); bisection on ``log lam``."""

    def d2(lam: float) -> float:
        S = P_pred[:6, :6] + (lam - 1.0) * Q[:6, :6] + R
        try:
            return float(r @ np.linalg.solve(S, r))
        except np.linalg.LinAlgError:
            return math.inf

    if most <= 1.0 or d2(most) > MANOEUVRE_CHI2:
        return max(most, 1.0)
    lo, hi = 0.0, math.log(most)
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        if d2(math.exp(mid)) > MANOEUVRE_CHI2:
            lo = mid
        else:
            hi = mid
    return math.exp(hi)


def nis_band(frames: int, probability: float = 0.95) -> tuple[float, float]:
    """The central ``probability`` interval of the mean of ``frames`` NIS values of a consistent track
    (chi-square with ``6 * frames`` degrees of freedom, divided by ``frames``); (0, inf) for none."""
    if frames < 1:
        return 0.0, math.inf
    tail = 0.5 * (1.0 - probability)
    return _stats.chi2_ppf(tail, 6 * frames) / frames, _stats.chi2_isf(tail, 6 * frames) / frames
