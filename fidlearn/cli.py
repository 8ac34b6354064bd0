"""The ``fidlearn`` command line.

Every command reports a user error as one line ``error: ...`` on stderr and
exits with status 2: never a traceback, never a half-written output file.
Inputs and output paths are checked before any work starts.

What "no partial output" means for each kind of output:

* one file (``-o``, ``--truth``): written to a hidden temporary file in the
  same folder and renamed when complete (:func:`fidlearn._io.atomic_write`);
  several PNG pages are all rendered before any is renamed.
* ``locate --json``: one JSON line per frame, flushed as each frame is done
  into a hidden temporary file, renamed to its name when the whole run ends
  well (stopping a live camera with Ctrl-C is a good end; an error in frame
  57 of a video leaves no file).
* ``--annotate DIR``: images are staged in a hidden folder beside ``DIR`` and
  moved into ``DIR`` (created if needed) only when the run succeeds.

Warnings (:class:`~fidlearn.errors.FidlearnWarning`) print as one line
``warning: ...`` on stderr and do not change the exit status.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import sys
import tempfile
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from . import (
    __version__,
    _cv,  # noqa: F401 - OpenCV that cannot import fails here, where fidlearn._entry reports it
    doctor,
)
from ._io import atomic_write, file_mode_for
from .doctor import OPENCV_WHEELS, WANTED_WHEEL  # noqa: F401 - kept importable from here
from .errors import FidlearnError, FidlearnWarning

__all__ = ["main", "build_parser"]


class UsageError(FidlearnError):
    """The command line itself is wrong (unknown option, missing argument)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, status 2, no usage dump
        raise UsageError(f"{self.prog}: {message} (see '{self.prog} --help')")


# -- fidlearn corners ----------------------------------------------------------------
def _add_corners(sub) -> None:
    p = sub.add_parser(
        "corners",
        help="world map (marker placements) to marker corners in mm",
        description="Turn a world map into the 3D corners of each marker (TL, TR, BR, BL, mm).",
    )
    p.add_argument("map", type=Path, help="world map JSON (bare seed layout or full layout)")
    p.add_argument("--units", choices=["mm", "cm", "m", "in", "ft"], help="units of a map that does not declare them")
    p.add_argument("--marker-size-mm", type=float, help="side of the black square in mm, if the map does not say")
    p.add_argument("--dictionary", help="ArUco dictionary, if the map does not say (default ARUCO_ORIGINAL)")
    p.add_argument("-o", "--output", type=Path, required=True, help="corner file to write (JSON)")
    p.set_defaults(run=_run_corners)


def _run_corners(args) -> int:
    from .markermap import MarkerMap

    _refuse_clobber([("-o", args.output)], [args.map])
    m = MarkerMap.load(args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=args.dictionary)
    m.save_corners(args.output)
    plane = (
        f"coplanar (within {m.planarity_mm():.2f} mm)"
        if m.is_coplanar()
        else f"not coplanar ({m.planarity_mm():.1f} mm off a plane)"
    )
    print(
        f"{args.output}: corners of {len(m)} marker{'s' if len(m) != 1 else ''} {m.ids}, {m.marker_size_mm:g} mm, {plane}"
    )
    return 0


# -- fidlearn doctor -----------------------------------------------------------------
def doctor_report() -> tuple[list[str], list[str]]:
    """Lines describing the environment, and the problems found (see :mod:`fidlearn.doctor`)."""
    return doctor.report()


def _add_doctor(sub) -> None:
    p = sub.add_parser(
        "doctor", help="check the Python, numpy and OpenCV installation", description="Check the installation."
    )
    p.set_defaults(run=_run_doctor)


def _run_doctor(args) -> int:
    return doctor.run()


# -- shared helpers ----------------------------------------------------------------------
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
        for opt2, out2 in named[:k]:
            if out.resolve() == out2.resolve() or _same_file(out, out2):
                raise UsageError(f"{opt} {out} and {opt2} {out2} are the same file; give each output its own name")
    if annotate is not None:
        folder = Path(annotate).resolve()
        for inp in files:
            if inp.resolve().parent == folder:
                raise UsageError(
                    f"--annotate {annotate} holds the input {inp}; its annotated copy would replace it: "
                    "give another folder"
                )
        for opt, out in named:
            if out.resolve().parent == folder:
                raise UsageError(
                    f"--annotate {annotate} is where {opt} {out} goes; give the annotations a folder of their own"
                )


class _Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP (a robot's supervisor, ``timeout``, a closed terminal), handled as Ctrl-C is."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _signal_name(exc: BaseException) -> str:
    return signal.Signals(exc.signum).name if isinstance(exc, _Interrupted) else "SIGINT"


def _raise_interrupted(signum, frame) -> None:
    raise _Interrupted(signum)


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


class _StreamFile:
    """A text output written record by record (JSON lines) to a hidden file beside its final name.

    It takes the final name when the run ends or is interrupted (every record in it is whole);
    on an error it is removed: an output is either whole up to the last frame done, or absent.
    """

    def __init__(self, path: Path, option: str):
        self.path, self.option, self.count = Path(path), option, 0
        self.tmp: Path | None = None
        self.file = None

    def __enter__(self):
        folder = self.path.parent if str(self.path.parent) else Path(".")
        try:
            fd, name = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".part", dir=folder)
        except OSError as exc:
            raise FidlearnError(
                f"{self.option} {self.path}: cannot write in {folder} ({exc.strerror}); check the folder's permissions"
            ) from None
        self.tmp = Path(name)
        self.file = os.fdopen(fd, "w", encoding="utf-8")
        return self

    def write(self, record: dict) -> None:
        try:
            self.file.write(json.dumps(record) + "\n")
            self.file.flush()
        except OSError as exc:
            raise FidlearnError(
                f"{self.option} {self.path}: cannot write it ({exc.strerror}); check the free disk space"
            ) from None
        self.count += 1

    def __exit__(self, exc_type, exc, tb) -> None:
        keep = exc_type is None or issubclass(exc_type, KeyboardInterrupt)
        try:
            self.file.close()
            if keep:
                os.chmod(self.tmp, file_mode_for(self.path))
                os.replace(self.tmp, self.path)
        except OSError as err:
            keep = False
            if exc_type is None:
                raise FidlearnError(f"{self.option} {self.path}: cannot write it ({err.strerror})") from None
        finally:
            if not keep:
                self.tmp.unlink(missing_ok=True)


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


def _json_text(obj) -> str:
    """Indented JSON with each innermost list of numbers on one line (readable matrices)."""
    text = json.dumps(obj, indent=2)
    return (
        re.sub(
            r"\[\s+([-+0-9.eE,\s]+?)\s+\]",
            lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]",
            text,
        )
        + "\n"
    )


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _write_image(path: Path, image) -> Path:
    """Encode an image by its file suffix and write it atomically."""
    import cv2

    ok, buf = cv2.imencode(path.suffix.lower(), image)
    if not ok:
        raise FidlearnError(f"{path}: OpenCV cannot encode a {path.suffix} image; use .png")
    return atomic_write(path, lambda tmp: tmp.write_bytes(buf.tobytes()))


def _load_map(args):
    from .markermap import MarkerMap

    return MarkerMap.load(
        args.map, units=args.units, marker_size_mm=args.marker_size_mm, dictionary=getattr(args, "dictionary", None)
    )


