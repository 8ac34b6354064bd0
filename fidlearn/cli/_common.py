"""What every command shares: the parser, output checks, signals, safe printing, progress, errors.

Output rules (see :mod:`fidlearn.cli`): every output path is checked before any work
(:func:`_check_output`, :func:`_refuse_clobber`); one file is written atomically; every output
is staged with the command's others (:class:`fidlearn.io.StagedOutputs`) and they take their names
together; a stream of JSON lines goes through :class:`_StreamFile`; annotated pictures through
:class:`_Staging`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

from .. import io as fidlearn_io
from ..boards import MAX_BOARD_CORNERS, Board, parse_grid
from ..camera import Camera
from ..errors import FidlearnError, UsageError
from ..images import encode_image
from ..io import StagedOutputs, current_outputs, signals_deferred
from ..markermap import MarkerMap

UNITS = ["mm", "cm", "m", "in", "ft"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, status 2, no usage dump
        raise UsageError(f"{self.prog}: {message} (see '{self.prog} --help')")


# -- output checks -------------------------------------------------------------------------------
def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _refuse_clobber(
    outputs: Sequence[tuple[str, Path | None]], inputs: Sequence[Path], annotate: Path | None = None
) -> None:
    """Before any work: no output may be one of the inputs, nor another output; no --annotate
    folder may hold an input (its annotated copy would replace it)."""
    named = [(opt, Path(p)) for opt, p in outputs if p is not None]
    files = [Path(p) for p in inputs if p is not None]
    for k, (opt, out) in enumerate(named):
        for inp in files:
            if _same_file(out, inp) or (not out.exists() and out.resolve() == inp.resolve()):
                raise UsageError(
                    f"{opt} {out} is one of the inputs ({inp}); write it under another name: nothing was written"
                )
            if inp.is_dir() and out.is_file() and out.resolve().parent == inp.resolve():  # a photo of a folder given
                raise UsageError(
                    f"{opt} {out} is one of the inputs (a file of the folder {inp}); write it under another name: "
                    "nothing was written"
                )
        for opt2, out2 in named[:k]:
            if out.resolve() == out2.resolve() or _same_file(out, out2):
                raise UsageError(f"{opt} {out} and {opt2} {out2} are the same file; give each output its own name")
    if annotate is not None:
        _refuse_annotate_clobber(Path(annotate), files, named)


def _refuse_annotate_clobber(annotate: Path, files: list[Path], named: list[tuple[str, Path]]) -> None:
    folder = annotate.resolve()
    if annotate.exists() and not annotate.is_dir():
        raise UsageError(f"--annotate {annotate} is a file; give a folder for the annotated pictures")
    for inp in files:
        if inp.resolve().parent == folder:
            raise UsageError(
                f"--annotate {annotate} holds the input {inp}; its annotated copy would replace it: give another folder"
            )
    for opt, out in named:
        if out.resolve() == folder:
            raise UsageError(f"--annotate {annotate} is the name {opt} gives its file; give each its own name")
        if out.resolve().parent == folder:
            raise UsageError(
                f"--annotate {annotate} is where {opt} {out} goes; give the annotations a folder of their own"
            )


def _check_output(path: Path, suffixes: Sequence[str], option: str = "-o") -> Path:
    """Refuse an output path before any work is done: wrong type, missing folder, or a folder."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise UsageError(f"{option} {path}: name the file {' or '.join(suffixes)}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise UsageError(f"{option} {path}: the folder {folder} does not exist; create it first")
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a folder; give a file name")
    return path


