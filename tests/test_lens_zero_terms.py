"""The lens's distortion leaves out the terms of coefficients that are zero: the same numbers, bit for bit, as
the whole polynomial, for every mix of zero and non-zero coefficients (equal values; a zero may lose its
sign, which no pixel shows)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from fidlearn._lens import distort_normalized


def _whole(xy, dist):
    """Every term of OpenCV's rational, tangential and thin-prism model, zero or not."""
    d = np.zeros(14)
    d[: dist.size] = dist
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d[:12]
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    r4, r6 = r2 * r2, r2 * r2 * r2
    radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
    return np.stack([xd, yd], axis=1)


@pytest.mark.parametrize("size", [4, 5, 8, 12])
def test_zero_terms_left_out_change_no_bit(size):
    rng = np.random.default_rng(size)
    xy = rng.uniform(-1.2, 1.2, size=(200, 2))
    xy[0] = 0.0
    values = rng.normal(scale=0.05, size=size)
    groups = [g for g in ([0, 1, 4], [2, 3], [5, 6, 7], [8, 9, 10, 11]) if g[0] < size]
    for zero in itertools.product([False, True], repeat=len(groups)):
        dist = values.copy()
        for g, z in zip(groups, zero):
            if z:
                dist[[i for i in g if i < size]] = 0.0
        got, want = distort_normalized(xy, dist), _whole(xy, dist)
        assert np.array_equal(got, want)  # equal values: the same bits (a zero may differ in sign only)