def _add_image_size_option(p) -> None:
    p.add_argument(
        "--image-size",
        metavar="WxH",
        help="resolution the camera was calibrated at, for an OpenCV YAML file that does not say "
        "(no image_width/image_height)",
    )


def _load_camera(args):
    from .camera import Camera

    size = None
    if args.image_size:
        from .printables import parse_pattern

        size = parse_pattern(args.image_size, "--image-size")
    return Camera.load(args.camera, image_size=size)


def _add_map_options(p, required: bool = True) -> None:
    p.add_argument("--map", type=Path, required=required, metavar="MAP.json", help="world map (marker placements)")
    p.add_argument("--units", choices=["mm", "cm", "m", "in", "ft"], help="units of a map that does not declare them")
    p.add_argument("--marker-size-mm", type=float, metavar="MM", help="black square side, if the map does not say")


# -- fidlearn markers ----------------------------------------------------------------------
def _add_markers(sub) -> None:
    p = sub.add_parser(
        "markers",
        help="print ArUco markers at exact size (PDF or PNG)",
        description=(
            "Print ArUco markers at exact physical size: each black square measures --size-mm when "
            "the page is printed at 100 % (no scaling). Each marker has a white margin of one cell, "
            "its id and dictionary under it and cut marks; every page has a 100 mm ruler. "
            "Markers that do not fit on one page go on the next."
        ),
    )
    p.add_argument("--ids", required=True, help="marker ids: 0-9, 0,3,7 or 0-3,8")
    p.add_argument("--size-mm", type=float, required=True, metavar="MM", help="side of the black square, mm")
    p.add_argument("--dictionary", default="ARUCO_ORIGINAL", help="ArUco dictionary (default ARUCO_ORIGINAL)")
    p.add_argument("--paper", choices=["a4", "letter"], default="a4", help="paper size (default a4)")
    p.add_argument("--dpi", type=float, default=300, help="pixels per inch of PNG output (default 300)")
    p.add_argument("-o", "--output", type=Path, required=True, help="markers.pdf (vector) or markers.png")
    p.set_defaults(run=_run_markers)


def _check_dpi(dpi: float) -> None:
    if not 50 <= dpi <= 1200:
        raise UsageError(f"--dpi {dpi:g}: give 50 to 1200 dots per inch (300 is a printer's)")


def _run_markers(args) -> int:
    from . import printables

    out = _check_output(args.output, (".pdf", ".png"))
    _check_dpi(args.dpi)
    ids = printables.parse_ids(args.ids)
    sheet = printables.layout_markers(ids, args.size_mm, args.dictionary, args.paper)
    files = printables.save_pages(printables.marker_figures(sheet), out, dpi=args.dpi)
    pages = len(sheet.pages)
    where = ", ".join(str(f) for f in files)
    extra = f" at {args.dpi:g} dpi" if out.suffix.lower() == ".png" else ""
    several = f", {sheet.per_page} per page" if pages > 1 else ""
    print(
        f"{where}: {len(ids)} marker{'s' if len(ids) > 1 else ''} of {sheet.size_mm:g} mm ({sheet.dictionary}) "
        f"on {pages} {sheet.paper} page{'s' if pages > 1 else ''}{extra}{several}"
    )
    print("print at 100 % (actual size, no 'fit to page') and check the 100 mm ruler with calipers")
    return 0


# -- fidlearn board ------------------------------------------------------------------------
def _add_board(sub) -> None:
    p = sub.add_parser(
        "board",
        help="print a checkerboard or ChArUco board at exact size",
        description=(
            "Print a calibration board at exact physical size with a 100 mm ruler. --pattern counts "
            "INNER corners, as OpenCV's findChessboardCorners does (9x6 gives 10x7 squares); "
            "--squares counts squares, as OpenCV's CharucoBoard does. The page turns to landscape "
            "when the board only fits that way."
        ),
    )
    size = p.add_mutually_exclusive_group(required=True)
    size.add_argument("--pattern", metavar="CxR", help="inner corners, e.g. 9x6 (10x7 squares)")
    size.add_argument("--squares", metavar="CxR", help="squares, e.g. 5x7 (4x6 inner corners)")
    p.add_argument("--square-mm", type=float, required=True, metavar="MM", help="side of one square, mm")
    p.add_argument("--charuco", action="store_true", help="a ChArUco board (markers in the white squares)")
    p.add_argument("--dictionary", help="ChArUco dictionary (default 6X6_250)")
    p.add_argument("--marker-mm", type=float, metavar="MM", help="ChArUco marker side, mm (smaller than the square)")
    p.add_argument("--paper", choices=["a4", "letter"], default="a4", help="paper size (default a4)")
    p.add_argument("--dpi", type=float, default=300, help="pixels per inch of PNG output (default 300)")
    p.add_argument("-o", "--output", type=Path, required=True, help="board.pdf (vector) or board.png")
    p.set_defaults(run=_run_board)


def _run_board(args) -> int:
    from . import printables

    out = _check_output(args.output, (".pdf", ".png"))
    _check_dpi(args.dpi)
    if args.pattern is not None:
        cols, rows = printables.parse_pattern(args.pattern, "--pattern")
        squares = (cols + 1, rows + 1)
    else:
        squares = printables.parse_pattern(args.squares, "--squares")
    if not args.charuco and (args.dictionary or args.marker_mm is not None):
        raise UsageError("--dictionary and --marker-mm describe a ChArUco board; add --charuco or drop them")
    sheet = printables.layout_board(
        squares, args.square_mm, args.paper, args.charuco, args.dictionary or "6X6_250", args.marker_mm
    )
    files = printables.save_pages([printables.board_figure(sheet)], out, dpi=args.dpi)
    turn = ", landscape" if sheet.landscape else ""
    print(f"{files[0]}: {sheet.describe()}, {sheet.paper}{turn}")
    print("print at 100 % (actual size, no 'fit to page') and check the 100 mm ruler with calipers")
    return 0


# -- fidlearn render -----------------------------------------------------------------------
_POSE_HELP = """The camera's pose in the world, two ways:
  --pose X,Y,Z,ROLL,PITCH,YAW   the camera's position (mm, world) and the rotation of the
                                camera frame in the world, R_world_camera = Rz(yaw) Ry(pitch)
                                Rx(roll) in degrees: the same numbers 'fidlearn locate' prints.
                                The camera frame is OpenCV's (x right, y down, z forward), so
                                0,0,0 looks straight up (+Z); -90,0,90 looks at the north wall
                                (along -X) upright; -90,0,0 looks along +Y.
  --from X,Y,Z --look-at X,Y,Z  the camera at one point (mm) looking at another, upright
                                (world +Z up in the image); --roll-deg turns it about its axis.
Example: fidlearn render --map world_map.json --camera camera.json \\
           --from 1200,150,250 --look-at 0,150,250 -o scene.png --truth truth.json"""


