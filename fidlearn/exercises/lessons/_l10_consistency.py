"""Lesson 10, q5: is the filter consistent? The mean NIS of a run against its 95 % band.

Kept apart from :mod:`.l10_tracking` (which lists ``_q5`` in its ``build``) for that module's length.
"""

from __future__ import annotations

import numpy as np

from ... import _stats
from .._engine import Question, QuestionText, _AnswerError
from .._parsers import _parts, _scalar
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
