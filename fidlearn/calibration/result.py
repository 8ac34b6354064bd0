"""The result of a calibration run: :class:`Calibration` and one :class:`ViewResult` per input image."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import frames
from ..boards import Board
from ..camera import Camera

__all__ = ["Calibration", "ViewResult"]


@dataclass(frozen=True)
class ViewResult:
    """What happened to one input image.

    Attributes
    ----------
    name : str
        The image's path as given, or ``"image i"`` (i counted from 0) for an array.
    status : str
        ``"used"``, ``"not found"``, ``"outlier"``, ``"duplicate"`` (the board where an earlier
        view had it, with ``reject_duplicates=True``), ``"other size"`` or ``"unreadable"``.
    n_points : int
        Board points found (0 when the board was not found or the image not read).
    rms_px : float or None
        RMS reprojection error of the view's points (px); for an outlier, its
        error in the first calibration. None when the board was not found.
    reason : str
        Why the view was rejected ("" when used).
    """

    name: str
    status: str
    n_points: int = 0
    rms_px: float | None = None
    reason: str = ""

    @property
    def found(self) -> bool:
        """Whether the board was found in this image (some board points)."""
        return self.n_points > 0


@dataclass(eq=False, repr=False)
class Calibration:
    """The outcome of a calibration run.

    Attributes
    ----------
    camera : Camera
        The calibrated camera; its ``source`` describes the run.
    rms_px : float
        RMS reprojection error over every point of the used views (px), as
        ``cv2.calibrateCamera`` returns it.
    per_view_rms_px : dict {str: float}
        RMS reprojection error of each used view (px), by name.
    used : list of str
        Names of the views the camera was computed from, in input order.
    std_intrinsics : dict {str: float}
        Standard deviations of ``fx, fy, cx, cy`` (px) and of the distortion
        coefficients ``k1, k2, p1, p2, k3, ...`` (0 for one held fixed), as
        ``cv2.calibrateCameraExtended`` gives them (``stdDeviationsIntrinsics``).
        Computed on first use (a few milliseconds), then kept; a dict given to the
        constructor is kept as it is.
    rejected : list of (str, str)
        ``(name, reason)`` for every image not used.
    T_camera_board : dict {str: ndarray (4, 4)}
        Each used view's board pose in the camera frame (mm); see the module
        docstring for the board frame.
    views : list of ViewResult
        Every input image, in input order (for :meth:`table`).
    board : Board or None
        The board the views show (:class:`fidlearn.Board`); None for a Calibration made by hand
        without one. The text of earlier fidlearn (``Board.describe()``'s words, perhaps with
        ``", legacy layout"``) is read into a Board. :attr:`board_description` says it in words.
    image_points_px : dict {str: ndarray (N, 2)}
        Each used view's detected board points (px, pixel centres at integers).
    board_points_mm : dict {str: ndarray (N, 3)}
        The same points on the board (mm, board frame, z = 0).
    first_rms_px : float or None
        RMS of the first calibration, before outlier views were removed
        (None when none were).
    coverage : ndarray, shape (3, 3), int, or None
        Board points of the used views per ninth of the picture, row 0 at the top
        (:func:`~fidlearn.calibration.quality.coverage_grid`).
    warnings : list of str
        What makes the camera less trustworthy than its RMS suggests, one sentence each: too
        few views, views too alike or nearly identical, parts of the picture with no board
        point or few (:func:`~fidlearn.calibration.quality.quality_warnings`). Empty when
        nothing is wrong; ``fidlearn calibrate`` prints each as a warning.
    held_out_rms_px : dict {str: float} or None
        With ``model="auto"``: each lens model's RMS reprojection error (px) on views left out of its
        calibration (``"pinhole"``, ``"fisheye"``); the camera's ``model`` is the lower. None otherwise.
    legacy_layout : bool
        A ChArUco board found with the marker layout of OpenCV before 4.6 (``legacy=True`` or found
        so by ``legacy="auto"``).
    """

    camera: Camera
    rms_px: float
    per_view_rms_px: dict
    used: list
    _std: dict | None = field(default=None, init=False, repr=False)  # std_intrinsics, once computed
    std_intrinsics: dict | None
    rejected: list
    T_camera_board: dict = field(default_factory=dict)
    views: list = field(default_factory=list)
    board: Board | None = None
    image_points_px: dict = field(default_factory=dict)
    board_points_mm: dict = field(default_factory=dict)
    first_rms_px: float | None = None
    coverage: np.ndarray | None = None
    warnings: list = field(default_factory=list)
    legacy_layout: bool = False
    _std_from: Callable[[], dict] | None = field(default=None, repr=False)
    held_out_rms_px: dict | None = None

    def __post_init__(self) -> None:
        if isinstance(self.board, str):  # earlier fidlearn's description: "" for none
            text: str = self.board
            self.legacy_layout = self.legacy_layout or text.endswith(", legacy layout")
            self.board = Board.from_description(text) if text else None

    @property
    def board_description(self) -> str:
        """The board in words, as the camera's ``source`` names it (``", legacy layout"`` for the old marker layout).

        Returns
        -------
        str
            ``Board.describe()``, ``""`` for no board.
        """
        if self.board is None:
            return ""
        return self.board.describe() + (", legacy layout" if self.legacy_layout else "")

    @property
    def T_board_camera(self) -> dict:
        """Each used view's camera pose in the board frame (4, 4), mm."""
        return {name: frames.invert_transform(T) for name, T in self.T_camera_board.items()}

    def table(self) -> str:
        """A text table of every input image: name, found, points, RMS (px), status and reason.

        Returns
        -------
        str
            One line per input image, in input order, under a header (and the folder they share).
        """
        names, folder = _display_names([v.name for v in self.views])
        wn = max([4] + [len(n) for n in names])
        lines = [f"views in {folder}"] if folder else []
        lines.append(f"{'view':<{wn}}  found  points  rms px  status")
        for n, v in zip(names, self.views):
            rms = f"{v.rms_px:6.3f}" if v.rms_px is not None else "     -"
            status = v.status if not v.reason else f"{v.status}: {v.reason}"
            lines.append(f"{n:<{wn}}  {'yes' if v.found else 'no':<5}  {v.n_points:6d}  {rms}  {status}")
        return "\n".join(lines)

    def summary(self) -> str:
        """The camera, its uncertainty, the warnings, and the table of views.

        Returns
        -------
        str
            Several lines: what Jupyter shows for a Calibration.
        """
        s = self.std_intrinsics or {}
        std = ", ".join(f"{k} {s[k]:.2f}" for k in ("fx", "fy", "cx", "cy") if k in s)
        head = [
            f"Calibration of {self.board_description}: {len(self.used)} of {len(self.views)} views used, "
            f"RMS {self.rms_px:.3f} px",
            f"  {self.camera!r}",
            f"  standard deviations (px): {std}",
        ]
        if self.first_rms_px is not None:
            head.append(f"  RMS before removing outlier views: {self.first_rms_px:.3f} px")
        if self.held_out_rms_px:
            errs = ", ".join(f"{m} {e:.3f} px" for m, e in self.held_out_rms_px.items())
            head.append(f"  lens model {self.camera.model}: RMS on held-out views {errs}")
        if "fx" in s and s["fx"] > 0.01 * self.camera.fx:
            head.append(
                f"  fx is uncertain to {100 * s['fx'] / self.camera.fx:.1f} %: add views with the board "
                "tilted in other directions and nearer the image's corners"
            )
        head += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(head) + "\n" + self.table()

    def __repr__(self) -> str:
        c = self.camera
        dist = c.dist if c.dist is not None else np.zeros(0)
        s = self.std_intrinsics or {}
        rej = f", rejected={[n for n, _ in self.rejected]}" if self.rejected else ""
        return (
            f"Calibration({len(self.used)}/{len(self.views)} views, rms={self.rms_px:.3f} px, "
            f"fx={c.fx:.2f}±{s.get('fx', float('nan')):.2f}, fy={c.fy:.2f}±{s.get('fy', float('nan')):.2f}, "
            f"cx={c.cx:.2f}±{s.get('cx', float('nan')):.2f}, cy={c.cy:.2f}±{s.get('cy', float('nan')):.2f}, "
            f"dist=[{', '.join(f'{v:.4g}' for v in dist)}], {c.width}x{c.height}{rej})"
        )

    def _repr_pretty_(self, p, cycle) -> None:  # IPython / Jupyter: the full summary
        p.text(repr(self) if cycle else self.summary())


def _get_std(self: Calibration) -> dict:
    if self._std is None and self._std_from is not None:
        self._std = self._std_from()
        self._std_from = None  # the points and poses it held are no longer needed
    return self._std if self._std is not None else {}


def _set_std(self: Calibration, value: dict | None) -> None:
    self._std = None if value is None else dict(value)


# std_intrinsics is a dataclass field (the constructor takes it) read through a property: None
# stands for "not computed yet", and the first read computes it with _std_from.
Calibration.std_intrinsics = property(  # type: ignore[assignment]
    _get_std,
    _set_std,
    doc="Standard deviations of the intrinsics (px) and distortion coefficients, computed on first use.",
)


def _display_names(names: list[str]) -> tuple[list[str], str]:
    """Names without the folder they all share (and that folder), for a narrower table."""
    dirs = {os.path.dirname(n) for n in names if not n.startswith("image ")}
    if len(dirs) == 1 and all(not n.startswith("image ") for n in names) and next(iter(dirs)):
        folder = next(iter(dirs))
        return [_short(os.path.basename(n)) for n in names], folder
    return [_short(n) for n in names], ""


def _short(name: str, width: int = 40) -> str:
    return name if len(name) <= width else "..." + name[-(width - 3) :]
