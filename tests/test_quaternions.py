"""Quaternions (x, y, z, w): hand-computed cases, the canonical w >= 0, round trips and bad input."""

import math

import cv2
import numpy as np
import pytest

from fidlearn import frames
from fidlearn.errors import TransformError

H = math.sqrt(0.5)  # sin 45 = cos 45

# (rotation matrix, its quaternion) worked out by hand from q = (k sin(theta/2), cos(theta/2))
HAND = [
    (np.eye(3), [0, 0, 0, 1]),
    ([[0, -1, 0], [1, 0, 0], [0, 0, 1]], [0, 0, H, H]),  # 90 deg about Z
    ([[1, 0, 0], [0, 0, -1], [0, 1, 0]], [H, 0, 0, H]),  # 90 deg about X
    ([[0, 0, -1], [0, 1, 0], [1, 0, 0]], [0, -H, 0, H]),  # -90 deg about Y (a floor marker's pitch)
    (np.diag([1.0, -1.0, -1.0]), [1, 0, 0, 0]),  # 180 deg about X
    (np.diag([-1.0, -1.0, 1.0]), [0, 0, 1, 0]),  # 180 deg about Z
    ([[0, 1, 0], [1, 0, 0], [0, 0, -1]], [H, H, 0, 0]),  # 180 deg about (1, 1, 0)/sqrt 2
    ([[0, 0, 1], [1, 0, 0], [0, 1, 0]], [0.5, 0.5, 0.5, 0.5]),  # 120 deg about (1, 1, 1)/sqrt 3: X->Y->Z->X
]


@pytest.mark.parametrize(("R", "q"), HAND)
def test_hand_computed_quaternions(R, q):
    assert frames.quaternion_from_matrix(R) == pytest.approx(q, abs=1e-15)
    assert np.allclose(frames.matrix_from_quaternion(q), R, atol=1e-15)


def test_a_rigid_transform_gives_its_rotation_quaternion():
    T = frames.make_transform([[0, -1, 0], [1, 0, 0], [0, 0, 1]], [100, 200, 300])
    assert frames.quaternion_from_matrix(T) == pytest.approx([0, 0, H, H], abs=1e-15)


def test_canonical_form_and_double_cover():
    # 270 deg about Z is -90 deg about Z: cos(135) < 0, so the canonical form is the negated one
    R = frames.rot_z(math.radians(270))
    q = frames.quaternion_from_matrix(R)
    assert q == pytest.approx([0, 0, -H, H], abs=1e-12)
    assert np.allclose(frames.matrix_from_quaternion(-q), R, atol=1e-12)
    # a half turn about -Z: w = 0, the first non-zero component made positive
    assert frames.quaternion_from_matrix(frames.rot_z(-math.pi)) == pytest.approx([0, 0, 1, 0], abs=1e-12)


def test_round_trip_and_agreement_with_rodrigues():
    rng = np.random.default_rng(3)
    for _ in range(200):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(0, math.pi)
        R = cv2.Rodrigues(angle * axis)[0]
        q = frames.quaternion_from_matrix(R)
        assert q[3] >= 0
        assert math.isclose(np.linalg.norm(q), 1.0)
        # the definition: vector part k sin(theta/2), scalar cos(theta/2)
        assert np.allclose(q, [*(axis * math.sin(angle / 2)), math.cos(angle / 2)], atol=1e-12)
        assert np.allclose(frames.matrix_from_quaternion(q), R, atol=1e-12)


def test_a_quaternion_with_few_digits_is_normalised():
    R = frames.matrix_from_quaternion([0, 0, 0.7071, 0.7071])  # norm 0.99999
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-15)
    assert frames.rotation_angle_deg(R, frames.rot_z(math.pi / 2)) < 1e-9


@pytest.mark.parametrize(
    ("q", "message"),
    [
        ([0, 0, 1], "4 finite numbers"),
        ([0, 0, 0, float("nan")], "4 finite numbers"),
        ([0, 0, 0, 2], "norm 2"),
        ([0, 0, 0, 0], "norm 0"),
        ("0 0 0 1", "text"),
    ],
)
def test_bad_quaternions_say_what_is_wrong(q, message):
    with pytest.raises(TransformError, match=message):
        frames.matrix_from_quaternion(q)


def test_a_matrix_that_is_no_rotation_is_refused():
    with pytest.raises(TransformError, match="reflection"):
        frames.quaternion_from_matrix(np.diag([1.0, 1.0, -1.0]))
