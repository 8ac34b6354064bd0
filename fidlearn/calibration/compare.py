"""Do two calibrations of one camera agree? Their projections compared across the picture, against their noise.

The intrinsics of two calibrations cannot be compared number by number: a focal length a little
longer with a principal point a little off can project almost exactly alike. What matters is
where each puts a ray on the picture. As mrcal does (its "differencing" and "uncertainty"
documentation), :func:`compare_calibrations` takes a grid of pixels, unprojects each with
calibration ``a`` to a ray, turns the rays by the small rotation that best maps ``a``'s camera
frame onto ``b``'s (two calibrations may disagree about where the optical axis points, which
moves every pose but no measurement; the rotation is fitted, weighted by how well both know each
ray), and projects them with ``b``: the difference is how far ``b`` puts what ``a`` saw.

Its expected size comes from both calibrations' uncertainty: each one's covariance of the
intrinsics (:func:`~fidlearn.calibration.uncertainty.intrinsics_uncertainty`, white corner noise
plus the views' own error) is carried through the whole comparison, the rotation's fit included,
by central differences. The verdict compares the two: ``ratio``, the RMS over the grid of each
difference measured in its own standard deviations (``sqrt(mean(d^T C^-1 d) / 2)``, about 1 when
the calibrations agree), above :data:`DIFFER_RATIO` is "differ beyond noise"; otherwise "agree"
when the expected differences are small (median under ``tolerance_px``), and "cannot tell" when
they are not, or when a camera file with no uncertainty was given.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import CalibrationError
from .uncertainty import _names, intrinsics_uncertainty

__all__ = ["CalibrationComparison", "compare_calibrations", "DIFFER_RATIO", "VERDICTS"]

#: Differences more than this many times their expected size (RMS over the grid, in standard deviations) differ.
DIFFER_RATIO = 2.0
#: The three verdicts of :func:`compare_calibrations`.
VERDICTS = ("agree", "differ beyond noise", "cannot tell")


@dataclass(frozen=True)
class CalibrationComparison:
    """Two calibrations' projections compared over a grid of pixels.

    Attributes
    ----------
    grid_px : ndarray, shape (rows, cols, 2)
        The pixels compared (x, y; pixel centres at integers).
    difference_px : ndarray, shape (rows, cols, 2)
        Where ``b`` puts what ``a`` sees there, minus the pixel (NaN where ``a``'s lens model has no ray).
    expected_px : ndarray, shape (rows, cols) or None
        The difference's expected size from both calibrations' noise: the square root of its
        covariance's trace (px); None when both are cameras without uncertainty.
    rotation_deg : float
        The fitted rotation between the two cameras' frames (degrees).
    ratio : float or None
        RMS of the differences in their own standard deviations (about 1 when they agree).
    verdict : str
        ``"agree"``, ``"differ beyond noise"`` or ``"cannot tell"``.
    reason : str
        The verdict in a sentence, with its numbers.
    """

    grid_px: np.ndarray
    difference_px: np.ndarray
    expected_px: np.ndarray | None
    rotation_deg: float
    ratio: float | None
    verdict: str
    reason: str

    @property
    def difference_norm_px(self) -> np.ndarray:
        """The length of each difference (px), shape (rows, cols)."""
        return np.linalg.norm(self.difference_px, axis=-1)

    @property
    def rms_difference_px(self) -> float:
        """RMS length of the differences over the grid (px)."""
        d = self.difference_norm_px
        return float(np.sqrt(np.nanmean(d**2)))

    def __str__(self) -> str:
        return f"{self.verdict}: {self.reason}"

    def plot(self, ax=None):
        """A heat map of the difference across the picture, beside its expected size.

        Parameters
        ----------
        ax : matplotlib Axes or sequence of two, optional
            Where to draw; a new figure (one panel, or two with the expected size) when None.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        panels = [("difference |b - a| (px)", self.difference_norm_px)]
        if self.expected_px is not None:
            panels.append(("expected from both calibrations' noise (px)", self.expected_px))
        if ax is None:
            fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4), squeeze=False)
            axes = list(axes[0])
        else:
            axes = list(np.atleast_1d(ax))
            fig = axes[0].figure
        g = self.grid_px
        extent = (g[0, 0, 0], g[0, -1, 0], g[-1, 0, 1], g[0, 0, 1])
        top = float(np.nanmax([np.nanpercentile(v, 95) for _, v in panels]))
        for a, (title, values) in zip(axes, panels):
            im = a.imshow(values, extent=extent, vmin=0, vmax=max(top, 1e-3), cmap="viridis", aspect="equal")
            a.set_title(title)
            a.set_xlabel("x (px)")
            fig.colorbar(im, ax=a, shrink=0.8)
        axes[0].set_ylabel("y (px)")
        fig.suptitle(str(self), fontsize=9)
        return fig


