"""Rotations on the manifold for the tracker: SO(3)'s exponential, logarithm and left Jacobian
(:mod:`fidlearn.frames._so3`, shared with the survey), quaternions, and chi-square(6).
"""

from __future__ import annotations

from .. import _stats
from ..frames import matrix_from_quaternion, quaternion_from_matrix
from ..frames._so3 import exp_so3, left_jacobian, log_so3, skew

__all__ = [
    "chi2_6_quantile",
    "exp_so3",
    "left_jacobian",
    "log_so3",
    "quaternion_xyzw",
    "rotation_from_xyzw",
    "skew",
]


def chi2_6_quantile(probability: float) -> float:
    """The ``probability`` quantile of chi-square with 6 degrees of freedom (the closed-form even-dof
    distribution of :mod:`fidlearn.pose`); e.g. 0.99 -> 16.812, 0.999 -> 22.458."""
    return _stats.chi2_isf(1.0 - probability, 6)


#: Quaternions are fidlearn.frames' own: (x, y, z, w), canonical w >= 0 (see there).
quaternion_xyzw = quaternion_from_matrix
rotation_from_xyzw = matrix_from_quaternion
