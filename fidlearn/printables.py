"""Printable markers and calibration boards at exact physical size.

Every page is drawn in millimetres on a figure the size of the paper, and every
black cell of a marker or square of a board is a vector rectangle, so the
printed black square measures exactly the size asked for when the page is
printed at 100 % ("actual size", no "fit to page"). Each page carries a
100 mm ruler with millimetre ticks to check that with calipers.

The page frame: origin at the paper's top-left corner, x to the right, y down,
millimetres. Nothing here opens a window: PDF pages go through matplotlib's
PDF backend, PNG pages through Agg, both used directly (no ``pyplot``, no
change to matplotlib's global state).

Examples
--------
>>> parse_ids("0-3,8")
[0, 1, 2, 3, 8]
>>> parse_pattern("9x6")
(9, 6)
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _cv
from ._io import atomic_write, file_mode_for
from .errors import DictionaryError, FidlearnError, PrintError

__all__ = [
    "PAPERS",
    "PrintError",
    "MarkerSheet",
    "BoardSheet",
    "parse_ids",
    "parse_pattern",
    "paper_size_mm",
    "marker_cells",
    "layout_markers",
    "layout_board",
    "board_quiet_zone_mm",
    "marker_figures",
    "board_figure",
    "markers_pdf",
    "markers_png",
    "board_pdf",
    "board_png",
    "save_pages",
]

#: Paper sizes (width, height) in mm, portrait.
PAPERS: dict[str, tuple[float, float]] = {"a4": (210.0, 297.0), "letter": (215.9, 279.4)}

PAGE_MARGIN_MM = 7.0  # [mm] kept blank at every edge: most printers cannot print there
STRIP_MM = 11.0  # [mm] thickness of the strip holding the title, the ruler and the note
STRIP_LEN_MM = 170.0  # [mm] length of that strip
STRIP_GAP_MM = 3.0  # [mm] between the strip and the markers or the board
RULER_MM = 100  # [mm] length of the ruler
GAP_MM = 8.0  # [mm] between two markers' cut rectangles (the cut marks live here)
CUT_MARK_MM = 3.0  # [mm] length of a cut mark
CUT_MARK_OFFSET_MM = 1.0  # [mm] from the cut corner to the start of its mark
LABEL_MM = 7.0  # [mm] strip under each marker for its id and dictionary
LINE_PT = 0.4  # [pt] width of cut marks


# -- parsing ------------------------------------------------------------------------------
#: The most marker ids one call prints, and one more than the largest id any dictionary has
#: (ARUCO_MIP_36h12: 250; APRILTAG_36h11: 587; ARUCO_ORIGINAL: 1024; the 4x4..7x7 families: 1000).
MAX_ID_COUNT = 1024


def parse_ids(text: str) -> list[int]:
    """Marker ids from ``"0-9"``, ``"0,3,7"`` or ``"0-3,8"`` (ranges inclusive), in the order given.

    Raises :class:`PrintError` for anything else, for a reversed range and for
    an id given twice (two markers with one id break localization).
    """
    if not isinstance(text, str) or not text.strip():
        raise PrintError("--ids is empty; give ids like 0-9, 0,3,7 or 0-3,8")
    ids: list[int] = []
    seen: set[int] = set()
    for part in text.replace(" ", "").split(","):
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if not m:
            raise PrintError(f"--ids {text!r}: {part!r} is not an id or a range; give ids like 0-9, 0,3,7 or 0-3,8")
        if max(len(m.group(1)), len(m.group(2) or "")) > 9:  # before int(): Python refuses 4300+ digits
            raise PrintError(
                f"--ids {text[:40]!r}: at most {MAX_ID_COUNT} markers, ids 0 to {MAX_ID_COUNT - 1} "
                "(the largest dictionary's)"
            )
        lo = int(m.group(1))
        hi = int(m.group(2)) if m.group(2) is not None else lo
        if hi < lo:
            raise PrintError(f"--ids {text!r}: the range {part} runs backwards; write {hi}-{lo}")
        if hi >= MAX_ID_COUNT or len(ids) + hi - lo + 1 > MAX_ID_COUNT:
            raise PrintError(
                f"--ids {text!r}: at most {MAX_ID_COUNT} markers, ids 0 to {MAX_ID_COUNT - 1} "
                "(the largest dictionary's); print them in parts"
            )
        twice = seen.intersection(range(lo, hi + 1)) if hi - lo < len(seen) else {i for i in seen if lo <= i <= hi}
        if twice:
            raise PrintError(
                f"--ids {text!r}: id {min(twice)} is listed twice; each marker id must be unique on the wall"
            )
        seen.update(range(lo, hi + 1))
        ids.extend(range(lo, hi + 1))
    return ids


def parse_pattern(text: str, what: str = "--pattern") -> tuple[int, int]:
    """``"9x6"`` -> ``(9, 6)`` (columns, rows); :class:`PrintError` for anything else."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(text))
    if not m:
        raise PrintError(f"{what} {text!r} is not COLUMNSxROWS; write it like 9x6")
    cols, rows = int(m.group(1)), int(m.group(2))
    if cols < 2 or rows < 2:
        raise PrintError(f"{what} {text}: needs at least 2 in each direction, e.g. 9x6")
    return cols, rows


