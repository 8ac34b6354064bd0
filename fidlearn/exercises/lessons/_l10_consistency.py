"""Lesson 10, q5: is the filter consistent? The mean NIS of a run against its 95 % band; q6: the rotation
innovation of an update, ``log(R_meas R_pred^T)``.

Kept apart from :mod:`.l10_tracking` (which lists ``_q5`` and ``_q6`` in its ``build``) for that module's length.
"""

from __future__ import annotations

import cv2
import numpy as np

from ... import _stats, frames
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import _array, _cmp_array, _parts, _scalar
from .._scenery import _rng

#: q5's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q5: QuestionText = {
    "title": "Is the filter consistent?",
    "task": """
        A tracker ran for k frames. For each frame it kept the innovation `innovations[i]` (6,), the
        measured pose minus the prediction (rotation in rad, then position in mm), and that
        innovation's covariance `S[i]` (6, 6) as the filter computed it. Write code that computes the
        mean NIS over the run and says whether the filter is consistent at 95 %: whether that mean
        lies inside the central 95 % band of the mean of k independent chi-square values with 6
        degrees of freedom (`scipy.stats.chi2` has the quantiles). Answer a dict
        `{"mean_nis": ..., "consistent": True or False}`.
        """,
    "hint": [
        "The NIS of one frame weighs its innovation by the inverse of its covariance, so that millimetres and "
        "radians count alike: each frame gives one number, chi-square with as many degrees of freedom as the "
        "innovation has components.",
        "The sum of k independent chi-square values is chi-square with k times the degrees of freedom; the band of "
        "the mean is that sum's 2.5 % and 97.5 % quantiles divided by k, much narrower than one value's band.",
    ],
    "solution": """
        from scipy.stats import chi2

        r, S = np.asarray(q5.inputs.innovations), np.asarray(q5.inputs.S)
        nis = np.array([ri @ np.linalg.solve(Si, ri) for ri, Si in zip(r, S)])
        k = len(nis)
        lo, hi = chi2.ppf([0.025, 0.975], 6 * k) / k
        q5.answer = {"mean_nis": nis.mean(), "consistent": bool(lo <= nis.mean() <= hi)}
        """,
    "level": "medium",
}

#: q5's kinds of run: the factor by which the innovations' true covariance exceeds S.
_Q5_KINDS = {"consistent": (1.0, 1.0), "overconfident": (1.6, 2.0), "cautious": (0.4, 0.6)}


def _mean_band(k: int, dof: int = 6) -> tuple[float, float]:
    """The central 95 % band of the mean of ``k`` chi-square values with ``dof`` degrees of freedom."""
    return _stats.chi2_ppf(0.025, dof * k) / k, _stats.chi2_isf(0.025, dof * k) / k