def _floats(text: str, n: int, option: str, meaning: str) -> list[float]:
    """``"1,2,3"`` -> [1.0, 2.0, 3.0]; a UsageError naming the option otherwise."""
    parts = [t for t in str(text).replace(" ", "").split(",")]
    try:
        values = [float(t) for t in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise UsageError(f"{option} {text!r}: expected {n} numbers separated by commas ({meaning})")
    return values


def _add_map_options(p, required: bool = True) -> None:
    p.add_argument("--map", type=Path, required=required, metavar="MAP.json", help="world map (marker placements)")
    p.add_argument("--units", choices=UNITS, help="units of a map that does not declare them")
    p.add_argument("--marker-size-mm", type=float, metavar="MM", help="black square side, if the map does not say")
    p.add_argument(
        "--dictionary", help="ArUco dictionary, if the map does not say (a WPILib field layout: apriltag_36h11)"
    )


def _add_image_size_option(p) -> None:
    p.add_argument(
        "--image-size",
        metavar="WxH",
        help="resolution the camera was calibrated at, for an OpenCV YAML file that does not say "
        "(no image_width/image_height)",
    )


def _load_map(args) -> MarkerMap:
    return MarkerMap.load(
        args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=getattr(args, "dictionary", None)
    )


def _load_camera(args) -> Camera:
    size = parse_grid(args.image_size, "--image-size") if args.image_size else None
    return Camera.load(args.camera, image_size=size)


def _check_dpi(dpi: float) -> None:
    if not 50 <= dpi <= 1200:
        raise UsageError(f"--dpi {dpi:g}: give 50 to 1200 dots per inch (300 is a printer's)")


def _board(args) -> Board:
    """The board from ``--pattern`` (inner corners) or ``--squares``, ``--square-mm`` and the ChArUco options."""
    if not args.charuco and (args.dictionary or args.marker_mm is not None):
        raise UsageError("--dictionary and --marker-mm describe a ChArUco board; add --charuco or drop them")
    if args.charuco and args.marker_mm is None:
        raise UsageError("--charuco needs --marker-mm, the side of one printed marker in mm (smaller than the square)")
    option, text, counts = (
        ("--pattern", args.pattern, "inner") if args.pattern is not None else ("--squares", args.squares, "squares")
    )
    cols, rows = parse_grid(text, option)
    corners = (cols - 1) * (rows - 1) if counts == "squares" else cols * rows
    if corners > MAX_BOARD_CORNERS:  # said before the board is built: the message names the option
        raise UsageError(
            f"{option} {text}: {corners} inner corners, more than {MAX_BOARD_CORNERS}, the most fidlearn "
            "searches a photo for; count the board again (9x6 inner corners for a board of 10x7 squares)"
        )
    return Board.parse(
        text,
        args.square_mm,
        counts=counts,
        charuco=args.charuco,
        marker_size_mm=args.marker_mm,
        dictionary=args.dictionary,
    )


# -- signals ---------------------------------------------------------------------------------------
class _Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP (a robot's supervisor, ``timeout``, a closed terminal), handled as Ctrl-C is."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _signal_name(exc: BaseException) -> str:
    return signal.Signals(exc.signum).name if isinstance(exc, _Interrupted) else "SIGINT"


def _exit_status(exc: BaseException) -> int:
    """128 + the signal's number, as a shell reports a process a signal stopped."""
    return 128 + (exc.signum if isinstance(exc, _Interrupted) else signal.SIGINT)


def _raise_interrupted(signum, _frame) -> None:
    raise _Interrupted(signum)


# -- printing --------------------------------------------------------------------------------------
class _SafeStdout:
    """The command's standard output: a reader that goes away (``| head``) silences it instead of
    stopping the work, and a name the terminal cannot encode is printed with escapes."""

    def __init__(self, stream):
        self.stream = stream
        self.broken = False

    def write(self, text: str) -> int:
        if self.broken:
            return len(text)
        try:
            try:
                return self.stream.write(text)
            except UnicodeEncodeError:
                enc = getattr(self.stream, "encoding", None) or "ascii"
                return self.stream.write(text.encode(enc, "backslashreplace").decode(enc))
        except BrokenPipeError:
            self._close()
            return len(text)

    def flush(self) -> None:
        if not self.broken:
            try:
                self.stream.flush()
            except BrokenPipeError:
                self._close()

    def _close(self) -> None:
        # Python's advice for SIGPIPE: point the descriptor at the null device so that nothing
        # (not even the interpreter's flush at exit) writes to the closed pipe again
        self.broken = True
        try:
            fd = self.stream.fileno()
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, fd)
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name):
        return getattr(self.stream, name)


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _error(text: str) -> None:
    line = f"error: {_one_line(text)}"
    try:
        print(line, file=sys.stderr)
    except UnicodeEncodeError:
        enc = getattr(sys.stderr, "encoding", None) or "ascii"
        print(line.encode(enc, "backslashreplace").decode(enc), file=sys.stderr)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ARG001 (warnings.showwarning's signature)
    print(f"warning: {_one_line(str(message))}", file=sys.stderr)


class _Progress:
    """A plain-text progress bar on stderr when it is a terminal; otherwise one counter line at the end."""

    def __init__(self, what: str):
        self.what = what
        self.tty = sys.stderr.isatty()
        self.done = 0
        self.total = 0

    def __call__(self, i: int, n: int, name: str) -> None:
        self.done, self.total = i, n
        if self.tty:
            width = 24
            filled = int(round(width * i / max(n, 1)))
            label = Path(name).name[-30:]
            sys.stderr.write(f"\r{self.what} [{'#' * filled}{'-' * (width - filled)}] {i}/{n} {label}\x1b[K")
            sys.stderr.flush()

    def clear(self) -> None:
        if self.tty and self.total:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()

    def finish(self, found: int) -> None:
        """After a successful run: the counter line (non-terminal output only)."""
        if not self.tty and self.total:
            print(f"{self.what}: searched {self.total} images, board found in {found}", file=sys.stderr)


# -- outputs written as the work goes ----------------------------------------------------------------
def _outputs() -> StagedOutputs:
    """The command's outputs (:func:`fidlearn.cli.main` opens them around every command)."""
    outputs = current_outputs()
    if outputs is None:
        raise RuntimeError("a command's outputs are staged inside fidlearn.cli.main")
    return outputs


def _commit() -> None:
    """Write every output staged so far under its name, all together (before saying they are written)."""
    _outputs().commit()


class _StreamFile:
    """A text output written record by record (JSON lines) to a hidden file beside its final name.

    It takes its name with the command's other outputs when the run ends, or at once when the run is
    interrupted (every record in it is whole); on an error it is removed: an output is either whole up
    to the last frame done, or absent.
    """

    def __init__(self, path: Path, option: str):
        self.path, self.option, self.count = Path(path), option, 0  # entry and file: made by __enter__

    def __enter__(self):
        outputs = _outputs()
        self.entry = outputs.temp(self.path)
        try:
            os.chmod(self.entry.tmp, fidlearn_io.file_mode_for(self.path))  # not mkstemp's private 0o600
            self.file = open(self.entry.tmp, "w", encoding="utf-8")  # noqa: SIM115 - closed in __exit__
        except OSError as exc:
            raise FidlearnError(
                f"{self.option} {self.path}: cannot write it ({exc.strerror}); {outputs.written()}"
            ) from None
        self.entry.whole = True  # no record yet is a whole file too
        return self

    def write(self, record) -> None:
        self._put(record if isinstance(record, str) else json.dumps(record))

    def _put(self, line: str) -> None:
        try:
            with signals_deferred():  # the record and its count together
                self.file.write(line + "\n")
                self.file.flush()
                self.count += 1
        except OSError as exc:
            raise FidlearnError(
                f"{self.option} {self.path}: cannot write it ({exc.strerror}); check the free disk space; "
                f"{_outputs().written()}"
            ) from None

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            self.file.close()
        except OSError as err:
            self.entry.whole = False
            if exc_type is None:
                raise FidlearnError(f"{self.option} {self.path}: cannot write it ({err.strerror})") from None
        if exc_type is not None and issubclass(exc_type, KeyboardInterrupt):
            _outputs().commit([self.entry])


class _Staging:
    """Annotated images staged with the command's outputs, moved into their folder when they are committed."""

    def __init__(self, folder: Path | None):
        self.folder = folder
        self.replaced = 0
        self.tmp: Path | None = None
        self.names: set[str] = set()
        if folder is not None:
            parent = folder.parent if str(folder.parent) else Path(".")
            if folder.exists() and not folder.is_dir():
                raise UsageError(f"--annotate {folder}: is a file; give a folder")
            if not parent.is_dir():
                raise UsageError(f"--annotate {folder}: the folder {parent} does not exist; create it first")

    def __enter__(self):
        if self.folder is not None:
            self.tmp = _outputs().staging_folder(self.folder)
        return self

    def save(self, name: str, image) -> None:
        if self.tmp is None or self.folder is None:  # no --annotate
            return
        video, sep, frame = name.rpartition("#")
        # "drive.mp4#7" -> drive_00007.png: the frame's own number, sortable
        stem = f"{Path(video).stem}_{int(frame):05d}" if sep and frame.isdigit() else Path(name).stem
        fname, k = f"{stem}.png", 1
        while fname in self.names:
            k += 1
            fname = f"{stem}-{k}.png"
        data = encode_image(fname, image)
        _outputs().stage(self.folder / fname, lambda tmp: tmp.write_bytes(data), folder=self.tmp, group=self.folder)
        self.names.add(fname)
        self.replaced += (self.folder / fname).exists()

    def __exit__(self, exc_type, exc, tb) -> None:
        pass

    def said(self) -> str:
        """What the folder received, for the closing line."""
        n = sum(1 for e in _outputs().committed if e.group == self.folder)
        again = f", replacing {self.replaced} earlier one{'s' if self.replaced != 1 else ''}" if self.replaced else ""
        return f"{n} annotated picture{'s' if n != 1 else ''} in {self.folder}/{again}"
