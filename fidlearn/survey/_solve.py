"""The adjustment: build the problem, solve it (robust, then plain), its covariance, and the suspect test.

The suspect test compares each taped marker's placement with where the photos alone put it.
With ``C`` the marker's 6x6 covariance in the joint solution and ``P`` its tape prior's
information (``diag(1/sigma_rot^2, 1/sigma_mm^2)``), the photos alone give the information
``C^-1 - P`` (the prior touches only that marker's block, so this is exact for the linearised
problem) and the estimate ``x + (C^-1 - P)^-1 P (x - tape)``. Its top-left corner minus the
tape's, over the photos' covariance plus the tape's (``sigma_mm^2 I``), gives a squared
Mahalanobis distance that is chi-square with 3 degrees of freedom for a correctly taped marker:
above the ``SUSPECT_P`` quantile the marker is named.
"""

from __future__ import annotations

import warnings

import numpy as np

from .. import _stats
from ..pose._stats import MIN_SIGMA_PX
from ._geometry import local_corners, log_so3
from ._problem import Problem

#: Level of the suspect test: a correctly taped marker is named with probability 1 - SUSPECT_P.
SUSPECT_P = 0.99
#: Scale of the robust (soft-L1) loss of the first pass on the tape residuals, in sigmas.
ROBUST_SCALE = 3.0
#: Corner noise assumed by the first pass when ``corner_sigma_px`` is not given, px.
FIRST_SIGMA_PX = 0.25


def build_problem(cams: list, slots: list, n_free: int, placed: dict, tape_priors: dict, opts: dict) -> Problem:
    """The problem for the located photos ``cams`` and the marker slots ``slots`` (free first).

    ``tape_priors`` is ``{id: (R, p)}`` for the free markers that keep a tape prior; ``opts`` holds
    ``marker_size_mm`` (the side of a marker not in ``sizes``), ``sizes`` (optional, ``{id: side mm}``),
    ``sigma_px``, ``sigma_mm``, ``sigma_rot_rad``, and ``groups`` (optional, ``{name: Group}``): a slot named
    by a group is a rigid entry (:mod:`fidlearn.survey._entries`), its markers' corners in its one placement.
    """
    groups = opts.get("groups", {})
    block = {}  # marker key -> (slot, its first corner's row in the slot's local corners)
    for k, i in enumerate(slots):
        block.update({m: (k, 4 * n) for n, m in enumerate(groups[i].members)} if i in groups else {i: (k, 0)})
    oc: list[int] = []
    om: list[int] = []
    ok: list[int] = []
    op, keys = [], []
    for c, ph in enumerate(cams):
        for i, px in ph.corners.items():
            if i in block:
                k, first = block[i]
                oc += [c] * 4
                om += [k] * 4
                ok += range(first, first + 4)
                op.append(px)
                keys.append(i)
    T_cw = [np.linalg.inv(ph.T_world_camera) for ph in cams]
    block_slot = {i: k for k, i in enumerate(slots)}
    prior_ids = [i for i in slots[:n_free] if i in tape_priors]
    cam = cams[0].camera
    return Problem(
        K=cam.K,
        dist=np.asarray(cam.dist, float).ravel(),
        local=_slot_corners(slots, groups, opts),
        R0_cam=np.array([T[:3, :3] for T in T_cw]),
        t0_cam=np.array([T[:3, 3] for T in T_cw]),
        R0_mark=np.array([placed[i][0] for i in slots]),
        p0_mark=np.array([placed[i][1] for i in slots], float),
        n_free=n_free,
        obs_cam=np.array(oc, int),
        obs_marker=np.array(om, int),
        obs_corner=np.array(ok, int),
        obs_px=np.concatenate(op).reshape(-1, 2),
        sigma_px=opts["sigma_px"],
        prior_slots=np.array([block_slot[i] for i in prior_ids], int),
        prior_R=np.array([tape_priors[i][0] for i in prior_ids]).reshape(-1, 3, 3),
        prior_p=np.array([tape_priors[i][1] for i in prior_ids], float).reshape(-1, 3),
        sigma_mm=opts["sigma_mm"],
        sigma_rot_rad=opts["sigma_rot_rad"],
        model=cam.model,
        sightings=tuple(keys),
    )


def _slot_corners(slots: list, groups: dict, opts: dict) -> np.ndarray:
    """Each slot's corners in its placement frame, (k, 4 * most markers in a slot, 3), mm, zeros past its own."""
    sizes = opts.get("sizes", {})
    own = [groups[i].local if i in groups else local_corners(sizes.get(i, opts["marker_size_mm"])) for i in slots]
    out = np.zeros((len(slots), max((len(c) for c in own), default=4), 3))
    for k, c in enumerate(own):
        out[k, : len(c)] = c
    return out