def _camera_and_covariance(x, which: str, inflate: bool):
    if isinstance(x, Camera):
        cov = x.intrinsics_covariance  # camera_with_uncertainty's, kept in its JSON file; 0 for a held parameter
        if cov is None:
            return x, None
        keep = np.flatnonzero(np.diag(cov) > 0)
        return x, (keep, np.asarray(cov)[np.ix_(keep, keep)])
    camera = getattr(x, "camera", None)
    if not isinstance(camera, Camera):
        raise CalibrationError(f"{which}: expected a Calibration or a Camera, got {type(x).__name__}")
    u = intrinsics_uncertainty(x)
    names = _names(camera)
    index = [names.index(n) for n in u.names]
    return camera, (np.array(index), u.covariance if inflate else u.white_covariance)


def _params(cam: Camera) -> np.ndarray:
    return np.concatenate([[cam.fx, cam.fy, cam.cx, cam.cy], cam.dist])


def _camera(theta: np.ndarray, like: Camera) -> Camera:
    K = np.array([[theta[0], 0.0, theta[2]], [0.0, theta[1], theta[3]], [0.0, 0.0, 1.0]])
    return Camera(K, theta[4:], like.image_size, model=like.model)


def _rays(cam: Camera, px: np.ndarray) -> np.ndarray:
    ideal = cam.undistort_points(px)
    xy = (ideal - [cam.cx, cam.cy]) / [cam.fx, cam.fy]
    v = np.column_stack([xy, np.ones(len(xy))])
    ok = np.all(np.isfinite(v), axis=1)
    back = np.full(px.shape, np.nan)
    back[ok] = cam.project(v[ok], np.eye(4))  # a ray the model cannot bring back to its pixel: none there
    bad = ~np.all(np.isfinite(back), axis=1) | (np.linalg.norm(back - px, axis=1) > 1e-3)
    v[bad] = np.nan
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _rotation(va: np.ndarray, vb: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The rotation R minimising sum w |R va - vb|^2 (Kabsch)."""
    ok = np.all(np.isfinite(va), axis=1) & np.all(np.isfinite(vb), axis=1)
    H = (va[ok] * w[ok, None]).T @ vb[ok]
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    return Vt.T @ D @ U.T


def _difference(ta, tb, cam_a, cam_b, px, w) -> tuple[np.ndarray, np.ndarray]:
    a, b = _camera(ta, cam_a), _camera(tb, cam_b)
    va = _rays(a, px)
    R = _rotation(va, _rays(b, px), w)
    ok = np.all(np.isfinite(va), axis=1)
    d = np.full(px.shape, np.nan)
    turned = va[ok] @ R.T
    with np.errstate(over="ignore", invalid="ignore"):  # rays far outside b's picture: checked below
        pb = b.project(turned, np.eye(4))
        # a ray b cannot hold (behind a pinhole, past where a fisheye's polynomial turns back) has no pixel in b
        back = _rays(b, np.where(np.isfinite(pb), pb, 0.0))
    held = np.sum(back * turned, axis=1) > np.cos(1e-6)
    d[np.flatnonzero(ok)[held]] = pb[held] - px[ok][held]
    return d, R


def _jacobian(which: int, index, thetas, cams, px, w) -> np.ndarray:
    """d difference / d the free parameters of calibration ``which`` (2M, q), central differences."""
    cols = []
    for j in index:
        step = 1e-6 * max(abs(thetas[which][j]), 1.0)
        plus, minus = [t.copy() for t in thetas], [t.copy() for t in thetas]
        plus[which][j] += step
        minus[which][j] -= step
        dp = _difference(plus[0], plus[1], cams[0], cams[1], px, w)[0]
        dm = _difference(minus[0], minus[1], cams[0], cams[1], px, w)[0]
        cols.append(((dp - dm) / (2 * step)).ravel())
    return np.column_stack(cols)


def _projection_variance(cam: Camera, cov, px: np.ndarray) -> np.ndarray:
    """Each pixel's projection variance (px^2, trace) from one calibration's covariance, its ray held."""
    import cv2

    v = _rays(cam, px)
    ok = np.all(np.isfinite(v), axis=1)
    out = np.full(len(px), np.inf)
    if cam.model == "fisheye":  # columns: f (2), c (2), k (4), rvec (3), tvec (3), skew
        zero = np.zeros((3, 1))
        _, J = cv2.fisheye.projectPoints(v[ok].reshape(-1, 1, 3), zero, zero, cam.K, cam.dist.reshape(1, 4))
        J = J[:, :8]
    else:
        _, J = cv2.projectPoints(v[ok].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.K, cam.dist)
        J = J[:, 6:]
    Ji = J[:, cov[0]].reshape(-1, 2, len(cov[0]))
    out[ok] = np.einsum("nij,jk,nik->n", Ji, cov[1], Ji)
    return out


def _weights(cams, covs, px: np.ndarray) -> np.ndarray:
    """How much each pixel counts in the rotation's fit: 1 / both projections' variance, or a central disc."""
    if covs[0] is None and covs[1] is None:
        w, h = cams[0].image_size
        return (np.hypot(px[:, 0] - (w - 1) / 2, px[:, 1] - (h - 1) / 2) <= min(w, h) / 2).astype(float)
    var = sum(_projection_variance(cam, cov, px) for cam, cov in zip(cams, covs) if cov is not None)
    return 1.0 / np.maximum(var, 1e-12)


def _verdict(d: np.ndarray, C, tolerance_px: float) -> tuple[float | None, str, str]:
    rms = float(np.sqrt(np.nanmean(np.sum(d * d, axis=1))))
    if C is None:
        return None, "cannot tell", f"RMS difference {rms:.2f} px, but neither camera carries its uncertainty"
    ok = np.all(np.isfinite(d), axis=1) & np.all(np.isfinite(C.reshape(len(C), -1)), axis=1)
    m2 = np.einsum("ni,nij,nj->n", d[ok], np.linalg.inv(C[ok] + 1e-12 * np.eye(2)), d[ok])
    ratio = float(np.sqrt(np.mean(m2) / 2))
    expected = float(np.median(np.sqrt(np.trace(C[ok], axis1=1, axis2=2))))
    said = f"RMS difference {rms:.2f} px, {ratio:.1f} times the noise (median expected {expected:.2f} px)"
    if ratio > DIFFER_RATIO:
        return ratio, "differ beyond noise", said
    if expected > tolerance_px:
        return ratio, "cannot tell", said + f": both too uncertain to tell differences under {tolerance_px:g} px"
    return ratio, "agree", said


def _check_options(grid, tolerance_px) -> tuple[int, int, float]:
    """``grid`` as (cols, rows) of 2 to 1000 each and ``tolerance_px`` a positive number, or a CalibrationError."""
    try:
        cols, rows = (operator.index(v) for v in grid)
        tol = float(tolerance_px)
    except (TypeError, ValueError):
        cols = rows = tol = -1
    if isinstance(tolerance_px, bool) or not (2 <= cols <= 1000 and 2 <= rows <= 1000 and 0 < tol < np.inf):
        raise CalibrationError(
            f"grid {grid!r}, tolerance_px {tolerance_px!r}: give grid as (columns, rows), 2 to 1000 each, "
            "e.g. (32, 24), and tolerance_px as a positive number of pixels"
        )
    return cols, rows, tol


def compare_calibrations(
    a, b, *, grid: tuple[int, int] = (32, 24), tolerance_px: float = 1.0, inflate: bool = True
) -> CalibrationComparison:
    """How far apart two calibrations of one camera project across the picture, and is it beyond their noise.

    For a grid of pixels: unproject with ``a``, turn by the fitted rotation between the two
    cameras' frames, project with ``b`` (as mrcal's ``projection_diff``); the difference's expected
    size comes from both calibrations' covariance of the intrinsics
    (:func:`~fidlearn.calibration.uncertainty.intrinsics_uncertainty`), carried through the whole
    comparison. See the module's docstring for the verdict.

    Parameters
    ----------
    a, b : Calibration or Camera
        Two calibrations of one camera at one resolution. A :class:`~fidlearn.camera.Camera` (a
        camera file) brings the covariance it carries (``intrinsics_covariance``, as
        :func:`~fidlearn.calibration.camera_with_uncertainty` gives and fidlearn's camera JSON keeps);
        one without is taken as exact beside a Calibration, and two such Cameras are compared, but
        the verdict is "cannot tell". Either may be a pinhole or a
        fisheye camera (a pinhole fitted to a fisheye lens against a fisheye fitted to it shows
        where the pinhole model fails).
    grid : (int, int)
        Columns and rows of pixels compared, spread over the whole picture.
    tolerance_px : float
        Calibrations whose expected differences (median over the grid) exceed this cannot be
        said to agree, only not to differ.
    inflate : bool
        True: each calibration's covariance includes its views' own error (``inflation``); False:
        white corner noise alone (OpenCV's standard deviations), which real sets outgrow.

    Returns
    -------
    CalibrationComparison
        The differences, their expected size, the verdict; ``.plot()`` draws them.

    Raises
    ------
    CalibrationError
        If ``a`` or ``b`` is neither a Calibration nor a Camera, or the two are of different
        resolutions; if ``grid`` or ``tolerance_px`` is not positive.

    Examples
    --------
    >>> from fidlearn import Board, calibrate_checkerboard
    >>> from fidlearn.data import data_path
    >>> views = sorted(data_path("calibration").glob("view_*.png"))
    >>> board = Board.checkerboard((9, 6), 25)
    >>> a = calibrate_checkerboard(views[0::2], board=board)
    >>> b = calibrate_checkerboard(views[1::2], board=board)
    >>> compare_calibrations(a, b).verdict
    'agree'
    """
    (cam_a, cov_a), (cam_b, cov_b) = (_camera_and_covariance(x, w, inflate) for x, w in ((a, "a"), (b, "b")))
    if cam_a.image_size != cam_b.image_size:
        raise CalibrationError(
            f"a is {cam_a.width}x{cam_a.height}, b {cam_b.width}x{cam_b.height}: compare calibrations at one "
            "resolution (Camera.scaled to bring one to the other's)"
        )
    cols, rows, tolerance_px = _check_options(grid, tolerance_px)
    w, h = cam_a.image_size
    X, Y = np.meshgrid(np.linspace(0, w - 1, cols), np.linspace(0, h - 1, rows))
    px = np.column_stack([X.ravel(), Y.ravel()])
    cams, thetas = (cam_a, cam_b), [_params(cam_a), _params(cam_b)]
    weights = _weights(cams, (cov_a, cov_b), px)
    d, R = _difference(thetas[0], thetas[1], cam_a, cam_b, px, weights)
    C = None
    for which, cov in enumerate((cov_a, cov_b)):
        if cov is not None:
            J = _jacobian(which, cov[0], thetas, cams, px, weights).reshape(len(px), 2, -1)
            C = np.einsum("nik,kl,njl->nij", J, cov[1], J) + (0.0 if C is None else C)
    ratio, verdict, reason = _verdict(d, C, tolerance_px)
    if (cov_a is None) != (cov_b is None):
        reason += f"; {'a' if cov_a is None else 'b'} is a camera without uncertainty, taken as exact"
    angle = float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))
    expected = None if C is None else np.sqrt(np.trace(C, axis1=1, axis2=2)).reshape(rows, cols)
    grid_px = px.reshape(rows, cols, 2)
    return CalibrationComparison(grid_px, d.reshape(rows, cols, 2), expected, angle, ratio, verdict, reason)
