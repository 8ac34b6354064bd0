"""The pose error by sampling: corner noise drawn many times, each draw solved as ``estimate_pose`` solves it.

First-order propagation (:mod:`fidlearn.planning.predict`) holds while the pose is a near-linear
function of the corners. It is not when the markers subtend little: a small marker seen face-on
has a tilt that moves its corners only to second order, and the camera centre, which rests on that
tilt times the distance, then has a longer tail than a Gaussian of the linearized covariance. Here
the corners' noise is drawn :data:`DRAWS` times and each draw is solved by Gauss-Newton from the
true pose, all draws at once; the spread of the solutions is the pose error with the nonlinearity
in it. The draws are fixed, so a prediction is the same every time.

Solved in the camera frame, on the normalized image plane: each corner's pixel noise is taken
there through the lens's local 2x2 Jacobian at that corner, and the residuals are weighted back
to pixels by it, so the fit is ``estimate_pose``'s unweighted least squares in pixels up to the
lens's curvature over a fraction of a pixel.
"""

from __future__ import annotations

import numpy as np

from .. import _lens
from ..camera import Camera

__all__ = ["DRAWS", "NONLINEAR_ROTATION_DEG", "sampled_position_errors"]

#: How many noise draws a sampled prediction solves.
DRAWS = 256
#: Gauss-Newton steps per draw (from the true pose: the noise moves the solution by little).
STEPS = 10
#: Largest rotation (rad) of one step: a larger one may leap to a solution no fit from the truth reaches.
MAX_TURN_RAD = 0.2
_RNG_SEED = 20261128

#: Fixed standard normal draws: the median of the position error of a Gaussian with a given
#: covariance is computed from these, so a prediction is the same every time.
_Z = np.random.default_rng(20261124).standard_normal((4000, 3))

#: Where the linearized rotation's standard deviation (degrees, its worst axis) exceeds this, the
#: position error is sampled (:mod:`~fidlearn.planning.sampling`) rather than taken from the
#: linearized covariance: beyond it the linearization overstates the error of a small marker seen
#: face-on (2 times at 15 deg), below it the two agree within 10 %.
NONLINEAR_ROTATION_DEG = 3.0


def _lens_jacobians(xy: np.ndarray, camera: Camera) -> np.ndarray:
    """(N, 2, 2) d(pixel) / d(normalized point) at each normalized point ``xy`` (N, 2)."""
    h = 1e-7
    dist = np.zeros(5) if camera.dist is None else camera.dist
    base = _lens.pixels_from_normalized(xy, camera.K, dist, camera.model)
    jx = (_lens.pixels_from_normalized(xy + [h, 0.0], camera.K, dist, camera.model) - base) / h
    jy = (_lens.pixels_from_normalized(xy + [0.0, h], camera.K, dist, camera.model) - base) / h
    return np.stack([jx, jy], axis=2)


