"""Printed calibration boards (checkerboard or ChArUco): the layout on one page, and the page."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import _cv, _cv_charuco
from ..errors import PrintError
from ._markers import marker_cells
from ._page import (
    PAGE_MARGIN_MM,
    STRIP_LEN_MM,
    _draw_strip,
    _fill_rects,
    _marker_rects,
    _page,
    _positive_mm,
    _usable_area,
    _with_suffix,
    paper_size_mm,
    parse_pattern,
    save_pages,
)


@dataclass(frozen=True)
class BoardSheet:
    """A calibration board on one page.

    Attributes
    ----------
    squares : (int, int)
        Squares (columns, rows); the inner corners are one fewer each way.
    square_size_mm : float
    origin_mm : (float, float)
        Top-left corner of the board (of its top-left square) in the page frame, mm.
    paper, paper_mm, landscape
        The page; ``landscape`` when the board only fits turned.
    strip : {"bottom", "right"}
        Where the title, the ruler and the note sit.
    charuco : bool
    marker_size_mm : float or None
        ChArUco only: side of each marker's black square.
    dictionary : str or None
        ChArUco only.
    black : list of (int, int)
        (column, row) of each black square.
    markers : list of (int, int, int)
        ChArUco only: (id, column, row) of the marker in each white square.
    """

    squares: tuple[int, int]
    square_size_mm: float
    origin_mm: tuple[float, float]
    paper: str
    paper_mm: tuple[float, float]
    landscape: bool
    strip: str
    charuco: bool
    marker_size_mm: float | None
    dictionary: str | None
    black: list[tuple[int, int]] = field(repr=False)
    markers: list[tuple[int, int, int]] = field(repr=False)

    @property
    def inner_corners(self) -> tuple[int, int]:
        """The pattern size OpenCV's ``findChessboardCorners`` wants: (squares - 1) each way."""
        return (self.squares[0] - 1, self.squares[1] - 1)

    @property
    def board_mm(self) -> tuple[float, float]:
        """(width, height) of the board, mm."""
        return (self.squares[0] * self.square_size_mm, self.squares[1] * self.square_size_mm)

    def describe(self) -> str:
        """One line for the page and the terminal.

        Returns
        -------
        str
            The board's kind, squares, inner corners and sizes.
        """
        (c, r), (ic, ir) = self.squares, self.inner_corners
        if self.charuco:
            return (
                f"ChArUco {c}x{r} squares ({ic}x{ir} inner corners), square {self.square_size_mm:g} mm, "
                f"marker {self.marker_size_mm:g} mm, {self.dictionary}"
            )
        return f"checkerboard {ic}x{ir} inner corners ({c}x{r} squares), square {self.square_size_mm:g} mm"


#: The white margin kept around a board: QUIET_FRACTION of a square, at least QUIET_MIN_MM.
QUIET_MIN_MM, QUIET_FRACTION = 3.0, 0.2


def board_quiet_zone_mm(square_size_mm: float) -> float:
    """The white margin a board needs on every side.

    Parameters
    ----------
    square_size_mm : float
        Side of one square, mm.

    Returns
    -------
    float
        :data:`QUIET_FRACTION` of a square, at least :data:`QUIET_MIN_MM`, mm.
    """
    return max(QUIET_MIN_MM, QUIET_FRACTION * square_size_mm)


#: Page arrangements tried for a board, in order of preference: (landscape, strip side).
_BOARD_ARRANGEMENTS = ((False, "bottom"), (False, "right"), (True, "bottom"), (True, "right"))


def _largest_square(squares: tuple[int, int], paper: str, landscape: bool, strip: str) -> float:
    """Largest square (mm) for which the board and its quiet zone fit the arrangement."""
    paper_mm = paper_size_mm(paper, landscape)
    if (paper_mm[1] if strip == "right" else paper_mm[0]) - 2 * PAGE_MARGIN_MM < STRIP_LEN_MM:
        return 0.0
    _, _, uw, uh = _usable_area(paper_mm, strip)
    # n * s + 2 * board_quiet_zone_mm(s) <= available, in both directions
    return max(
        0.0, min(min((a - 2 * QUIET_MIN_MM) / n, a / (n + 2 * QUIET_FRACTION)) for n, a in zip(squares, (uw, uh)))
    )


