"""The page: paper sizes, margins, the ruler strip, parsing of ids and patterns, and writing pages to files.

The page frame: origin at the paper's top-left corner, x to the right, y down,
millimetres.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write, outputs_together
from ..errors import PrintError

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


#: The most marker ids one call prints, and one more than the largest id any dictionary has
#: (ARUCO_MIP_36h12: 250; APRILTAG_36h11: 587; ARUCO_ORIGINAL: 1024; the 4x4..7x7 families: 1000).
MAX_ID_COUNT = 1024


def parse_ids(text: str) -> list[int]:
    """Marker ids from ``"0-9"``, ``"0,3,7"`` or ``"0-3,8"`` (ranges inclusive), in the order given.

    Parameters
    ----------
    text : str
        Ids and inclusive ranges separated by commas, as the command line's ``--ids``.

    Returns
    -------
    list of int
        The ids, at most :data:`MAX_ID_COUNT`.

    Raises
    ------
    PrintError
        For anything else, a reversed range, too many ids, and an id given twice (two markers with one
        id break localization).

    Examples
    --------
    >>> parse_ids("0-3,8")
    [0, 1, 2, 3, 8]
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


def paper_size_mm(paper: str, landscape: bool = False) -> tuple[float, float]:
    """The size of a sheet of paper.

    Parameters
    ----------
    paper : {"a4", "letter"}
        Case does not matter.
    landscape : bool
        Turned: width and height swapped.

    Returns
    -------
    (float, float)
        (width, height), mm.

    Raises
    ------
    PrintError
        For an unknown paper.

    Examples
    --------
    >>> paper_size_mm("a4", landscape=True)
    (297.0, 210.0)
    """
    key = str(paper).lower()
    if key not in PAPERS:
        raise PrintError(f"unknown paper {paper!r}; use {' or '.join(PAPERS)}")
    w, h = PAPERS[key]
    return (h, w) if landscape else (w, h)


def _positive_mm(value: Any, what: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PrintError(f"{what} must be a length in mm, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise PrintError(f"{what} must be a positive length in mm, got {value!r}")
    if v < 1.0:  # nothing prints under 1 mm: a length in metres, as OpenCV's tutorials write it
        raise PrintError(f"{what} {v:g} is under 1 mm; if that is metres, give millimetres ({v * 1000:g})")
    return v


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


def _page(paper_mm: tuple[float, float]):
    """A figure the size of the paper with one axes covering it, in mm, y down."""
    from matplotlib.figure import Figure

    w, h = paper_mm
    fig = Figure(figsize=(w / 25.4, h / 25.4))
    ax = fig.add_axes((0, 0, 1, 1))
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


def save_pages(figures: Sequence, path: str | os.PathLike, dpi: float | None = None) -> list[Path]:
    """Write pages: one multi-page PDF for ``.pdf``; for ``.png`` one file per page at ``dpi``.

    Several PNG pages are named ``stem-1.png``, ``stem-2.png``, ... Every file
    is written to a temporary file first and renamed only when all pages are
    rendered, so a failure leaves nothing behind.

    Parameters
    ----------
    figures : sequence of matplotlib.figure.Figure
        The pages, each the size of the paper (:func:`marker_figures`, :func:`board_figure`).
    path : path-like
        ``.pdf`` or ``.png``.
    dpi : float, optional
        PNG resolution, 30 to 2400 (300 by default); ignored for PDF (vector).

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    PrintError
        For another suffix or a dpi out of range.
    FidlearnError
        If the PNG's folder does not exist.
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
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    with outputs_together() as outputs:  # every page staged before any takes its name
        for fig, name in zip(figures, names):
            w_mm, h_mm = fig.get_size_inches() * 25.4
            # whole pixels: Agg truncates, so ask for round(size) + a quarter pixel
            w_px, h_px = round(w_mm / 25.4 * dpi), round(h_mm / 25.4 * dpi)
            fig.set_size_inches((w_px + 0.25) / dpi, (h_px + 0.25) / dpi)
            FigureCanvasAgg(fig)
            outputs.stage(
                name, lambda tmp, fig=fig: fig.savefig(tmp, format="png", dpi=dpi, metadata={"Software": "fidlearn"})
            )
    return names


def _with_suffix(path, suffix: str) -> Path:
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise PrintError(f"{path}: expected a {suffix} file name")
    return path
