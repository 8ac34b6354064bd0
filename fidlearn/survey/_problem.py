"""The survey's least-squares problem: unknowns, residuals and their sparse Jacobian.

Unknowns, 6 per camera pose and 6 per free marker, as increments from a reference pose:

* camera i: ``T_camera_world`` with ``R = exp([phi_i]x) @ R0_i`` and ``t = t0_i + dt_i`` (mm);
* marker j: its placement, ``R = exp([phi_j]x) @ R0_j`` about its top-left corner
  ``p = p0_j + dp_j`` (world, mm). A marker of ``fixed_ids`` is not an unknown.

Residuals, each divided by its standard deviation:

* every corner of every marker seen in every photo: projected through the camera's lens model
  (OpenCV's pinhole with its distortion, or the Kannala-Brandt fisheye) minus detected, in the
  picture's own pixels, 2 per corner, over ``sigma_px``;
* every free marker with a tape placement: ``log(R @ R_tape^T)`` over ``sigma_rot_rad`` and
  ``p - p_tape`` over ``sigma_mm`` (6 per marker).

The Jacobian is analytic (the lens model's 2x2 part by central differences on the normalized point) and sparse: a
corner's two rows touch only its camera's 6 columns and its marker's 6.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._lens import pixels_from_normalized as _pixels_from_normalized
from ._geometry import exp_so3, left_jacobian, left_jacobian_inv, log_so3, skew

_H_NORM = 1e-6  # step of the central differences on normalized coordinates


@dataclass
class Problem:
    """Everything the residuals need, in arrays.

    ``obs_cam`` (n,), ``obs_marker`` (n,) index the cameras and the marker slots of each of the n
    observed corners, ``obs_corner`` (n,) which corner (its row in the slot's ``local``: 0-3 for a marker, any of
    a rigid entry's), ``obs_px`` (n, 2) where it was detected. Marker slots ``0 .. n_free - 1`` are unknowns,
    the rest held (``fixed``).
    """

    K: np.ndarray
    dist: np.ndarray
    local: np.ndarray  # (k, c, 3) each slot's corners in its placement frame (its own side; an entry's c), mm
    R0_cam: np.ndarray  # (m, 3, 3)
    t0_cam: np.ndarray  # (m, 3)
    R0_mark: np.ndarray  # (k, 3, 3), free markers first
    p0_mark: np.ndarray  # (k, 3)
    n_free: int
    obs_cam: np.ndarray
    obs_marker: np.ndarray
    obs_corner: np.ndarray
    obs_px: np.ndarray
    sigma_px: float
    prior_slots: np.ndarray  # free marker slots with a tape prior
    prior_R: np.ndarray  # (q, 3, 3)
    prior_p: np.ndarray  # (q, 3)
    sigma_mm: float
    sigma_rot_rad: float
    model: str = "pinhole"  # the lens model: "pinhole" or "fisheye" (Camera.model)
    sightings: tuple = ()  # the marker key of each sighting (4 corners each, in the order of obs_*)

    @property
    def n_cams(self) -> int:
        return len(self.R0_cam)

    @property
    def n_params(self) -> int:
        return 6 * (self.n_cams + self.n_free)

    def poses(self, x: np.ndarray):
        """Camera rotations and translations (T_camera_world) and marker rotations and corners at ``x``."""
        m = self.n_cams
        xc = x[: 6 * m].reshape(m, 6)
        xm = x[6 * m :].reshape(self.n_free, 6)
        R_cam = exp_so3(xc[:, :3]) @ self.R0_cam
        t_cam = self.t0_cam + xc[:, 3:]
        R_mark = self.R0_mark.copy()
        p_mark = self.p0_mark.copy()
        R_mark[: self.n_free] = exp_so3(xm[:, :3]) @ self.R0_mark[: self.n_free]
        p_mark[: self.n_free] += xm[:, 3:]
        return R_cam, t_cam, R_mark, p_mark

    def _points(self, x: np.ndarray):
        R_cam, t_cam, R_mark, p_mark = self.poses(x)
        c, j = self.obs_cam, self.obs_marker
        arm = np.einsum("nij,nj->ni", R_mark[j], self.local[j, self.obs_corner])  # R_j L_k
        X = p_mark[j] + arm
        P = np.einsum("nij,nj->ni", R_cam[c], X) + t_cam[c]
        return R_cam, X, arm, P

    def reprojection_px(self, x: np.ndarray) -> np.ndarray:
        """Projected minus detected corners (n, 2), px."""
        _, _, _, P = self._points(x)
        return _pixels_from_normalized(P[:, :2] / P[:, 2:3], self.K, self.dist, self.model) - self.obs_px

    def prior_residuals(self, x: np.ndarray) -> np.ndarray:
        """Tape prior residuals (q, 6): rotation over sigma_rot_rad, then position over sigma_mm."""
        _, _, R_mark, p_mark = self.poses(x)
        s = self.prior_slots
        rot = np.array([log_so3(R_mark[k] @ self.prior_R[i].T) for i, k in enumerate(s)]).reshape(-1, 3)
        return np.hstack([rot / self.sigma_rot_rad, (p_mark[s] - self.prior_p) / self.sigma_mm])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Every residual (whitened), reprojection first then the tape priors."""
        return np.concatenate([(self.reprojection_px(x) / self.sigma_px).ravel(), self.prior_residuals(x).ravel()])

    def jacobian(self, x: np.ndarray):
        """The Jacobian of :meth:`residuals` at ``x``, sparse (CSR)."""
        R_cam, _, arm, P = self._points(x)
        D = _projection_jacobian(P, self.K, self.dist, self.model) / self.sigma_px  # (n, 2, 3)
        m6 = 6 * self.n_cams
        xc = x[:m6].reshape(-1, 6)
        c, j = self.obs_cam, self.obs_marker
        RX = P - (self.t0_cam + xc[:, 3:])[c]  # R_c X: dP/dphi_c = -[R_c X]x J_l(phi_c)
        blocks = [np.einsum("nij,njk->nik", D, -skew(RX) @ left_jacobian(xc[:, :3])[c]), D]
        cols = [6 * c[:, None] + np.arange(6)]
        free = j < self.n_free
        if self.n_free:
            jj = np.where(free, j, 0)
            Jl_mark = left_jacobian(x[m6:].reshape(-1, 6)[jj, :3])
            DR = np.einsum("nij,njk->nik", D, R_cam[c])
            blocks += [np.einsum("nij,njk->nik", DR, -skew(arm) @ Jl_mark), DR]
            cols.append(m6 + 6 * jj[:, None] + np.arange(6))
        data = np.concatenate(blocks, axis=2)  # (n, 2, 6 or 12)
        if self.n_free:
            data[~free, :, 6:] = 0.0
        return _assemble(data, np.hstack(cols), self, x)


def _assemble(data: np.ndarray, cols: np.ndarray, prob: Problem, x: np.ndarray):
    """Stack the corner blocks (n, 2, w) at columns (n, w) and the prior blocks into one sparse matrix (CSR)."""
    from scipy import sparse  # imported on first use: ``import fidlearn`` stays quick

    n, _, w = data.shape
    rows = np.repeat(np.arange(2 * n).reshape(n, 2, 1), w, axis=2)
    col = np.repeat(cols[:, None, :], 2, axis=1)
    pd, pr, pc = _prior_entries(prob, x, 2 * n)
    shape = (2 * n + 6 * len(prob.prior_slots), prob.n_params)
    J = sparse.coo_matrix(
        (np.concatenate([data.ravel(), pd]), (np.concatenate([rows.ravel(), pr]), np.concatenate([col.ravel(), pc]))),
        shape=shape,
    ).tocsr()
    J.eliminate_zeros()
    return J


def _prior_entries(prob: Problem, x: np.ndarray, row0: int):
    """Nonzeros of the prior rows: ``J_l^-1(psi) J_l(phi) / sigma_rot`` and ``I / sigma_mm``."""
    m6 = 6 * prob.n_cams
    _, _, R_mark, _ = prob.poses(x)
    data, rows, cols = [], [], []
    for i, k in enumerate(prob.prior_slots):
        phi = x[m6 + 6 * k : m6 + 6 * k + 3]
        psi = log_so3(R_mark[k] @ prob.prior_R[i].T)
        block = left_jacobian_inv(psi) @ left_jacobian(phi) / prob.sigma_rot_rad
        r0, c0 = row0 + 6 * i, m6 + 6 * k
        rr, cc = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
        data += [block.ravel(), np.full(3, 1.0 / prob.sigma_mm)]
        rows += [(r0 + rr).ravel(), r0 + 3 + np.arange(3)]
        cols += [(c0 + cc).ravel(), c0 + 3 + np.arange(3)]
    if not data:
        return np.zeros(0), np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(data), np.concatenate(rows), np.concatenate(cols)


def _projection_jacobian(P: np.ndarray, K: np.ndarray, dist: np.ndarray, model: str = "pinhole") -> np.ndarray:
    """d(pixel)/d(point in the camera frame), (n, 2, 3): depth division analytic, lens model by central differences."""
    z = P[:, 2]
    xy = P[:, :2] / z[:, None]
    h = _H_NORM
    steps = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
    px = _pixels_from_normalized((xy[:, None, :] + steps).reshape(-1, 2), K, dist, model).reshape(-1, 4, 2)
    A = np.stack([px[:, 0] - px[:, 1], px[:, 2] - px[:, 3]], axis=2) / (2 * h)  # (n, 2, 2): d pixel / d normalized
    B = np.zeros((len(P), 2, 3))
    B[:, 0, 0] = 1 / z
    B[:, 1, 1] = 1 / z
    B[:, :, 2] = -xy / z[:, None]
    return A @ B