def _arrangement(cols: int, rows: int, square_size_mm: float, paper_key: str) -> tuple[bool, str]:
    """``(landscape, strip side)``: the first page arrangement the board fits; :class:`PrintError` if none."""
    fits = [
        (lan, strip)
        for lan, strip in _BOARD_ARRANGEMENTS
        if square_size_mm <= _largest_square((cols, rows), paper_key, lan, strip) + 1e-9
    ]
    if not fits:
        largest = max(_largest_square((cols, rows), paper_key, lan, strip) for lan, strip in _BOARD_ARRANGEMENTS)
        raise PrintError(
            f"a {cols}x{rows}-square board of {square_size_mm:g} mm squares "
            f"({cols * square_size_mm:g} x {rows * square_size_mm:g} mm "
            f"plus a white margin) does not fit on {paper_key} paper; the largest square that fits is "
            f"{math.floor(largest * 10) / 10:g} mm: use --square-mm {math.floor(largest * 10) / 10:g} or less"
        )
    return fits[0]


def _charuco_squares(
    cols: int, rows: int, square_size_mm: float, dictionary: str | None, marker_size_mm: float | None
) -> tuple[str, float, list[tuple[int, int]], list[tuple[int, int, int]]]:
    """ChArUco: the dictionary, the marker side (mm), the black squares and the ``(id, column, row)`` markers."""
    name = _cv.dictionary_name(dictionary or "6X6_250")
    if marker_size_mm is None:
        raise PrintError("a ChArUco board needs --marker-mm (the side of each marker, smaller than the square)")
    marker_size_mm = _positive_mm(marker_size_mm, "--marker-mm")
    if marker_size_mm >= square_size_mm:
        raise PrintError(
            f"--marker-mm {marker_size_mm:g} must be smaller than --square-mm {square_size_mm:g}; "
            f"try {0.75 * square_size_mm:g}"
        )
    n_markers = (cols * rows) // 2
    if n_markers > _cv.dictionary_size(name):
        raise PrintError(
            f"a {cols}x{rows} ChArUco board needs {n_markers} markers but {name} has only "
            f"{_cv.dictionary_size(name)}; choose a bigger dictionary such as 6X6_250"
        )
    board = _cv_charuco.charuco_board((cols, rows), square_size_mm, marker_size_mm, name)
    obj = np.asarray(board.getObjPoints(), dtype=np.float64).reshape(-1, 4, 3)
    ids = np.asarray(board.getIds()).reshape(-1)
    markers, white = [], set()
    for mid, pts in zip(ids, obj):
        cx, cy = pts[:, :2].mean(axis=0)
        c, r = int(cx // square_size_mm), int(cy // square_size_mm)
        markers.append((int(mid), c, r))
        white.add((c, r))
    black = [(c, r) for r in range(rows) for c in range(cols) if (c, r) not in white]
    return name, marker_size_mm, black, markers


def layout_board(
    squares: tuple[int, int],
    square_size_mm: float,
    *,
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
) -> BoardSheet:
    """Place a checkerboard or ChArUco board on one page.

    The page turns to landscape when the board only fits that way. The top-left square is black
    (OpenCV's ChArUco layout).

    Parameters
    ----------
    squares : (int, int)
        Squares (columns, rows), at least 3 x 3; the inner corners are one fewer each way.
    square_size_mm : float
        Side of one square, mm.
    paper : {"a4", "letter"}
    charuco : bool
        A ChArUco board: a marker in every white square.
    dictionary : str, optional
        ChArUco's dictionary (``"6X6_250"`` by default).
    marker_size_mm : float, optional
        ChArUco only, required: side of each marker's black square, mm, smaller than the square.

    Returns
    -------
    BoardSheet
        The layout (page frame, mm).

    Raises
    ------
    PrintError
        If the board is too small, does not fit the paper (the largest square that fits is named), or
        a ChArUco marker is missing, not smaller than its square, or the dictionary is too small.
    """
    cols, rows = (int(v) for v in squares)
    if cols < 3 or rows < 3:
        raise PrintError(f"a board needs at least 3x3 squares (2x2 inner corners), got {cols}x{rows} squares")
    square_size_mm = _positive_mm(square_size_mm, "--square-mm")
    paper_key = str(paper).lower()
    paper_size_mm(paper_key)
    landscape, strip = _arrangement(cols, rows, square_size_mm, paper_key)
    paper_mm = paper_size_mm(paper_key, landscape)
    x0, y0, uw, uh = _usable_area(paper_mm, strip)
    origin = (x0 + (uw - cols * square_size_mm) / 2, y0 + (uh - rows * square_size_mm) / 2)
    markers: list[tuple[int, int, int]] = []
    name = None
    if charuco:
        name, marker_size_mm, black, markers = _charuco_squares(cols, rows, square_size_mm, dictionary, marker_size_mm)
    else:
        black = [(c, r) for r in range(rows) for c in range(cols) if (c + r) % 2 == 0]
    return BoardSheet(
        (cols, rows),
        square_size_mm,
        origin,
        paper_key,
        paper_mm,
        landscape,
        strip,
        bool(charuco),
        marker_size_mm if charuco else None,
        name,
        black,
        markers,
    )


def board_figure(sheet: BoardSheet):
    """The page of a :class:`BoardSheet` as a matplotlib figure (nothing written).

    Parameters
    ----------
    sheet : BoardSheet
        From :func:`layout_board`.

    Returns
    -------
    matplotlib.figure.Figure
        The size of the paper, drawn in mm.
    """
    fig, ax = _page(sheet.paper_mm)
    s = sheet.square_size_mm
    ox, oy = sheet.origin_mm
    rects = [(ox + c * s, oy + r * s, s, s) for c, r in sheet.black]
    if sheet.charuco:
        cells_n = _cv.dictionary_marker_bits(sheet.dictionary) + 2
        cell = sheet.marker_size_mm / cells_n
        inset = (s - sheet.marker_size_mm) / 2
        for mid, c, r in sheet.markers:
            rects += _marker_rects(marker_cells(sheet.dictionary, mid), ox + c * s + inset, oy + r * s + inset, cell)
    _fill_rects(ax, rects)
    _draw_strip(ax, sheet.paper_mm, sheet.strip, f"fidlearn {sheet.describe()}")
    return fig


def _inner_corners(pattern) -> tuple[int, int]:
    """``(9, 6)`` or ``"9x6"`` as two whole numbers; :class:`PrintError` for anything else."""
    if isinstance(pattern, str):
        return parse_pattern(pattern, "pattern")
    try:
        cols, rows = pattern
    except (TypeError, ValueError):
        raise PrintError(
            f"pattern {pattern!r} must be two whole numbers of inner corners, e.g. (9, 6) or '9x6'"
        ) from None
    if any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in (cols, rows)):
        raise PrintError(f"pattern {pattern!r} must be two whole numbers of inner corners, e.g. (9, 6) or '9x6'")
    return int(cols), int(rows)