def _add_render(sub) -> None:
    p = sub.add_parser(
        "render",
        help="synthetic picture of a world map seen from a pose",
        description="Render a synthetic picture of the markers of a world map as a calibrated camera\n"
        "at a given pose would see them, to try the pipeline without hardware.",
        epilog=_POSE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_map_options(p)
    p.add_argument(
        "--camera", type=Path, required=True, metavar="CAMERA", help="camera file (fidlearn JSON or OpenCV YAML)"
    )
    _add_image_size_option(p)
    pose = p.add_mutually_exclusive_group(required=True)
    pose.add_argument("--pose", metavar="X,Y,Z,R,P,Y", help="camera position (mm) and roll,pitch,yaw (deg), see below")
    pose.add_argument("--look-at", metavar="X,Y,Z", help="point the camera looks at (mm); needs --from")
    p.add_argument("--from", dest="eye", metavar="X,Y,Z", help="camera position (mm) for --look-at")
    p.add_argument("--roll-deg", type=float, default=0.0, help="with --look-at: turn about the optical axis (deg)")
    p.add_argument("--size", metavar="WxH", help="render at another resolution of the same aspect ratio")
    p.add_argument("--seed", type=int, default=0, help="random seed of the wall texture and noise (default 0)")
    p.add_argument("--noise", type=float, default=0.0, metavar="STD", help="sensor noise, gray levels (default 0)")
    p.add_argument("--blur", type=float, default=0.0, metavar="PX", help="defocus blur sigma, px (default 0)")
    p.add_argument("--truth", type=Path, metavar="TRUTH.json", help="also write the true pose and pixel corners")
    p.add_argument("-o", "--output", type=Path, required=True, help="image to write (.png)")
    p.set_defaults(run=_run_render)


#: Largest picture ``fidlearn render`` draws (pixels); rendering supersamples it 16 times.
MAX_RENDER_PIXELS = 40_000_000
#: Largest coordinate (mm) a pose on the command line may have: 100 km.
MAX_COORD_MM = 1e8


def _check_coords(option: str, values) -> None:
    if max(abs(v) for v in values) > MAX_COORD_MM:
        raise UsageError(
            f"{option}: {max(abs(v) for v in values):g} mm is beyond any room ({MAX_COORD_MM:g} mm at most); "
            "positions are in millimetres"
        )


def _pose_from_args(args):
    from . import frames, synthetic

    if args.pose is not None:
        if args.eye is not None:
            raise UsageError("--from goes with --look-at; --pose already gives the position")
        x, y, z, roll, pitch, yaw = _floats(args.pose, 6, "--pose", "x,y,z in mm, roll,pitch,yaw in degrees")
        _check_coords("--pose", (x, y, z))
        if max(abs(roll), abs(pitch), abs(yaw)) > 3600:
            raise UsageError(f"--pose {args.pose}: roll, pitch and yaw are degrees, -360 to 360")
        return frames.make_transform(frames.rotation_from_rpy_deg(roll, pitch, yaw), [x, y, z])
    if args.eye is None:
        raise UsageError("--look-at needs --from X,Y,Z, the camera's position in mm")
    eye = _floats(args.eye, 3, "--from", "x,y,z in mm")
    target = _floats(args.look_at, 3, "--look-at", "x,y,z in mm")
    _check_coords("--from", eye)
    _check_coords("--look-at", target)
    if not abs(args.roll_deg) <= 3600:
        raise UsageError("--roll-deg is degrees, -360 to 360")
    return synthetic.look_at(eye, target, roll_deg=args.roll_deg)


def _run_render(args) -> int:
    import numpy as np

    from . import frames, synthetic

    out = _check_output(args.output, (".png", ".bmp", ".tif", ".tiff"))
    truth_path = _check_output(args.truth, (".json",), "--truth") if args.truth else None
    _refuse_clobber([("-o", out), ("--truth", truth_path)], [args.map, args.camera])
    if not (0 <= args.noise <= 255) or not (0 <= args.blur <= 100):
        raise UsageError("--noise must be 0 to 255 gray levels and --blur 0 to 100 px")
    if not 0 <= args.seed < 2**32:
        raise UsageError(f"--seed {args.seed}: give a whole number from 0 to {2**32 - 1}")
    marker_map = _load_map(args)
    camera = _load_camera(args)
    if args.size:
        from .printables import parse_pattern

        w, h = parse_pattern(args.size, "--size")
        if w * h > MAX_RENDER_PIXELS or max(w, h) > 20000:
            raise UsageError(
                f"--size {w}x{h}: at most {MAX_RENDER_PIXELS // 1_000_000} megapixels and 20000 pixels a side"
            )
        camera = camera.scaled((w, h))
    T_world_camera = _pose_from_args(args)
    image, truth = synthetic.render_scene(
        camera, marker_map, T_world_camera, seed=args.seed, noise_std=args.noise, blur_px=args.blur
    )

    def write_both(tmp_truth=None):
        if tmp_truth is not None:
            record = {
                "image": out.name,
                "camera": camera.to_dict(),
                "map": str(args.map),
                "dictionary": marker_map.dictionary,
                "marker_size_mm": marker_map.marker_size_mm,
                "T_world_camera": np.asarray(T_world_camera).tolist(),
                "position_mm": T_world_camera[:3, 3].tolist(),
                "rpy_deg": frames.rpy_deg_from_rotation(T_world_camera[:3, :3]).tolist(),
                "markers_px": {str(k): v.tolist() for k, v in sorted(truth.items())},
                "pixel_convention": "pixel centres at integer coordinates; corners TL, TR, BR, BL",
                "seed": args.seed,
                "noise_std": args.noise,
                "blur_px": args.blur,
            }
            tmp_truth.write_text(_json_text(record), encoding="utf-8")
        _write_image(out, image)

    if truth_path is not None:
        atomic_write(truth_path, write_both)
    else:
        write_both()
    seen = ", ".join(str(i) for i in sorted(truth)) or "none"
    print(
        f"{out}: {camera.width}x{camera.height}, markers seen whole: {seen}"
        + (f"; truth in {truth_path}" if truth_path else "")
    )
    if not truth:
        warnings.warn("no marker of the map is in view; check the pose (see 'fidlearn render --help')", FidlearnWarning)
    return 0


# -- inputs: images, folders, videos, cameras ----------------------------------------------
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm")


def _expand_inputs(paths: Sequence[Path], videos: bool) -> list[tuple[str, Path]]:
    """``[("image" | "video", path), ...]`` from files and folders, checked before any work."""
    items: list[tuple[str, Path]] = []
    for path in paths:
        path = Path(path)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise UsageError(f"{path}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")
            items += [("image", p) for p in found]
        elif not path.exists():
            raise UsageError(f"{path}: no such file or folder; check the path")
        elif videos and path.suffix.lower() in VIDEO_SUFFIXES:
            items.append(("video", path))
        elif path.suffix.lower() in IMAGE_SUFFIXES:
            items.append(("image", path))
        else:
            kinds = IMAGE_SUFFIXES + (VIDEO_SUFFIXES if videos else ())
            raise UsageError(
                f"{path}: not an image{' or a video' if videos else ''} by its name; expected {', '.join(kinds)}"
            )
    return items


def _open_capture(source, what: str):
    """An opened ``cv2.VideoCapture`` for a file or a camera index, or an ImageError."""
    import cv2

    from .errors import ImageError

    cap = cv2.VideoCapture(source)
    opened = cap.isOpened()
    if not opened:
        cap.release()
        if isinstance(source, int):
            raise ImageError(f"camera {source}: cannot open it; check --camera-index (0 is the first camera)")
        raise ImageError(f"{what}: OpenCV cannot open this video; is it truncated, or a codec OpenCV lacks?")
    return cap


def _declared_frames(cap) -> int:
    """The frame count a video file's header announces (0 when it does not say)."""
    import cv2

    try:
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    except cv2.error:
        return 0
    return int(count) if count > 0 and count == count and count < 1e9 else 0


def _read_capture(cap, prefix: str):
    k = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            return
        yield f"{prefix}#{k}", frame
        k += 1


def _frames(items: list[tuple[str, Path]], camera_index: int | None, max_pixels: int = 100_000_000):
    """Yield ``(name, image)`` for every image, every video frame and every camera frame.

    Every video (and the camera) is opened once before the first frame, so a
    video that cannot be read stops the run before anything is printed.
    """
    from .detection import load_image
    from .errors import ImageError

    for kind, path in items:
        if kind == "video":
            _open_capture(str(path), str(path)).release()
    if camera_index is not None:
        _open_capture(int(camera_index), "").release()
    for kind, path in items:
        if kind == "image":
            yield path.name, load_image(path, max_pixels=max_pixels)
            continue
        cap = _open_capture(str(path), str(path))
        try:
            n = 0
            for name, frame in _read_capture(cap, path.name):
                n += 1
                yield name, frame
            if n == 0:
                raise ImageError(f"{path}: the video has no frame OpenCV can decode")
            declared = _declared_frames(cap)
            if declared > n:
                import warnings

                from .errors import FidlearnWarning

                warnings.warn(
                    f"{path}: the video ended after {n} of the {declared} frames its header announces; "
                    "the file may be truncated (an interrupted copy or recording)",
                    FidlearnWarning,
                )
        finally:
            cap.release()
    if camera_index is not None:
        cap = _open_capture(int(camera_index), "")
        try:
            yield from _read_capture(cap, f"camera{camera_index}")
        finally:
            cap.release()


class _Staging:
    """Annotated images staged in a hidden folder and moved into place only when the run succeeds."""

    def __init__(self, folder: Path | None, keep_on_interrupt: bool = False):
        self.folder = folder
        self.keep_on_interrupt = keep_on_interrupt
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
            import tempfile

            parent = self.folder.parent if str(self.folder.parent) else Path(".")
            self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.folder.name}.", dir=parent))
        return self

    def save(self, name: str, image) -> None:
        if self.tmp is None:
            return
        video, sep, frame = name.rpartition("#")
        if sep and frame.isdigit():  # "drive.mp4#7" -> drive_00007.png: the frame's own number, sortable
            stem = f"{Path(video).stem}_{int(frame):05d}"
        else:
            stem = Path(name).stem
        fname, k = f"{stem}.png", 1
        while fname in self.names:
            k += 1
            fname = f"{stem}-{k}.png"
        _write_image(self.tmp / fname, image)
        self.names.add(fname)  # only once the picture is whole: an interruption keeps whole pictures only

    def __exit__(self, exc_type, exc, tb) -> None:
        import shutil

        if self.tmp is None:
            return
        try:
            interrupted = exc_type is not None and issubclass(exc_type, KeyboardInterrupt)
            if exc_type is None or (interrupted and self.keep_on_interrupt):
                self.folder.mkdir(exist_ok=True)
                for fname in sorted(self.names):
                    self.replaced += (self.folder / fname).exists()
                    os.replace(self.tmp / fname, self.folder / fname)
        finally:
            shutil.rmtree(self.tmp, ignore_errors=True)

    def said(self) -> str:
        """What the folder received, for the closing line."""
        again = f", replacing {self.replaced} earlier one{'s' if self.replaced != 1 else ''}" if self.replaced else ""
        return f"{len(self.names)} annotated picture{'s' if len(self.names) != 1 else ''} in {self.folder}/{again}"


