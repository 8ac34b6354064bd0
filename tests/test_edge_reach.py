"""How far the "edges" refinement moves a marker's corners: as far as its profiles find the edges.

A hand-drawn dark square of 40 px (10 cells of 4 px, as a 36h11 tag with a 2-bit border), turned 12 degrees,
its true corners known; the input corners are the true ones moved inwards along both sides, as OpenCV's come out
on Kalibr's AprilGrid, where the grid's small squares touch each tag's corners (``data/real/tumvi_aprilgrid``).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fidlearn.refinement import _refine_edges, refine_corners_edges

SUPER = 8
SIDE, CELLS = 40.0, 10
CENTRE = np.array([50.3, 49.6])
UNIT = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])  # TL, TR, BR, BL


def _turned(half: float) -> np.ndarray:
    a = np.deg2rad(12.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return CENTRE + (UNIT * half) @ R.T


TRUTH = _turned(SIDE / 2)


@pytest.fixture(scope="module")
def picture() -> np.ndarray:
    """The square drawn 8 times finer and averaged down (pixel centres at integers), gray 25 on 230."""
    big = np.full((100 * SUPER, 100 * SUPER), 230, np.uint8)
    fine = ((TRUTH + 0.5) * SUPER - 0.5) * 16  # the fine picture's pixels, 4 fractional bits
    cv2.fillConvexPoly(big, np.round(fine).astype(np.int32), 25, lineType=cv2.LINE_AA, shift=4)
    return cv2.resize(big, (100, 100), interpolation=cv2.INTER_AREA)


def _error(corners: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(corners).reshape(4, 2) - TRUTH, axis=1).max())


@pytest.mark.parametrize("inset", [0.0, 1.0, 2.6, 3.0])
def test_corners_up_to_the_profiles_reach_are_found(picture, inset):
    """Inputs up to 3 px inside each side (corners 3.6 px off, farther than the 3 px a corner was once allowed
    to move at 4 px a cell) come out within 0.15 px of the truth, and the quad passes as the marker's outline.
    A single pass leaves such corners 0.5-1 px off (the edges lie near the ends of its profiles); the second
    pass, from the corners found, does not."""
    start = _turned(SIDE / 2 - inset)
    corners, ok = _refine_edges(picture, start[None], CELLS)
    assert ok[0]
    assert _error(corners) < 0.15
    assert _error(refine_corners_edges(picture, start[None], CELLS)) < 0.15
    if inset >= 2.6:
        assert _error(start) > 3.0


def test_corners_beyond_the_reach_are_not_fitted(picture):
    """5 px inside each side (6 px off) the profiles, 2.4 px either side of their centres, cannot see the
    edges: the quad is no marker's outline and the refinement keeps its corners."""
    start = _turned(SIDE / 2 - 5.0)
    corners, ok = _refine_edges(picture, start[None], CELLS)
    assert not ok[0]
    np.testing.assert_array_equal(refine_corners_edges(picture, start[None], CELLS)[0], start)