def board_pdf(
    path,
    pattern: tuple[int, int],
    square_size_mm: float,
    *,
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
) -> BoardSheet:
    """Write a one-page PDF of a calibration board.

    Parameters
    ----------
    path : path-like
        The ``.pdf`` file to write (atomically).
    pattern : (int, int) or str
        INNER corners (columns, rows), e.g. ``(9, 6)`` or ``"9x6"``: a board of 10 x 7 squares.
    square_size_mm, paper, charuco, dictionary, marker_size_mm :
        As for :func:`layout_board`.

    Returns
    -------
    BoardSheet
        The layout.

    Raises
    ------
    PrintError
        For a malformed pattern, or as :func:`layout_board`.
    """
    pattern = _inner_corners(pattern)
    sheet = layout_board(
        (pattern[0] + 1, pattern[1] + 1),
        square_size_mm,
        paper=paper,
        charuco=charuco,
        dictionary=dictionary,
        marker_size_mm=marker_size_mm,
    )
    save_pages([board_figure(sheet)], _with_suffix(path, ".pdf"))
    return sheet


def board_png(
    path,
    pattern: tuple[int, int],
    square_size_mm: float,
    *,
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
    dpi: float = 300,
) -> tuple[BoardSheet, list[Path]]:
    """Write a board page as PNG at ``dpi``.

    Parameters
    ----------
    path : path-like
        The ``.png`` file.
    pattern, square_size_mm, paper, charuco, dictionary, marker_size_mm :
        As for :func:`board_pdf`.
    dpi : float
        Resolution, 30 to 2400.

    Returns
    -------
    sheet : BoardSheet
        The layout.
    files : list of Path
        The file written.

    Raises
    ------
    PrintError
        As :func:`board_pdf` and :func:`save_pages`.
    """
    pattern = _inner_corners(pattern)
    sheet = layout_board(
        (pattern[0] + 1, pattern[1] + 1),
        square_size_mm,
        paper=paper,
        charuco=charuco,
        dictionary=dictionary,
        marker_size_mm=marker_size_mm,
    )
    return sheet, save_pages([board_figure(sheet)], _with_suffix(path, ".png"), dpi=dpi)