# -- fidlearn calibrate --------------------------------------------------------------------
#: Fewer used views than this earns a warning: OpenCV's advice is 10 to 20 varied views.
MIN_GOOD_VIEWS = 10
#: A ninth of the picture with fewer corners than this share of an even spread (but some) earns a warning.
SPARSE_CELL_SHARE = 0.1
#: A calibration whose board normals all lie within this angle (deg) of each other is too flat a set.
MIN_TILT_SPREAD_DEG = 10.0
#: Two views closer than this (deg and fraction of the distance) are near duplicates.
DUPLICATE_DEG, DUPLICATE_FRACTION = 2.0, 0.02
_CELL_NAMES = (("top-left", "top", "top-right"), ("left", "centre", "right"), ("bottom-left", "bottom", "bottom-right"))


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


def coverage_grid(points_px: Sequence, image_size: tuple[int, int]):
    """Board corners per cell of a 3x3 grid over the image: (3, 3) int, row 0 at the top.

    ``points_px`` holds one (N, 2) array of pixels per view (pixel centres at
    integers, so the image spans -0.5 .. width - 0.5).
    """
    import numpy as np

    w, h = image_size
    grid = np.zeros((3, 3), dtype=int)
    for pts in points_px:
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        col = np.clip(((pts[:, 0] + 0.5) * 3 // w).astype(int), 0, 2)
        row = np.clip(((pts[:, 1] + 0.5) * 3 // h).astype(int), 0, 2)
        np.add.at(grid, (row, col), 1)
    return grid


def view_diversity(T_camera_board: dict) -> tuple[float, list[tuple[str, str, float, float]]]:
    """How different the board poses are.

    Returns the largest angle (deg) between the board's normals over all pairs
    of views (0 for one view), and the near-duplicate pairs ``(a, b, angle_deg,
    moved_fraction)``: views whose board turned less than ``DUPLICATE_DEG`` and
    moved less than ``DUPLICATE_FRACTION`` of its distance.
    """
    import numpy as np

    from . import frames

    names = list(T_camera_board)
    normals = [np.asarray(T_camera_board[n])[:3, 2] for n in names]
    spread = 0.0
    duplicates = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            cos = float(np.clip(abs(normals[i] @ normals[j]), -1.0, 1.0))
            spread = max(spread, math.degrees(math.acos(cos)))
            Ti, Tj = np.asarray(T_camera_board[names[i]]), np.asarray(T_camera_board[names[j]])
            angle = frames.rotation_angle_deg(Ti[:3, :3], Tj[:3, :3])
            moved = float(np.linalg.norm(Ti[:3, 3] - Tj[:3, 3]) / max(np.linalg.norm(Ti[:3, 3]), 1e-9))
            if angle < DUPLICATE_DEG and moved < DUPLICATE_FRACTION:
                duplicates.append((names[i], names[j], angle, moved))
    return spread, duplicates


def _add_calibrate(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="camera intrinsics and distortion from photos of a board",
        description=(
            "Calibrate a camera from photos of a printed checkerboard (or a ChArUco board with --charuco). "
            "Prints a table of every photo (board found, reprojection error, rejected and why), the "
            "intrinsics with their standard deviations, how well the corners cover the picture, and "
            "warnings when the views are too few (< 10), too alike, or leave parts of the picture empty. "
            "Measure one printed square with calipers and give that as --square-mm."
        ),
    )
    p.add_argument(
        "inputs", nargs="+", type=Path, metavar="IMAGE_OR_FOLDER", help="photos of the board, or folders of them"
    )
    size = p.add_mutually_exclusive_group(required=True)
    size.add_argument("--pattern", metavar="CxR", help="inner corners, e.g. 9x6 (a board of 10x7 squares)")
    size.add_argument("--squares", metavar="CxR", help="squares, e.g. 5x7 (OpenCV's ChArUco count)")
    p.add_argument("--square-mm", type=float, required=True, metavar="MM", help="side of one printed square, mm")
    p.add_argument("--charuco", action="store_true", help="a ChArUco board")
    p.add_argument("--marker-mm", type=float, metavar="MM", help="ChArUco marker side, mm")
    p.add_argument("--dictionary", help="ChArUco dictionary (default 6X6_250)")
    p.add_argument("--annotate", type=Path, metavar="DIR", help="save each photo with its detected corners drawn")
    p.add_argument(
        "--report",
        type=Path,
        metavar="REPORT.png",
        help="draw the calibration's reprojection uncertainty over the picture and the next photo to take",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="camera file to write (.json, or OpenCV .yml/.xml)")
    p.set_defaults(run=_run_calibrate)


def _draw_calibration_view(path: Path, view, points_px, pattern, charuco: bool):
    import cv2
    import numpy as np

    from .detection import _as_bgr, load_image

    out = _as_bgr(load_image(path))
    unit = max(out.shape[:2]) / 640
    if points_px is not None:
        pts = np.asarray(points_px, dtype=np.float32).reshape(-1, 1, 2)
        if charuco:
            for u, v in pts.reshape(-1, 2):
                cv2.circle(
                    out, (int(round(u * 16)), int(round(v * 16))), int(4 * unit * 16), (0, 200, 0), 1, cv2.LINE_AA, 4
                )
        else:
            cv2.drawChessboardCorners(out, pattern, pts, True)
        text = f"{view.status}: {len(pts)} corners, rms {view.rms_px:.3f} px"
        colour = (0, 160, 0)
    else:
        text = f"{view.status}: {view.reason}"
        colour = (0, 0, 255)
    scale = 0.45 * unit
    lines = _wrap_to_width(text, out.shape[1] - 16, scale)
    (_, th), base = cv2.getTextSize("Ay", cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    step = th + base + 4
    tw = max(cv2.getTextSize(line, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] for line in lines)
    cv2.rectangle(out, (0, 0), (tw + 16, step * len(lines) + 8), (255, 255, 255), -1)
    for k, line in enumerate(lines):
        cv2.putText(out, line, (8, th + 6 + k * step), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)
    return out


def _wrap_to_width(text: str, width_px: int, scale: float) -> list[str]:
    """``text`` in lines no wider than ``width_px`` at OpenCV's simplex font of ``scale`` (a word too long stays whole)."""
    import cv2

    lines: list[str] = []
    for word in text.split():
        trial = f"{lines[-1]} {word}" if lines else word
        if lines and cv2.getTextSize(trial, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] <= width_px:
            lines[-1] = trial
        else:
            lines.append(word)
    return lines or [""]


def _run_calibrate(args) -> int:
    from . import calibration
    from .printables import parse_pattern

    out = _check_output(args.output, (".json", ".yml", ".yaml", ".xml"))
    report = _check_output(args.report, (".png",), "--report") if args.report else None
    items = _expand_inputs(args.inputs, videos=False)
    _refuse_clobber([("-o", out), ("--report", report)], [p for _, p in items], args.annotate)
    staging = _Staging(args.annotate)
    if args.pattern is not None:
        cols, rows = parse_pattern(args.pattern, "--pattern")
        squares = (cols + 1, rows + 1)
    else:
        squares = parse_pattern(args.squares, "--squares")
    pattern = (squares[0] - 1, squares[1] - 1)
    if not args.charuco and (args.dictionary or args.marker_mm is not None):
        raise UsageError("--dictionary and --marker-mm describe a ChArUco board; add --charuco or drop them")
    if args.charuco and args.marker_mm is None:
        raise UsageError("--charuco needs --marker-mm, the side of one printed marker in mm")
    paths = [str(p) for _, p in items]
    progress = _Progress("calibrate")
    try:
        if args.charuco:
            cal = calibration.calibrate_charuco(
                paths, squares, args.square_mm, args.marker_mm, args.dictionary or "6X6_250", progress=progress
            )
        else:
            cal = calibration.calibrate_checkerboard(paths, pattern, args.square_mm, progress=progress)
    finally:
        progress.clear()
    progress.finish(sum(1 for v in cal.views if v.found))

    c, sd = cal.camera, cal.std_intrinsics
    print(cal.table())
    print()
    print(
        f"camera {c.width}x{c.height} from {len(cal.used)} of {len(cal.views)} views of a {cal.board}, "
        f"RMS reprojection error {cal.rms_px:.3f} px"
    )
    for name, value in (("fx", c.fx), ("fy", c.fy), ("cx", c.cx), ("cy", c.cy)):
        print(f"  {name} {value:10.2f} ± {sd.get(name, float('nan')):.2f} px")
    dist_names = calibration.INTRINSIC_NAMES[4 : 4 + len(c.dist)]
    print(
        "  distortion " + ", ".join(f"{n} {v:.4f} ± {sd.get(n, float('nan')):.4f}" for n, v in zip(dist_names, c.dist))
    )

    grid = coverage_grid(cal.image_points_px.values(), c.image_size)
    print("board corners per ninth of the picture (3x3 grid):")
    for row in grid:
        print("  " + " ".join(f"{v:6d}" for v in row))
    empty = [_CELL_NAMES[r][k] for r in range(3) for k in range(3) if grid[r, k] == 0]
    even_share = grid.sum() / 9.0
    sparse = [_CELL_NAMES[r][k] for r in range(3) for k in range(3) if 0 < grid[r, k] < SPARSE_CELL_SHARE * even_share]
    if len(cal.used) < MIN_GOOD_VIEWS:
        warnings.warn(
            f"only {len(cal.used)} views used; {MIN_GOOD_VIEWS} to 20 views from varied angles give a "
            "trustworthy camera: take more photos",
            FidlearnWarning,
        )
    spread, duplicates = view_diversity(cal.T_camera_board)
    if len(cal.used) > 1 and spread < MIN_TILT_SPREAD_DEG:
        warnings.warn(
            f"views too similar: the board faces the camera within {spread:.1f} deg in every view; "
            "tilt it 20 to 45 deg in different directions, or the focal length stays uncertain",
            FidlearnWarning,
        )
    if duplicates:
        a, b, _, _ = duplicates[0]
        warnings.warn(
            f"{len(duplicates)} pair(s) of nearly identical views (e.g. {Path(a).name} and {Path(b).name}); "
            "they add no information: move or tilt the board between photos",
            FidlearnWarning,
        )
    if empty:
        warnings.warn(
            f"no board corner in the {', '.join(empty)} of the picture; hold the board there too, "
            "or the lens distortion is guessed where nothing was measured",
            FidlearnWarning,
        )
    if sparse:
        counts = ", ".join(f"{grid[r, k]}" for r in range(3) for k in range(3) if _CELL_NAMES[r][k] in sparse)
        warnings.warn(
            f"few board corners in the {', '.join(sparse)} of the picture ({counts}, under a tenth of the "
            f"{even_share:.0f} an even spread gives); hold the board there too, or the lens distortion "
            "is guessed where almost nothing was measured",
            FidlearnWarning,
        )

    from .planning.coach import coach_calibration

    coached = coach_calibration(cal)
    print("calibration coach: " + coached.report().replace("\n", "\n  "))
    with staging:
        if args.annotate:
            for view, path in zip(cal.views, paths):  # views come back in input order
                pts = cal.image_points_px.get(view.name)
                staging.save(Path(path).name, _draw_calibration_view(Path(path), view, pts, pattern, args.charuco))
        if report is not None:
            from .planning.figure import coach_figure

            fig = coach_figure(coached, c)
            atomic_write(report, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
        c.save(out)  # last: written only when everything before it succeeded
    print(f"camera written to {out}" + (f"; the coach's picture in {report}" if report else ""))
    if args.annotate:
        print(staging.said())
    return 0


# -- fidlearn locate -----------------------------------------------------------------------
def _add_locate(sub) -> None:
    p = sub.add_parser(
        "locate",
        help="camera pose in the world from the markers in images or a video",
        description=(
            "Find the camera's pose in the world for every image, every frame of a video "
            "(.mp4, .avi, ...) or a live camera: detect the map's markers, solve PnP over all "
            "of them, invert. One line per frame: position x, y, z (mm, world), roll, pitch, yaw "
            "(deg, the camera frame's rotation in the world, as 'fidlearn render --pose' takes "
            "it), the markers used, the RMS reprojection error (px) and whether a second pose "
            "explains the image as well (ambiguous). A frame with no marker of the map is "
            "reported, not an error. --json and --annotate are written only when the whole run "
            "succeeds: --json goes to a hidden temporary file, flushed frame by frame, renamed at "
            "the end; annotated images are staged in a hidden folder and moved into DIR at the end."
        ),
    )
    p.add_argument(
        "inputs", nargs="*", type=Path, metavar="IMAGE_OR_FOLDER_OR_VIDEO", help="images, folders of images, videos"
    )
    p.add_argument(
        "--camera", type=Path, required=True, metavar="CAMERA", help="camera file (fidlearn JSON or OpenCV YAML)"
    )
    _add_image_size_option(p)
    _add_map_options(p)
    p.add_argument(
        "--camera-index", type=int, metavar="N", help="also read a live camera (0 is the first); Ctrl-C stops"
    )
    p.add_argument("--json", type=Path, metavar="POSES.jsonl", help="write one JSON line per frame with T_world_camera")
    p.add_argument(
        "--annotate", type=Path, metavar="DIR", help="save each frame with the markers and the world axes drawn"
    )
    p.add_argument(
        "--refine", choices=["edges", "subpix", "contour", "apriltag", "none"], help="corner refinement (default edges)"
    )
    p.add_argument(
        "--max-megapixels",
        type=float,
        default=100.0,
        metavar="MP",
        help="largest picture read, in megapixels (default 100): a larger one is refused from its header",
    )
    p.set_defaults(run=_run_locate)


def _fmt_row(name: str, width: int, pose=None, note: str = "") -> str:
    import numpy as np

    if pose is None:
        return f"{name:<{width}}  {note}"
    x, y, z = np.round(pose.position_mm, 1) + 0.0  # + 0.0 turns -0.0 into 0.0
    r, pi, yw = np.round(pose.rpy_deg, 1) + 0.0
    ids = ",".join(str(i) for i in pose.marker_ids)
    flag = "AMBIGUOUS" if pose.ambiguous else "-"
    row = f"{name:<{width}} {x:9.1f} {y:9.1f} {z:9.1f} {r:7.1f} {pi:7.1f} {yw:7.1f}  {ids:<9} {pose.reprojection_rms_px:6.2f}  {flag}"
    return row + (f"  {note}" if note else "")


def _pose_record(name: str, pose) -> dict:
    import numpy as np

    rec = {
        "frame": name,
        "located": True,
        "T_world_camera": np.asarray(pose.T_world_camera).tolist(),
        "position_mm": pose.position_mm.tolist(),
        "rpy_deg": pose.rpy_deg.tolist(),
        # null, not NaN, when the pose is not determined: NaN is not JSON (strict readers, fidlearn's own, refuse it)
        "position_std_mm": pose.position_std_mm.tolist() if pose.covariance is not None else None,
        "marker_ids": list(pose.marker_ids),
        "reprojection_rms_px": pose.reprojection_rms_px,
        "ambiguous": bool(pose.ambiguous),
        "rejected_ids": list(pose.rejected_ids),
        "ignored_ids": list(pose.ignored_ids),
        "method": pose.method,
    }
    if pose.alternative is not None:
        rec["alternative_position_mm"] = pose.alternative.position_mm.tolist()
    return rec


def _draw_pose(image, detections, camera, pose, marker_map):
    """The frame with the detections, the world axes and the pose written on it."""
    import cv2
    import numpy as np

    from .detection import draw_detections

    out = draw_detections(image, detections, corner_labels=False)
    if pose is None:
        cv2.putText(out, "no known marker", (10, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 255), 2, cv2.LINE_AA)
        return out
    length = 2.0 * marker_map.marker_size_mm
    axes = np.array([[0, 0, 0], [length, 0, 0], [0, length, 0], [0, 0, length]], dtype=float)
    if np.all(camera.points_in_front(axes, pose.T_world_camera)):
        px = camera.project(axes, pose.T_world_camera)
        if np.all(np.abs(px) < 1e5):
            o = tuple(int(round(v)) for v in px[0])
            for k, colour in ((1, (0, 0, 255)), (2, (0, 200, 0)), (3, (255, 0, 0))):  # X red, Y green, Z blue
                cv2.arrowedLine(out, o, tuple(int(round(v)) for v in px[k]), colour, 2, cv2.LINE_AA, tipLength=0.15)
                cv2.putText(
                    out,
                    "XYZ"[k - 1],
                    tuple(int(round(v)) + 4 for v in px[k]),
                    cv2.FONT_HERSHEY_SIMPLEX,
                    0.6,
                    colour,
                    2,
                    cv2.LINE_AA,
                )
    x, y, z = np.round(pose.position_mm) + 0.0
    r, p, yw = np.round(pose.rpy_deg, 1) + 0.0
    text = f"x {x:.0f} y {y:.0f} z {z:.0f} mm  rpy {r:.1f} {p:.1f} {yw:.1f} deg  rms {pose.reprojection_rms_px:.2f} px"
    if pose.ambiguous:
        text += "  AMBIGUOUS"
    scale = 0.45 * max(out.shape[:2]) / 640
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    cv2.rectangle(out, (0, 0), (tw + 16, th + base + 12), (0, 0, 0), -1)
    cv2.putText(out, text, (8, th + 6), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def _run_locate(args) -> int:
    import statistics

    from .camera import Camera
    from .detection import detect_markers
    from .errors import CameraError, NoMarkersError, PoseError
    from .pose import estimate_pose

    if not args.inputs and args.camera_index is None:
        raise UsageError("give images, folders or videos to locate in, or --camera-index N for a live camera")
    if args.camera_index is not None and not 0 <= args.camera_index <= 255:
        # cv2.VideoCapture(-1) crashes the interpreter (segmentation fault) on OpenCV 4.x and 5.x
        # when no camera is attached, and 2**31 overflows OpenCV's int: refuse both before OpenCV sees them.
        raise UsageError(f"--camera-index {args.camera_index}: cameras are numbered 0 (the first camera) to 255")
    if not 0.01 <= args.max_megapixels <= 2000:
        raise UsageError(f"--max-megapixels {args.max_megapixels:g}: give 0.01 to 2000")
    items = _expand_inputs(args.inputs, videos=True)
    json_path = _check_output(args.json, (".jsonl", ".json"), "--json") if args.json else None
    _refuse_clobber([("--json", json_path)], [p for _, p in items] + [args.camera, args.map], args.annotate)
    staging = _Staging(args.annotate, keep_on_interrupt=True)
    camera = _load_camera(args)
    marker_map = _load_map(args)
    refine = {"refine": args.refine} if args.refine else {}
    width = max(
        [len(p.name) + (8 if k == "video" else 0) for k, p in items] + [len(f"camera{args.camera_index}#00000"), 5]
    )
    width = min(width, 40)
    cameras: dict[tuple[int, int], Camera] = {}
    stats = {"frames": 0, "located": 0, "ambiguous": 0, "rms": []}

    header = (
        f"{'frame':<{width}} {'x_mm':>9} {'y_mm':>9} {'z_mm':>9} {'roll':>7} {'pitch':>7} {'yaw':>7}  "
        f"{'markers':<9} {'rms_px':>6}  ambiguous"
    )

    def process(sink) -> None:
        with staging:
            try:
                for name, image in _frames(items, args.camera_index, int(args.max_megapixels * 1_000_000)):
                    size = (image.shape[1], image.shape[0])
                    if size not in cameras:  # rescale (and warn) once per resolution
                        try:
                            cameras[size] = camera.for_image(size)
                        except CameraError as exc:  # say which picture, in a folder of many
                            raise CameraError(f"{name}: {exc}") from None
                    cam = cameras[size]
                    detections = detect_markers(image, dictionary=marker_map.dictionary, **refine)
                    failure = "no known marker"
                    try:
                        pose = estimate_pose(detections, marker_map, cam)
                    except NoMarkersError:
                        pose = None
                    except PoseError as exc:  # a degenerate view: report the frame, keep going
                        pose, failure = None, f"no pose: {_one_line(str(exc))}"
                    if pose is None:
                        seen = sorted({d.id for d in detections})
                        note = failure
                        if failure == "no known marker" and seen:
                            note += f" (saw ids {', '.join(map(str, seen))}, not in the map)"
                        row = _fmt_row(name, width, None, note)
                        record = {"frame": name, "located": False, "reason": failure, "detected_ids": seen}
                    else:
                        stats["located"] += 1
                        stats["ambiguous"] += bool(pose.ambiguous)
                        stats["rms"].append(pose.reprojection_rms_px)
                        note = f"rejected {list(pose.rejected_ids)}" if pose.rejected_ids else ""
                        row = _fmt_row(name, width, pose, note)
                        record = _pose_record(name, pose)
                    if sink is not None:  # the record first: a row on the screen is always in the file
                        sink.write(record)
                    if stats["frames"] == 0:
                        print(header)
                    print(row, flush=True)
                    staging.save(name, _draw_pose(image, detections, cam, pose, marker_map))
                    stats["frames"] += 1
            except KeyboardInterrupt as exc:
                if args.camera_index is None or isinstance(exc, _Interrupted):
                    raise
                # Ctrl-C stopping a live camera is its normal end: keep what was seen

    try:
        if json_path is not None:
            with _StreamFile(json_path, "--json") as sink:
                process(sink)
        else:
            process(None)
    except KeyboardInterrupt as exc:
        kept = []
        if json_path is not None:
            n = sink.count
            kept.append(f"{json_path} holds {n} whole frame record{'s' if n != 1 else ''}")
        if args.annotate:
            kept.append(staging.said())
        print(
            f"error: interrupted by {_signal_name(exc)} after {stats['frames']} frames"
            + (f"; {'; '.join(kept)}" if kept else ""),
            file=sys.stderr,
        )
        return 128 + (exc.signum if isinstance(exc, _Interrupted) else signal.SIGINT)
    n, located = stats["frames"], stats["located"]
    if n > 1 or args.camera_index is not None:
        med = f", median rms {statistics.median(stats['rms']):.2f} px" if stats["rms"] else ""
        amb = f", {stats['ambiguous']} ambiguous" if stats["ambiguous"] else ""
        print(f"{n} frames, {located} located ({100.0 * located / max(n, 1):.0f} %){med}{amb}")
    if json_path:
        print(f"poses written to {json_path}")
    if args.annotate:
        print(staging.said())
    return 0


#: Subcommand builders, in the order ``fidlearn --help`` lists them.
def _add_plan(sub) -> None:
    from .planning import command

    p = sub.add_parser("plan", help=command.HELP, description=command.__doc__)
    command.add_arguments(p)
    p.set_defaults(run=command.run)


def _add_release(sub) -> None:
    p = sub.add_parser(
        "release",
        help="an exercise lesson for each learner of a class, its answers kept by the instructor",
        description="Write OUT/<learner>/ for every learner of the roster: the lesson's student notebook and "
        "fidlearn_inputs.json, that learner's numbers without their answers (seeded by the class "
        "secret). 'fidlearn grade' grades what comes back.",
    )
    p.add_argument("--lesson", required=True, help="lesson number, e.g. 03")
    p.add_argument(
        "--secret-file", type=Path, required=True, help="the class secret ('fidlearn grade --new-secret FILE')"
    )
    p.add_argument("--learners", type=Path, required=True, help="roster: one learner id per line")
    p.add_argument("-o", "--output", type=Path, required=True, help="folder to write the learners' folders in")
    p.set_defaults(run=_run_release)


def _run_release(args) -> int:
    from . import grading
    from ._files import MAX_TEXT_BYTES, read_bytes

    _, data = read_bytes(args.learners, UsageError, "roster", MAX_TEXT_BYTES)
    learners = [
        line.strip()
        for line in data.decode("utf-8", "replace").splitlines()
        if line.strip() and not line.startswith("#")
    ]
    if not learners:
        raise UsageError(f"--learners {args.learners}: no learner ids (one per line)")
    folders = grading.release(args.lesson, learners, args.secret_file, args.output)
    print(f"{len(folders)} learner folders in {args.output}/ (lesson {args.lesson}); hand each learner their own")
    return 0


def _add_grade(sub) -> None:
    p = sub.add_parser(
        "grade",
        help="grade learners' exercise notebooks, each in a sandbox, the answer key outside it",
        description="Run each submitted notebook in a process of its own (scratch folder, time and memory "
        "limits, no instructor's environment; as 'nobody' when run as root) and grade the answers "
        "it leaves in the grader's process, against the variant the class secret gives that "
        "learner. A notebook that crashes, hangs or cheats gets 0 with the reason; the CSV is "
        "always written. Grading runs learners' code: see docs/teaching.md.",
    )
    p.add_argument("notebooks", nargs="*", type=Path, help="submitted notebooks (.ipynb)")
    p.add_argument("--lesson", help="lesson number, e.g. 03")
    p.add_argument("--secret-file", type=Path, help="the class secret")
    p.add_argument(
        "--learner", help="the learner of every notebook given (default: each file's name, e.g. alice.ipynb)"
    )
    p.add_argument("-o", "--output", type=Path, help="grades.csv: one row per question")
    p.add_argument("--timeout", type=int, default=120, help="seconds a notebook may run (default 120)")
    p.add_argument("--memory-mb", type=int, default=3000, help="memory a notebook may use, MB (default 3000)")
    p.add_argument("--run-as", metavar="USER", help="run notebooks as this user (default 'nobody' when root)")
    p.add_argument("--new-secret", type=Path, metavar="FILE", help="create a class secret in FILE and stop")
    p.set_defaults(run=_run_grade)


def _run_grade(args) -> int:
    from . import grading

    if args.new_secret is not None:
        grading.new_secret(args.new_secret)
        print(f"{args.new_secret}: a new class secret; keep it private (it decides every learner's numbers)")
        return 0
    missing = [
        opt
        for opt, v in (("--lesson", args.lesson), ("--secret-file", args.secret_file), ("-o", args.output))
        if v is None
    ]
    if missing or not args.notebooks:
        raise UsageError(
            "give the notebooks, --lesson, --secret-file and -o grades.csv"
            if not missing
            else f"{missing[0]} is required to grade"
        )
    out = _check_output(args.output, (".csv",))
    if not 5 <= args.timeout <= 3600 or not 200 <= args.memory_mb <= 65536:
        raise UsageError("--timeout is 5 to 3600 s and --memory-mb 200 to 65536")
    _refuse_clobber([("-o", out)], [*args.notebooks, args.secret_file])
    for nb in args.notebooks:
        if not nb.is_file():
            raise UsageError(f"{nb}: no such notebook; give the learners' .ipynb files")
    if os.geteuid() != 0 and args.run_as is None:
        print(
            "warning: grading as your own user: a notebook can read what you can; see docs/teaching.md", file=sys.stderr
        )

    def progress(k: int, n: int, g) -> None:
        print(f"[{k}/{n}] {g.line()}", flush=True)

    grades = grading.grade(
        args.notebooks,
        args.lesson,
        args.secret_file,
        out,
        learner=args.learner,
        timeout_s=args.timeout,
        memory_mb=args.memory_mb,
        run_as=args.run_as,
        progress=progress,
    )
    print(f"{len(grades)} notebooks graded; grades in {out}")
    return 0


COMMANDS: list[Callable] = [
    _add_board,
    _add_calibrate,
    _add_markers,
    _add_corners,
    _add_locate,
    _add_render,
    _add_plan,
    _add_release,
    _add_grade,
    _add_doctor,
]


_WORKFLOW = """\
from printer to pose:
  fidlearn board --pattern 9x6 --square-mm 25 -o board.pdf         print, measure a square
  fidlearn calibrate photos/ --pattern 9x6 --square-mm 25 -o camera.json
  fidlearn markers --ids 0-2 --size-mm 80 -o markers.pdf           print, tape up, measure
  fidlearn corners map.json -o corners.json                        check the map
  fidlearn locate frames/ --camera camera.json --map map.json      the camera's pose
  fidlearn plan map.json --camera camera.json -o plan.png          the error to expect, before printing
'fidlearn COMMAND --help' tells more."""


class _TopHelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps each command and its help on one line (argparse forgets the commands' extra indent)."""

    def __init__(self, prog):
        super().__init__(prog, max_help_position=24, width=100)

    def add_argument(self, action):
        super().add_argument(action)
        if isinstance(action, argparse._SubParsersAction):
            longest = max((len(name) for name in action.choices), default=0)
            self._action_max_length = max(self._action_max_length, longest + 2 * self._indent_increment + 2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="fidlearn",
        description="Camera localization from ArUco fiducials: calibrate, map, detect, locate.",
        epilog=_WORKFLOW,
        formatter_class=_TopHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"fidlearn {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in COMMANDS:
        add(sub)
    return parser


def _quiet_opencv() -> None:
    """The command's own process: OpenCV's and FFmpeg's log lines would break the one-line errors.

    fidlearn reports every failure itself. This sets OpenCV's log level for this process (the
    command line owns it); the library never does, and never redirects file descriptors.
    """
    import os

    import cv2

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET, read when a video is opened
    log = getattr(getattr(cv2, "utils", None), "logging", None)
    if log is not None and hasattr(log, "LOG_LEVEL_SILENT"):
        log.setLogLevel(log.LOG_LEVEL_SILENT)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 problem found, 2 user error).

    SIGTERM and SIGHUP are handled as Ctrl-C is: a streaming output keeps every frame finished,
    under its final name. A standard output that closes (``| head``) silences the rest of the
    printing, not the work.
    """
    _quiet_opencv()
    stdout, handlers = sys.stdout, {}
    sys.stdout = _SafeStdout(stdout)
    try:
        for sig in (signal.SIGTERM, signal.SIGHUP):
            try:
                handlers[sig] = signal.signal(sig, _raise_interrupted)
            except (ValueError, OSError):  # not the main thread: leave signals alone
                pass
        return _main(argv)
    finally:
        for sig, old in handlers.items():
            signal.signal(sig, old)
        sys.stdout.flush()
        sys.stdout = stdout


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(_join_negative_values(sys.argv[1:] if argv is None else list(argv)))
        if not getattr(args, "run", None):
            parser.print_help()
            return 2
        with warnings.catch_warnings():
            warnings.simplefilter("always", FidlearnWarning)
            warnings.showwarning = _show_warning
            return int(args.run(args) or 0)
    except FidlearnError as exc:
        _error(str(exc))
        return 2
    except KeyboardInterrupt as exc:
        _error(f"interrupted by {_signal_name(exc)}; nothing was written")
        return 128 + (exc.signum if isinstance(exc, _Interrupted) else signal.SIGINT)
    except OSError as exc:  # the disk, not the code: permission denied, disk full, ...
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        _error(f"{where}{exc.strerror or exc}; check the path and its permissions")
        return 2


def _error(text: str) -> None:
    line = f"error: {_one_line(text)}"
    try:
        print(line, file=sys.stderr)
    except UnicodeEncodeError:
        enc = getattr(sys.stderr, "encoding", None) or "ascii"
        print(line.encode(enc, "backslashreplace").decode(enc), file=sys.stderr)


#: Options whose value is a comma-separated list of numbers that may start with a minus sign.
_NUMBER_LIST_OPTIONS = ("--pose", "--look-at", "--from", "--area")
_NUMBER_LIST = re.compile(r"-\d*\.?\d+(e[-+]?\d+)?(,\s*-?\d*\.?\d+(e[-+]?\d+)?)*", re.IGNORECASE)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--from -1000,190,230`` -> ``--from=-1000,190,230``.

    argparse takes a value starting with ``-`` for an option unless it is a single
    negative number, so a camera behind the wall (x < 0) failed with "expected one argument".
    """
    out: list[str] = []
    k = 0
    while k < len(argv):
        arg = argv[k]
        if arg in _NUMBER_LIST_OPTIONS and k + 1 < len(argv) and _NUMBER_LIST.fullmatch(argv[k + 1]):
            out.append(f"{arg}={argv[k + 1]}")
            k += 2
            continue
        out.append(arg)
        k += 1
    return out


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {_one_line(str(message))}", file=sys.stderr)
