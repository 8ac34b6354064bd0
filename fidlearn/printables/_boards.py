"""Printed calibration boards (checkerboard or ChArUco): the layout on one page, and the page."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import _cv
from ..boards import Board
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
    save_pages,
)


@dataclass(frozen=True)
class BoardSheet:
    """A calibration board on one page.

    Attributes
    ----------
    board : Board
        The board: its squares (columns, rows), square size, and ChArUco's markers.
    origin_mm : (float, float)
        Top-left corner of the board (of its top-left square) in the page frame, mm.
    paper, paper_mm, landscape
        The page; ``landscape`` when the board only fits turned.
    strip : {"bottom", "right"}
        Where the title, the ruler and the note sit.
    black : list of (int, int)
        (column, row) of each black square.
    markers : list of (int, int, int)
        ChArUco only: (id, column, row) of the marker in each white square.
    """

    board: Board
    origin_mm: tuple[float, float]
    paper: str
    paper_mm: tuple[float, float]
    landscape: bool
    strip: str
    black: list[tuple[int, int]] = field(repr=False)
    markers: list[tuple[int, int, int]] = field(repr=False)

    @property
    def board_mm(self) -> tuple[float, float]:
        """(width, height) of the board, mm."""
        (c, r), s = self.board.squares, self.board.square_size_mm
        return (c * s, r * s)

    def describe(self) -> str:
        """One line for the page and the terminal.

        Returns
        -------
        str
            The board's kind, squares, inner corners and sizes.
        """
        b = self.board
        (c, r), (ic, ir) = b.squares, b.inner_corners
        if b.is_charuco:
            return (
                f"ChArUco {c}x{r} squares ({ic}x{ir} inner corners), square {b.square_size_mm:g} mm, "
                f"marker {b.marker_size_mm:g} mm, {b.dictionary}"
            )
        return f"checkerboard {ic}x{ir} inner corners ({c}x{r} squares), square {b.square_size_mm:g} mm"


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


def _charuco_squares(board: Board) -> tuple[list[tuple[int, int]], list[tuple[int, int, int]]]:
    """ChArUco: the black squares and the ``(id, column, row)`` markers."""
    cols, rows = board.squares
    s = board.square_size_mm
    obj = np.asarray(board.cv_board().getObjPoints(), dtype=np.float64).reshape(-1, 4, 3)
    ids = np.asarray(board.cv_board().getIds()).reshape(-1)
    markers, white = [], set()
    for mid, pts in zip(ids, obj):
        cx, cy = pts[:, :2].mean(axis=0)
        c, r = int(cx // s), int(cy // s)
        markers.append((int(mid), c, r))
        white.add((c, r))
    black = [(c, r) for r in range(rows) for c in range(cols) if (c, r) not in white]
    return black, markers


def layout_board(board: Board, paper: str = "a4") -> BoardSheet:
    """Place a checkerboard or ChArUco board on one page.

    The page turns to landscape when the board only fits that way. The top-left square is black
    (OpenCV's ChArUco layout).

    Parameters
    ----------
    board : Board
        The board (:meth:`fidlearn.Board.checkerboard` or :meth:`fidlearn.Board.charuco`).
    paper : {"a4", "letter"}

    Returns
    -------
    BoardSheet
        The layout (page frame, mm).

    Raises
    ------
    PrintError
        If ``board`` is not a :class:`~fidlearn.Board`, or does not fit the paper (the largest
        square that fits is named).

    Examples
    --------
    >>> layout_board(Board.checkerboard((9, 6), 25)).describe()
    'checkerboard 9x6 inner corners (10x7 squares), square 25 mm'
    """
    if not isinstance(board, Board):
        raise PrintError(
            f"board must be a fidlearn.Board (Board.checkerboard((9, 6), 25) or Board.charuco(...)), got {board!r:.60}"
        )
    _positive_mm(board.square_size_mm, "--square-mm")  # nothing prints under 1 mm: a size in metres?
    if board.is_charuco:
        _positive_mm(board.marker_size_mm, "--marker-mm")
    cols, rows = board.squares
    paper_key = str(paper).lower()
    paper_size_mm(paper_key)
    landscape, strip = _arrangement(cols, rows, board.square_size_mm, paper_key)
    paper_mm = paper_size_mm(paper_key, landscape)
    x0, y0, uw, uh = _usable_area(paper_mm, strip)
    origin = (x0 + (uw - cols * board.square_size_mm) / 2, y0 + (uh - rows * board.square_size_mm) / 2)
    markers: list[tuple[int, int, int]] = []
    if board.is_charuco:
        black, markers = _charuco_squares(board)
    else:
        black = [(c, r) for r in range(rows) for c in range(cols) if (c + r) % 2 == 0]
    return BoardSheet(board, origin, paper_key, paper_mm, landscape, strip, black, markers)


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
    board = sheet.board
    s = board.square_size_mm
    ox, oy = sheet.origin_mm
    rects = [(ox + c * s, oy + r * s, s, s) for c, r in sheet.black]
    if board.is_charuco:
        assert board.marker_size_mm is not None  # a ChArUco Board has a marker size and a dictionary
        assert board.dictionary is not None
        cells_n = _cv.dictionary_marker_bits(board.dictionary) + 2
        cell = board.marker_size_mm / cells_n
        inset = (s - board.marker_size_mm) / 2
        for mid, c, r in sheet.markers:
            rects += _marker_rects(marker_cells(board.dictionary, mid), ox + c * s + inset, oy + r * s + inset, cell)
    _fill_rects(ax, rects)
    _draw_strip(ax, sheet.paper_mm, sheet.strip, f"fidlearn {sheet.describe()}")
    return fig


def board_pdf(path, board: Board, paper: str = "a4") -> BoardSheet:
    """Write a one-page PDF of a calibration board.

    Parameters
    ----------
    path : path-like
        The ``.pdf`` file to write (atomically).
    board : Board
        The board, e.g. ``Board.checkerboard((9, 6), 25)``: 9x6 INNER corners, a board of 10 x 7 squares.
    paper : {"a4", "letter"}

    Returns
    -------
    BoardSheet
        The layout.

    Raises
    ------
    PrintError
        As :func:`layout_board` and :func:`save_pages`.
    """
    sheet = layout_board(board, paper)
    save_pages([board_figure(sheet)], _with_suffix(path, ".pdf"))
    return sheet


def board_png(path, board: Board, paper: str = "a4", dpi: float = 300) -> tuple[BoardSheet, list[Path]]:
    """Write a board page as PNG at ``dpi``.

    Parameters
    ----------
    path : path-like
        The ``.png`` file.
    board, paper :
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
    sheet = layout_board(board, paper)
    return sheet, save_pages([board_figure(sheet)], _with_suffix(path, ".png"), dpi=dpi)