def _q5_run(rng: np.random.Generator, kind: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Innovations (k, 6) and their covariances (k, 6, 6) of a run of ``kind``, clear of the band's edges."""
    while True:
        k = int(rng.integers(40, 81))
        factor = float(rng.uniform(*_Q5_KINDS[kind]))
        S, r = np.empty((k, 6, 6)), np.empty((k, 6))
        for i in range(k):
            A = rng.normal(size=(6, 6))
            C = A @ A.T / 6 + 0.5 * np.eye(6)
            d = np.r_[rng.uniform(0.002, 0.01, 3), rng.uniform(3, 30, 3)] / np.sqrt(np.diag(C))
            S[i] = np.round(C * np.outer(d, d), 12)
            r[i] = np.round(np.sqrt(factor) * np.linalg.cholesky(S[i]) @ rng.normal(size=6), 9)
        mean = float(np.mean([ri @ np.linalg.solve(Si, ri) for ri, Si in zip(r, S)]))
        lo, hi = _mean_band(k)
        margin = 0.25 * (hi - lo)
        if {
            "consistent": lo + margin <= mean <= hi - margin,
            "overconfident": hi + margin <= mean <= 13.0,
            "cautious": 1.8 <= mean <= lo - margin,
        }[kind]:
            return r, S, mean


def _parse_verdict(a: object) -> bool:
    if isinstance(a, (bool, np.bool_)):
        return bool(a)
    raise _AnswerError(f"the verdict should be True or False, got {a!r:.40}")


def _q5(learner: str) -> Question:
    """q5: Is the filter consistent?"""
    rng = _rng("10", learner, "q5")
    kind = str(rng.choice(list(_Q5_KINDS)))
    r, S, mean = _q5_run(rng, kind)
    k = len(r)
    lo, hi = _mean_band(k)
    key = {"mean_nis": mean, "consistent": bool(lo <= mean <= hi)}
    plain = float(np.mean(np.sum(r**2, axis=1)))
    one = (_stats.chi2_ppf(0.025, 6), _stats.chi2_isf(0.025, 6))
    lo3, hi3 = _mean_band(k, 3)

    def mean_is(a, value):
        return abs(a["mean_nis"] - value) <= 1e-4 * abs(value)

    def verdict_from(a, low, high):
        return mean_is(a, mean) and a["consistent"] == (low <= mean <= high) != key["consistent"]

    def compare(a, b):
        if not mean_is(a, b["mean_nis"]):
            return f"the mean NIS {a['mean_nis']:.4g} is not the mean of r^T S^-1 r over the {k} frames"
        if a["consistent"] != b["consistent"]:
            return "the mean NIS is right, the verdict is not"
        return None

    return Question(
        "q5",
        inputs={"innovations": r, "S": S},
        expected=key,
        parse=_parts(mean_nis=_scalar("the mean NIS"), consistent=_parse_verdict),
        compare=compare,
        wrong=[
            (
                lambda a: mean_is(a, plain),
                (
                    "that is the mean of r^T r, the innovation's squared length with the identity in place of S: "
                    "it adds rad^2 and mm^2 and ignores what the filter expected. Weigh with S^-1: r^T S^-1 r"
                ),
            ),
            (
                lambda a: mean_is(a, k * mean),
                f"that is the sum of the {k} frames' NIS; the test is on their mean",
            ),
            (
                lambda a: verdict_from(a, *one),
                (
                    f"the mean is right, but that verdict compares it with the band of ONE chi-square(6) value "
                    f"({one[0]:.2f} to {one[1]:.2f}); a mean of {k} values varies much less: its band is the "
                    f"chi-square with 6 * {k} degrees of freedom's quantiles divided by {k}"
                ),
            ),
            (
                lambda a: verdict_from(a, lo3, hi3),
                (
                    "the mean is right, but that verdict uses 3 degrees of freedom: the innovation has 6 components "
                    "(3 of rotation and 3 of position), so each NIS is chi-square with 6"
                ),
            ),
        ],
        **_Q5,
    )


#: q6's words: its title and task (the notebook's markdown), hint, solution code and level.
_Q6: QuestionText = {
    "title": "The rotation innovation",
    "task": """
        The tracker predicted the camera's orientation for this frame, `R_pred` (3x3, R_world_camera);
        the frame's pose says `R_meas`. The filter's rotation error is a small rotation vector in world
        axes, applied on the left: `R_meas = exp([r]x) R_pred`. Write code that computes the rotation
        part of the innovation, `r` (3,), in radians: what the update weighs with the Kalman gain.
        """,
    "hint": [
        "Two rotations do not subtract like vectors: the difference between them is itself a rotation, the one "
        "that turns the prediction into the measurement. Find that rotation first, then its rotation vector.",
        "The error is applied on the left, in world axes: the rotation that, applied after R_pred, gives R_meas. "
        "Undoing a rotation is its transpose; OpenCV's Rodrigues turns a rotation matrix into its rotation vector.",
    ],
    "solution": """
        R_pred, R_meas = np.asarray(q6.inputs.R_pred), np.asarray(q6.inputs.R_meas)
        q6.answer = cv2.Rodrigues(R_meas @ R_pred.T)[0].ravel()
        """,
    "level": "medium",
}

#: q6's tolerance on each component of r, rad (0.006 deg); every named wrong answer lies 50 times further.
_Q6_TOL = 1e-4


def _rvec(R: np.ndarray) -> np.ndarray:
    """A rotation matrix to its rotation vector (3,), rad."""
    return cv2.Rodrigues(np.asarray(R, dtype=float))[0].ravel()


def _q6_wrong(R_pred: np.ndarray, R_meas: np.ndarray) -> dict[str, np.ndarray]:
    """The rotation vectors of q6's named mistakes."""
    return {
        "camera axes": _rvec(R_pred.T @ R_meas),
        "sign": _rvec(R_pred @ R_meas.T),
        "subtracted": _rvec(R_meas) - _rvec(R_pred),
        "degrees": np.degrees(_rvec(R_meas @ R_pred.T)),
    }


def _q6_pair(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A predicted orientation (a camera facing a wall, turned well round) and a measured one a few degrees off,
    every named mistake far from the key."""
    while True:
        yaw = float(rng.uniform(120, 178) * rng.choice([-1, 1]))
        rpy = np.round([-90 + rng.uniform(-15, 15), rng.uniform(-15, 15), yaw], 3)
        R_pred = np.round(frames.rotation_from_rpy_deg(*rpy), 9)
        axis = rng.normal(size=3)
        r = axis / np.linalg.norm(axis) * np.radians(rng.uniform(2, 8))
        R_meas = np.round(cv2.Rodrigues(r)[0] @ R_pred, 9)
        key = _rvec(R_meas @ R_pred.T)
        if all(np.abs(w - key).max() > 50 * _Q6_TOL for w in _q6_wrong(R_pred, R_meas).values()):
            return R_pred, R_meas


def _q6(learner: str) -> Question:
    """q6: The rotation innovation."""
    rng = _rng("10", learner, "q6")
    R_pred, R_meas = _q6_pair(rng)
    key = _rvec(R_meas @ R_pred.T)
    wrong = _q6_wrong(R_pred, R_meas)

    def near(v):
        return lambda a: a.shape == (3,) and np.abs(a - v).max() <= _Q6_TOL

    return Question(
        "q6",
        inputs={"R_pred": R_pred, "R_meas": R_meas},
        expected=key,
        parse=_array((3,), "the rotation innovation r"),
        compare=_cmp_array(_Q6_TOL, " rad"),
        wrong=[
            (
                near(wrong["camera axes"]),
                (
                    "that is the rotation in the camera's own axes, applied on the right (R_meas = R_pred exp(r)): "
                    "the same turn, written in other axes. The filter's error is in world axes, applied on the left"
                ),
            ),
            (
                near(wrong["sign"]),
                "the sign is turned round: that rotation takes the measurement to the prediction, not the other way",
            ),
            (
                near(wrong["subtracted"]),
                (
                    "that subtracts the two rotation vectors: rotation vectors do not add or subtract like "
                    "positions (near 180 deg they even wrap). Compose the rotations first, then take the log"
                ),
            ),
            (near(wrong["degrees"]), "that is in degrees; the innovation is in radians"),
        ],
        **_Q6,
    )