def fit(problem: Problem, x0: np.ndarray, robust: bool) -> np.ndarray:
    """``scipy.optimize.least_squares`` (trust region, sparse Jacobian) from ``x0``."""
    from scipy.optimize import least_squares  # imported on first use: ``import fidlearn`` stays quick

    res = least_squares(
        problem.residuals,
        x0,
        jac=problem.jacobian,
        method="trf",
        tr_solver="lsmr",
        tr_options={"atol": 1e-10, "btol": 1e-10},
        loss=prior_loss(problem) if robust else "linear",
        x_scale="jac",
        ftol=1e-6 if robust else 1e-8,
        xtol=1e-6 if robust else 1e-8,
        gtol=1e-8,
        max_nfev=200 if robust else 15,
    )
    return _polish(problem, res.x) if not robust else res.x


def prior_loss(problem: Problem):
    """The first pass's loss: soft-L1 (scale ``ROBUST_SCALE`` sigmas) on the tape residuals, squares on the corners.

    It is the tape that may be wrong by a lot (a marker moved after it was measured); the corners
    are detected to a fraction of a pixel. A robust loss on the corners too would let the solver
    give up a marker's corners in one photo and tilt it into a false minimum.
    """
    n_reproj = 2 * len(problem.obs_cam)
    c2 = ROBUST_SCALE**2

    def loss(z: np.ndarray) -> np.ndarray:
        rho = np.empty((3, z.size))
        rho[0], rho[1], rho[2] = z, 1.0, 0.0
        t = 1.0 + z[n_reproj:] / c2
        rho[0, n_reproj:] = 2 * c2 * (np.sqrt(t) - 1)
        rho[1, n_reproj:] = 1 / np.sqrt(t)
        rho[2, n_reproj:] = -0.5 / c2 * t**-1.5
        return rho

    return loss


def _polish(problem: Problem, x: np.ndarray, steps: int = 8) -> np.ndarray:
    """Gauss-Newton steps with a direct sparse solve (halved while they raise the cost).

    The trust-region steps of ``least_squares`` solve each step's linear problem iteratively (LSMR)
    and creep along the weakly held directions (the whole map moving within the tape's sigma);
    a few Newton steps on the normal equations finish the job to the last digit.
    """
    from scipy.sparse.linalg import MatrixRankWarning, spsolve

    r = problem.residuals(x)
    cost = float(r @ r)
    for _ in range(steps):
        J = problem.jacobian(x)
        with warnings.catch_warnings():  # singular (a placement nothing holds): the step is NaN, and not taken
            warnings.simplefilter("ignore", MatrixRankWarning)
            dx = spsolve((J.T @ J).tocsc(), -(J.T @ r))
        if not np.all(np.isfinite(dx)):
            break
        for _ in range(4):
            r_new = problem.residuals(x + dx)
            if float(r_new @ r_new) <= cost:
                break
            dx = dx / 2
        else:
            break
        x, r, done = x + dx, r_new, float(r_new @ r_new) > cost * (1 - 1e-15)
        cost = float(r @ r)
        if done:
            break
    return x


def corner_sigma(problem: Problem, x: np.ndarray, gauge_free: bool) -> float:
    """Corner noise (px) from the reprojection residuals, with their degrees of freedom."""
    r = problem.reprojection_px(x)
    dof = r.size - problem.n_params + (6 if gauge_free else 0)
    return max(float(np.sqrt(np.sum(r**2) / max(dof, 1))), MIN_SIGMA_PX)


def covariance(problem: Problem, x: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` of the whitened residuals at ``x``: the unknowns' covariance (dense)."""
    J = problem.jacobian(x)
    H = (J.T @ J).toarray()
    try:
        return np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(H)


def marker_block(problem: Problem, C: np.ndarray, slot: int) -> np.ndarray:
    """The 6x6 covariance ``[rotation (rad), top-left corner (mm)]`` of a free marker slot."""
    k = 6 * (problem.n_cams + slot)
    return C[k : k + 6, k : k + 6]


def tape_test(problem: Problem, x: np.ndarray, C: np.ndarray, slot: int, tape, has_prior: bool):
    """``(distance_mm, sigmas)`` of the photos' placement of a marker from its tape placement."""
    _, _, R_mark, p_mark = problem.poses(x)
    e = np.concatenate([log_so3(R_mark[slot] @ tape[0].T), p_mark[slot] - tape[1]])
    Ck = marker_block(problem, C, slot)
    if has_prior:
        P = np.diag([problem.sigma_rot_rad**-2] * 3 + [problem.sigma_mm**-2] * 3)
        C_photo = np.linalg.pinv(np.linalg.pinv(Ck) - P)
        d = (e + C_photo @ P @ e)[3:]
    else:
        C_photo, d = Ck, e[3:]
    S = C_photo[3:, 3:] + problem.sigma_mm**2 * np.eye(3)
    m2 = float(d @ np.linalg.solve(S, d))
    return float(np.linalg.norm(d)), float(np.sqrt(max(m2, 0.0)))


def suspect_threshold() -> float:
    """Squared-sigma threshold of the suspect test (chi-square, 3 degrees of freedom, ``SUSPECT_P``)."""
    return _stats.chi2_ppf(SUSPECT_P, 3)