def paper_size_mm(paper: str, landscape: bool = False) -> tuple[float, float]:
    """(width, height) in mm of ``"a4"`` or ``"letter"``, portrait unless ``landscape``."""
    key = str(paper).lower()
    if key not in PAPERS:
        raise PrintError(f"unknown paper {paper!r}; use {' or '.join(PAPERS)}")
    w, h = PAPERS[key]
    return (h, w) if landscape else (w, h)


def _positive_mm(value: float, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PrintError(f"{what} must be a length in mm, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise PrintError(f"{what} must be a positive length in mm, got {value!r}")
    if v < 1.0:  # nothing prints under 1 mm: a length in metres, as OpenCV's tutorials write it
        raise PrintError(f"{what} {v:g} is under 1 mm; if that is metres, give millimetres ({v * 1000:g})")
    return v


# -- markers --------------------------------------------------------------------------------
def marker_cells(dictionary: str, marker_id: int) -> np.ndarray:
    """The marker's cells, black border included: (n, n) bool, True = black, row 0 at the top.

    ``n`` is the dictionary's marker size plus 2 (7 for ARUCO_ORIGINAL, 8 for 6X6_250).
    """
    name = _cv.dictionary_name(dictionary)
    size = _cv.dictionary_size(name)
    if not 0 <= int(marker_id) < size:
        raise DictionaryError(f"marker id {marker_id} does not exist in {name}, which has ids 0 to {size - 1}")
    n = _cv.dictionary_marker_bits(name) + 2
    return _cv.generate_marker(name, int(marker_id), n, border_bits=1) < 128


@dataclass(frozen=True)
class MarkerSheet:
    """Where each marker goes on each page.

    Attributes
    ----------
    paper : str
    paper_mm : (float, float)
        Page (width, height) in mm.
    marker_size_mm : float
        Side of each black square (border included), mm.
    cell_mm : float
        Side of one cell, mm (``marker_size_mm`` / cells per side).
    dictionary : str
    pages : list of list of (int, float, float)
        Per page: ``(id, x_mm, y_mm)``, the top-left corner of each black square
        in the page frame (origin top-left of the paper, y down).
    """

    paper: str
    paper_mm: tuple[float, float]
    marker_size_mm: float
    cell_mm: float
    dictionary: str
    pages: list[list[tuple[int, float, float]]] = field(repr=False)

    @property
    def per_page(self) -> int:
        """How many markers fit on one page."""
        return max(len(p) for p in self.pages)

    def __repr__(self) -> str:
        n = sum(len(p) for p in self.pages)
        return (
            f"MarkerSheet({n} markers of {self.marker_size_mm:g} mm, {self.dictionary}, {self.paper} "
            f"{self.paper_mm[0]:g}x{self.paper_mm[1]:g} mm, {len(self.pages)} page(s), {self.per_page} per page)"
        )


def _usable_area(paper_mm: tuple[float, float], strip: str = "bottom") -> tuple[float, float, float, float]:
    """(x0, y0, width, height) of the page area left by the margins and the ruler strip, mm.

    ``strip`` is ``"bottom"`` (a horizontal strip above the bottom margin) or
    ``"right"`` (a vertical strip inside the right margin).
    """
    w, h = paper_mm
    uw, uh = w - 2 * PAGE_MARGIN_MM, h - 2 * PAGE_MARGIN_MM
    if strip == "bottom":
        uh -= STRIP_MM + STRIP_GAP_MM
    else:
        uw -= STRIP_MM + STRIP_GAP_MM
    return PAGE_MARGIN_MM, PAGE_MARGIN_MM, uw, uh


def layout_markers(
    ids: Sequence[int], marker_size_mm: float, dictionary: str = "ARUCO_ORIGINAL", paper: str = "a4"
) -> MarkerSheet:
    """Place markers in a grid, as many per page as fit, with a white quiet zone of one cell.

    Each marker's cut rectangle holds the black square, a white margin of one
    cell on every side, and a label strip under it; cut rectangles are
    :data:`GAP_MM` apart.
    """
    marker_size_mm = _positive_mm(marker_size_mm, "--size-mm")
    name = _cv.dictionary_name(dictionary)
    if isinstance(ids, str):
        ids = parse_ids(ids)  # "0-9", "0,3,7" as on the command line
    ids = list(ids) if isinstance(ids, Iterable) and not isinstance(ids, (bytes, bytearray)) else [ids]
    wrong = [i for i in ids if isinstance(i, bool) or not isinstance(i, (int, np.integer))]
    if wrong:
        raise PrintError(f"marker id {wrong[0]!r} is not a whole number; give ids like range(10) or [0, 3, 7]")
    ids = [int(i) for i in ids]
    if not ids:
        raise PrintError("no marker ids to print; give --ids like 0-9")
    for i in ids:
        marker_cells(name, i)  # raises for an id outside the dictionary
    paper_mm = paper_size_mm(paper)
    cells = _cv.dictionary_marker_bits(name) + 2
    cell = marker_size_mm / cells
    slot_w = marker_size_mm + 2 * cell
    slot_h = marker_size_mm + 2 * cell + LABEL_MM
    x0, y0, uw, uh = _usable_area(paper_mm)
    cols = int((uw + GAP_MM + 1e-9) // (slot_w + GAP_MM))
    rows = int((uh + GAP_MM + 1e-9) // (slot_h + GAP_MM))
    if cols < 1 or rows < 1:
        largest = min(uw * cells / (cells + 2), (uh - LABEL_MM) * cells / (cells + 2))
        raise PrintError(
            f"a {marker_size_mm:g} mm marker (with its one-cell white margin and label) does not fit on "
            f"{paper} paper; the largest that fits is {math.floor(largest * 10) / 10:g} mm: lower --size-mm"
        )
    grid_w = cols * slot_w + (cols - 1) * GAP_MM
    grid_h = rows * slot_h + (rows - 1) * GAP_MM
    left = x0 + (uw - grid_w) / 2
    top = y0 + (uh - grid_h) / 2
    per_page = cols * rows
    pages = []
    for start in range(0, len(ids), per_page):
        page = []
        for k, mid in enumerate(ids[start : start + per_page]):
            r, c = divmod(k, cols)
            page.append((mid, left + c * (slot_w + GAP_MM) + cell, top + r * (slot_h + GAP_MM) + cell))
        pages.append(page)
    return MarkerSheet(str(paper).lower(), paper_mm, marker_size_mm, cell, name, pages)


# -- boards ---------------------------------------------------------------------------------
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
        """One line for the page and the terminal."""
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
    """The white margin (mm) a board of ``square_size_mm`` squares needs on every side."""
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


def layout_board(
    squares: tuple[int, int],
    square_size_mm: float,
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
) -> BoardSheet:
    """Place a checkerboard or ChArUco board of ``squares`` (columns, rows) on one page.

    The page turns to landscape when the board only fits that way. A board
    that does not fit at all raises :class:`PrintError` naming the largest
    square that fits. The top-left square is black (OpenCV's ChArUco layout).
    """
    cols, rows = (int(v) for v in squares)
    if cols < 3 or rows < 3:
        raise PrintError(f"a board needs at least 3x3 squares (2x2 inner corners), got {cols}x{rows} squares")
    square_size_mm = _positive_mm(square_size_mm, "--square-mm")
    paper_key = str(paper).lower()
    paper_size_mm(paper_key)
    fits = [
        (lan, strip)
        for lan, strip in _BOARD_ARRANGEMENTS
        if square_size_mm <= _largest_square((cols, rows), paper_key, lan, strip) + 1e-9
    ]
    if not fits:
        largest = max(_largest_square((cols, rows), paper_key, lan, strip) for lan, strip in _BOARD_ARRANGEMENTS)
        raise PrintError(
            f"a {cols}x{rows}-square board of {square_size_mm:g} mm squares ({cols * square_size_mm:g} x {rows * square_size_mm:g} mm "
            f"plus a white margin) does not fit on {paper_key} paper; the largest square that fits is "
            f"{math.floor(largest * 10) / 10:g} mm: use --square-mm {math.floor(largest * 10) / 10:g} or less"
        )
    landscape, strip = fits[0]
    paper_mm = paper_size_mm(paper_key, landscape)
    x0, y0, uw, uh = _usable_area(paper_mm, strip)
    origin = (x0 + (uw - cols * square_size_mm) / 2, y0 + (uh - rows * square_size_mm) / 2)
    black: list[tuple[int, int]] = []
    markers: list[tuple[int, int, int]] = []
    name = None
    if charuco:
        name = _cv.dictionary_name(dictionary or "6X6_250")
        if marker_size_mm is None:
            raise PrintError("a ChArUco board needs --marker-mm (the side of each marker, smaller than the square)")
        marker_size_mm = _positive_mm(marker_size_mm, "--marker-mm")
        if marker_size_mm >= square_size_mm:
            raise PrintError(
                f"--marker-mm {marker_size_mm:g} must be smaller than --square-mm {square_size_mm:g}; try {0.75 * square_size_mm:g}"
            )
        n_markers = (cols * rows) // 2
        if n_markers > _cv.dictionary_size(name):
            raise PrintError(
                f"a {cols}x{rows} ChArUco board needs {n_markers} markers but {name} has only "
                f"{_cv.dictionary_size(name)}; choose a bigger dictionary such as 6X6_250"
            )
        board = _cv.charuco_board((cols, rows), square_size_mm, marker_size_mm, name)
        obj = np.asarray(board.getObjPoints(), dtype=np.float64).reshape(-1, 4, 3)
        ids = np.asarray(board.getIds()).reshape(-1)
        white = set()
        for mid, pts in zip(ids, obj):
            cx, cy = pts[:, :2].mean(axis=0)
            c, r = int(cx // square_size_mm), int(cy // square_size_mm)
            markers.append((int(mid), c, r))
            white.add((c, r))
        black = [(c, r) for r in range(rows) for c in range(cols) if (c, r) not in white]
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


# -- drawing --------------------------------------------------------------------------------
def _page(paper_mm: tuple[float, float]):
    """A figure the size of the paper with one axes covering it, in mm, y down."""
    from matplotlib.figure import Figure

    w, h = paper_mm
    fig = Figure(figsize=(w / 25.4, h / 25.4))
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_axis_off()
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect("auto")
    return fig, ax


def _fill_rects(ax, rects: Iterable[tuple[float, float, float, float]], color: str = "black") -> None:
    """Fill rectangles (x, y, w, h in mm) as ONE vector path, so shared edges leave no seam."""
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    verts, codes = [], []
    for x, y, w, h in rects:
        verts += [(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)]
        codes += [MplPath.MOVETO, MplPath.LINETO, MplPath.LINETO, MplPath.LINETO, MplPath.CLOSEPOLY]
    if not verts:
        return
    patch = PathPatch(
        MplPath(verts, codes), facecolor=color, edgecolor="none", linewidth=0, antialiased=True, snap=False
    )
    ax.add_patch(patch)


def _marker_rects(cells: np.ndarray, x: float, y: float, cell: float) -> list[tuple[float, float, float, float]]:
    """Black cells as rectangles (mm), runs along each row merged."""
    rects = []
    for r, row in enumerate(cells):
        c = 0
        while c < len(row):
            if row[c]:
                start = c
                while c < len(row) and row[c]:
                    c += 1
                rects.append((x + start * cell, y + r * cell, (c - start) * cell, cell))
            else:
                c += 1
    return rects


def _draw_strip(ax, paper_mm: tuple[float, float], side: str, title: str) -> None:
    """The page's title, a 100 mm ruler with mm ticks and the printing instruction.

    Drawn in strip coordinates (u along the strip, v across it, mm) and placed
    above the bottom margin (``side="bottom"``) or, turned to read upwards,
    inside the right margin (``side="right"``).
    """
    w, h = paper_mm
    if side == "bottom":
        ox, oy = PAGE_MARGIN_MM, h - PAGE_MARGIN_MM - STRIP_MM

        def to_page(u, v):
            return ox + u, oy + v

        def rect(u, v, du, dv):
            return (ox + u, oy + v, du, dv)

        rotation = 0
    else:
        ox, oy = w - PAGE_MARGIN_MM - STRIP_MM, h - PAGE_MARGIN_MM

        def to_page(u, v):
            return ox + v, oy - u

        def rect(u, v, du, dv):
            return (ox + v, oy - u - du, dv, du)

        rotation = 90

    def text(u, v, s, ha="left", va="top", size=6.5):
        ax.text(*to_page(u, v), s, ha=ha, va=va, fontsize=size, rotation=rotation, rotation_mode="anchor")

    text(0, 0, title, size=7)
    base, tick_w = 3.5, 0.2
    rects = [rect(-tick_w / 2, base, RULER_MM + tick_w, 0.3)]
    for i in range(RULER_MM + 1):
        length = 4.5 if i % 10 == 0 else (3.2 if i % 5 == 0 else 2.0)
        rects.append(rect(i - tick_w / 2, base + 0.3, tick_w, length))
    _fill_rects(ax, rects)
    for i in range(0, RULER_MM + 1, 10):
        text(i, base + 5.2, str(i), ha="center", size=5)
    text(RULER_MM + 4, base + 0.6, "100 mm ruler: print at 100 % (actual size),")
    text(RULER_MM + 4, base + 3.4, "no scaling, no 'fit to page'; check with calipers.")


def _cut_marks(ax, x: float, y: float, w: float, h: float) -> None:
    """Crop marks outside each corner of the rectangle (x, y, w, h) in mm."""
    from matplotlib.collections import LineCollection

    o, L = CUT_MARK_OFFSET_MM, CUT_MARK_MM
    segs = []
    for cx, sx in ((x, -1), (x + w, 1)):
        for cy, sy in ((y, -1), (y + h, 1)):
            segs.append([(cx + sx * o, cy), (cx + sx * (o + L), cy)])  # horizontal, on the cut line
            segs.append([(cx, cy + sy * o), (cx, cy + sy * (o + L))])  # vertical, on the cut line
    ax.add_collection(LineCollection(segs, colors="black", linewidths=LINE_PT, antialiased=True))


def marker_figures(sheet: MarkerSheet) -> list:
    """One matplotlib ``Figure`` per page of a :class:`MarkerSheet` (nothing written)."""
    figs = []
    cell = sheet.cell_mm
    for k, page in enumerate(sheet.pages):
        fig, ax = _page(sheet.paper_mm)
        title = (
            f"fidlearn markers, {sheet.dictionary}, black square {sheet.marker_size_mm:g} mm, "
            f"page {k + 1} of {len(sheet.pages)}"
        )
        rects = []
        for mid, x, y in page:
            rects += _marker_rects(marker_cells(sheet.dictionary, mid), x, y, cell)
            cut = (x - cell, y - cell, sheet.marker_size_mm + 2 * cell, sheet.marker_size_mm + 2 * cell + LABEL_MM)
            _cut_marks(ax, *cut)
            label_y = y + sheet.marker_size_mm + cell + LABEL_MM / 2
            long = f"id {mid}   {sheet.dictionary}   {sheet.marker_size_mm:g} mm"
            if len(long) * 1.3 > cut[2]:  # about 1.3 mm per character at 7 pt
                ax.text(x + sheet.marker_size_mm / 2, label_y - 1.4, f"id {mid}", ha="center", va="center", fontsize=7)
                ax.text(
                    x + sheet.marker_size_mm / 2,
                    label_y + 1.6,
                    f"{sheet.dictionary} {sheet.marker_size_mm:g} mm",
                    ha="center",
                    va="center",
                    fontsize=5,
                )
            else:
                ax.text(x + sheet.marker_size_mm / 2, label_y, long, ha="center", va="center", fontsize=7)
        _fill_rects(ax, rects)
        _draw_strip(ax, sheet.paper_mm, "bottom", title)
        figs.append(fig)
    return figs


def board_figure(sheet: BoardSheet):
    """The matplotlib ``Figure`` of a :class:`BoardSheet` (nothing written)."""
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


def save_pages(figures: Sequence, path: str | os.PathLike, dpi: float | None = None) -> list[Path]:
    """Write pages: one multi-page PDF for ``.pdf``; for ``.png`` one file per page at ``dpi``.

    Several PNG pages are named ``stem-1.png``, ``stem-2.png``, ... Every file
    is written to a temporary file first and renamed only when all pages are
    rendered, so a failure leaves nothing behind.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".pdf":
        from matplotlib.backends.backend_pdf import PdfPages

        def write(tmp: Path) -> None:
            with PdfPages(tmp, metadata={"Creator": "fidlearn", "CreationDate": None}) as pdf:
                for fig in figures:
                    pdf.savefig(fig)

        return [atomic_write(path, write)]
    if suffix == ".png":
        if dpi is None:
            dpi = 300
        dpi = float(dpi)
        if not math.isfinite(dpi) or not 30 <= dpi <= 2400:
            raise PrintError(f"--dpi {dpi:g} is out of range; use 30 to 2400 (300 is typical for printing)")
        names = (
            [path]
            if len(figures) == 1
            else [path.with_name(f"{path.stem}-{k + 1}{path.suffix}") for k in range(len(figures))]
        )
        return _write_pngs(figures, names, dpi)
    raise PrintError(f"{path}: unknown output type {path.suffix or '(none)'!r}; name the file .pdf or .png")


def _write_pngs(figures: Sequence, names: list[Path], dpi: float) -> list[Path]:
    import tempfile

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    tmps: list[Path] = []
    try:
        for fig, name in zip(figures, names):
            folder = name.parent if str(name.parent) else Path(".")
            if not folder.is_dir():
                raise FidlearnError(f"{name}: the folder {folder} does not exist; create it first")
            w_mm, h_mm = fig.get_size_inches() * 25.4
            # whole pixels: Agg truncates, so ask for round(size) + a quarter pixel
            w_px, h_px = round(w_mm / 25.4 * dpi), round(h_mm / 25.4 * dpi)
            fig.set_size_inches((w_px + 0.25) / dpi, (h_px + 0.25) / dpi)
            fd, tmp_name = tempfile.mkstemp(prefix=f".{name.name}.", suffix=".png", dir=folder)
            os.close(fd)
            tmps.append(Path(tmp_name))
            FigureCanvasAgg(fig)
            fig.savefig(tmp_name, format="png", dpi=dpi, metadata={"Software": "fidlearn"})
        for tmp, name in zip(tmps, names):
            os.chmod(tmp, file_mode_for(name))
            os.replace(tmp, name)
    except BaseException:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)
        raise
    return names


# -- one-call helpers -----------------------------------------------------------------------
def markers_pdf(
    path, ids: Sequence[int], marker_size_mm: float, dictionary: str = "ARUCO_ORIGINAL", paper: str = "a4"
) -> MarkerSheet:
    """Write a (multi-page) PDF of markers at exact size; returns the layout.

    Parameters
    ----------
    path : path-like
        The ``.pdf`` file to write (atomically).
    ids : sequence of int
        Marker ids, in print order.
    marker_size_mm : float
        Side of each black square (border included), mm.
    dictionary : str
        ArUco dictionary name, e.g. ``"ARUCO_ORIGINAL"`` or ``"6X6_250"``.
    paper : {"a4", "letter"}
    """
    sheet = layout_markers(ids, marker_size_mm, dictionary, paper)
    save_pages(marker_figures(sheet), _with_suffix(path, ".pdf"))
    return sheet


def markers_png(
    path,
    ids: Sequence[int],
    marker_size_mm: float,
    dictionary: str = "ARUCO_ORIGINAL",
    paper: str = "a4",
    dpi: float = 300,
) -> tuple[MarkerSheet, list[Path]]:
    """Write the marker pages as PNG at ``dpi``; returns the layout and the files written."""
    sheet = layout_markers(ids, marker_size_mm, dictionary, paper)
    return sheet, save_pages(marker_figures(sheet), _with_suffix(path, ".png"), dpi=dpi)


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
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
) -> BoardSheet:
    """Write a one-page PDF of a calibration board; ``pattern`` is INNER corners (9x6 -> 10x7 squares)."""
    pattern = _inner_corners(pattern)
    sheet = layout_board((pattern[0] + 1, pattern[1] + 1), square_size_mm, paper, charuco, dictionary, marker_size_mm)
    save_pages([board_figure(sheet)], _with_suffix(path, ".pdf"))
    return sheet


def board_png(
    path,
    pattern: tuple[int, int],
    square_size_mm: float,
    paper: str = "a4",
    charuco: bool = False,
    dictionary: str | None = None,
    marker_size_mm: float | None = None,
    dpi: float = 300,
) -> tuple[BoardSheet, list[Path]]:
    """Write a board page as PNG at ``dpi``; ``pattern`` is INNER corners. Returns the layout and the file."""
    pattern = _inner_corners(pattern)
    sheet = layout_board((pattern[0] + 1, pattern[1] + 1), square_size_mm, paper, charuco, dictionary, marker_size_mm)
    return sheet, save_pages([board_figure(sheet)], _with_suffix(path, ".png"), dpi=dpi)


def _with_suffix(path, suffix: str) -> Path:
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise PrintError(f"{path}: expected a {suffix} file name")
    return path
