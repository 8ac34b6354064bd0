"""Calibration boards as values: a checkerboard or a ChArUco board, its counts, sizes and points.

One :class:`Board` describes a printed board wherever fidlearn meets one: calibration
(:func:`fidlearn.calibrate_checkerboard`, :func:`fidlearn.calibrate_charuco`), printing
(:mod:`fidlearn.printables`), drawing, the renderer
(:func:`fidlearn.synthetic.render_calibration_views`) and the command line.

Counts follow OpenCV: a checkerboard is named by its INNER corners (columns, rows), as
``cv2.findChessboardCorners`` counts them (9x6 for a board of 10x7 squares); a ChArUco board by
its SQUARES (x, y), as ``cv2.aruco.CharucoBoard`` counts them. Both are stored as squares.

Board frame, mm, z into the paper: a checkerboard's origin is its first inner corner, x along a
row; a ChArUco board's is the outer corner of its top-left square (OpenCV's
``getChessboardCorners()``), so its first chess corner is at (s, s).

Examples
--------
>>> board = Board.checkerboard((9, 6), square_size_mm=25)
>>> board.squares, board.inner_corners, board.object_points().shape
((10, 7), (9, 6), (54, 3))
>>> Board.parse("5x7", 36.195, counts="squares", marker_size_mm=18.256).describe()
'ChArUco 5x7 squares, 36.195 mm squares, 18.256 mm markers, 6X6_250'
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _cv, _cv_charuco
from .errors import BoardError

__all__ = ["Board", "parse_grid", "MAX_BOARD_CORNERS"]

#: Most inner corners a board may have (50 x 50): a larger count is a typing slip, and its search and
#: calibration would run for minutes.
MAX_BOARD_CORNERS = 2500

_KINDS = ("checkerboard", "charuco")


def parse_grid(text: str, what: str = "--pattern") -> tuple[int, int]:
    """``"9x6"`` as ``(9, 6)`` (columns, rows): the command line's form of a count or a size.

    Parameters
    ----------
    text : str
        ``COLUMNSxROWS``, at least 2 each way (``x``, ``X`` or ``×``).
    what : str
        The option's name in the error message.

    Returns
    -------
    (int, int)
        (columns, rows).

    Raises
    ------
    BoardError
        For anything else.

    Examples
    --------
    >>> parse_grid("9x6")
    (9, 6)
    """
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(text))
    if not m:
        raise BoardError(f"{what} {text!r} is not COLUMNSxROWS; write it like 9x6")
    cols, rows = int(m.group(1)), int(m.group(2))
    if cols < 2 or rows < 2:
        raise BoardError(f"{what} {text}: needs at least 2 in each direction, e.g. 9x6")
    return cols, rows


def _two_counts(value: Any, what: str, example: str) -> tuple[int, int]:
    """Two whole numbers (columns, rows) from a pair or ``"CxR"``; :class:`BoardError` otherwise."""
    if isinstance(value, str):
        return parse_grid(value, what)
    try:
        cols, rows = value
    except (TypeError, ValueError):
        cols = rows = None
    ok = all(
        not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating)) and float(v) == int(v)
        for v in (cols, rows)
    )
    if not ok:
        raise BoardError(f"{what} {value!r:.60} must be two whole numbers (columns, rows), e.g. {example}")
    return int(cols), int(rows)


def _length_mm(value: Any, what: str, fix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise BoardError(f"{what} must be a number of millimetres, got {value!r:.40}; {fix}")
    v = float(value)
    if not math.isfinite(v) or not 0 < v <= 100_000:
        raise BoardError(f"{what} must be positive, at most 100 m, got {value!r}; {fix}")
    return v


@dataclass(frozen=True)
class Board:
    """A printed calibration board: a checkerboard or a ChArUco board.

    Build one with :meth:`checkerboard`, :meth:`charuco` or :meth:`parse`; every field is checked
    there, with a message that says how to mend it.

    Attributes
    ----------
    kind : {"checkerboard", "charuco"}
    squares : (int, int)
        Squares (columns, rows) of the printed board; the inner corners are one fewer each way.
    square_size_mm : float
        Side of one printed square, mm.
    marker_size_mm : float or None
        ChArUco only: side of each marker's black square, mm, smaller than the square.
    dictionary : str or None
        ChArUco only: the markers' ArUco dictionary (fidlearn's name, e.g. ``"6X6_250"``).
    """

    kind: str
    squares: tuple[int, int]
    square_size_mm: float
    marker_size_mm: float | None = None
    dictionary: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise BoardError(f"kind {self.kind!r} is unknown; use Board.checkerboard(...) or Board.charuco(...)")
        cols, rows = _two_counts(self.squares, "squares", "(10, 7)")
        square = _length_mm(
            self.square_size_mm,
            "square_size_mm",
            "measure one printed square in millimetres (command line: --square-mm)",
        )
        object.__setattr__(self, "squares", (cols, rows))
        object.__setattr__(self, "square_size_mm", square)
        if self.kind == "checkerboard":
            self._check_checkerboard(cols, rows)
        else:
            self._check_charuco(cols, rows, square)
        if (cols - 1) * (rows - 1) > MAX_BOARD_CORNERS:
            raise BoardError(
                f"a board of {cols}x{rows} squares has {(cols - 1) * (rows - 1)} inner corners, more than "
                f"{MAX_BOARD_CORNERS}, the most fidlearn searches a photo for; count the board again "
                "(a board of 10x7 squares has 9x6 inner corners)"
            )

    def _check_checkerboard(self, cols: int, rows: int) -> None:
        if cols < 3 or rows < 3:
            raise BoardError(
                f"a checkerboard needs at least 2x2 inner corners, got {cols - 1}x{rows - 1}; "
                "count the corners where four squares meet (a board of 10x7 squares has 9x6)"
            )
        if self.marker_size_mm is not None or self.dictionary is not None:
            raise BoardError("a checkerboard has no markers; use Board.charuco(...) for a board with markers")

    def _check_charuco(self, cols: int, rows: int, square: float) -> None:
        if cols < 3 or rows < 3:
            raise BoardError(f"a ChArUco board needs at least 3x3 squares, got {cols}x{rows}; e.g. (5, 7)")
        if self.marker_size_mm is None:
            raise BoardError(
                "a ChArUco board needs marker_size_mm (command line: --marker-mm), smaller than the square"
            )
        marker = _length_mm(
            self.marker_size_mm,
            "marker_size_mm",
            "measure one printed marker's black square (command line: --marker-mm)",
        )
        if marker >= square:
            raise BoardError(
                f"marker_size_mm ({marker:g}) must be smaller than square_size_mm ({square:g}) (command line: "
                f"--marker-mm, --square-mm): the markers sit inside the white squares; try {0.75 * square:g} "
                "(OpenCV's tutorial board: 40 mm squares, 20 mm markers)"
            )
        name = _cv.dictionary_name(self.dictionary or "6X6_250")
        if (cols * rows) // 2 > _cv.dictionary_size(name):
            raise BoardError(
                f"a {cols}x{rows} ChArUco board needs {(cols * rows) // 2} markers but {name} has only "
                f"{_cv.dictionary_size(name)}; choose a bigger dictionary such as 6X6_250"
            )
        object.__setattr__(self, "marker_size_mm", marker)
        object.__setattr__(self, "dictionary", name)

    @classmethod
    def checkerboard(cls, inner_corners: Any, square_size_mm: float) -> Board:
        """A checkerboard named by its inner corners.

        Parameters
        ----------
        inner_corners : (int, int) or str
            INNER corners (columns, rows), as ``cv2.findChessboardCorners`` counts them, e.g.
            ``(9, 6)`` or ``"9x6"``: a board of 10x7 squares.
        square_size_mm : float
            Side of one printed square, mm.

        Returns
        -------
        Board

        Raises
        ------
        BoardError
            For counts that are not two whole numbers of at least 2, or a size that is not a positive length.

        Examples
        --------
        >>> Board.checkerboard("9x6", 25).describe()
        'checkerboard 9x6 inner corners, 25 mm squares'
        """
        cols, rows = _two_counts(inner_corners, "inner_corners", "(9, 6)")
        return cls("checkerboard", (cols + 1, rows + 1), square_size_mm)

    @classmethod
    def charuco(cls, squares: Any, square_size_mm: float, marker_size_mm: float, dictionary: str = "6X6_250") -> Board:
        """A ChArUco board named by its squares.

        Parameters
        ----------
        squares : (int, int) or str
            SQUARES (x, y), as ``cv2.aruco.CharucoBoard`` counts them (OpenCV's tutorial board: (5, 7)).
        square_size_mm, marker_size_mm : float
            Printed side of a chess square and of a marker's black square, mm; marker < square.
        dictionary : str
            The markers' ArUco dictionary (``"6X6_250"`` or ``"DICT_6X6_250"``).

        Returns
        -------
        Board

        Raises
        ------
        BoardError
            For bad counts or sizes, a marker not smaller than its square, or a dictionary with too
            few markers for the board.
        DictionaryError
            For a dictionary name OpenCV does not know.
        """
        return cls("charuco", _two_counts(squares, "squares", "(5, 7)"), square_size_mm, marker_size_mm, dictionary)

    @classmethod
    def parse(
        cls,
        text: str,
        square_size_mm: float,
        *,
        counts: str = "inner",
        charuco: bool = False,
        marker_size_mm: float | None = None,
        dictionary: str | None = None,
    ) -> Board:
        """A board from the command line's text: ``--pattern 9x6`` (inner corners) or ``--squares 5x7``.

        Parameters
        ----------
        text : str
            ``COLUMNSxROWS``.
        square_size_mm : float
            Side of one printed square, mm (``--square-mm``).
        counts : {"inner", "squares"}
            What ``text`` counts: inner corners (``--pattern``) or squares (``--squares``).
        charuco : bool
            A ChArUco board; implied by ``marker_size_mm``. A ChArUco board may be named by its
            inner corners too.
        marker_size_mm : float, optional
            ChArUco's marker side, mm (``--marker-mm``).
        dictionary : str, optional
            ChArUco's dictionary (``--dictionary``, default ``"6X6_250"``).

        Returns
        -------
        Board

        Raises
        ------
        BoardError
            As :meth:`checkerboard` and :meth:`charuco`, or ``counts`` neither "inner" nor "squares".

        Examples
        --------
        >>> Board.parse("9x6", 25).squares
        (10, 7)
        """
        if counts not in ("inner", "squares"):
            raise BoardError(f"counts {counts!r} is unknown; use 'inner' (--pattern) or 'squares' (--squares)")
        what = "--pattern" if counts == "inner" else "--squares"
        cols, rows = parse_grid(text, what)
        squares = (cols + 1, rows + 1) if counts == "inner" else (cols, rows)
        if charuco or marker_size_mm is not None:
            return cls("charuco", squares, square_size_mm, marker_size_mm, dictionary or "6X6_250")
        if dictionary is not None:
            raise BoardError("a dictionary describes a ChArUco board; give its marker size too, or drop the dictionary")
        return cls("checkerboard", squares, square_size_mm)

    @classmethod
    def from_description(cls, text: str) -> Board:
        """The board that :meth:`describe` named, read back from its words.

        fidlearn before the :class:`Board` value kept a calibration's board as this description only;
        a camera file's ``source`` holds it too (``"... views of a checkerboard 9x6 inner corners, 25 mm
        squares, RMS ..."``), and the description may stand anywhere in ``text``.

        Parameters
        ----------
        text : str
            Words holding ``checkerboard CxR inner corners, S mm squares`` or ``ChArUco XxY squares,
            S mm squares, M mm markers, DICTIONARY``.

        Returns
        -------
        Board
            Its sizes as written there (:meth:`describe` keeps 6 significant digits).

        Raises
        ------
        BoardError
            When ``text`` names no board this way, or names one that is not a board.

        Examples
        --------
        >>> Board.from_description("checkerboard 9x6 inner corners, 25 mm squares").squares
        (10, 7)
        >>> Board.from_description("ChArUco 5x7 squares, 40 mm squares, 20 mm markers, 6X6_250").marker_size_mm
        20.0
        """
        number = r"(\d+(?:\.\d*)?(?:e[+-]?\d+)?)"
        text = str(text)
        m = re.search(rf"ChArUco (\d+)x(\d+) squares, {number} mm squares, {number} mm markers, (\w+)", text)
        if m:
            squares = (int(m.group(1)), int(m.group(2)))
            return cls.charuco(squares, float(m.group(3)), float(m.group(4)), m.group(5))
        m = re.search(rf"checkerboard (\d+)x(\d+) inner corners, {number} mm squares", text)
        if m:
            return cls.checkerboard((int(m.group(1)), int(m.group(2))), float(m.group(3)))
        raise BoardError(
            f"{text!r:.80} names no board; expected Board.describe()'s words, e.g. "
            "'checkerboard 9x6 inner corners, 25 mm squares'"
        )

    @property
    def inner_corners(self) -> tuple[int, int]:
        """(columns, rows) of inner corners: the ``patternSize`` of ``cv2.findChessboardCorners``."""
        return (self.squares[0] - 1, self.squares[1] - 1)

    @property
    def is_charuco(self) -> bool:
        """Whether the board carries ArUco markers."""
        return self.kind == "charuco"

    def describe(self) -> str:
        """One line naming the board.

        Returns
        -------
        str
            Its kind, counts and sizes.
        """
        if self.is_charuco:
            x, y = self.squares
            return (
                f"ChArUco {x}x{y} squares, {self.square_size_mm:g} mm squares, "
                f"{self.marker_size_mm:g} mm markers, {self.dictionary}"
            )
        cols, rows = self.inner_corners
        return f"checkerboard {cols}x{rows} inner corners, {self.square_size_mm:g} mm squares"

    def object_points(self) -> np.ndarray:
        """The inner (chess) corners in the board frame, in the order OpenCV reports them.

        Returns
        -------
        ndarray, shape (columns * rows, 3)
            Corners, mm, z = 0, row by row, x along a row: a checkerboard's from its first inner
            corner, a ChArUco board's as ``getChessboardCorners()`` gives them (corner id = row).

        Examples
        --------
        >>> Board.checkerboard((3, 2), 25).object_points()[:4].tolist()
        [[0.0, 0.0, 0.0], [25.0, 0.0, 0.0], [50.0, 0.0, 0.0], [0.0, 25.0, 0.0]]
        """
        cols, rows = self.inner_corners
        jj, ii = np.mgrid[0:rows, 0:cols]
        points = np.column_stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)]) * self.square_size_mm
        return points + [self.square_size_mm, self.square_size_mm, 0.0] if self.is_charuco else points

    def cv_board(self, legacy: bool = False):
        """OpenCV's ``cv2.aruco.CharucoBoard`` of a ChArUco board (sizes in mm).

        Parameters
        ----------
        legacy : bool
            The marker layout of boards made before OpenCV 4.6 (differs only with an even number of rows).

        Returns
        -------
        cv2.aruco.CharucoBoard

        Raises
        ------
        BoardError
            For a checkerboard, which has none.
        """
        if not self.is_charuco:
            raise BoardError("a checkerboard has no cv2.aruco board; its points are Board.object_points()")
        assert self.marker_size_mm is not None  # a ChArUco board's marker size and dictionary are set by __post_init__
        assert self.dictionary is not None
        return _cv_charuco.charuco_board(
            self.squares, self.square_size_mm, self.marker_size_mm, self.dictionary, legacy=legacy
        )