def _rotations(w: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotation matrices of the rotation vectors ``w`` (K, 3) (Rodrigues)."""
    theta = np.linalg.norm(w, axis=1)[:, None, None]
    small = theta < 1e-12
    k = w / np.where(small[:, :, 0], 1.0, theta[:, :, 0])
    Kx = np.zeros((len(w), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    Kx = Kx - Kx.transpose(0, 2, 1)
    s, c = np.sin(theta), np.cos(theta)
    return np.eye(3) + s * Kx + (1 - c) * Kx @ Kx


def _noise_draws(blocks: list[np.ndarray], draws: int) -> np.ndarray:
    """(draws, 8M) pixel noise of the corners, marker by marker from each (8, 8) covariance in ``blocks``."""
    rng = np.random.default_rng(_RNG_SEED)
    z = rng.standard_normal((draws, 8 * len(blocks)))
    out = np.empty_like(z)
    for m, C in enumerate(blocks):
        w, V = np.linalg.eigh(C)
        L = V * np.sqrt(np.clip(w, 0.0, None))
        out[:, 8 * m : 8 * m + 8] = z[:, 8 * m : 8 * m + 8] @ L.T
    return out


def sampled_position_errors(
    points_world: np.ndarray,
    T_world_camera: np.ndarray,
    camera: Camera,
    blocks: list[np.ndarray],
    *,
    draws: int = DRAWS,
) -> np.ndarray:
    """Camera-centre errors (draws, 3), world axes, mm, of the least-squares pose from noisy corners.

    Parameters
    ----------
    points_world : ndarray, shape (4M, 3)
        The M markers' corners (mm, world), four by four.
    T_world_camera : ndarray, shape (4, 4)
        The true camera pose (mm).
    camera : Camera
        The camera.
    blocks : list of ndarray, shape (8, 8)
        Each marker's corner covariance (px^2), in the order of ``points_world``.
    draws : int
        How many draws.

    Returns
    -------
    ndarray, shape (draws, 3)
        Estimated minus true camera centre of every draw (mm, world); a draw whose solution runs
        away (behind the camera) is NaN.
    """
    R_wc, C0 = T_world_camera[:3, :3], T_world_camera[:3, 3]
    X0 = (points_world - C0) @ R_wc  # the corners in the camera frame, (N, 3)
    xy0 = X0[:, :2] / X0[:, 2:3]
    A = _lens_jacobians(xy0, camera)  # (N, 2, 2)
    noise_px = _noise_draws(blocks, draws).reshape(draws, -1, 2)
    obs = xy0 + np.einsum("nij,knj->kni", np.linalg.inv(A), noise_px)  # noisy normalized corners (K, N, 2)
    K = draws
    Q = np.tile(np.eye(3), (K, 1, 1))
    tau = np.zeros((K, 3))
    for _ in range(STEPS):
        Xc = np.einsum("kij,nj->kni", Q, X0) + tau[:, None, :]  # (K, N, 3)
        z = Xc[:, :, 2]
        z = np.where(np.abs(z) < 1e-9, 1e-9, z)
        x, y = Xc[:, :, 0] / z, Xc[:, :, 1] / z
        d = np.stack([x, y], axis=2) - obs
        r = A[None, :, :, 0] * d[:, :, 0:1] + A[None, :, :, 1] * d[:, :, 1:2]  # pixel residuals (K, N, 2)
        gx = np.stack([1 / z, np.zeros_like(z), -x / z], axis=2)  # d(x) / d(camera-frame point)
        gy = np.stack([np.zeros_like(z), 1 / z, -y / z], axis=2)
        Xr = Xc - tau[:, None, :]  # the rotated points: a small rotation w moves them by w x Xr
        Jn = np.stack(
            [np.concatenate([np.cross(Xr, gx), gx], axis=2), np.concatenate([np.cross(Xr, gy), gy], axis=2)], axis=2
        )  # (K, N, 2, 6) normalized point against (rotation, translation)
        J = (A[None, :, :, 0:1] * Jn[:, :, 0:1, :] + A[None, :, :, 1:2] * Jn[:, :, 1:2, :]).reshape(K, -1, 6)
        JtJ = np.einsum("kna,knb->kab", J, J)
        rhs = -np.einsum("kna,kn->ka", J, r.reshape(K, -1))
        step = np.linalg.solve(JtJ + 1e-12 * np.eye(6), rhs[:, :, None])[:, :, 0]
        angle = np.linalg.norm(step[:, :3], axis=1, keepdims=True)
        step = step * np.minimum(1.0, MAX_TURN_RAD / np.maximum(angle, 1e-300))  # no leap past the basin
        Q = _rotations(step[:, :3]) @ Q
        tau = tau + step[:, 3:]
    err = -np.einsum("klj,kl->kj", Q, tau) @ R_wc.T  # C' - C0 = -R_wc Q^T tau
    Xc = np.einsum("kij,nj->kni", Q, X0) + tau[:, None, :]
    err[np.any(Xc[:, :, 2] <= 0, axis=1) | ~np.all(np.isfinite(err), axis=1)] = np.nan
    return err


def _gaussian_draws(cov: np.ndarray) -> np.ndarray:
    """(len(_Z), 3) fixed draws of a Gaussian with covariance ``cov`` (3, 3)."""
    w, V = np.linalg.eigh(cov)
    return (_Z * np.sqrt(np.clip(w, 0, None))) @ V.T


def _position_errors(
    P: np.ndarray, T: np.ndarray, camera: Camera, cov_C: np.ndarray, blocks: list, common: np.ndarray, sample: bool
) -> np.ndarray:
    """Draws (K, 3) of the camera centre's error about its bias: from the linearized covariance ``cov_C``, or,
    when ``sample`` and the rotation is known worse than :data:`NONLINEAR_ROTATION_DEG`, by solving noisy
    corners (:func:`sampled_position_errors`) plus the common size spread ``common``."""
    if not sample:
        return _gaussian_draws(cov_C)
    errors = sampled_position_errors(P, T, camera, blocks)
    errors = errors[np.all(np.isfinite(errors), axis=1)]
    if len(errors) < DRAWS // 2:  # the solutions ran away: no better than the linearization
        return _gaussian_draws(cov_C)
    return errors + _gaussian_draws(common)[: len(errors)] if np.any(common) else errors


def _error_stats(components: list[tuple[float, np.ndarray, float, np.ndarray]]) -> tuple[float, float, float]:
    """Median, 90th percentile and RMS of the error's length over a mixture: each component
    ``(weight, errors, p_flip, flip_offset)`` holds draws ``errors`` (K, 3), mixed with the same errors moved
    by ``flip_offset`` (the other planar solution) in a fraction ``p_flip``."""
    lengths, weights = [], []
    for w, errors, p_flip, flip_offset in components:
        d = np.linalg.norm(errors, axis=1)
        flips = p_flip > 0 and bool(np.all(np.isfinite(flip_offset)))
        lengths.append(d)
        weights.append(np.full(len(d), w * (1.0 - p_flip if flips else 1.0) / len(d)))
        if flips:
            lengths.append(np.linalg.norm(errors + flip_offset, axis=1))
            weights.append(np.full(len(d), w * p_flip / len(d)))
    d, weight = np.concatenate(lengths), np.concatenate(weights)
    order = np.argsort(d)
    d, cum = d[order], np.cumsum(weight[order]) / np.sum(weight)
    median, p90 = (float(d[min(int(np.searchsorted(cum, q)), len(d) - 1)]) for q in (0.5, 0.9))
    return median, p90, float(np.sqrt(np.sum(weight[order] * d**2) / np.sum(weight)))
